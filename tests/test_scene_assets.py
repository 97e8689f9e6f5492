"""Scene assets from 3D files ([[scene.asset]], [scene] layers) and `check` on what render rejects.

Formats are read by the real readers (trimesh for glTF/PLY/STL, pxr for USD, bpy for FBX) and
compared with the geometry that was written; the conversion to Z-up metres with closed forms.
"""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from pxr import Sdf, Usd, UsdGeom, UsdShade, UsdUtils

from humv_usd.errors import InputError
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.inputs import read_values
from humv_usd.scene.assets import read_asset
from humv_usd.usd.check import check_stage

ROOT = Path(__file__).resolve().parents[1]
STREET = ROOT / "examples" / "street.toml"
ASSETS = ROOT / "examples" / "assets"


def street_raw(tmp_path: Path, humans: bool = False) -> dict:
    """examples/street.toml with its assets copied next to a scenario file in tmp_path; without
    people unless asked; small LWIR sensor only (the fast tests)."""
    shutil.copytree(ASSETS, tmp_path / "assets")
    raw = tomllib.loads(STREET.read_text())
    if not humans:
        raw.pop("human"), raw.pop("placement")
    raw["sensor"] = [dict(raw["sensor"][0], resolution=[64, 48], pixel_pitch_um=17.0)]
    raw["sensor"][0].pop("preset")
    raw["sensor"][0].update(band="LWIR", focal_length_mm=25.0 / 16)
    raw["general"]["duration_s"] = 0.0
    raw["thermal"]["surface_spin_up_s"] = 3600.0
    return raw


def scenario_at(tmp_path: Path, raw: dict):
    return validate(raw, tmp_path / "street.toml")


# ------------------------------------------------------------------------------------ formats
def test_gltf_y_up_becomes_z_up_metres():
    """The car: trimesh's own read of the GLB (Y-up) against ours, (x, y, z) -> (x, -z, y)."""
    asset = read_asset(str(ASSETS / "vehicle.glb"))
    scene = trimesh.load(ASSETS / "vehicle.glb", force="scene")
    ref = scene.to_geometry().vertices
    ours = np.concatenate([m.points for m in asset.meshes])
    np.testing.assert_allclose(
        ours.min(axis=0), [ref[:, 0].min(), -ref[:, 2].max(), ref[:, 1].min()], atol=1e-6
    )
    np.testing.assert_allclose(
        ours.max(axis=0), [ref[:, 0].max(), -ref[:, 2].min(), ref[:, 1].max()], atol=1e-6
    )
    assert ours[:, 2].min() == pytest.approx(0.0, abs=1e-6)  # wheels on the ground
    assert {m.material for m in asset.meshes} == {"Paint", "Glass", "Tyre"}


@pytest.mark.parametrize("suffix", [".ply", ".stl", ".obj"])
def test_mesh_formats_with_units_and_up_axis(tmp_path, suffix):
    """A 2 x 4 x 6 box exported by trimesh, declared Y-up in cm: 0.02 x 0.06 x 0.04 m, Z-up."""
    box = trimesh.creation.box(extents=[2.0, 4.0, 6.0])
    box.apply_translation([1.0, 2.0, 3.0])  # corner at the origin
    path = tmp_path / f"box{suffix}"
    box.export(path)
    asset = read_asset(str(path), units="cm", up_axis="Y")
    pts = np.concatenate([m.points for m in asset.meshes])
    np.testing.assert_allclose(pts.min(axis=0), [0.0, -0.06, 0.0], atol=1e-9)
    np.testing.assert_allclose(pts.max(axis=0), [0.02, 0.0, 0.04], atol=1e-9)
    faces = sum(len(m.face_counts) for m in asset.meshes)
    assert faces == len(box.faces)


def test_obj_objects_and_materials():
    asset = read_asset(str(ASSETS / "bench.obj"))
    assert [(m.name, m.material) for m in asset.meshes] == [
        ("Seat", "Wood"),
        ("Back", "Wood"),
        ("LegLeft", "Metal"),
        ("LegRight", "Metal"),
    ]


def test_usd_asset_units_read_from_the_file():
    asset = read_asset(str(ASSETS / "building.usda"))
    assert (asset.kind, asset.meters_per_unit, asset.up_axis, asset.root_prim) == (
        "usd",
        0.01,
        "Y",
        "/Building",
    )
    assert {m.material for m in asset.meshes} == {"Wall", "Glass", "Frame"}


@pytest.mark.slow
def test_fbx_through_blender(tmp_path):
    """An FBX written by Blender (bpy) comes back with its object, material and size."""
    bpy = pytest.importorskip("bpy")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(1.0, 2.0, 3.0))
    cube = bpy.context.active_object
    cube.name = "Crate"
    cube.data.materials.append(bpy.data.materials.new("Planks"))
    bpy.ops.export_scene.fbx(filepath=str(tmp_path / "crate.fbx"))
    asset = read_asset(str(tmp_path / "crate.fbx"))
    (m,) = asset.meshes
    assert (m.name, m.material, len(m.face_counts)) == ("Crate", "Planks", 6)
    np.testing.assert_allclose(m.points.min(axis=0), [0.0, 1.0, 2.0], atol=1e-5)
    np.testing.assert_allclose(m.points.max(axis=0), [2.0, 3.0, 4.0], atol=1e-5)


