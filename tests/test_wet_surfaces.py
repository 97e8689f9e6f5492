"""Wet surfaces after rain (issue 30.4): water's optics, a film over a substrate, the wet
variants of library materials and their binding by the thermal tool."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Sdf, Usd, UsdGeom, UsdShade
from scipy.integrate import quad

from humv_usd.catalog.dyes import material
from humv_usd.catalog.wet import WET_LEVELS, split_wet_name, wet_level, wet_name
from humv_usd.physics import planck
from humv_usd.physics import water_film as W
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.wet import author_wet_surfaces
from humv_usd.usd.materials import band_emissivity as stage_band_emissivity
from humv_usd.usd.materials import face_materials, mesh_material, read_material, write_material

LWIR, MWIR = (8.0, 14.0), (3.0, 5.0)


def _band_eps(m, band):
    return planck.band_emissivity(m.spectrum_wavelengths, m.spectrum_emissivity, band)


# --- water's optics ------------------------------------------------------------------------------


@pytest.mark.parametrize("wl", [0.55, 4.0, 10.0, 12.0])
def test_normal_incidence_fresnel_is_the_textbook_closed_form(wl):
    """R(0) = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) (Born & Wolf 14.2) for water's n + ik."""
    m = complex(W.water_refractive_index(wl))
    n, k = m.real, m.imag
    assert_allclose(W.fresnel_reflectance(1.0, m), ((n - 1) ** 2 + k**2) / ((n + 1) ** 2 + k**2), rtol=1e-12)


def test_water_emits_like_water_at_nadir_in_lwir():
    """Masuda, Takashima & Takayama (1988): pure water's nadir emissivity 0.98-0.99 in 8-13 um."""
    wl = np.array([8.0, 9.0, 10.0, 11.0, 12.0])
    eps = 1.0 - W.fresnel_reflectance(1.0, W.water_refractive_index(wl))
    assert np.all((eps > 0.98) & (eps < 0.995)), eps


def test_diffuse_interface_reflectance_of_calm_water():
    """A real-index flat interface under diffuse light, integrated with scipy's quad over
    Hecht's real-angle Fresnel formulas: r_e = 2 int R(theta) cos sin dtheta, 0.066 for
    n = 1.333 (the diffuse albedo of calm water)."""
    n = 1.333

    def r(theta):
        t = np.arcsin(np.sin(theta) / n)
        if theta == 0.0:
            return ((n - 1) / (n + 1)) ** 2
        rs = np.sin(theta - t) ** 2 / np.sin(theta + t) ** 2
        rp = np.tan(theta - t) ** 2 / np.tan(theta + t) ** 2
        return 0.5 * (rs + rp)

    ref = 2.0 * quad(lambda th: r(th) * np.cos(th) * np.sin(th), 0.0, np.pi / 2, limit=200)[0]
    assert_allclose(W.diffuse_interface_reflectance(n + 0j), ref, rtol=1e-4)
    assert abs(ref - 0.066) < 0.001


def test_film_limits():
    """A film that absorbs nothing over a white substrate reflects everything; a thick film in
    the thermal infrared reflects what water's interface does; a black substrate leaves the
    interface alone; a thin film darkens a bright substrate in the visible (Lekner & Dorf 1988:
    total internal reflection traps light in the film)."""
    wl = 0.55
    r_n = W.fresnel_reflectance(1.0, W.water_refractive_index(wl))
    assert_allclose(W.film_reflectance(wl, 1.0, 1e-6), 1.0, atol=1e-6)
    assert_allclose(W.film_reflectance(wl, 0.0, 0.5), r_n, rtol=1e-9)
    assert_allclose(
        W.film_reflectance(10.0, 0.3, 0.5),
        W.fresnel_reflectance(1.0, W.water_refractive_index(10.0)),
        rtol=1e-6,
    )
    # Lekner & Dorf's closed form for a non-absorbing film: R_n + (1 - R_n)(1 - r_i) A / (1 - r_i A),
    # r_i = 1 - (1 - r_e) / n^2 from the independent quad integral above (r_e 0.066, n 1.333)
    a, r_i = 0.3, 1.0 - (1.0 - 0.0663) / 1.333**2
    expected = r_n + (1 - r_n) * (1 - r_i) * a / (1 - r_i * a)
    assert_allclose(W.film_reflectance(wl, a, 0.1), expected, rtol=3e-3)
    assert W.film_reflectance(wl, a, 0.1) < 0.75 * a  # wet concrete/sand: darker by a quarter or more


