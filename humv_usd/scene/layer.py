"""Scene tool: ground, objects (buildings, props, panels), assets from 3D files and whole site
layers → layers/scene.usda.

Assets (``[[scene.asset]]``, :mod:`humv_usd.scene.assets`) live at /World/Scene/<id>, an Xform
with the asset's scale and placement and HumvLabelAPI (instance id ``asset:<id>``, class):

* a USD file is referenced, not copied (the written layer holds the path relative to its
  folder when they share one, see :mod:`humv_usd.pipeline.compose`), by the child /World/Scene/<id>/<root prim name> (the
  file's defaultPrim, else its first root prim); the asset's transform also converts the file's
  metersPerUnit and upAxis to Z-up metres (recorded in customData ``humv:assetSource`` for
  ``humv-usd check``); the layer adds ``over``s on its meshes and their material GeomSubsets:
  material binding to the mapped library material (the render and the thermal slabs honour
  per-subset bindings: a subset's faces are slabs of its material), class where a ``classes`` pattern matches, ``instanceable = false`` on its
  instance roots (the thermal layer writes a temperature onto each mesh);
* a mesh file (OBJ, glTF/GLB, PLY, STL, FBX) becomes UsdGeom.Mesh children written into this
  layer, converted to Z-up metres. Written inline rather than as a sidecar usdc next to the layer:
  compose builds every layer in memory and writes each file atomically once all succeeded,
  recognises hand edits by the layer's text and keys caches by it; a sidecar would be a file
  outside that bookkeeping. The price is a larger usda for big assets.

Site layers (``[scene] layers``) are sublayers of this layer (relative paths in the written
file, as for assets): they compose at the
scene layer's strength, below its own opinions. Their meshes without a HumV material are bound to
``layer_material``; each top prim under /World/Scene gets an instance id (``layer:<i>:<name>``).
"""

from __future__ import annotations

import math
from pathlib import Path

from pxr import Sdf, Usd, UsdGeom

from humv_usd.errors import InputError
from humv_usd.scenario import Scenario
from humv_usd.scenario.ids import SITE_SCOPE, instance_ids, site_layer_prims
from humv_usd.scenario.inputs import FRAMES
from humv_usd.scenario.places import scene_clutter, scene_objects
from humv_usd.scenario.times import utc_times
from humv_usd.scene.assets import (
    AssetFile,
    first_match,
    placement,
    prim_name,
    read_asset,
    source_correction,
)
from humv_usd.scene.geometry import box
from humv_usd.scene.ground import author_ground, cover_roof, footprint_base, scene_terrain
from humv_usd.scene.objects import author_clutter
from humv_usd.scene.puddles import author_puddles, puddle_discs
from humv_usd.scene.vegetation import PLANT_KINDS, author_plant
from humv_usd.usd.labels import nearest_class
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage, set_kind, usd_error_text
from humv_usd.usd.materials import has_stage_material
from humv_usd.usd.mesh import bind_material, define_mesh, label, write_asset_source, write_class
from humv_usd.usd.paths import GROUND, material_path, object_path