# ---------------------------------------------------------------------------------- compose
@pytest.fixture
def street(tmp_path):
    raw = street_raw(tmp_path)
    scenario = scenario_at(tmp_path, raw)
    compose(scenario, tmp_path / "o")
    return scenario, tmp_path / "o"


def _meshes_under(stage, path):
    return [p for p in Usd.PrimRange(stage.GetPrimAtPath(path)) if p.IsA(UsdGeom.Mesh)]


def test_assets_composed_with_materials_labels_and_temperatures(street):
    scenario, out = street
    stage = Usd.Stage.Open(str(out / "stage.usda"))
    ids = instance_ids(scenario)
    expect = {
        "/World/Scene/car/Body": ("painted_metal", "vehicle", ids["asset:car"]),
        "/World/Scene/car/Windscreen": ("glass", "vehicle", ids["asset:car"]),
        "/World/Scene/car/Wheel0": ("soil", "vehicle", ids["asset:car"]),
        "/World/Scene/building/Building/Walls": ("concrete", "building", ids["asset:building"]),
        "/World/Scene/building/Building/WindowGlass3": ("glass", "building", ids["asset:building"]),
        "/World/Scene/building/Building/Door": ("painted_metal", "other", ids["asset:building"]),
        "/World/Scene/bench/LegLeft": ("painted_metal", "prop", ids["asset:bench"]),
    }
    from humv_usd.usd.labels import instance_id, nearest_class

    for path, (material, cls, iid) in expect.items():
        prim = stage.GetPrimAtPath(path)
        assert prim.IsA(UsdGeom.Mesh), path
        bound, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        assert bound.GetPath() == Sdf.Path(f"/World/Materials/{material}"), path
        assert nearest_class(prim)[1] == cls, path
        assert instance_id(prim) == iid, path
    # the building (Y-up cm) stands on the ground, facade at y = 4 m facing the street
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_])
    box = cache.ComputeWorldBound(stage.GetPrimAtPath("/World/Scene/building")).ComputeAlignedRange()
    np.testing.assert_allclose(box.GetMin(), [-6.0, 3.94, 0.0], atol=1e-6)  # glass 6 cm proud
    np.testing.assert_allclose(box.GetMax(), [6.0, 12.0, 6.0], atol=1e-6)
    # every asset mesh has one temperature per face from the thermal tool: slabs, the bench held
    thermal = json.loads((out / "compose.json").read_text())
    assert any(e["name"] == "thermal" for e in thermal["layers"])
    for prim in _meshes_under(stage, "/World/Scene"):
        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:thermal:temperature")
        faces = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get())
        values = np.asarray(pv.Get(0))
        assert len(values) == faces, prim.GetPath()
        if str(prim.GetPath()).startswith("/World/Scene/bench"):
            assert np.all(values == 295.0)
        else:
            assert np.all((values > 250.0) & (values < 340.0)), prim.GetPath()
    assert check_stage(out / "stage.usda") == []


def test_assets_shade_the_ground_slab(street):
    """The building's meshes cast shadows in the thermal tool's slab model: ground faces under
    its footprint (shaded all through the spin-up) are cooler than open ground."""
    _, out = street
    stage = Usd.Stage.Open(str(out / "stage.usda"))
    ground = stage.GetPrimAtPath("/World/Scene/Ground")
    mesh = UsdGeom.Mesh(ground)
    pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    idx = np.split(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()), np.cumsum(counts)[:-1])
    centres = np.array([pts[i].mean(axis=0) for i in idx])
    temps = np.asarray(UsdGeom.PrimvarsAPI(ground).GetPrimvar("humv:thermal:temperature").Get(0))
    under = (np.abs(centres[:, 0]) < 5.0) & (centres[:, 1] > 5.0) & (centres[:, 1] < 11.0)
    far = np.hypot(centres[:, 0], centres[:, 1] - 8.0) > 25.0
    assert under.sum() >= 1 and far.sum() > 10
    assert temps[under].max() < np.median(temps[far]) - 1.0


def test_asset_file_content_is_in_the_cache_key(tmp_path):
    raw = street_raw(tmp_path)
    before = read_values(scenario_at(tmp_path, raw), ("scene",))
    with open(tmp_path / "assets" / "bench.obj", "a") as f:
        f.write("# edited\n")
    after = read_values(scenario_at(tmp_path, raw), ("scene",))
    changed = [k for k in before if before[k] != after[k]]
    assert changed == ["scene.asset.2.file"]


