"""Materials tool: the library entries a scenario uses → layers/materials.usda."""
from __future__ import annotations

from pxr import Gf, Sdf, UsdShade, Vt

from humv_usd.clothing.garments import fabrics
from humv_usd.materials.library import LIBRARY, WAVELENGTHS_UM
from humv_usd.scenario import Scenario
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage

NAME = "materials"
READS = ("general", "human", "scene")


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


def material_path(name: str) -> Sdf.Path:
    return SCOPES["materials"].AppendChild(name)


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    stage = new_layer_stage(g["fps"], scenario.frame_count,
                            "HumV-USD materials layer: spectral and thermal material properties")
    for name in used_materials(scenario):
        m = LIBRARY[name]
        mat = UsdShade.Material.Define(stage, material_path(name))
        prim = mat.GetPrim()
        prim.ApplyAPI(S.MATERIAL_API)
        prim.GetAttribute(S.MATERIAL_WAVELENGTHS).Set(Vt.FloatArray(WAVELENGTHS_UM))
        prim.GetAttribute(S.MATERIAL_EMISSIVITY).Set(Vt.FloatArray(m.emissivity))
        prim.GetAttribute(S.MATERIAL_REFLECTANCE).Set(Vt.FloatArray(m.reflectance))
        for attr, value in ((S.MATERIAL_CONDUCTIVITY, m.conductivity),
                            (S.MATERIAL_DENSITY, m.density),
                            (S.MATERIAL_SPECIFIC_HEAT, m.specific_heat),
                            (S.MATERIAL_THICKNESS, m.thickness),
                            (S.MATERIAL_SOLAR_ABSORPTIVITY, m.solar_absorptivity),
                            (S.MATERIAL_SOURCE, m.source)):
            prim.GetAttribute(attr).Set(value)
        # A UsdPreviewSurface so DCC tools (Blender, usdview) show a sensible colour.
        shader = UsdShade.Shader.Define(stage, mat.GetPath().AppendChild("PreviewSurface"))
        shader.CreateIdAttr("UsdPreviewSurface")
        shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(
            Gf.Vec3f(*m.display_color))
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.9)
        mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return finish(stage)
