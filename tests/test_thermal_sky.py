"""The thermal layer's sky: the atmosphere layer's longwave table, cloud cover, fallbacks."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import trimesh
from conftest import atmosphere_layer_of
from numpy.testing import assert_allclose
from pxr import Usd
from scipy.integrate import quad

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.errors import InputError
from humv_usd.physics import planck
from humv_usd.physics.sky import effective_sky_temperature
from humv_usd.scenario import validate
from humv_usd.thermal import qrad as Q
from humv_usd.thermal import scene_radiance as SR
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.human import scenario_sky
from humv_usd.thermal.sky import (
    ClearSky,
    cloudy_sky_emissivity,
    hemispherical_irradiance,
    stage_longwave_table,
)
from humv_usd.usd import schemas as S


def _atmosphere_stage(raw, cloud):
    raw = copy.deepcopy(raw)
    raw["atmosphere"]["model"] = "analytic"
    raw["atmosphere"]["cloud_cover"] = cloud
    sc = validate(raw)
    stage = Usd.Stage.Open(atmosphere_layer_of(sc))
    return sc, stage


@pytest.fixture(scope="module")
def skies(humvvex_raw):
    """{cloud cover: (scenario, stage with the atmosphere layer)} for 0, 0.5 and 1."""
    return {c: _atmosphere_stage(humvvex_raw, c) for c in (0.0, 0.5, 1.0)}


def _cosine_weighted_mean(zen_deg, rad):
    """int L cos dOmega / int cos dOmega over the upper hemisphere (quadrature of np.interp)."""
    f = lambda t: np.interp(np.degrees(t), zen_deg, rad) * np.cos(t) * np.sin(t)  # noqa: E731
    breaks = np.radians(zen_deg)
    value, _ = quad(
        f,
        0.0,
        np.pi / 2,
        points=breaks[(breaks > 0) & (breaks < np.pi / 2)],
        limit=200,
        epsabs=0.0,
        epsrel=1e-12,
    )
    return value / 0.5


def test_hemispherical_irradiance_is_pi_times_the_cosine_weighted_mean():
    zen = np.array([0.0, 10.0, 30.0, 60.0, 75.0, 89.0])
    rad = np.array([70.0, 71.0, 76.0, 98.0, 115.0, 126.0])
    assert_allclose(hemispherical_irradiance(zen, rad), np.pi * _cosine_weighted_mean(zen, rad), rtol=1e-10)
    # a uniform sky: pi L; a table not starting at the zenith holds its first value there
    assert_allclose(hemispherical_irradiance([0.0, 45.0, 89.0], [5.0] * 3), np.pi * 5.0, rtol=1e-12)
    assert_allclose(hemispherical_irradiance([20.0, 60.0], [4.0, 4.0]), np.pi * 4.0, rtol=1e-12)
    with pytest.raises(ValueError, match="ascend"):
        hemispherical_irradiance([0.0, 0.0], [1.0, 2.0])


def test_layer_authors_the_cloudy_longwave_table(skies):
    sc, stage0 = skies[0.0]
    t_air = sc["atmosphere"]["air_temperature_k"]
    zen, clear = stage_longwave_table(stage0)
    assert zen.size == clear.size >= 10 and zen[0] == 0.0 and zen[-1] < 90.0
    # clear: the analytic law, brighter towards the horizon, flux of the Berdahl-Martin sky
    _, eps_bm = effective_sky_temperature(t_air, sc["atmosphere"]["relative_humidity"])
    assert np.all(np.diff(clear) > 0)
    assert_allclose(hemispherical_irradiance(zen, clear), eps_bm * SIGMA * t_air**4, rtol=3e-3)
    for c in (0.5, 1.0):
        _, stage = skies[c]
        z, lw = stage_longwave_table(stage)
        # Crawford & Duchon: a fraction c of the dome is a blackbody at the air temperature
        assert_allclose(lw, c * SIGMA * t_air**4 / np.pi + (1 - c) * clear, rtol=1e-6)
        assert np.all(lw >= clear * (1 - 1e-6)) and lw[0] > clear[0] + 10.0  # ~1 at 89 deg
        prim = stage.GetPrimAtPath("/World/Atmosphere")
        eps = prim.GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY).Get()
        assert eps == pytest.approx(float(cloudy_sky_emissivity(eps_bm, c)), rel=1e-6)
        t_sky = prim.GetAttribute(S.ATMOSPHERE_SKY_TEMPERATURE).Get()
        assert t_sky == pytest.approx(eps**0.25 * t_air, rel=1e-6)
        # the render's spectral sky gets the same mix: 8-14 um rows vs the clear ones
        wl = np.asarray(prim.GetAttribute(S.ATMOSPHERE_WAVELENGTHS).Get(), dtype=float)
        rows = np.asarray(prim.GetAttribute(S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE).Get(0), dtype=float).reshape(
            z.size, wl.size
        )
        rows0 = np.asarray(
            stage0.GetPrimAtPath("/World/Atmosphere").GetAttribute(S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE).Get(0),
            dtype=float,
        ).reshape(z.size, wl.size)
        m = (wl > 8.0) & (wl < 14.0)
        assert_allclose(
            rows[:, m], c * planck.spectral_radiance(wl[m], t_air) + (1 - c) * rows0[:, m], rtol=1e-5
        )
    # overcast: the dome is uniform at the air temperature
    assert_allclose(stage_longwave_table(skies[1.0][1])[1], SIGMA * t_air**4 / np.pi, rtol=1e-6)


def test_thermal_sky_irradiance_is_the_tables(skies):
    sc, stage = skies[0.5]
    table = stage_longwave_table(stage)
    closed = np.pi * _cosine_weighted_mean(*table)
    w = {"air_temperature_k": 289.0, "relative_humidity": 0.45, "cloud_cover": 0.5}
    sky = scenario_sky(sc, w, longwave=table)
    assert sky.tabulated
    # what the slabs and the scene surfaces use, and what the radiance maps integrate to
    assert_allclose(sky.downwelling_irradiance()[1], closed, rtol=1e-3)
    env = SR.radiance_map([0, 0, 0], sky, None, 90)
    assert_allclose(env.irradiance(np.array([[0.0, 0.0, 1.0]]))[1, 0], closed, rtol=1e-3)
    # the radiance map takes the table's values by zenith
    zen = np.radians([5.0, 40.0, 80.0])
    d = np.stack([np.sin(zen), 0 * zen, np.cos(zen)], axis=1)
    assert_allclose(sky.radiance(d)[1], np.interp([5.0, 40.0, 80.0], *table), rtol=1e-12)
    # slab forcing scaled to the table: at frame 0 the slab sees the same irradiance
    n = 3
    one = np.ones(n)
    f = SF.SurfaceForcing(
        np.array([-1200.0, -600.0, 0.0]),
        289.0 * one,
        0.45 * one,
        3.0 * one,
        np.tile([0.0, 0.0, 1.0], (n, 1)),
        np.zeros(n, bool),
        0 * one,
        0 * one,
        0 * one,
        0.5 * one,
    )
    g = SF.with_sky_table(f, table, 2)
    assert_allclose(g.sky_longwave[2], closed, rtol=1e-3)
    assert SF.with_sky_table(f, None, 2) is f


def test_cloudy_sky_is_warmer_and_analytic_fallback_has_the_cloud_mix(skies, humvvex_raw):
    sc, _ = skies[0.0]
    w = {"air_temperature_k": 289.0, "relative_humidity": 0.45}
    d = np.array([[0.0, 0.0, 1.0], [np.sin(1.2), 0.0, np.cos(1.2)]])
    clear = scenario_sky(sc, dict(w, cloud_cover=0.0))
    cloudy = scenario_sky(sc, dict(w, cloud_cover=1.0))
    half = scenario_sky(sc, dict(w, cloud_cover=0.5))
    assert not clear.tabulated
    assert np.all(cloudy.radiance(d)[1] > clear.radiance(d)[1])
    assert_allclose(cloudy.radiance(d)[1], SIGMA * 289.0**4 / np.pi, rtol=1e-12)
    assert half.emissivity == pytest.approx(0.5 + 0.5 * clear.emissivity, rel=1e-12)
    assert cloudy.downwelling_irradiance()[1] > clear.downwelling_irradiance()[1] + 90.0
    # the fallback when the upstream stage has no atmosphere layer (or no table)
    assert stage_longwave_table(Usd.Stage.CreateInMemory()) is None
    assert stage_longwave_table(None) is None
    # the slab forcing gets the same mix
    one = np.ones(2)
    f = SF.SurfaceForcing(
        np.array([-600.0, 0.0]),
        289.0 * one,
        0.45 * one,
        one,
        np.tile([0.0, 0.0, 1.0], (2, 1)),
        np.zeros(2, bool),
        0 * one,
        0 * one,
        0 * one,
        np.array([0.0, 1.0]),
    )
    assert_allclose(f.sky_longwave, [clear.longwave_irradiance(), SIGMA * 289.0**4], rtol=1e-12)


@pytest.mark.parametrize("tabulated", [False, True])
def test_overcast_sky_is_a_uniform_enclosure(tabulated):
    """Closed form: overcast sky over a ground at the air temperature with its reflection of
    the sky is a uniform sky L = sigma T^4 / pi; every facet of a sphere absorbs eps pi L."""
    t = 289.0
    kw = dict(air_temperature_k=t, relative_humidity=0.45, ground_temperature_k=t, ground_emissivity=0.9)
    if tabulated:
        kw.update(longwave_zenith_deg=(0.0, 45.0, 89.0), longwave_radiance=(SIGMA * t**4 / np.pi,) * 3)
    else:
        kw.update(cloud_cover=1.0)
    sky = ClearSky(**kw)
    sphere = trimesh.creation.icosphere(2, radius=0.3)
    env = SR.radiance_map([0, 0, 0], sky, None, 48)
    assert_allclose(env.radiance[1], SIGMA * t**4 / np.pi, rtol=1e-12)
    for method in ("brute", "fast"):
        q = Q.absorbed_radiation(sphere, env, [0.6, 0.95], method=method, rays=16)
        assert_allclose(q[1], 0.95 * SIGMA * t**4, rtol=1e-6)


def test_malformed_table_is_an_input_error():
    stage = Usd.Stage.CreateInMemory()
    prim = stage.DefinePrim("/World/Atmosphere", "Scope")
    prim.ApplyAPI(S.ATMOSPHERE_API)
    prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).Set([0.0, 30.0, 60.0])
    prim.GetAttribute(S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE).Set([80.0, 90.0])
    with pytest.raises(InputError, match="skyLongwaveRadiance"):
        stage_longwave_table(stage)
    prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).Set([0.0, 60.0, 30.0])
    prim.GetAttribute(S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE).Set([80.0, 90.0, 95.0])
    with pytest.raises(InputError, match="skyZenithAngles"):
        stage_longwave_table(stage)
    prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).Set([0.0, 30.0, 60.0])
    assert_allclose(stage_longwave_table(stage)[1], [80.0, 90.0, 95.0])
