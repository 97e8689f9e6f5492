"""Materials tool: the library entries a scenario uses → layers/materials.usda."""

from __future__ import annotations

from pathlib import Path

from pxr import Sdf, UsdGeom, UsdShade

from humv_usd.catalog.dyes import garment_materials
from humv_usd.catalog.dyes import material as library_material
from humv_usd.catalog.materials import LIBRARY
from humv_usd.catalog.skin import skin_material_name
from humv_usd.catalog.snow import cover_name
from humv_usd.human.chair import CHAIR_MATERIAL
from humv_usd.scenario import Scenario
from humv_usd.scenario.ids import carries_box, sits_on_chair
from humv_usd.scenario.inputs import FRAMES
from humv_usd.scenario.places import scene_materials, scene_objects
from humv_usd.usd.layers import SCOPES, finish, library_layer_main, new_layer_stage
from humv_usd.usd.materials import write_material, write_substrate
from humv_usd.usd.paths import material_path
from humv_usd.usd.snow import snow_depths

NAME = "materials"
READS = (
    *FRAMES,
    "human.*.clothing",
    "human.*.skin_tone",
    "human.*.clothing_colors",
    "human.*.clothing_prints",
    "human.*.clothing_print_colors",
    "@wood",
    "human.*.hair_color",
    "scene.ground.material",
    "scene.ground.puddles",
    "scene.ground.snow_depth_m",
    "atmosphere.rain_mm_h",
    "scene.object.*.material",
    "scene.object.*.kind",
    "scene.asset.*.material",
    "scene.asset.*.materials",
    "scene.layers",
    "scene.layer_material",
    "scene.terrain.zone",
    "scene.clutter",
    "scene.place",
)
UPSTREAM = ()
#: 3: /World/Materials a Scope; 4: warm clutter and generated places; 5: SWIR bands of fabrics;
#: 6: water for puddles after rain; 7: snow on the ground (and the library snow's spectrum);
#: 8: shallow snow over the ground's and the roofs' materials (<material>__snow<mm>);
#: 9: garment prints (two dyes and their mix) and the wood of a sitChair chair or a carried box
VERSION = "9"
#: material of the scene layer's puddles (humv_usd.scene.puddles.MATERIAL; tests/test_puddles.py)
PUDDLE_MATERIAL = "water"

#: Library material under a slab ground (the thermal tool's ground construction reaches 1 m).
GROUND_SUBSTRATE = "soil"


def used_materials(scenario: Scenario) -> list[str]:
    """Materials the scenario needs, in a stable order (only these are written)."""
    names = set()
    if scenario["human"]:
        names.update(skin_material_name(h.get("skin_tone")) for h in scenario["human"])
        names.update(
            name
            for h in scenario["human"]
            for g in h["clothing"]
            for name in garment_materials(
                g,
                h.get("clothing_colors"),
                h.get("hair_color"),
                h.get("clothing_prints"),
                h.get("clothing_print_colors"),
            )
        )
        if any(sits_on_chair(h) or carries_box(h) for h in scenario["human"]):
            names.add(CHAIR_MATERIAL)  # the chair or box the avatar tool authors (humv_usd.human.chair)
    scene = scenario["scene"]
    if scene:
        names.update(ground_materials(scenario))
        names.update(o["material"] for o in scene["object"])
        if any(o.get("kind") == "tree" for o in scene["object"]):
            names.add("wood")  # trunks (humv_usd.scene.vegetation.TRUNK_MATERIAL)
        for a in scene.get("asset") or ():  # the default and every mapped material
            names.add(a["material"])
            names.update(value for _, value in a["materials"])
        if scene.get("layers"):
            names.add(scene["layer_material"])
        names.update(scene_materials(scene))  # generated places and warm clutter
        depth = float(scene["ground"].get("snow_depth_m") or 0.0)
        if depth > 0.0:  # snow on the objects' flat roofs (humv_usd.scene.ground.cover_roof)
            roofs = {o["material"] for o in scene_objects(scene)}
            names.update(cover_name(n, depth) for n in roofs)
        if _slab_ground(scenario):
            names.add(GROUND_SUBSTRATE)
    return sorted(names)


def ground_materials(scenario: Scenario) -> list[str]:
    """The ground's material and those of its terrain zones (``[[scene.terrain.zone]]``)."""
    scene = scenario["scene"]
    zones = (scene.get("terrain") or {}).get("zone") or ()
    names = [scene["ground"]["material"], *(z["material"] for z in zones)]
    on_ground, on_zone = snow_depths(scene)  # humv_usd.scene.ground: snow over each piece
    covers = [cover_name(n, d) for n, d in zip(names, [on_ground, *on_zone]) if d > 0.0]
    if (
        float(scene["ground"].get("puddles") or 0.0) > 0.0
        and float((scenario["atmosphere"] or {}).get("rain_mm_h") or 0.0) > 0.0
    ):
        names.append(PUDDLE_MATERIAL)  # humv_usd.scene.puddles
    return list(dict.fromkeys(names + covers))


def _slab_ground(scenario: Scenario) -> bool:
    """The ground is solved as a slab (no held temperature_k): it needs its substrate."""
    ground = (scenario["scene"] or {}).get("ground")
    return bool(ground) and ground.get("temperature_k") is None


def author_material(stage, name: str) -> UsdShade.Material:
    """Define /World/Materials/<name> from the library: HumvMaterialAPI spectra (the material's
    own wavelength grid; transmittance only for materials one can see through) and thermal data,
    plus a UsdPreviewSurface for DCC viewports."""
    return write_material(stage, material_path(name), library_material(name))


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, "HumV-USD materials layer: spectral and thermal material properties"
    )
    UsdGeom.Scope.Define(stage, SCOPES["materials"])  # a typed scope, not a typeless def
    for name in used_materials(scenario):
        author_material(stage, name)
    if _slab_ground(scenario):
        # the thermal tool's ground construction continues below the ground material with
        # this substrate, read from the stage like every other material property
        for name in ground_materials(scenario):
            write_substrate(stage.GetPrimAtPath(material_path(name)), material_path(GROUND_SUBSTRATE))
    return finish(stage)


# ---------------------------------------------------------------------------- library file
LIBRARY_FILE = Path(__file__).resolve().parents[2] / "layers" / "materials.usda"


def build_library() -> Sdf.Layer:
    """Every library material in one layer (the reusable layers/materials.usda)."""
    stage = new_layer_stage(
        1.0,
        1,
        "HumV-USD material library: every built-in material "
        "(humv_usd.catalog.materials) with its spectra, thermal data and sources. "
        "Generated: python -m humv_usd.materials.layer",
    )
    for name in sorted(LIBRARY):
        author_material(stage, name)
    return finish(stage)


def main(argv=None) -> int:
    """Write layers/materials.usda (``--check``: exit 1 if it is out of date)."""
    return library_layer_main(LIBRARY_FILE, build_library, main.__doc__, argv)


if __name__ == "__main__":
    raise SystemExit(main())
