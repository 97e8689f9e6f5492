"""Snow cover (issue 30.4): snow's spectrum from ice's optical constants, its conductivity, a
snow layer on the ground slab that melts at 0 degC, and its binding by the scene and thermal
tools."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
from conftest import general_toml, place_keys, scene_stage
from numpy.testing import assert_allclose
from pxr import Sdf, Usd, UsdGeom, UsdShade
from scipy.optimize import brentq

from humv_usd.catalog.dyes import material
from humv_usd.catalog.snow import cover_name
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.materials.layer import used_materials
from humv_usd.physics import planck, sky, slab
from humv_usd.physics import snow as S
from humv_usd.physics.convection import watmuff
from humv_usd.scenario import validate
from humv_usd.scene.geometry import box
from humv_usd.scene.ground import author_ground, cover_roof
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.snow import author_snow_cover
from humv_usd.usd.materials import face_materials, mesh_material, read_material, write_material
from humv_usd.usd.mesh import define_mesh
from humv_usd.usd.snow import SnowCover, read_snow_cover

# --- optics ---------------------------------------------------------------------------------------

#: Warren & Brandt (2008) k of ice at wavelengths between the nodes physics.snow keeps
#: (their table; the subset must reproduce it there)
WB2008_BETWEEN = {0.62: 8.58e-9, 0.88: 3.35e-7, 1.06: 1.96e-6, 1.26: 1.32e-5, 1.538: 4.594e-4,
                  1.76: 1.522e-4, 2.041: 1.458e-3, 2.27: 2.171e-4, 2.46: 6.82e-4}  # fmt: skip


def test_ice_absorption_subset_reproduces_warren_brandt_between_its_nodes():
    wl = np.array(list(WB2008_BETWEEN))
    assert_allclose(S.ice_absorption_index(wl), list(WB2008_BETWEEN.values()), rtol=0.2)


def test_snow_albedo_grain_size_dependence_after_wiscombe_warren():
    """Wiscombe & Warren (1980): the visible albedo of pure snow is 0.95-0.99+ whatever the
    grain size, the near-infrared falls as grains grow (0.05 to 1 mm), and the 1.03, 1.5 and
    2.0 um ice bands are minima between maxima at 1.1, 1.8 and 2.25 um (Warren 1982, Fig. 5)."""
    d = S.optical_diameter_m(np.array([100.0, 40.0, 20.0, 8.0]))  # SSA [m2/kg]
    vis = S.spherical_albedo(np.array([0.40, 0.50, 0.60])[:, None], d)
    assert np.all(vis > 0.95) and np.ptp(vis[0]) < 0.01
    for wl in (0.9, 1.03, 1.3):
        r = S.spherical_albedo(wl, d)
        assert np.all(np.diff(r) < -0.01), (wl, r)
    fine = S.optical_diameter_m(60.0)
    a = {wl: float(S.spherical_albedo(wl, fine)) for wl in (1.03, 1.1, 1.5, 1.8, 2.0, 2.25)}
    assert a[1.03] < a[1.1] and a[1.5] < a[1.8] > a[2.0] < a[2.25]
    assert a[1.5] < 0.1 and a[2.0] < 0.05


def test_spherical_albedo_weak_absorption_limit():
    """exp(-sqrt(alpha)) -> 1 - sqrt(16 B gamma d / (9 (1 - g))) for gamma d -> 0 (Kokhanovsky &
    Zege 2004, eq. for weakly absorbing snow); gamma = 4 pi k / lambda."""
    wl, d = 0.55, 1e-4
    gamma = 4 * np.pi * 2.289e-9 / 0.55e-6  # Warren & Brandt k at 0.55 um
    expect = 1.0 - np.sqrt(16 * 1.6 * gamma * d / (9 * (1 - 0.845)))
    assert_allclose(S.spherical_albedo(wl, d), expect, atol=1e-4)


@pytest.mark.parametrize(
    "r_inf, k_e, depth, r_g", [(0.98, 5.0, 0.05, 0.1), (0.9, 30.0, 0.02, 0.5), (0.66, 120.0, 0.005, 0.05)]
)
def test_layer_albedo_solves_the_two_flux_equations(r_inf, k_e, depth, r_g):
    """Kubelka's closed form against the two-flux equations dI/dz = -(K+S) I + S J, dJ/dz =
    (K+S) J - S I solved by scipy's solve_bvp (I(0) = 1, J(h) = R_g I(h)), with K/S =
    (1 - R_inf)^2 / (2 R_inf) and k_e = sqrt(K (K + 2 S)); and its limits R_g at h = 0, R_inf
    deep."""
    from scipy.integrate import solve_bvp

    ks = (1.0 - r_inf) ** 2 / (2.0 * r_inf)
    sc = k_e / np.sqrt(ks * (ks + 2.0))
    k = ks * sc
    z = np.linspace(0.0, depth, 200)

    def rhs(_, y):
        return np.vstack([-(k + sc) * y[0] + sc * y[1], (k + sc) * y[1] - sc * y[0]])

    sol = solve_bvp(
        rhs, lambda a, b: np.array([a[0] - 1.0, b[1] - r_g * b[0]]), z, np.ones((2, z.size)), tol=1e-8
    )
    assert sol.success
    assert_allclose(S.layer_albedo(r_inf, k_e, depth, r_g), sol.sol(0.0)[1], atol=1e-5)
    assert_allclose(S.layer_albedo(r_inf, k_e, 1e-9, r_g), r_g, atol=1e-6)
    assert_allclose(S.layer_albedo(r_inf, k_e, 50.0 / k_e, r_g), r_inf, atol=1e-9)


def test_shallow_snow_shows_the_ground_in_the_visible_only():
    """<material>__snow<mm>: over soil the visible albedo rises with depth from the soil's
    towards deep snow's (1 cm: ~0.75, 5 cm: ~0.93 at 0.55 um; Wiscombe & Warren 1980: snow is
    not semi-infinite in the visible below a few cm of water); at 1.5 um and in the thermal
    infrared any depth is the snow's (ice opaque within a millimetre)."""
    soil, deep = material("soil"), material("snow")
    vis = [material(f"soil__snow{mm}").at(0.55) for mm in (5, 10, 20, 50, 100, 200)]
    assert soil.at(0.55) < vis[0] and np.all(np.diff(vis) > 0) and vis[-1] < deep.at(0.55) + 1e-9
    assert 0.7 < vis[1] < 0.8 and 0.9 < vis[3] < 0.96
    for mm in (5, 50):
        m = material(f"soil__snow{mm}")
        assert_allclose(m.at([1.5, 4.0, 10.0, 12.0]), deep.at([1.5, 4.0, 10.0, 12.0]), atol=0.01)
    assert cover_name("soil", 0.06) == "soil__snow50" and cover_name("soil", 0.5) == "snow"