NAME = "scene"
#: ``@clutterAir``: the clock and the air, read only when there is warm clutter (its held
#: temperatures: engines, coats, lit lamps at night); a scene without clutter keeps its layer
#: across start times and weather
READS = (*FRAMES, "scene", "@ids", "@clutterAir", "@puddles")
UPSTREAM = ()
#: 4: model kinds; 5: warm clutter and generated places; 6: terrain, ground to the horizon; 7: plants
#: 8: puddles after rain; 9: snow cover on the ground ([scene.ground] snow_depth_m); 10: and roofs;
#: 11: shallow snow bound as <material>__snow<mm>
VERSION = "11"


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g, scene = scenario["general"], scenario["scene"]
    ids = instance_ids(scenario)
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, "HumV-USD scene layer: " + (scene["site"] or "ground and objects")
    )
    set_kind(UsdGeom.Xform.Define(stage, SCOPES["scene"]).GetPrim(), "group")
    author_ground(stage, scene, ids)  # terrain, zones, out to the horizon
    terrain = scene_terrain(scene)
    for o in scene_objects(scene):  # the scenario's, then a generated place's
        if o["kind"] in PLANT_KINDS:  # trees, bushes, hedges (issue 30.2)
            x, y, _ = o["center_m"]
            base = footprint_base(terrain, (x, y), (0.5, 0.5)) - 0.05  # the trunk a little into the ground
            set_kind(author_plant(stage, o, base, ids[f"object:{o['id']}"]), "component")
            continue
        mesh = define_mesh(
            stage,
            object_path(o["id"]),
            *box(_on_terrain(terrain, o), o["size_m"], o["heading_deg"]),
            material=material_path(o["material"]),
        )
        label(mesh.GetPrim(), ids[f"object:{o['id']}"], o["class"])
        set_kind(mesh.GetPrim(), "component")
        cover_roof(stage, mesh, scene, o["material"])  # snow on its roof (issue 30.4)
    for a in scene.get("asset") or ():
        prim = author_asset(
            stage, a, read_asset(a["file"], a["units"], a["up_axis"]), ids[f"asset:{a['id']}"]
        )
        set_kind(prim, "component")
    if scene.get("layers"):
        add_site_layers(stage, scene, ids)
    clutter = scene_clutter(scene)
    if clutter:
        atm = scenario["atmosphere"] or {}
        air_k = float(atm.get("air_temperature_k", 293.15))
        elevation = sun_elevation_deg(scenario)
        for c in clutter:
            author_clutter(
                stage,
                c,
                ids[f"clutter:{c['id']}"],
                air_k,
                float(atm.get("wind_speed_m_s", 1.0)),
                elevation,
                float(atm.get("cloud_cover", 0.0)),
                g["fps"],
                scenario.frame_count,
                terrain.height,  # standing on the terrain (and following it while driving)
            )
    share = float(scene["ground"].get("puddles") or 0.0)
    if share > 0.0 and float((scenario["atmosphere"] or {}).get("rain_mm_h") or 0.0) > 0.0:
        seed = int(g.get("seed") or 0)
        discs = puddle_discs(seed, share, scene["ground"]["size_m"], _keep_out(scene))
        author_puddles(stage, discs, terrain, ids["ground_puddles"], seed)
    return finish(stage)


def _keep_out(scene: dict) -> list[tuple[float, float, float]]:
    """(x, y, radius) [m] circles around what stands on the ground (objects, plants, assets,
    warm clutter), where no puddle lies (:mod:`humv_usd.scene.puddles`)."""
    out = []
    for o in scene_objects(scene):
        x, y, _ = o["center_m"]
        out.append((x, y, 0.5 * math.hypot(o["size_m"][0], o["size_m"][1])))
    for a in scene.get("asset") or ():
        if a.get("position_m") is not None:
            out.append((a["position_m"][0], a["position_m"][1], 3.0))
    for c in scene_clutter(scene):
        out.append((c["position_m"][0], c["position_m"][1], 3.0 * float(c.get("scale") or 1.0)))
    return out


def sun_elevation_deg(scenario: Scenario) -> float:
    """Apparent sun elevation at frame 0 [deg] (NREL SPA through pvlib): lamps' photocells and
    the parked cars' solar cabin heating."""
    import pvlib

    g = scenario["general"]
    pos = pvlib.solarposition.get_solarposition(
        utc_times(scenario, [0.0]), g["latitude_deg"], g["longitude_deg"], g["elevation_m"]
    )
    return float(pos["apparent_elevation"].iloc[0])


def _on_terrain(terrain, o: dict) -> list[float]:
    """An object's base centre with its z taken above the terrain under its footprint
    (:func:`humv_usd.scene.ground.footprint_base`; unchanged on flat ground)."""
    x, y, z = o["center_m"]
    return [x, y, z + footprint_base(terrain, (x, y), o["size_m"][:2], o["heading_deg"])]


def author_asset(stage: Usd.Stage, a: dict, asset: AssetFile, instance_id: int) -> Usd.Prim:
    """/World/Scene/<id>: placement, label and the asset's meshes (see the module doc)."""
    root = UsdGeom.Xform.Define(stage, object_path(a["id"]))
    matrix = placement(a)
    if asset.kind == "usd":  # the file stays as it is: its units and up axis are corrected here
        matrix = source_correction(asset.meters_per_unit, asset.up_axis) * matrix
    root.AddTransformOp().Set(matrix)
    label(root.GetPrim(), instance_id, a["class"])
    if asset.kind == "usd":
        _reference_usd(stage, root.GetPrim(), a, asset)
        return root.GetPrim()
    taken: set[str] = set()
    for m in asset.meshes:
        path = root.GetPath().AppendChild(prim_name(m.name, taken))
        material = material_path(first_match(a["materials"], m, a["material"]))
        mesh = define_mesh(stage, path, m.points, m.face_counts, m.face_indices, material)
        _mapped_class(mesh.GetPrim(), a, m)
    return root.GetPrim()


