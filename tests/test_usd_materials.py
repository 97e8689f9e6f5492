"""The stage's material reader (humv_usd.usd.materials) and the thermal tool's use of it."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade
from test_render import add_material, add_mesh, rect_z

from humv_usd.catalog.materials import LIBRARY
from humv_usd.errors import InputError
from humv_usd.materials.layer import LIBRARY_FILE
from humv_usd.physics import planck
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.human import LONGWAVE_BAND_UM, longwave_emissivity
from humv_usd.usd import schemas as S
from humv_usd.usd.materials import band_emissivity, bound_material, mesh_material, read_material
from humv_usd.usd.paths import material_path


@pytest.fixture(scope="module")
def library():
    return Usd.Stage.Open(str(LIBRARY_FILE))


@pytest.mark.parametrize("name", ["skin", "cotton_white", "concrete", "glass"])
def test_reader_returns_what_the_materials_tool_authored(library, name):
    m = read_material(library.GetPrimAtPath(material_path(name)))
    ref = LIBRARY[name]
    assert m.path == str(material_path(name)) and m.name == name
    np.testing.assert_allclose(m.wavelengths_um, ref.spectrum_wavelengths, rtol=1e-6)
    np.testing.assert_allclose(m.emissivity, ref.spectrum_emissivity, atol=1e-6)
    np.testing.assert_allclose(m.reflectance, ref.spectrum_reflectance, atol=1e-6)
    assert m.opaque == ref.opaque
    for field in ("conductivity", "density", "specific_heat", "thickness"):
        assert getattr(m, field) == pytest.approx(getattr(ref, field), rel=1e-6)
    # the tool authors the solar absorptivity of the material's own spectrum
    assert m.solar_absorptivity == pytest.approx(ref.spectral_solar_absorptivity, rel=1e-6)
    assert m.source == ref.source
    # the band emissivity: Planck-weighted at 300 K over the band, the same as the catalogue's
    lwir = planck.band_emissivity(ref.spectrum_wavelengths, ref.spectrum_emissivity, (8.0, 14.0), None, 300.0)
    assert band_emissivity(m, (8.0, 14.0)) == pytest.approx(lwir, abs=1e-6)
    assert longwave_emissivity(m) == band_emissivity(m, LONGWAVE_BAND_UM)


def _plate(tmp_path, material=True):
    stage = Usd.Stage.CreateNew(str(tmp_path / "s.usda"))
    UsdGeom.Scope.Define(stage, "/World/Scene")
    mat = add_material(stage, "gray", [0.9, 0.5], wavelengths=(8.0, 14.0)) if material else None
    add_mesh(stage, "/World/Scene/plate", *rect_z(-1, 1, -1, 1), material=mat)
    return stage


def test_binding_on_an_ancestor_counts_and_no_binding_names_the_mesh(tmp_path):
    stage = _plate(tmp_path, material=False)
    with pytest.raises(InputError, match=r"/World/Scene/plate\.material:binding"):
        mesh_material(stage.GetPrimAtPath("/World/Scene/plate"))
    mat = add_material(stage, "gray", [0.9, 0.5], wavelengths=(8.0, 14.0))
    UsdShade.MaterialBindingAPI.Apply(stage.GetPrimAtPath("/World/Scene")).Bind(mat)
    assert bound_material(stage.GetPrimAtPath("/World/Scene/plate")).GetPath() == mat.GetPath()
    m = mesh_material(stage.GetPrimAtPath("/World/Scene/plate"))
    # linear 0.9 -> 0.5 over the band (as float32 on the stage): the Planck-weighted mean at
    # 300 K, which leans to the short end where the 300 K blackbody is brighter
    stored = np.float32([0.9, 0.5]).astype(float)
    eps = band_emissivity(m, (8.0, 14.0))
    assert eps == pytest.approx(
        planck.band_emissivity([8.0, 14.0], stored, (8.0, 14.0), None, 300.0), rel=1e-12
    )
    assert 0.7 < eps < 0.9
    assert m.conductivity is None and m.solar_absorptivity is None  # render-only material
    with pytest.raises(InputError, match=r"/World/Materials/gray\.humv:material:solarAbsorptivity.*plate"):
        m.require("solar_absorptivity", "/World/Scene/plate")


def test_bad_tables_are_named(tmp_path):
    stage = _plate(tmp_path)
    prim = stage.GetPrimAtPath("/World/Materials/gray")
    prim.GetAttribute(S.MATERIAL_EMISSIVITY).Set([0.9, 1.5])
    with pytest.raises(InputError, match=r"gray\.humv:material:emissivity.*0-1"):
        read_material(prim)
    prim.GetAttribute(S.MATERIAL_EMISSIVITY).Set([0.9, 0.5])
    prim.CreateAttribute(S.MATERIAL_SOLAR_ABSORPTIVITY, Sdf.ValueTypeNames.Float).Set(1.25)
    with pytest.raises(InputError, match=r"gray\.humv:material:solarAbsorptivity = 1\.25"):
        read_material(prim)
    prim.GetAttribute(S.MATERIAL_SOLAR_ABSORPTIVITY).Set(0.5)
    with pytest.raises(InputError, match=r"reaches into the band 3-5 um"):
        band_emissivity(read_material(prim), (3.0, 5.0))


def test_thermal_tool_names_a_mesh_without_a_usable_material(tmp_path):
    """No silent defaults: a scene mesh without a HumvMaterialAPI material, or a slab whose
    material lacks the thermal data, is one clear error naming the mesh."""
    stage = _plate(tmp_path)
    with pytest.raises(InputError, match=r"gray\.humv:material:conductivity.*/World/Scene/plate"):
        SF.scene_meshes(stage, {"scene": None})
    stage.GetRootLayer().subLayerPaths.append(str(LIBRARY_FILE))
    wood = UsdShade.Material(stage.GetPrimAtPath(material_path("wood")))
    UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/World/Scene/plate")).Bind(wood)
    [plate] = SF.scene_meshes(stage, {"scene": None})
    assert plate.held_k is None and plate.material.path == str(material_path("wood"))
    assert plate.material.conductivity == pytest.approx(LIBRARY["wood"].conductivity, rel=1e-6)
    add_mesh(stage, "/World/Scene/bare", *rect_z(2, 3, -1, 1))
    with pytest.raises(InputError, match=r"/World/Scene/bare\.material:binding"):
        SF.scene_meshes(stage, {"scene": None})
    preview_only = UsdShade.Material.Define(stage, "/World/Materials/preview")
    UsdShade.MaterialBindingAPI.Apply(stage.GetPrimAtPath("/World/Scene/bare")).Bind(preview_only)
    with pytest.raises(
        InputError, match=r"/World/Materials/preview\.humv:material:wavelengths.*/World/Scene/bare"
    ):
        SF.scene_meshes(stage, {"scene": None})