def test_library_snow_broadband_albedo_and_thermal_emissivity():
    """Broadband solar albedo of settled snow ~0.8 (Warren 1982; Oke 1987, Table 1.1: 0.4-0.95);
    8-14 um emissivity 0.98-0.99 (Dozier & Warren 1982; Hori et al. 2006); the spectrum goes
    from 0.4 to 14 um (EO, NIR, SWIR, MWIR and LWIR)."""
    m = material("snow")
    assert 0.75 < 1.0 - m.spectral_solar_absorptivity < 0.85
    assert m.spectrum_wavelengths[0] <= 0.4 and m.spectrum_wavelengths[-1] >= 14.0
    eps = planck.band_emissivity(
        m.spectrum_wavelengths, m.spectrum_emissivity, (8.0, 14.0), temperature_k=263.0
    )
    assert 0.98 <= eps <= 0.99
    mwir = planck.band_emissivity(
        m.spectrum_wavelengths, m.spectrum_emissivity, (3.0, 5.0), temperature_k=263.0
    )
    assert 0.96 <= mwir <= 0.99
    assert m.at(0.55) > 0.95 and m.at(1.5) < 0.05  # white in EO, black at 1.5 um (SWIR)


def test_sturm_conductivity_is_continuous_and_grows_with_density():
    """Sturm et al. (1997) eq. 4: the two branches meet at 0.156 g/cm3; k rises with density
    (0.05 W/(m K) for fresh snow to ~0.4 for wind slab at 500 kg/m3)."""
    k = S.effective_conductivity
    assert abs(float(k(155.999)) - float(k(156.0))) < 2e-3
    rho = np.linspace(60.0, 550.0, 50)
    assert np.all(np.diff(k(rho)) > 0)
    assert 0.03 < float(k(100.0)) < 0.06 and 0.3 < float(k(500.0)) < 0.5