@pytest.mark.parametrize(
    ("name", "content", "what"),
    [
        ("broken.glb", b"glTF\x02\x00\x00\x00garbage", "cannot be read"),
        ("broken.usda", b"#usda 1.0\ndef Mesh (", "does not open as USD"),
        ("empty.obj", b"# nothing\n", "holds no triangle mesh"),
        ("bad.obj", b"v 0 0 0\nf 1 2 3\n", "line 2"),
    ],
)
def test_bad_asset_file_is_one_line_and_nothing_written(tmp_path, name, content, what):
    raw = street_raw(tmp_path)
    (tmp_path / name).write_bytes(content)
    raw["scene"]["asset"][2]["file"] = name
    with pytest.raises(InputError) as err:
        compose(scenario_at(tmp_path, raw), tmp_path / "o")
    assert len(err.value.problems) == 1
    line = err.value.problems[0]
    assert line.startswith(str(tmp_path / name)) and what in line
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_bad_asset_file_on_the_command_line(tmp_path):
    """`humv-usd compose`: exit 2, one line naming the file, no output folder content."""
    import tomlkit

    from humv_usd.cli.main import main

    raw = street_raw(tmp_path)
    (tmp_path / "car.glb").write_bytes(b"not a glb")
    raw["scene"]["asset"][0]["file"] = "car.glb"
    (tmp_path / "street.toml").write_text(tomlkit.dumps(raw))
    result = CliRunner().invoke(main, ["compose", str(tmp_path / "street.toml"), "-o", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f"humv-usd: error: {tmp_path / 'car.glb'}: cannot be read"
    ), lines
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_bad_scenario_keys(tmp_path):
    raw = street_raw(tmp_path)
    raw["scene"]["asset"][0]["materials"] = {"Glass": "glas"}
    with pytest.raises(InputError) as err:
        scenario_at(tmp_path, raw)
    text = str(err.value)
    assert "scene.asset[0].materials.Glass = 'glas'" in text and "did you mean 'glass'" in text
    raw["scene"]["asset"][0]["materials"] = {"Glass": "glass"}
    raw["scene"]["asset"][1]["file"] = "assets/building.max"
    raw["scene"]["asset"][2]["transform"] = [[1, 0, 0, 0]]
    with pytest.raises(InputError) as err:
        scenario_at(tmp_path, raw)
    text = str(err.value)
    assert "scene.asset[1].file = 'assets/building.max': expected a file ending in" in text
    assert "scene.asset[2].transform" in text


def test_full_transform_equals_position_and_heading(tmp_path):
    raw = street_raw(tmp_path)
    a = raw["scene"]["asset"][0]
    h = np.radians(30.0)
    rows = [[np.cos(h), np.sin(h), 0, 0], [-np.sin(h), np.cos(h), 0, 0], [0, 0, 1, 0], [1.0, 2.0, 0.5, 1]]
    a.update(position_m=[1.0, 2.0, 0.5], heading_deg=30.0)
    compose(scenario_at(tmp_path, raw), tmp_path / "a")
    del a["position_m"], a["heading_deg"]
    a["transform"] = [[float(v) for v in r] for r in rows]
    compose(scenario_at(tmp_path, raw), tmp_path / "b")
    worlds = []
    for o in ("a", "b"):
        stage = Usd.Stage.Open(str(tmp_path / o / "stage.usda"))
        prim = stage.GetPrimAtPath("/World/Scene/car/Body")
        worlds.append(np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(0)))
    np.testing.assert_allclose(worlds[0], worlds[1], atol=1e-9)


def _shed_layer(site: Path) -> Usd.Stage:
    """A DCC layer (Z-up metres) with a shed under /World/Scene and no HumV material."""
    stage = Usd.Stage.CreateNew(str(site))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    UsdGeom.Xform.Define(stage, "/World/Scene")
    UsdGeom.Xform.Define(stage, "/World/Scene/Shed")
    cube = UsdGeom.Mesh.Define(stage, "/World/Scene/Shed/Walls")
    cube.CreatePointsAttr(
        [(8, 8, 0), (10, 8, 0), (10, 10, 0), (8, 10, 0), (8, 8, 2), (10, 8, 2), (10, 10, 2), (8, 10, 2)]
    )
    cube.CreateFaceVertexCountsAttr([4] * 6)
    cube.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7])
    stage.GetRootLayer().Save()
    return stage


