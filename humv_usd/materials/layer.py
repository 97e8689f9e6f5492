"""Materials tool: the library entries a scenario uses → layers/materials.usda."""

from __future__ import annotations

from pathlib import Path

from pxr import Gf, Sdf, UsdShade, Vt

from humv_usd.catalog.garments import fabrics
from humv_usd.catalog.materials import LIBRARY
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import FRAMES
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import finish, library_layer_main, new_layer_stage
from humv_usd.usd.paths import material_path

NAME = "materials"
READS = (*FRAMES, "human.*.clothing", "scene.ground.material", "scene.object.*.material")
UPSTREAM = ()
VERSION = "1"


def used_materials(scenario: Scenario) -> list[str]:
    """Materials the scenario needs, in a stable order (only these are written)."""
    names = set()
    if scenario["human"]:
        names.add("skin")
        names.update(fabrics(g for h in scenario["human"] for g in h["clothing"]))
    scene = scenario["scene"]
    if scene:
        names.add(scene["ground"]["material"])
        names.update(o["material"] for o in scene["object"])
    return sorted(names)


def author_material(stage, name: str) -> UsdShade.Material:
    """Define /World/Materials/<name> from the library: HumvMaterialAPI spectra (the material's
    own wavelength grid; transmittance only for materials one can see through) and thermal data,
    plus a UsdPreviewSurface for DCC viewports."""
    m = LIBRARY[name]
    mat = UsdShade.Material.Define(stage, material_path(name))
    prim = mat.GetPrim()
    prim.ApplyAPI(S.MATERIAL_API)
    prim.GetAttribute(S.MATERIAL_WAVELENGTHS).Set(Vt.FloatArray(m.spectrum_wavelengths))
    prim.GetAttribute(S.MATERIAL_EMISSIVITY).Set(Vt.FloatArray(m.spectrum_emissivity))
    prim.GetAttribute(S.MATERIAL_REFLECTANCE).Set(Vt.FloatArray(m.spectrum_reflectance))
    if not m.opaque:
        prim.GetAttribute(S.MATERIAL_TRANSMITTANCE).Set(Vt.FloatArray(m.spectrum_transmittance))
    for attr, value in (
        (S.MATERIAL_CONDUCTIVITY, m.conductivity),
        (S.MATERIAL_DENSITY, m.density),
        (S.MATERIAL_SPECIFIC_HEAT, m.specific_heat),
        (S.MATERIAL_THICKNESS, m.thickness),
        (S.MATERIAL_SOLAR_ABSORPTIVITY, m.solar_absorptivity),
        (S.MATERIAL_SOURCE, m.source),
    ):
        prim.GetAttribute(attr).Set(value)
    # A UsdPreviewSurface so DCC tools (Blender, usdview) show a sensible colour.
    shader = UsdShade.Shader.Define(stage, mat.GetPath().AppendChild("PreviewSurface"))
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*m.display_color))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.9)
    if not m.opaque:  # glass: see-through in viewports
        visible = float(m.at([0.45, 0.55, 0.65], "transmittance").mean())
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(round(1.0 - visible, 6))
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.05)
    mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return mat


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, "HumV-USD materials layer: spectral and thermal material properties"
    )
    for name in used_materials(scenario):
        author_material(stage, name)
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