# --- wet variants --------------------------------------------------------------------------------


def test_wet_asphalt_emissivity_lies_between_dry_asphalt_and_water():
    dry, water = material("asphalt"), material("water")
    for band in (LWIR, MWIR):
        eps = [_band_eps(dry, band)] + [_band_eps(material(wet_name("asphalt", v)), band) for v in WET_LEVELS]
        assert np.all(np.diff(eps) > 0), (band, eps)  # wetter: closer to water
        assert eps[-1] <= _band_eps(water, band) + 0.01, (band, eps, _band_eps(water, band))
    # in LWIR a wet surface is water to within its interface reflection (film opaque)
    assert abs(_band_eps(material("asphalt__wet100"), LWIR) - _band_eps(water, LWIR)) < 0.01
    # thermal data and the name
    w, c = material("concrete__wet50"), material("concrete")
    assert (w.conductivity, w.thickness, w.label_class) == (c.conductivity, c.thickness, c.label_class)
    assert split_wet_name("concrete__wet50") == ("concrete", 50) and split_wet_name("concrete__wet7") is None
    with pytest.raises(KeyError):
        material("nonsense__wet50")


def test_wet_levels_round_to_quarters():
    assert list(wet_level([0.0, 0.1, 0.13, 0.37, 0.38, 0.74, 0.9, 1.0])) == [0, 0, 25, 25, 50, 75, 100, 100]


# --- the thermal tool: wet share out of the slab, wet bindings in its layer ----------------------


def _library_stage():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/World")
    for name in ("asphalt", "soil"):
        write_material(stage, f"/World/Materials/{name}", material(name))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Scene/Ground")
    mesh.CreatePointsAttr([(x, y, 0) for y in range(3) for x in range(3)])
    mesh.CreateFaceVertexCountsAttr([4, 4, 4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7])
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(
        UsdShade.Material(stage.GetPrimAtPath("/World/Materials/asphalt"))
    )
    return stage


def _ground_mesh(stage):
    m = mesh_material(stage.GetPrimAtPath("/World/Scene/Ground"))
    pts = np.array([(x, y, 0) for y in range(3) for x in range(3)], float)
    tri = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]])
    return SF.SceneMesh("/World/Scene/Ground", pts, tri, np.repeat(np.arange(4), 2), 4, m, None, True)


def _composed(upstream, shares):
    layer = Usd.Stage.CreateInMemory()
    report = author_wet_surfaces(layer, upstream, [_ground_mesh(upstream)], {"/World/Scene/Ground": shares})
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.subLayerPaths = [layer.GetRootLayer().identifier, upstream.GetRootLayer().identifier]
    return Usd.Stage.Open(root), layer, report


def test_thermal_layer_binds_wet_faces_to_wet_variants():
    upstream = _library_stage()
    stage, _, report = _composed(upstream, np.array([0.0, 0.3, 0.6, 1.0]))
    assert report == {"/World/Scene/Ground": {"25": 1, "50": 1, "100": 1}}
    mats, index = face_materials(stage.GetPrimAtPath("/World/Scene/Ground"), 4)
    names = [mats[i].name for i in index]
    assert names == ["asphalt", "asphalt__wet25", "asphalt__wet50", "asphalt__wet100"]
    eps = [stage_band_emissivity(mats[i], LWIR) for i in index]
    assert np.all(np.diff(eps) > 0)
    # the stage's wet variant is the catalogue's (same spectra from the same model)
    wet = read_material(stage.GetPrimAtPath("/World/Materials/asphalt__wet50"))
    assert_allclose(wet.reflectance, material("asphalt__wet50").spectrum_reflectance, atol=1e-5)
    # one level on every face: the mesh itself is bound, no subsets
    stage, _, _ = _composed(upstream, np.full(4, 0.9))
    prim = stage.GetPrimAtPath("/World/Scene/Ground")
    assert not UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets()
    assert mesh_material(prim).name == "asphalt__wet100"


def test_dry_scene_gets_no_wet_opinion():
    upstream = _library_stage()
    _, layer, report = _composed(upstream, np.array([0.0, 0.05, 0.1, 0.0]))
    assert report == {}
    assert layer.GetRootLayer().ExportToString().count("def ") == 0
    assert layer.GetRootLayer().ExportToString().count("over ") == 0