# --- the snow layer on the ground slab ------------------------------------------------------------

SOIL_DZ = np.full(8, 0.1)
SOIL_K, SOIL_RC = 1.0, 2.0e6


def test_sunlit_snow_at_air_above_zero_stays_at_0c_and_melts_at_the_balance_rate():
    """Constant sun, sky and +5 degC air over snow on an adiabatic ground: the column is at
    0 degC throughout, so the melt rate is the surface balance at 273.15 K, q = aG + eps (L -
    sigma T^4) + h (T_a - T), and the snow water W falls linearly, W(t) = W0 - q t / L_f, until
    it is gone at t* = W0 L_f / q; then the bare ground warms above 0 degC."""
    a_g, lw, air, h, eps = 100.0, 290.0, 278.15, 5.0, 0.985
    t = np.arange(0.0, 48 * 3600.0 + 1, 600.0)
    ts, res, swe = S.simulate_cover(
        t,
        a_g,
        0.8 * a_g / 0.2,
        lw,
        air,
        h,
        0.1,
        200.0,
        SOIL_DZ,
        SOIL_K,
        SOIL_RC,
        eps,
        0.95,
        bottom="adiabatic",
    )
    q = a_g + eps * (lw - STEFAN_BOLTZMANN * 273.15**4) + h * (air - 273.15)
    w0 = 0.1 * 200.0
    t_out = w0 * S.LATENT_HEAT_OF_FUSION / q
    covered = t < t_out - 600.0
    assert_allclose(ts[covered, 0], 273.15, atol=1e-9)
    assert_allclose(swe[covered, 0], w0 - q * t[covered] / S.LATENT_HEAT_OF_FUSION, rtol=1e-6)
    assert np.all(swe[t >= t_out + 1.0, 0] == 0.0)
    assert ts[-1, 0] > 275.0 and res < 1e-6


def test_clear_calm_night_snow_surface_falls_far_below_the_air():
    """A clear calm night at -5 degC (RH 0.8, Berdahl & Martin sky, 0.5 m/s): snow insulates
    the surface from the ground's heat, so it settles within 1 K of the balance without any
    conduction, eps (L - sigma T^4) + h (T_a - T) = 0, 5-15 K below the air, as measured over
    snow on clear calm nights (Oke 1987, Boundary Layer Climates, ch. 4: strong surface
    inversions over snow); a bare soil under the same sky stays warmer (its heat store)."""
    air, rh = 268.15, 0.8
    _, e_sky = sky.effective_sky_temperature(air, rh)
    lw, h = e_sky * STEFAN_BOLTZMANN * air**4, float(watmuff(0.5))
    t = np.arange(0.0, 12 * 3600.0 + 1, 600.0)
    ts, _, swe = S.simulate_cover(
        t, 0.0, 0.0, lw, air, h, 0.3, 250.0, SOIL_DZ, SOIL_K, SOIL_RC, 0.985, 0.95, deep_temperature_k=275.0
    )
    radiative = brentq(lambda x: 0.985 * (lw - STEFAN_BOLTZMANN * x**4) + h * (air - x), 200.0, 300.0)
    assert abs(ts[-1, 0] - radiative) < 1.0
    assert 5.0 < air - ts[-1, 0] < 15.0
    assert swe[-1, 0] == pytest.approx(0.3 * 250.0)  # nothing melts below 0 degC
    bare, _ = slab.simulate_many(t, 0.0, lw, air, h, SOIL_DZ, SOIL_K, SOIL_RC, 0.95, "fixed", 275.0)
    assert bare[-1, 0] > ts[-1, 0] + 2.0


def test_a_warm_neighbour_melts_the_snow_beside_it():
    """Melt around a warm object: two faces under the same freezing night, one also receiving
    the long wave of a 60 degC car body that fills half its view (a net surplus of ~100 W/m2
    at 0 degC): that
    one melts out within a day and goes on as bare ground above 0 degC, the other keeps all
    its snow below 0 degC."""
    air = 272.15
    base = 0.75 * STEFAN_BOLTZMANN * air**4
    warm = base + 0.5 * STEFAN_BOLTZMANN * (333.15**4 - air**4)
    t = np.arange(0.0, 24 * 3600.0 + 1, 600.0)
    ts, _, swe = S.simulate_cover(
        t, 0.0, 0.0, np.array([[base, warm]]), air, 4.0, 0.05, 250.0, SOIL_DZ, SOIL_K, SOIL_RC,
        deep_temperature_k=274.0,
    )  # fmt: skip
    assert swe[-1, 0] == pytest.approx(12.5) and ts[-1, 0] < 273.15
    assert swe[-1, 1] == 0.0 and ts[-1, 1] > 273.15