def _reference_usd(stage: Usd.Stage, root: Usd.Prim, a: dict, asset: AssetFile) -> None:
    """The child that references the file (typeless: it takes the type of the file's root),
    with overs on its meshes."""
    src = Sdf.Path(asset.root_prim)
    prim = stage.DefinePrim(root.GetPath().AppendChild(src.name))
    prim.GetReferences().AddReference(str(Path(asset.file).resolve()), src)
    prim.SetInstanceable(False)
    write_asset_source(prim, asset.file, asset.meters_per_unit, asset.up_axis)
    for rel in asset.instances:
        stage.OverridePrim(prim.GetPath().AppendPath(rel)).SetInstanceable(False)
    for m in asset.meshes:
        over = stage.OverridePrim(prim.GetPath().AppendPath(m.path)) if m.path != "." else prim
        bind_material(over, material_path(first_match(a["materials"], m, a["material"])))
        _mapped_class(over, a, m)


def _mapped_class(prim: Usd.Prim, a: dict, mesh) -> None:
    cls = first_match(a["classes"], mesh, None)
    if cls is not None and cls != a["class"]:
        write_class(prim, cls)


def add_site_layers(stage: Usd.Stage, scene: dict, ids: dict[str, int]) -> None:
    """Sublayer the site layers; bind their meshes without a HumV material, label their top prims."""
    files = list(scene["layers"])
    ours = {GROUND.name} | {o["id"] for o in scene["object"]} | {a["id"] for a in scene.get("asset") or ()}
    for file in files:
        _check_site_layer(file)
        clash = sorted(ours & set(site_layer_prims(file)))
        if clash:
            raise InputError(
                f"{file}: {SITE_SCOPE}/{clash[0]} is also a scene object, asset or the ground of the "
                "scenario; rename one of them"
            )
    stage.GetRootLayer().subLayerPaths = [str(Path(f).resolve()) for f in files]
    material = material_path(scene["layer_material"])
    for i, file in enumerate(files):
        site = Usd.Stage.Open(file)
        scope = site.GetPrimAtPath(SITE_SCOPE)
        for prim in Usd.PrimRange(scope) if scope else ():
            if prim.IsA(UsdGeom.Mesh) and not has_stage_material(prim):
                bind_material(stage.OverridePrim(prim.GetPath()), material)
        for key, iid in ids.items():
            if not key.startswith(f"layer:{i}:"):
                continue
            path = SITE_SCOPE.AppendChild(key.split(":", 2)[2])
            _, own = nearest_class(site.GetPrimAtPath(path))
            label(stage.OverridePrim(path), iid, own or scene["layer_class"])


def _check_site_layer(file: str) -> None:
    """A site layer must open, be Z-up in metres (a sublayer cannot be converted) and hold
    prims under /World/Scene."""
    try:
        layer = Sdf.Layer.FindOrOpen(file)
    except Exception as exc:  # noqa: BLE001 (pxr raises Tf.ErrorException)
        raise InputError(f"{file}: does not open as a USD layer ({usd_error_text(exc)[:200]})") from None
    if layer is None:
        raise InputError(f"{file}: does not open as a USD layer")
    up = (
        layer.pseudoRoot.GetInfo(UsdGeom.Tokens.upAxis)
        if layer.pseudoRoot.HasInfo(UsdGeom.Tokens.upAxis)
        else "Y"
    )
    mpu = (
        layer.pseudoRoot.GetInfo(UsdGeom.Tokens.metersPerUnit)
        if layer.pseudoRoot.HasInfo(UsdGeom.Tokens.metersPerUnit)
        else 0.01
    )
    if up != UsdGeom.Tokens.z or not math.isclose(float(mpu), 1.0):
        raise InputError(
            f"{file}: upAxis {up}, metersPerUnit {mpu} (USD's fallbacks where unauthored); a site layer "
            "must be Z-up in metres: re-export it so, or bring it in as a [[scene.asset]] with units/up_axis"
        )
    if not layer.GetPrimAtPath(SITE_SCOPE):
        raise InputError(f"{file}: no prims under {SITE_SCOPE} (a site layer's prims live there)")
