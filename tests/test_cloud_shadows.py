"""Broken cloud that moves and casts shadows (issue 30.4): the cover fraction of the field, its
motion with the wind, and a surface's thermal history under a passing shadow against the
closed form of a first-order response."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Usd
from scipy.integrate import solve_ivp

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.materials.layer import LIBRARY_FILE
from humv_usd.physics import clouds as C
from humv_usd.physics.convection import watmuff
from humv_usd.physics.sun import cloud_dni_factor
from humv_usd.thermal import surfaces as SF
from humv_usd.usd.materials import read_material
from humv_usd.usd.paths import material_path

_LIBRARY = Usd.Stage.Open(str(LIBRARY_FILE))


@pytest.mark.parametrize("cover", [0.2, 0.5, 0.8])
def test_shadow_cover_matches_the_key(cover):
    """The share of the ground in shadow is the cloud cover: over a 40 km square (ensemble over
    space) and at one point over 10 h of passing clouds (over time)."""
    field = C.cloud_field(3, 500.0)
    x, y = np.meshgrid(np.linspace(-2e4, 2e4, 200), np.linspace(-2e4, 2e4, 200))
    shade = 1.0 - C.cloud_shadow(field, x, y, [[0.0, 0.0]], cover)
    assert abs(shade.mean() - cover) < 0.02
    t = np.arange(0.0, 36000.0, 30.0)
    d = C.cloud_displacement(t, C.cloud_level_wind(3.0), 45.0)
    point = 1.0 - C.cloud_shadow(field, [0.0], [0.0], d, cover)
    assert abs(point.mean() - cover) < 0.06
    assert 0.0 < shade.mean() < 1.0 and np.any(np.diff(point[:, 0]) != 0)  # broken, and moving


def test_field_moves_with_the_cloud_level_wind():
    """Frozen turbulence: the shadow at p + X(t) at time t is the shadow at p at t = 0, X the
    integral of the cloud-level wind (the 1/7 power law: 100^(1/7) = 1.93 times the 10 m wind)
    along the direction the wind blows to."""
    assert_allclose(C.cloud_level_wind(5.0), 5.0 * 100.0 ** (1.0 / 7.0))
    t = np.array([-600.0, 0.0, 300.0, 900.0])
    speed = np.array([2.0, 2.0, 4.0, 4.0])
    d = C.cloud_displacement(t, speed, 90.0)  # toward the east
    assert_allclose(d[:, 0], [-1200.0, 0.0, 900.0, 3300.0])
    assert_allclose(d[:, 1], 0.0, atol=1e-9)
    field = C.cloud_field(7, 300.0)
    p = np.random.default_rng(1).uniform(-400.0, 400.0, (2, 200))
    at0 = C.cloud_shadow(field, p[0], p[1], d[1:2], 0.4)[0]
    for k in range(len(t)):
        assert np.array_equal(
            C.cloud_shadow(field, p[0] + d[k, 0], p[1] + d[k, 1], d[k : k + 1], 0.4)[0], at0
        )


def _flat(path, material, is_ground, size=1.0):
    m = read_material(_LIBRARY.GetPrimAtPath(material_path(material)))
    soil = read_material(_LIBRARY.GetPrimAtPath(material_path("soil"))) if is_ground else None
    h = size / 2
    pts = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], dtype=float)
    tri = np.array([[0, 1, 2], [0, 2, 3]])
    return SF.SceneMesh(path, pts, tri, np.array([0, 0]), 1, m, None, is_ground, soil)


def test_a_passing_shadow_cools_a_surface_with_its_time_constant():
    """A car roof (0.6 mm painted steel, adiabatic behind) at the origin under a passing cloud
    of seed 14 (size 2 km, cover 0.5, 1 m/s wind from the west: in sun to t = 2040 s, in shadow
    to 5090 s, then in sun): its temperature follows the lumped first-order balance
    rho c d dT/dt = alpha E(t) + eps (L_sky - sigma T^4) + h (T_air - T) (solved here by scipy),
    and it cools and recovers with the time constant tau = rho c d / (h + 4 eps sigma T^3) of
    the closed form T - T_eq ~ exp(-t / tau); an asphalt ground (its slab's heat capacity and the
    soil under it) cools far less over the first 10 minutes of shade."""
    t = np.arange(1800.0, 6600.0 + 1, 2.0)  # the slab's backward-Euler steps: 2 s << tau
    n, one = len(t), np.ones(len(t))
    cover, dni_layer, dhi = 0.5, 600.0, 150.0
    f = SF.SurfaceForcing(
        t, 293.15 * one, 0.5 * one, 1.0 * one, np.tile([0.0, 0.0, 1.0], (n, 1)), np.ones(n, bool),
        dni_layer * one, dhi * one, (dni_layer + dhi) * one, cover * one,
    )  # fmt: skip
    scenario = {"atmosphere": {"cloud_size_m": 2000.0, "wind_direction_deg": 270.0}, "general": {"seed": 14}}
    f = SF.with_cloud_shadows(f, scenario)
    gate = f.beam_gate(np.array([0.0]), np.array([0.0]))[:, 0]
    clear = 1.0 / cloud_dni_factor(cover)  # between clouds: the clear-sky beam
    in_sun = gate > 0
    assert (
        np.all(in_sun[t < 2030]) and not np.any(in_sun[(t > 2050) & (t < 5080)]) and np.all(in_sun[t > 5100])
    )
    assert_allclose(gate[in_sun], clear)

    roof = _flat("/World/Scene/roof", "painted_metal", False)
    t_roof = SF.surface_temperatures(None, [roof], t, 0.0, forcing=f, exchange=False)[0][roof.path][:, 0]

    m = roof.material
    alpha, eps = m.solar_absorptivity, SF.longwave_emissivity(m)
    rcd = m.density * m.specific_heat * m.thickness
    h = float(watmuff(1.0))
    l_sky = float(f.sky_longwave[0])

    def rhs(e_abs):
        return lambda s, temp: (e_abs + eps * (l_sky - SIGMA * temp**4) + h * (293.15 - temp)) / rcd

    # the slab holds each sample's forcing over the step that ends there: between switches the
    # forcing is constant and the balance an autonomous ODE, solved segment by segment
    ref, temp = np.empty(n), t_roof[0]
    ref[0] = temp
    cuts = [0, *(np.flatnonzero(np.diff(gate) != 0)), n - 1]
    for a, b in zip(cuts[:-1], cuts[1:]):
        e_abs = alpha * (dni_layer * gate[a + 1] + dhi)
        sol = solve_ivp(rhs(e_abs), (t[a], t[b]), [temp], t_eval=t[a : b + 1], rtol=1e-10, atol=1e-10)
        ref[a : b + 1], temp = sol.y[0], sol.y[0][-1]
    assert np.max(np.abs(t_roof - ref)) < 0.25, np.max(np.abs(t_roof - ref))
    drop = t_roof[t == 2030][0] - t_roof[t == 5080][0]
    assert drop > 10.0  # the roof cools in the shadow ...

    def fitted_tau(start, stop):
        sel = (t > start) & (t < stop)
        excess = np.abs(t_roof[sel] - t_roof[t == stop - 2][0])
        keep = excess > 0.05 * excess[0]
        slope = np.polyfit(t[sel][keep], np.log(excess[keep]), 1)[0]
        return -1.0 / slope, t_roof[t == stop - 2][0]

    for start, stop in ((2040.0, 5090.0), (5090.0, 6600.0)):  # cooling, recovery
        tau, t_eq = fitted_tau(start, stop)
        closed = rcd / (h + 4.0 * eps * SIGMA * t_eq**3)
        assert abs(tau / closed - 1.0) < 0.06, (start, tau, closed)
    assert t_roof[-1] > t_roof[t == 5080][0] + 0.9 * drop  # ... and recovers in the sun
    # the ground under the same sky, on 60 s steps: ten minutes of shade cool it far less
    ground = _flat("/World/Scene/Ground", "asphalt", True, 20.0)
    coarse = np.arange(0, n, 30)
    g = SF.surface_temperatures(None, [ground], t[coarse], 0.0, forcing=_every(f, coarse), exchange=False)[0]
    t_ground = g[ground.path][:, 0]
    ten = (t[coarse] >= 2040) & (t[coarse] <= 2640)
    roof_ten = (t >= 2040) & (t <= 2640)
    assert (t_ground[ten][0] - t_ground[ten][-1]) < 0.5 * (t_roof[roof_ten][0] - t_roof[roof_ten][-1])


def _every(f, rows):
    """The forcing at sample rows ``rows`` (its cloud shadows too)."""
    gate = f.beam_gate
    out = SF.SurfaceForcing(
        *[np.asarray(getattr(f, k))[rows] for k in ("times_s", "air_temperature_k", "relative_humidity",
                                                    "wind_speed_m_s", "sun_direction", "sun_up", "dni_w_m2",
                                                    "dhi_w_m2", "ghi_w_m2", "cloud_cover")],
    )  # fmt: skip
    out.beam_gate = lambda x, y: gate(x, y)[rows]
    return out


def test_no_shadows_without_size_or_clouds():
    t = np.arange(0.0, 600.0, 60.0)
    n, one = len(t), np.ones(len(t))
    f = SF.SurfaceForcing(
        t, 293.15 * one, 0.5 * one, one, np.tile([0.0, 0.0, 1.0], (n, 1)), np.ones(n, bool),
        500 * one, 100 * one, 600 * one, 0.4 * one,
    )  # fmt: skip
    assert SF.with_cloud_shadows(f, {"atmosphere": {"cloud_size_m": 0.0}, "general": {"seed": 0}}) is f
    clear = SF.SurfaceForcing(*[getattr(f, k) for k in ("times_s", "air_temperature_k", "relative_humidity",
                                                        "wind_speed_m_s", "sun_direction", "sun_up", "dni_w_m2",
                                                        "dhi_w_m2", "ghi_w_m2")], 0.0 * one)  # fmt: skip
    assert (
        SF.with_cloud_shadows(clear, {"atmosphere": {"cloud_size_m": 500.0}, "general": {"seed": 0}}) is clear
    )


def test_people_get_the_cloud_shadow_where_they_stand():
    """The people's sun is gated by the cloud shadow at their placements' centroid: the same
    factor as a ground face there; ones without shadows or without people."""
    t = np.arange(0.0, 3600.0, 60.0)
    n, one = len(t), np.ones(len(t))
    f = SF.SurfaceForcing(
        t, 293.15 * one, 0.5 * one, 2.0 * one, np.tile([0.0, 0.0, 1.0], (n, 1)), np.ones(n, bool),
        600 * one, 100 * one, 700 * one, 0.5 * one,
    )  # fmt: skip
    scenario = {
        "atmosphere": {"cloud_size_m": 300.0, "wind_direction_deg": 0.0},
        "general": {"seed": 1},
        "placement": [{"position_m": [10.0, 0.0, 0.0]}, {"position_m": [30.0, 20.0, 0.0]}],
    }
    shaded = SF.with_cloud_shadows(f, scenario)
    gate = SF.people_beam_gate(shaded, scenario)
    assert_allclose(gate, shaded.beam_gate(np.array([20.0]), np.array([10.0]))[:, 0])
    assert np.any(gate == 0.0) and np.any(gate > 1.0)  # shadows pass over them
    assert np.all(SF.people_beam_gate(f, scenario) == 1.0)
    assert np.all(SF.people_beam_gate(shaded, {**scenario, "placement": []}) == 1.0)