def test_site_layer_sublayered_bound_and_labelled(tmp_path):
    """A DCC layer (Z-up metres) with a shed under /World/Scene and no HumV material."""
    stage = _shed_layer(tmp_path / "site.usda")
    raw = street_raw(tmp_path)
    raw["scene"].update(layers=["site.usda"], layer_material="wood", layer_class="building")
    scenario = scenario_at(tmp_path, raw)
    compose(scenario, tmp_path / "o")
    composed = Usd.Stage.Open(str(tmp_path / "o" / "stage.usda"))
    walls = composed.GetPrimAtPath("/World/Scene/Shed/Walls")
    bound, _ = UsdShade.MaterialBindingAPI(walls).ComputeBoundMaterial()
    assert bound.GetPath() == Sdf.Path("/World/Materials/wood")
    from humv_usd.usd.labels import instance_id, nearest_class

    assert instance_id(walls) == instance_ids(scenario)["layer:0:Shed"]
    assert nearest_class(walls)[1] == "building"
    temps = UsdGeom.PrimvarsAPI(walls).GetPrimvar("humv:thermal:temperature").Get(0)
    # one per face of the composed mesh: the thermal tool refines the walls' faces where sun and
    # shadow vary across them and writes the refined topology (6 authored faces before)
    faces = UsdGeom.Mesh(walls).GetFaceVertexCountsAttr().Get()
    assert len(temps) == len(faces) >= 6
    assert check_stage(tmp_path / "o" / "stage.usda") == []
    # a site prim named like an asset: one line naming the file and the prim
    raw["scene"]["asset"][0]["id"] = "Shed"
    with pytest.raises(InputError, match=r"site.usda: /World/Scene/Shed is also a scene object"):
        compose(scenario_at(tmp_path, raw), tmp_path / "o3")
    raw["scene"]["asset"][0]["id"] = "car"
    # a Y-up site layer cannot be converted: one line naming it
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.GetRootLayer().Save()
    with pytest.raises(InputError, match=r"site.usda: upAxis Y"):
        compose(scenario_at(tmp_path, raw), tmp_path / "o2")


# ------------------------------------------------------------------------------------- check
def _user_layer(out: Path, fn) -> None:
    """A user layer (stronger than compose's) edited by ``fn(stage)``."""
    layer = Sdf.Layer.CreateNew(str(out / "edit.usda"))
    root = Sdf.Layer.FindOrOpen(str(out / "stage.usda"))
    root.subLayerPaths.insert(0, "./edit.usda")
    root.Save()
    stage = Usd.Stage.Open(root)
    stage.SetEditTarget(layer)
    fn(stage)
    layer.Save()


def test_check_finds_unconverted_units_missing_files_and_bare_meshes(street):
    _, out = street

    def edit(stage):
        raw = stage.DefinePrim("/World/Scene/raw_building")
        raw.GetReferences().AddReference(str(ASSETS / "building.usda"))
        gone = stage.DefinePrim("/World/Scene/gone")
        gone.GetReferences().AddReference(str(out / "no_such_asset.usd"))
        mesh = UsdGeom.Mesh.Define(stage, "/World/Scene/extra")
        mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
        mesh.CreateFaceVertexCountsAttr([3])
        mesh.CreateFaceVertexIndicesAttr([0, 1, 2])

    _user_layer(out, edit)
    found = check_stage(out / "stage.usda")
    assert any(
        f.startswith("humv:assetUnits: /World/Scene/raw_building: references") and "fix:" in f for f in found
    )
    assert not any("/World/Scene/building" in f and "assetUnits" in f for f in found)  # converted
    assert any(f.startswith("humv:asset: /World/Scene/gone:") and "no_such_asset.usd" in f for f in found)
    assert any(f.startswith("humv:temperature: /World/Scene/extra: no per-face temperature") for f in found)
    assert any(f.startswith("humv:material: /World/Scene/extra: no bound material") for f in found)


def test_check_camera_without_sensor_attributes(street):
    _, out = street

    def edit(stage):
        stage.OverridePrim("/World/Sensors").SetActive(False)
        UsdGeom.Camera.Define(stage, "/World/Cam")

    _user_layer(out, edit)
    found = check_stage(out / "stage.usda")
    assert any(f.startswith("humv:sensor: /World/Cam: a camera without HumvSensorAPI") for f in found)


def test_flattened_stage_and_usdz_pass_check(street):
    _, out = street
    flat = out / "flat.usda"
    Usd.Stage.Open(str(out / "stage.usda")).Export(str(flat))
    assert check_stage(flat) == []
    package = out / "stage.usdz"
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(flat)), str(package))
    assert check_stage(package) == []


# ------------------------------------------------------------------------------------- render
#: resolution of the four HUMVVEX sensors in the render test (the field of view is the preset's)
SMALL_WIDTH = 96


def _static_scene(stage):
    """World triangles and instance id per triangle of every mesh under /World/Scene, read with
    plain UsdGeom (independent of the render's export)."""
    from humv_usd.usd.labels import instance_id

    tris, ids = [], []
    for prim in _meshes_under(stage, "/World/Scene"):
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
        xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(0))
        pts = pts @ xf[:3, :3] + xf[3, :3]
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
        start = 0
        for c in counts:
            face = idx[start : start + c]
            tris += [pts[[face[0], face[k], face[k + 1]]] for k in range(1, c - 1)]
            ids += [instance_id(prim)] * (c - 2)
            start += c
    return np.asarray(tris), np.asarray(ids)