def test_a_heated_roof_melts_its_snow_from_below():
    """Snow on a 0.2 m concrete roof over a 21 degC room on a freezing night: the snow's base is
    held at 0 degC and melts at the room's flux through the roof less what the snow conducts up
    to its cold surface, (T_room - T_m) / (R_si + d / k) - k_s (T_m - T_s) / h_s (ISO 6946
    R_si = 0.13; steady conduction), within 10 %; over an unheated (adiabatic) roof nothing
    melts."""
    air = 268.15
    lw = 0.75 * STEFAN_BOLTZMANN * air**4
    t = np.arange(0.0, 12 * 3600.0 + 1, 600.0)
    roof_dz, k_roof, rc_roof = np.full(8, 0.025), 1.4, 880.0 * 2300.0
    kw = dict(deep_temperature_k=294.15)
    ts, _, swe = S.simulate_cover(
        t, 0.0, 0.0, lw, air, 4.0, 0.05, 250.0, roof_dz, k_roof, rc_roof, bottom="interior", **kw
    )
    melt = (swe[-13, 0] - swe[-1, 0]) / (2 * 3600.0) * S.LATENT_HEAT_OF_FUSION  # the last 2 h [W/m2]
    up = S.effective_conductivity(250.0) / 0.05 * (273.15 - ts[-1, 0])
    assert swe[-1, 0] > 0.0
    assert melt == pytest.approx((294.15 - 273.15) / (0.13 + 0.2 / k_roof) - up, rel=0.1)
    _, _, cold = S.simulate_cover(
        t, 0.0, 0.0, lw, air, 4.0, 0.05, 250.0, roof_dz, k_roof, rc_roof, bottom="adiabatic", **kw
    )
    assert np.all(cold == pytest.approx(12.5))


# --- the tools: scene binds snow, thermal melts it and binds the bare faces -----------------------

SNOW_SCENARIO = """
[general]
name = "snow_tiny"
start = 2021-03-02T14:00:00
utc_offset_h = 1.0
time_zone = "Europe/Berlin"
latitude_deg = 48.14
longitude_deg = 11.58

[scene.ground]
material = "soil"
size_m = [20.0, 20.0]
horizon_m = 0.0
snow_depth_m = 0.05

[[sensor]]
id = "lwir"
preset = "boson640"
position_m = [0.0, -8.0, 4.0]
look_at_m = [0.0, 0.0, 0.0]
"""


def test_scene_tool_binds_snow_and_records_the_bare_ground():
    scenario = validate(tomllib.loads(SNOW_SCENARIO))
    stage = Usd.Stage.CreateInMemory()
    author_ground(stage, scenario["scene"], {"ground": 1})
    prim = stage.GetPrimAtPath("/World/Scene/Ground")
    rel = UsdShade.MaterialBindingAPI(prim).GetDirectBindingRel().GetTargets()
    assert [str(p) for p in rel] == ["/World/Materials/soil__snow50"]  # 5 cm: shallow snow over soil
    assert read_snow_cover(prim) == SnowCover(0.05, 250.0, "/World/Materials/soil")
    assert {"soil__snow50", "soil"} <= set(used_materials(scenario))
    bare = tomllib.loads(SNOW_SCENARIO)
    del bare["scene"]["ground"]["snow_depth_m"]
    bare = validate(bare)
    assert not [n for n in used_materials(bare) if "snow" in n]
    stage = Usd.Stage.CreateInMemory()
    author_ground(stage, bare["scene"], {"ground": 1})
    assert read_snow_cover(stage.GetPrimAtPath("/World/Scene/Ground")) is None