def test_slab_reports_the_wet_share_while_it_rains_and_as_it_dries():
    """Rain for an hour under a noon sun, then sun only: the wet share is 1 while it rains, falls
    once the rain stops, and the surface is dry (share 0) again within a few hours; without rain
    there is no wet share at all."""
    upstream = _library_stage()
    ground = dataclasses.replace(
        _ground_mesh(upstream), substrate=read_material(upstream.GetPrimAtPath("/World/Materials/soil"))
    )
    t = np.arange(0.0, 6 * 3600.0 + 1, 600.0)
    n, one = len(t), np.ones(len(t))
    f = SF.SurfaceForcing(
        t, 293.15 * one, 0.5 * one, 2.0 * one, np.tile([0.0, 0.0, 1.0], (n, 1)), np.ones(n, bool),
        700.0 * one, 100.0 * one, 800.0 * one,
        rain_kg_m2_s=np.where(t <= 3600.0, 4.0 / 3600.0, 0.0),
    )  # fmt: skip
    out, diag = SF.surface_temperatures(None, [ground], t, 0.0, forcing=f, exchange=False)
    wet = diag["wetFraction"]["/World/Scene/Ground"][:, 0]
    assert np.all(wet[(t > 0) & (t <= 3600.0)] > 0.99)
    after = wet[t > 3600.0]
    assert np.all(np.diff(after) <= 1e-12) and after[0] < 1.0 and after[-1] == 0.0
    dry, diag_dry = SF.surface_temperatures(
        None, [ground], t, 0.0, forcing=dataclasses.replace(f, rain_kg_m2_s=None), exchange=False
    )
    assert "wetFraction" not in diag_dry
    assert out["/World/Scene/Ground"][6, 0] < dry["/World/Scene/Ground"][6, 0] - 5.0  # wet: cooler


WET_SCENARIO = """
[general]
name = "wet_tiny"
start = 2018-07-14T13:00:00
utc_offset_h = -4.0
time_zone = "America/New_York"
latitude_deg = 39.80
longitude_deg = -84.03
fps = 5.0
duration_s = 0.0

[scene.ground]
material = "asphalt"
size_m = [30.0, 30.0]
horizon_m = 0.0
puddles = 0.05

[[scene.object]]
id = "wall"
material = "concrete"
center_m = [0.0, 4.0, 0.0]
size_m = [6.0, 1.0, 3.0]

[[sensor]]
id = "lwir"
preset = "boson640"
resolution = [64, 48]
pixel_pitch_um = 96.0
position_m = [0.0, -12.0, 3.0]
look_at_m = [0.0, 2.0, 0.5]

[thermal]
model = "fixed"

[atmosphere]
model = "analytic"
air_temperature_k = 293.0
relative_humidity = 0.6
wind_speed_m_s = 2.0
cloud_cover = 0.3
rain_mm_h = 4.0
rain_end_h = 0.5
rain_duration_h = 1.0
"""


@pytest.mark.extended
def test_composed_stage_after_rain_is_wet_and_checks_clean(tmp_path):
    """End to end (about a minute): compose a tiny scene half an hour after a shower: the ground
    and the wall are bound to wet variants, the puddles are free water and stay dry-bound, the
    stage checks clean; without rain nothing is wet."""
    import tomllib

    from humv_usd.pipeline.compose import compose
    from humv_usd.scenario import validate
    from humv_usd.usd.check import check_stage

    compose(validate(tomllib.loads(WET_SCENARIO)), tmp_path / "wet")
    stage = Usd.Stage.Open(str(tmp_path / "wet" / "stage.usda"))
    assert check_stage(tmp_path / "wet" / "stage.usda") == []
    ground = stage.GetPrimAtPath("/World/Scene/Ground")
    n = len(UsdGeom.Mesh(ground).GetFaceVertexCountsAttr().Get())
    mats, index = face_materials(ground, n)
    assert any(split_wet_name(m.name) for m in mats)
    puddles = stage.GetPrimAtPath("/World/Scene/Puddles")
    assert mesh_material(puddles).name == "water"
    dry = tomllib.loads(WET_SCENARIO)
    dry["atmosphere"]["rain_mm_h"] = 0.0
    compose(validate(dry), tmp_path / "dry")
    stage = Usd.Stage.Open(str(tmp_path / "dry" / "stage.usda"))
    assert mesh_material(stage.GetPrimAtPath("/World/Scene/Ground")).name == "asphalt"
    assert not stage.GetPrimAtPath("/World/Scene/Puddles")