@pytest.mark.slow
def test_street_renders_in_four_bands_with_exact_asset_labels(tmp_path):
    """examples/street.toml (people included) at a small size: every sensor renders; the asset
    pixels' instance ids match an independent ray cast of the static scene (trimesh) wherever
    the person is not in front, their class ids are the assets' classes, and COCO has them."""
    from humv_usd.catalog.sensors import scenario_values
    from humv_usd.groundtruth.labels import CLASS_ID
    from humv_usd.images import read_exr
    from humv_usd.pipeline.render import render_stage

    shutil.copytree(ASSETS, tmp_path / "assets")
    raw = tomllib.loads(STREET.read_text())
    for s in raw["sensor"]:
        p = scenario_values(s["preset"])
        w, h = p["resolution"]
        s.update(  # same field of view: focal length scaled with the image width
            resolution=[SMALL_WIDTH, round(h * SMALL_WIDTH / w)],
            focal_length_mm=p["focal_length_mm"] * SMALL_WIDTH / w,
        )
    raw["general"]["duration_s"] = 0.0
    raw["thermal"]["surface_spin_up_s"] = 3600.0
    scenario = validate(raw, tmp_path / "street.toml")
    compose(scenario, tmp_path / "o")
    manifest = render_stage(tmp_path / "o" / "stage.usda", tmp_path / "r", spp=2)
    rendered = {s["name"] for s in manifest["sensors"]} | {s["name"] for s in manifest["eo_sensors"]}
    assert rendered == {"atom1024_lwir", "lwir640", "mwir_insb", "eo_rgb"}
    ids = instance_ids(scenario)
    assets = {ids["asset:car"]: "vehicle", ids["asset:building"]: "building", ids["asset:bench"]: "prop"}
    stage = Usd.Stage.Open(str(tmp_path / "o" / "stage.usda"))
    tris, tri_ids = _static_scene(stage)
    caster = trimesh.ray.ray_pyembree.RayMeshIntersector(  # embree, not the render's Mitsuba
        trimesh.Trimesh(tris.reshape(-1, 3), np.arange(len(tris) * 3).reshape(-1, 3), process=False)
    )
    coco = json.loads((tmp_path / "r" / "coco.json").read_text())
    for sensor in sorted(rendered):
        exr = read_exr(tmp_path / "r" / sensor / "0000.exr")
        inst, cls = exr["instance_id"].astype(int), exr["class_id"].astype(int)
        cam = json.loads((tmp_path / "r" / sensor / "camera.json").read_text())
        k, r, t = np.asarray(cam["K"]), np.asarray(cam["frames"][0]["R"]), np.asarray(cam["frames"][0]["t"])
        v, u = np.mgrid[0 : cam["height"], 0 : cam["width"]]
        pix = np.stack([u.ravel() + 0.5, v.ravel() + 0.5, np.ones(u.size)], axis=1)
        dirs = (pix @ np.linalg.inv(k).T) @ r  # R^T d, row vectors
        origin = -r.T @ t
        first = caster.intersects_first(np.broadcast_to(origin, dirs.shape).copy(), dirs)
        expected = np.where(first >= 0, tri_ids[first], 0).reshape(inst.shape)
        person = inst == ids["human:p1"]
        compare = ~person & np.isin(expected, list(assets))
        assert compare.sum() > 50, sensor
        agree = (inst[compare] == expected[compare]).mean()
        assert agree >= 0.995, (sensor, agree)  # pixel centres on triangle edges may differ
        for iid, name in assets.items():
            on = inst == iid
            if name == "building":  # the door carries its own class
                assert set(np.unique(cls[on])) <= {CLASS_ID["building"], CLASS_ID["other"]}
            else:
                assert np.all(cls[on] == CLASS_ID[name]), (sensor, name)
        image = next(i["id"] for i in coco["images"] if i["file_name"].startswith(f"{sensor}/"))
        anns = {a["humv_instance_id"]: a for a in coco["annotations"] if a["image_id"] == image}
        for iid, name in assets.items():
            if (inst == iid).sum():
                assert anns[iid]["category_id"] == CLASS_ID[name]
                assert anns[iid]["area"] == (inst == iid).sum()