def test_a_plowed_road_zone_has_no_snow():
    """[[scene.terrain.zone]] snow_depth_m = 0: the road zone keeps its asphalt and records no
    snow; a drift zone gets its own depth; the ground keeps the ground's."""
    raw = tomllib.loads(SNOW_SCENARIO)
    raw["scene"]["terrain"] = {
        "zone": [
            {
                "material": "asphalt",
                "path_m": [[-10.0, 0.0], [10.0, 0.0]],
                "width_m": 4.0,
                "snow_depth_m": 0.0,
            },
            {"material": "grass", "path_m": [[-10.0, 6.0], [10.0, 6.0]], "width_m": 2.0, "snow_depth_m": 0.4},
        ]
    }
    scenario = validate(raw)
    stage = Usd.Stage.CreateInMemory()
    author_ground(stage, scenario["scene"], {"ground": 1})

    def bound(path):
        return [
            str(p)
            for p in UsdShade.MaterialBindingAPI(stage.GetPrimAtPath(path)).GetDirectBindingRel().GetTargets()
        ]

    assert bound("/World/Scene/GroundZone0") == ["/World/Materials/asphalt"]
    assert read_snow_cover(stage.GetPrimAtPath("/World/Scene/GroundZone0")) is None
    assert bound("/World/Scene/GroundZone1") == ["/World/Materials/snow"]  # 40 cm: deep
    assert read_snow_cover(stage.GetPrimAtPath("/World/Scene/GroundZone1")).depth_m == 0.4
    assert bound("/World/Scene/Ground") == ["/World/Materials/soil__snow50"]
    assert {"asphalt", "snow", "soil__snow50"} <= set(used_materials(scenario))
    assert "asphalt__snow50" not in used_materials(scenario)


def _snow_ground():
    stage = Usd.Stage.CreateInMemory()
    for name in ("soil__snow50", "soil"):
        write_material(stage, f"/World/Materials/{name}", material(name))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Scene/Ground")
    mesh.CreatePointsAttr([(x, y, 0) for y in range(3) for x in range(3)])
    mesh.CreateFaceVertexCountsAttr([4, 4, 4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7])
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(
        UsdShade.Material(stage.GetPrimAtPath("/World/Materials/soil__snow50"))
    )
    soil = read_material(stage.GetPrimAtPath("/World/Materials/soil"))
    pts = np.array([(x, y, 0) for y in range(3) for x in range(3)], float)
    tri = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]])
    ground = SF.SceneMesh(
        "/World/Scene/Ground", pts, tri, np.repeat(np.arange(4), 2), 4,
        mesh_material(mesh.GetPrim()), None, True, soil,
    )  # fmt: skip
    ground.snow, ground.bare = SnowCover(0.05, 250.0, "/World/Materials/soil"), soil
    return stage, ground


def _forcing(t, air, ghi):
    n, one = len(t), np.ones(len(t))
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    return SF.SurfaceForcing(t, air * one, 0.6 * one, 1.0 * one, up, np.full(n, ghi > 0), 0.8 * ghi * one,
                             0.2 * ghi * one, ghi * one)  # fmt: skip


def test_thermal_solve_reports_snow_water_and_holds_melting_snow_at_0c():
    """The thermal tool's surface solve on a snow-covered ground: a sunny +3 degC day keeps the
    surface at 0 degC while the snow water falls; a freezing night keeps all of it."""
    _, ground = _snow_ground()
    t = np.arange(0.0, 6 * 3600.0 + 1, 600.0)
    out, diag = SF.surface_temperatures(
        None, [ground], t, 0.0, forcing=_forcing(t, 276.15, 600.0), exchange=False
    )
    w = diag["snowWater"]["/World/Scene/Ground"][:, 0]
    assert_allclose(out["/World/Scene/Ground"][1:, 0], 273.15, atol=1e-9)
    assert w[0] == pytest.approx(12.5) and np.all(np.diff(w) < 0)
    out, diag = SF.surface_temperatures(
        None, [ground], t, 0.0, forcing=_forcing(t, 268.15, 0.0), exchange=False
    )
    assert np.all(diag["snowWater"]["/World/Scene/Ground"] == pytest.approx(12.5))
    assert np.all(out["/World/Scene/Ground"] < 268.15)


