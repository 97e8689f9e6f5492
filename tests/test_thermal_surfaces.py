"""Scene surface temperatures (humv_usd.thermal.surfaces) against closed forms."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose
from pxr import Usd
from scipy.optimize import brentq

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.materials.layer import LIBRARY_FILE
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.human import longwave_emissivity
from humv_usd.usd.materials import read_material
from humv_usd.usd.paths import material_path

# materials as the stage holds them: the library layer (layers/materials.usda)
_LIBRARY = Usd.Stage.Open(str(LIBRARY_FILE))


#: a sky of one radiance in every direction (SurfaceForcing.sky_shape)
ISOTROPIC_SKY = (np.array([0.0, 90.0]), np.ones(2))


def stage_material(name):
    return read_material(_LIBRARY.GetPrimAtPath(material_path(name)))


def _quad(corners, path, material, held=None, ground=False):
    pts = np.asarray(corners, dtype=float)
    under = stage_material("soil") if ground else None
    return SF.SceneMesh(
        path,
        pts,
        np.array([[0, 1, 2], [0, 2, 3]]),
        np.array([0, 0]),
        1,
        stage_material(material),
        held,
        ground,
        under,
    )


def _forcing(n, sun_dir, dni=800.0, dhi=100.0, ghi=500.0, air=290.0, rh=0.5, wind=2.0):
    s = np.asarray(sun_dir, dtype=float)
    s = s / np.linalg.norm(s)
    t = np.arange(n) * 600.0 - (n - 1) * 600.0
    one = np.ones(n)
    return SF.SurfaceForcing(
        t,
        air * one,
        rh * one,
        wind * one,
        np.tile(s, (n, 1)),
        np.ones(n, dtype=bool),
        dni * one,
        dhi * one,
        ghi * one,
        # an isotropic sky: the closed forms below use the (1 + n_z) / 2 view factor
        sky_shape=ISOTROPIC_SKY,
    )


def _panel_equilibrium(cos_sun, lit, f, ground_k, ground_eps, albedo, material, nz):
    """alpha_s E_sw + eps E_lw = eps sigma T^4 + h (T - T_air) for a thin adiabatic plate."""
    a_s = stage_material(material).solar_absorptivity
    eps = longwave_emissivity(stage_material(material))
    up, down = 0.5 * (1 + nz), 0.5 * (1 - nz)
    e_sky = float(f.sky_longwave[0])
    e_sw = f.dni_w_m2[0] * cos_sun * lit + f.dhi_w_m2[0] * up + albedo * f.ghi_w_m2[0] * down
    e_lw = e_sky * up + (ground_eps * SIGMA * ground_k**4 + (1 - ground_eps) * e_sky) * down
    h = 2.8 + 3.0 * f.wind_speed_m_s[0]
    ta = f.air_temperature_k[0]
    return brentq(lambda t: a_s * e_sw + eps * (e_lw - SIGMA * t**4) - h * (t - ta), 150.0, 500.0)


def test_sunlit_and_shaded_panels_reach_the_closed_form_equilibrium():
    # ground held at 300 K; a south-facing metal panel in the sun, and one behind a screen
    ground = _quad(
        [[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]],
        "/World/Scene/Ground",
        "concrete",
        held=300.0,
        ground=True,
    )
    lit_panel = _quad([[0, 0, 1], [2, 0, 1], [2, 0, 3], [0, 0, 3]], "/World/Scene/a", "painted_metal")
    shaded = _quad([[10, 0, 1], [12, 0, 1], [12, 0, 3], [10, 0, 3]], "/World/Scene/b", "painted_metal")
    screen = _quad(
        [[9, -1, 0.5], [13, -1, 0.5], [13, -1, 6.0], [9, -1, 6.0]], "/World/Scene/c", "wood", held=295.0
    )
    for m in (lit_panel, shaded):
        assert_allclose(m.face_geometry()[0][0], [0, -1, 0], atol=1e-12)  # faces south
    sun = np.array([0.0, -np.cos(np.radians(40)), np.sin(np.radians(40))])
    f = _forcing(30, sun)
    # the closed form is the open-sky model (ground irradiance = GHI, sky (1 + n_z) / 2):
    # exchange=False; the screen's long wave on panel b is tested in test_surface_views.py
    out, diag = SF.surface_temperatures(
        None,
        [ground, lit_panel, shaded, screen],
        np.array([0.0]),
        spin_up_s=17400.0,
        forcing=f,
        exchange=False,
    )
    assert diag["surfaceModels"] == {
        "/World/Scene/Ground": "held",
        "/World/Scene/a": "slab",
        "/World/Scene/b": "slab",
        "/World/Scene/c": "held",
    }
    assert out["/World/Scene/Ground"][0, 0] == 300.0 and out["/World/Scene/c"][0, 0] == 295.0
    concrete = stage_material("concrete")
    eps_g, albedo = longwave_emissivity(concrete), 1 - concrete.solar_absorptivity
    expect_lit = _panel_equilibrium(
        np.cos(np.radians(40)), 1.0, f, 300.0, eps_g, albedo, "painted_metal", 0.0
    )
    expect_shade = _panel_equilibrium(
        np.cos(np.radians(40)), 0.0, f, 300.0, eps_g, albedo, "painted_metal", 0.0
    )
    assert_allclose(out["/World/Scene/a"][0, 0], expect_lit, atol=1e-6)
    assert_allclose(out["/World/Scene/b"][0, 0], expect_shade, atol=1e-6)
    assert expect_lit > expect_shade + 10.0
    assert diag["slabMaxResidual_W_m2"] < 1e-6


def test_ground_slab_follows_the_sun_and_lags_it():
    # a concrete pad over soil under a sinusoidal sun (6:00-18:00): warmest after noon
    ground = _quad(
        [[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]],
        "/World/Scene/Ground",
        "concrete",
        ground=True,
    )
    t = np.arange(-2 * 86400.0, 1.0, 600.0)
    hour = (t / 3600.0) % 24.0
    elev = np.maximum(np.sin(np.pi * (hour - 6.0) / 12.0), 0.0)
    one = np.ones_like(t)
    s = np.stack([np.zeros_like(t), -np.sqrt(1 - elev**2), elev], axis=1)
    f = SF.SurfaceForcing(
        t,
        290.0 * one,
        0.5 * one,
        2.0 * one,
        s,
        elev > 0,
        800.0 * (elev > 0),
        80.0 * elev,
        800.0 * elev**2 + 80.0 * elev,
    )
    out, diag = SF.surface_temperatures(None, [ground], t, 0.0, forcing=f)
    last = t >= -86400.0
    ts = out["/World/Scene/Ground"][last, 0]
    day = hour[last]
    assert 12.0 < day[np.argmax(ts)] < 16.0  # surface maximum lags solar noon
    assert ts.max() > 300.0 and ts.min() < 290.0  # sunny day, clear night below the air
    assert np.all(np.isfinite(ts)) and diag["slabMaxResidual_W_m2"] < 1e-6