def test_usd_asset_dependencies_are_in_the_cache_key(tmp_path):
    """A USD asset that references another file: editing the inner file changes the key."""
    raw = street_raw(tmp_path)
    inner = tmp_path / "assets" / "inner.usda"
    shutil.move(tmp_path / "assets" / "building.usda", inner)
    outer = Usd.Stage.CreateNew(str(tmp_path / "assets" / "building.usda"))
    UsdGeom.SetStageUpAxis(outer, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(outer, 0.01)
    root = outer.DefinePrim("/Building")
    root.GetReferences().AddReference("./inner.usda")
    outer.SetDefaultPrim(root)
    outer.GetRootLayer().Save()
    before = read_values(scenario_at(tmp_path, raw), ("scene",))
    with open(inner, "a") as f:
        f.write("\n")
    after = read_values(scenario_at(tmp_path, raw), ("scene",))
    assert [k for k in before if before[k] != after[k]] == ["scene.asset.1.file"]


def test_usdz_asset(tmp_path):
    """A .usdz package (the building) is referenced like any USD file."""
    raw = street_raw(tmp_path)
    package = tmp_path / "assets" / "building.usdz"
    assert UsdUtils.CreateNewUsdzPackage(
        Sdf.AssetPath(str(tmp_path / "assets" / "building.usda")), str(package)
    )
    raw["scene"]["asset"][1]["file"] = "assets/building.usdz"
    compose(scenario_at(tmp_path, raw), tmp_path / "o")
    stage = Usd.Stage.Open(str(tmp_path / "o" / "stage.usda"))
    glass = stage.GetPrimAtPath("/World/Scene/building/Building/WindowGlass3")
    bound, _ = UsdShade.MaterialBindingAPI(glass).ComputeBoundMaterial()
    assert bound.GetPath() == Sdf.Path("/World/Materials/glass")
    assert check_stage(tmp_path / "o" / "stage.usda") == []


@pytest.mark.slow
def test_flattened_and_usdz_stages_render_like_the_composed_one(street, tmp_path):
    """What check passes renders: the flattened stage and its usdz package give the composed
    stage's labels and radiance."""
    from humv_usd.images import read_exr
    from humv_usd.pipeline.render import render_stage

    _, out = street
    flat = out / "flat.usda"
    Usd.Stage.Open(str(out / "stage.usda")).Export(str(flat))
    package = out / "flat.usdz"
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(flat)), str(package))
    images = {}
    for name, path in (("composed", out / "stage.usda"), ("flat", flat), ("usdz", package)):
        assert check_stage(path) == [], name
        render_stage(path, tmp_path / name, spp=2)
        (exr,) = sorted((tmp_path / name).glob("*/0000.exr"))
        images[name] = read_exr(exr)
    for name in ("flat", "usdz"):
        np.testing.assert_array_equal(images[name]["instance_id"], images["composed"]["instance_id"])
        np.testing.assert_array_equal(images[name]["class_id"], images["composed"]["class_id"])
        np.testing.assert_allclose(images[name]["radiance"], images["composed"]["radiance"], rtol=1e-6)


def test_usd_asset_with_material_subsets(tmp_path):
    """A mesh with per-face materials as GeomSubsets (as DCCs export them): each subset is bound
    to its mapped library material, so the render sees no foreign material."""
    raw = street_raw(tmp_path)
    path = tmp_path / "assets" / "kiosk.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Kiosk")
    stage.SetDefaultPrim(root.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/Kiosk/Box")
    mesh.CreatePointsAttr(
        [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    )
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7])
    binding = UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim())
    paint, glass = (UsdShade.Material.Define(stage, f"/Kiosk/Looks/{n}") for n in ("Paint", "Glass"))
    binding.Bind(paint)
    for name, faces, material in (("walls", [0, 1, 2, 3, 5], paint), ("window", [4], glass)):
        subset = binding.CreateMaterialBindSubset(name, faces)
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()
    raw["scene"]["asset"].append(
        {
            "id": "kiosk",
            "file": "assets/kiosk.usda",
            "position_m": [6.0, 2.0, 0.0],
            "material": "wood",
            "materials": {"Glass": "glass"},
        }
    )
    compose(scenario_at(tmp_path, raw), tmp_path / "o")
    composed = Usd.Stage.Open(str(tmp_path / "o" / "stage.usda"))
    for sub, material in (("Box/walls", "wood"), ("Box/window", "glass"), ("Box", "wood")):
        prim = composed.GetPrimAtPath(f"/World/Scene/kiosk/Kiosk/{sub}")
        bound, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        assert bound.GetPath() == Sdf.Path(f"/World/Materials/{material}"), sub
    assert check_stage(tmp_path / "o" / "stage.usda") == []
    from humv_usd.render.scene_export import SceneMeshes

    info = SceneMeshes(composed).mesh_info(composed.GetPrimAtPath("/World/Scene/kiosk/Kiosk/Box"), 0)
    assert sorted(p.material.path for p in info.parts) == ["/World/Materials/glass", "/World/Materials/wood"]