def test_thermal_layer_binds_melted_faces_to_the_bare_ground():
    upstream, ground = _snow_ground()
    layer = Usd.Stage.CreateInMemory()
    water = np.array([0.0, 3.0, 0.0, 12.5])  # kg/m2 at 250 kg/m3: bare, 12 mm, bare, 50 mm
    report = author_snow_cover(layer, upstream, [ground], {"/World/Scene/Ground": water})
    assert report["/World/Scene/Ground"]["snowFree"] == 2
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.subLayerPaths = [layer.GetRootLayer().identifier, upstream.GetRootLayer().identifier]
    stage = Usd.Stage.Open(root)
    mats, index = face_materials(stage.GetPrimAtPath("/World/Scene/Ground"), 4)
    assert [mats[i].name for i in index] == ["soil", "soil__snow10", "soil", "soil__snow50"]
    # the level the scene did not author is this layer's, from the catalogue
    assert_allclose(mats[index[1]].reflectance, material("soil__snow10").spectrum_reflectance, atol=1e-5)
    layer = Usd.Stage.CreateInMemory()  # all snow still at the scene's level: no opinion at all
    author_snow_cover(layer, upstream, [ground], {"/World/Scene/Ground": np.full(4, 12.5)})
    assert "over " not in layer.GetRootLayer().ExportToString()
    gone = dataclasses.replace(ground)
    layer = Usd.Stage.CreateInMemory()  # melted everywhere: the mesh is bound whole
    author_snow_cover(layer, upstream, [gone], {"/World/Scene/Ground": np.zeros(4)})
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.subLayerPaths = [layer.GetRootLayer().identifier, upstream.GetRootLayer().identifier]
    composed = Usd.Stage.Open(root)
    assert mesh_material(composed.GetPrimAtPath("/World/Scene/Ground")).name == "soil"


@pytest.mark.extended
def test_composed_snowy_yard_melts_around_a_barbecue_and_checks_clean(tmp_path):
    """End to end (about 10 s): a tiny yard under 5 cm of snow with a lit barbecue on a sunny
    +2 degC March afternoon: the faces within 0.5 m of the grill are bound bare (soil), none
    beyond 1.5 m is, the open snow is at or below 0 degC and the stage checks clean."""
    from humv_usd.pipeline.compose import compose
    from humv_usd.usd.check import check_stage

    raw = tomllib.loads(SNOW_SCENARIO)
    raw["scene"]["clutter"] = [
        {"id": "bbq", "kind": "barbecue", "position_m": [0.0, 0.0, 0.0], "run_s": 7200.0}
    ]
    raw["sensor"][0].update(resolution=[64, 48], pixel_pitch_um=48.0)
    raw["atmosphere"] = {"model": "analytic", "air_temperature_k": 275.0, "relative_humidity": 0.7}
    compose(validate(raw), tmp_path / "snow")
    assert check_stage(tmp_path / "snow" / "stage.usda") == []
    stage = Usd.Stage.Open(str(tmp_path / "snow" / "stage.usda"))
    prim = stage.GetPrimAtPath("/World/Scene/Ground")
    mesh = UsdGeom.Mesh(prim)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    mats, index = face_materials(prim, len(counts))
    bare = np.array([mats[i].name == "soil" for i in index])
    pts, idx = np.asarray(mesh.GetPointsAttr().Get()), np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
    first = np.r_[0, np.cumsum(counts)[:-1]]
    centre = np.array([pts[idx[s : s + c]].mean(axis=0) for s, c in zip(first, counts)])
    r = np.hypot(centre[:, 0], centre[:, 1])
    assert bare[r < 0.5].all() and not bare[r > 1.5].any()
    temp = np.asarray(prim.GetAttribute("primvars:humv:thermal:temperature").Get(0))
    # bare soil is above 0 degC (at 0 degC where it melted out in the last step)
    assert np.all(temp[~bare] <= 273.15 + 1e-6) and np.all(temp[bare] >= 273.15 - 1e-6)
    assert np.median(temp[bare]) > 283.15