def test_committed_assets_are_what_the_script_makes(tmp_path):
    """examples/assets is tools/make_street_assets.py's output, byte for byte."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_street_assets", ROOT / "tools" / "make_street_assets.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main([str(tmp_path)]) == 0
    made = sorted(p.name for p in tmp_path.iterdir())
    assert made == sorted(p.name for p in ASSETS.iterdir())
    for name in made:
        assert (tmp_path / name).read_bytes() == (ASSETS / name).read_bytes(), name
    assert sum((ASSETS / n).stat().st_size for n in made) < 1_000_000


def test_check_finds_a_y_up_sublayer(street):
    _, out = street
    _user_layer(out, lambda stage: None)
    edit = Sdf.Layer.FindOrOpen(str(out / "edit.usda"))
    edit.pseudoRoot.SetInfo("upAxis", "Y")
    edit.Save()
    found = check_stage(out / "stage.usda")
    assert any(f.startswith(f"humv:assetUnits: {out / 'edit.usda'}: a sublayer with upAxis Y") for f in found)


# ------------------------------------------------------------------------------ relocatable
def _street_with_site_layer(folder: Path) -> tuple:
    """The fast street scenario in ``folder`` (assets copied beside it) with the shed site
    layer; composed into folder/o."""
    folder.mkdir(parents=True)
    _shed_layer(folder / "site.usda")
    raw = street_raw(folder)
    raw["scene"].update(layers=["site.usda"], layer_material="wood", layer_class="building")
    scenario = scenario_at(folder, raw)
    compose(scenario, folder / "o")
    return raw, folder / "o"


def _moved(tmp_path: Path) -> Path:
    """Compose in tmp_path/a, copy the scenario folder (assets, site layer, output) to
    tmp_path/b/moved keeping their relative placement, delete the original: the moved output."""
    _, out = _street_with_site_layer(tmp_path / "a")
    text = (out / "layers" / "scene.usda").read_text()
    assert str(tmp_path) not in text  # nothing points back at where it was composed
    assert "@../../assets/building.usda@" in text and "@../../site.usda@" in text
    shutil.copytree(tmp_path / "a", tmp_path / "b" / "moved")
    shutil.rmtree(tmp_path / "a")
    return tmp_path / "b" / "moved" / "o"


def test_output_moved_with_its_assets_still_composes_and_checks(tmp_path):
    """Assets and site layers are written relative to the layer: a copy of the scenario folder
    with its output elsewhere (a dataset on a share mounted at another path) composes, checks
    clean, and a re-run of compose there still keys the layers by the assets' content."""
    out = _moved(tmp_path)
    assert check_stage(out / "stage.usda") == []
    stage = Usd.Stage.Open(str(out / "stage.usda"))
    for path in ("/World/Scene/building/Building/WindowGlass3", "/World/Scene/Shed/Walls"):
        prim = stage.GetPrimAtPath(path)
        assert prim.IsA(UsdGeom.Mesh), path
        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:thermal:temperature")
        assert len(pv.Get(0)) == len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get()), path
    del stage, prim, pv  # an open stage keeps its layers registered, which would hide a failure
    # compose again in the new place, then edit the USD asset: the scene layer is rebuilt
    folder = out.parent
    raw = street_raw(tmp_path / "c")  # the same scenario values, read against the moved folder
    raw["scene"].update(layers=["site.usda"], layer_material="wood", layer_class="building")
    compose(scenario_at(folder, raw), out)
    # the thermal layer rebuilt on the cached scene layer (read back from its file: its
    # relative paths are anchored there) still finds the assets
    raw["thermal"]["surface_spin_up_s"] = 1800.0
    report = compose(scenario_at(folder, raw), out)
    assert "thermal" in report.rebuilt and "scene" not in report.rebuilt
    assert check_stage(out / "stage.usda") == []
    with open(folder / "assets" / "building.usda", "a") as f:
        f.write("\n")
    report = compose(scenario_at(folder, raw), out)
    assert "scene" in report.rebuilt
    assert check_stage(out / "stage.usda") == []


def test_paths_outside_the_output_tree_stay_absolute(tmp_path):
    """Only a file sharing a folder (other than /) with the layer's folder becomes relative."""
    from humv_usd.usd.layers import anchored_asset_paths, relative_asset_paths

    layer = Sdf.Layer.CreateAnonymous(".usda")
    prim = Sdf.CreatePrimInLayer(layer, "/A")
    prim.referenceList.Prepend(Sdf.Reference(str(tmp_path / "assets" / "car.usd")))
    prim2 = Sdf.CreatePrimInLayer(layer, "/B")
    prim2.referenceList.Prepend(Sdf.Reference("/opt/library/tree.usd"))
    layer.subLayerPaths.append(str(tmp_path / "site.usda"))
    rel = relative_asset_paths(layer, tmp_path / "o" / "layers")
    refs = {p: [r.assetPath for r in rel.GetPrimAtPath(p).referenceList.prependedItems] for p in ("/A", "/B")}
    assert refs == {"/A": ["../../assets/car.usd"], "/B": ["/opt/library/tree.usd"]}
    assert list(rel.subLayerPaths) == ["../../site.usda"]
    assert layer.GetPrimAtPath("/A").referenceList.prependedItems[0].assetPath == str(
        tmp_path / "assets" / "car.usd"
    )
    back = anchored_asset_paths(rel, tmp_path / "o" / "layers")
    assert back.GetPrimAtPath("/A").referenceList.prependedItems[0].assetPath == str(
        tmp_path / "assets" / "car.usd"
    )
    assert list(back.subLayerPaths) == [str(tmp_path / "site.usda")]


@pytest.mark.slow
def test_moved_output_renders_like_the_original(tmp_path):
    """A tiny LWIR render of the moved output equals the render made before the move."""
    from humv_usd.images import read_exr
    from humv_usd.pipeline.render import render_stage

    _, out = _street_with_site_layer(tmp_path / "first")
    render_stage(out / "stage.usda", tmp_path / "r0", spp=1)
    shutil.copytree(tmp_path / "first", tmp_path / "elsewhere" / "copy")
    shutil.rmtree(tmp_path / "first")
    moved = tmp_path / "elsewhere" / "copy" / "o"
    render_stage(moved / "stage.usda", tmp_path / "r1", spp=1)
    (a,), (b,) = (sorted((tmp_path / r).glob("*/0000.exr")) for r in ("r0", "r1"))
    a, b = read_exr(a), read_exr(b)
    ids = {int(i) for i in np.unique(a["instance_id"])}
    assert len(ids) >= 4  # ground, assets, the shed
    np.testing.assert_array_equal(a["instance_id"], b["instance_id"])
    np.testing.assert_allclose(a["radiance"], b["radiance"], rtol=1e-6)


# ------------------------------------------------------------------------ per-face materials
_BOX_POINTS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
_BOX_FACES = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
_WINDOW = 4  # the +y side


def _kiosk(path: Path, split: bool) -> None:
    """A 1 m box, painted, with a glass +y side: one mesh with material GeomSubsets (as DCCs
    export it), or (``split``) the same faces as two meshes of one material each."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/Kiosk").GetPrim())
    paint, glass = (UsdShade.Material.Define(stage, f"/Kiosk/Looks/{n}") for n in ("Paint", "Glass"))

    def mesh(name, faces):
        m = UsdGeom.Mesh.Define(stage, f"/Kiosk/{name}")
        m.CreatePointsAttr(_BOX_POINTS)
        m.CreateFaceVertexCountsAttr([4] * len(faces))
        m.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
        return UsdShade.MaterialBindingAPI.Apply(m.GetPrim())

    walls = [f for i, f in enumerate(_BOX_FACES) if i != _WINDOW]
    if split:
        mesh("Box", walls).Bind(paint)
        mesh("Window", [_BOX_FACES[_WINDOW]]).Bind(glass)
    else:
        binding = mesh("Box", _BOX_FACES)
        binding.Bind(paint)
        for name, faces, material in (("walls", [0, 1, 2, 3, 5], paint), ("window", [_WINDOW], glass)):
            subset = binding.CreateMaterialBindSubset(name, faces)
            UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(material)
    stage.GetRootLayer().Save()


def _kiosk_temperatures(tmp_path: Path, name: str, split: bool, materials: dict) -> dict:
    """{face centre (rounded): temperature at frame 0} of the kiosk composed alone on the ground."""
    folder = tmp_path / name
    folder.mkdir()
    raw = street_raw(folder)
    _kiosk(folder / "assets" / "kiosk.usda", split)
    raw["scene"]["asset"] = [
        {"id": "kiosk", "file": "assets/kiosk.usda", "position_m": [6.0, 2.0, 0.0], "material": "concrete"}
        | ({"materials": materials} if materials else {})
    ]
    compose(scenario_at(folder, raw), folder / "o")
    assert check_stage(folder / "o" / "stage.usda") == []
    stage = Usd.Stage.Open(str(folder / "o" / "stage.usda"))
    out = {}
    for prim in _meshes_under(stage, "/World/Scene/kiosk"):
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get())
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 4)
        temps = UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:thermal:temperature").Get(0)
        for face, t in zip(idx, temps):
            out[tuple(np.round(pts[face].mean(axis=0), 3))] = float(t)
    assert len(out) == 6
    return out


def test_material_subsets_get_the_slab_of_their_material(tmp_path):
    """A face in a glass GeomSubset of a painted-concrete box is a glass slab: its temperature is
    the one the same face gets as a separate glass mesh (the single-material path), and differs
    from the box made all of concrete, whose other faces it shares exactly."""
    mapping = {"Glass": "glass", "Paint": "concrete"}
    subsets = _kiosk_temperatures(tmp_path, "subsets", False, mapping)
    split = _kiosk_temperatures(tmp_path, "split", True, mapping)
    concrete = _kiosk_temperatures(tmp_path, "concrete", False, {})
    window = next(c for c in subsets if c[1] == 1.0)
    assert subsets.keys() == split.keys() == concrete.keys()
    for c in subsets:
        assert subsets[c] == pytest.approx(split[c], abs=1e-3), c
        if c != window:
            # the other faces see the ground, which sees the window (scene long-wave exchange,
            # issue 25): the same within a few mK, not to the last mK
            assert subsets[c] == pytest.approx(concrete[c], abs=5e-3), c
    assert abs(subsets[window] - concrete[window]) > 0.1, (subsets[window], concrete[window])