@pytest.mark.parametrize("depth, density", [(0.01, 60.0), (0.3, 250.0), (2.0, 500.0)])
def test_snow_layer_is_stable_over_an_extreme_grid(depth, density):
    """DESIGN's stability grid: air -40..+10 degC, wind 0-30 m/s, sun 0-1200 W/m2 (snow
    absorbs 20 %), 10-minute steps: no NaN, the covered surface never above 0 degC, the snow
    water never grows, the step residual stays small."""
    air, wind, sun = np.meshgrid([233.15, 263.15, 283.15], [0.0, 5.0, 30.0], [0.0, 600.0, 1200.0])
    air, h, sun = air.ravel()[None, :], watmuff(wind.ravel())[None, :], sun.ravel()[None, :]
    lw = 0.7 * STEFAN_BOLTZMANN * air**4
    t = np.arange(0.0, 24 * 3600.0 + 1, 600.0)
    ts, res, swe = S.simulate_cover(
        t,
        0.2 * sun,
        0.8 * sun,
        lw,
        air,
        h,
        depth,
        density,
        SOIL_DZ,
        SOIL_K,
        SOIL_RC,
        deep_temperature_k=268.0,
    )
    assert np.all(np.isfinite(ts)) and np.all(np.isfinite(swe)) and res < 1e-3
    assert np.all(np.diff(swe, axis=0) <= 1e-12)
    assert np.all(ts[swe > 0.0] <= 273.15 + 1e-9)
    with pytest.raises(ValueError, match="snow_depth_m"):
        S.simulate_cover(t, 0.0, 0.0, 250.0, 270.0, 5.0, 0.0, density, SOIL_DZ, SOIL_K, SOIL_RC)


def test_roof_snow_is_a_subset_that_the_thermal_layer_melts_away():
    """A box object under snow: the scene tool binds its roof face (normal up) to snow in the
    GeomSubset Snow and records the cover; the thermal tool reads it as snow over concrete on
    that face only; a roof still at the scene's 50 mm keeps it, one melted to 20 mm is bound to
    that level, one melted bare takes the object's concrete again."""
    scenario = validate(tomllib.loads(SNOW_SCENARIO))
    stage = Usd.Stage.CreateInMemory()
    for name in ("concrete__snow50", "concrete"):
        write_material(stage, f"/World/Materials/{name}", material(name))
    mesh = define_mesh(
        stage,
        "/World/Scene/house",
        *box((0.0, 0.0, 0.0), (4.0, 3.0, 3.0)),
        material="/World/Materials/concrete",
    )
    cover_roof(stage, mesh, scenario["scene"], "concrete")
    mats, index = face_materials(mesh.GetPrim(), 6)
    assert [mats[i].name for i in index] == ["concrete", "concrete__snow50", *["concrete"] * 4]
    (house,) = SF.scene_meshes(stage, {"scene": None})
    assert house.snow == SnowCover(0.05, 250.0, "/World/Materials/concrete") and house.bare.name == "concrete"
    water = np.full(6, np.nan)
    for left, names in ((12.5, "concrete__snow50"), (5.0, "concrete__snow20"), (0.0, "concrete")):
        water[1] = left
        layer = Usd.Stage.CreateInMemory()
        report = author_snow_cover(layer, stage, [house], {"/World/Scene/house": water})
        assert report["/World/Scene/house"]["faces"] == 1
        root = Sdf.Layer.CreateAnonymous(".usda")
        root.subLayerPaths = [layer.GetRootLayer().identifier, stage.GetRootLayer().identifier]
        composed = Usd.Stage.Open(root)  # held: a prim does not keep its stage alive
        mats, index = face_materials(composed.GetPrimAtPath("/World/Scene/house"), 6)
        assert mats[index[1]].name == names


def test_every_material_a_snowy_street_binds_is_authored():
    """A generated street (facades, parked cars, lamps) under 6 cm of snow: the scene binds its
    ground and its box roofs to snow over their materials, and the materials tool writes every
    material the scene binds (mesh or GeomSubset), so ``check`` finds none missing."""
    raw = tomllib.loads(general_toml("snowy_street", seed=3))
    raw["scene"] = {"ground": {"material": "asphalt", "size_m": [60.0, 60.0], "snow_depth_m": 0.06}}
    raw["scene"]["place"] = place_keys("street")
    stage = scene_stage(validate(raw))
    bound, roofs = set(), 0
    for prim in stage.Traverse():
        rel = prim.GetRelationship("material:binding")
        if rel and rel.GetTargets():
            bound.add(str(rel.GetTargets()[0]))
        roofs += prim.GetName() == "Snow" and prim.IsA(UsdGeom.Subset)
    assert "/World/Materials/asphalt__snow50" in bound and roofs > 0
    missing = [p for p in bound if not stage.GetPrimAtPath(p)]
    assert not missing, missing
