"""Atmosphere: LOWTRAN7 sky, paths and sun; analytic fallback; cache; the atmosphere layer."""

from __future__ import annotations

import copy
import datetime as dt

import numpy as np
import pytest
from conftest import atmosphere_layer_of, atmosphere_layers_of, upstream_of

from humv_usd.atmosphere import lowtran as lt
from humv_usd.atmosphere import model as M
from humv_usd.atmosphere import paths as paths_layer
from humv_usd.compat import trapezoid
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.environment import layer as environment_layer
from humv_usd.environment.sun import scenario_sun
from humv_usd.physics import planck
from humv_usd.physics.sky import directional_sky_emissivity, effective_sky_temperature
from humv_usd.scenario import validate
from humv_usd.usd import schemas as S
from humv_usd.usd.atmosphere import PATHS
from humv_usd.usd.layers import layer_text


def _atmosphere_for(sc):
    """The scenario's Atmosphere, with weather and sun of its environment layer."""
    return M.atmosphere_for(sc, upstream_of(sc))


needs_lowtran = pytest.mark.skipif(not lt.available(), reason="LOWTRAN7 not built")


def _band_bt(wl, spectral, band=(8.0, 14.0)):
    m = (wl >= band[0]) & (wl <= band[1])
    radiance = trapezoid(spectral[..., m], wl[m], axis=-1)
    return planck.brightness_temperature(radiance, [wl[m][0], wl[m][-1]])


@pytest.fixture(scope="session")
def lowtran_cache(tmp_path_factory):
    return tmp_path_factory.mktemp("atmosphere-cache")


@pytest.fixture(scope="session")
def humvvex_lowtran(humvvex_raw, lowtran_cache):
    """humvvex with LOWTRAN7, computed once into an empty cache: (scenario, atmosphere, runs)."""
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "lowtran7"
    sc = validate(raw)
    mp = pytest.MonkeyPatch()
    mp.setenv(M.CACHE_ENV, str(lowtran_cache))
    try:
        before = lt.CALLS
        atm = _atmosphere_for(sc)
        runs = lt.CALLS - before
    finally:
        mp.undo()
    return sc, atm, runs


@needs_lowtran
def test_lowtran_runs_once_then_cache(humvvex_lowtran, lowtran_cache, monkeypatch):
    sc, atm, runs = humvvex_lowtran
    assert atm.source == "lowtran7" and atm.ran["lowtran7"] == "ran"
    assert 0 < runs < 150  # batched: sky, paths, sun
    assert all("miss" in c for c in atm.ran["cache"])
    monkeypatch.setenv(M.CACHE_ENV, str(lowtran_cache))
    before = lt.CALLS
    again = _atmosphere_for(sc)
    assert lt.CALLS == before  # nothing rerun
    assert all(c.endswith("hit") for c in again.ran["cache"])
    np.testing.assert_array_equal(again.sky_radiance, atm.sky_radiance)
    np.testing.assert_array_equal(again.path_transmittance, atm.path_transmittance)


@needs_lowtran
def test_grid_covers_only_the_sensor_bands(humvvex_lowtran):
    from humv_usd.render.radiometry import covers

    sc, atm, _ = humvvex_lowtran
    wl = atm.wavelengths_um
    assert np.all(np.diff(wl) > 0)
    for s in sc["sensor"]:
        assert covers(wl, s["wavelength_um"]), s["id"]
    bands = M.sensor_bands(sc)
    pad = 0.3  # one LOWTRAN sample beyond each edge
    inside = np.zeros(wl.size, bool)
    for lo, hi in bands:
        inside |= (wl >= lo - pad) & (wl <= hi + pad)
    assert inside.all()
    assert not np.any((wl > 5.4) & (wl < 7.0))  # the gap between MWIR and LWIR


@needs_lowtran
def test_clear_sky_colder_than_air_and_rises_to_horizon(humvvex_lowtran):
    sc, atm, _ = humvvex_lowtran
    t_air = sc["atmosphere"]["air_temperature_k"]
    zen = np.array([0.0, 30.0, 60.0, 80.0, 89.0])
    bt = _band_bt(atm.wavelengths_um, atm.sky_spectral_radiance(zen))
    assert bt[0] < t_air - 40.0  # 8-14 um zenith: ~217 K vs 289 K
    assert np.all(np.diff(bt) > 0)  # brighter toward the horizon
    assert abs(bt[-1] - t_air) < 8.0  # near-horizontal: almost the air
    assert np.all(atm.sky_spectral_radiance(zen) >= 0)


@needs_lowtran
def test_broadband_sky_close_to_berdahl_martin(humvvex_lowtran):
    sc, atm, _ = humvvex_lowtran
    a = sc["atmosphere"]
    _, eps_bm = effective_sky_temperature(a["air_temperature_k"], a["relative_humidity"])
    assert atm.sky_emissivity == pytest.approx(float(eps_bm), abs=0.05)
    # effective temperature and emissivity are the same flux
    assert STEFAN_BOLTZMANN * atm.sky_temperature_k**4 == pytest.approx(
        atm.sky_emissivity * STEFAN_BOLTZMANN * a["air_temperature_k"] ** 4, rel=1e-9
    )


@needs_lowtran
def test_paths_fall_with_range_and_obey_kirchhoff(humvvex_lowtran):
    sc, atm, _ = humvvex_lowtran
    wl = atm.wavelengths_um
    tau, rad = atm.path(None, atm.path_ranges_m)
    assert np.all(np.diff(tau, axis=0) <= 1e-6)  # every wavelength, every range step
    lw = (wl >= 8) & (wl <= 14)
    mean = tau[:, lw].mean(axis=1)
    assert mean[0] > 0.99 and mean[-1] < 0.3
    # isothermal, non-scattering path: L = (1 - tau) B(T_air) (LOWTRAN's own emission)
    bb = planck.spectral_radiance(wl, sc["atmosphere"]["air_temperature_k"])
    ir = wl > 2.5
    np.testing.assert_allclose(
        trapezoid(rad[:, ir], wl[ir], axis=1), trapezoid(((1 - tau) * bb)[:, ir], wl[ir], axis=1), rtol=0.02
    )
    opaque = (tau[-1] < 1e-4) & ir
    assert opaque.sum() > 5  # CO2 4.3 um, 14 um edges
    np.testing.assert_allclose(rad[-1, opaque], bb[opaque], rtol=0.01)  # units: W m-2 sr-1 um-1
    t0, r0 = atm.path(None, [0.0])
    assert np.all(t0 == 1.0) and np.all(r0 == 0.0)


@needs_lowtran
def test_paths_without_the_sun_are_the_same_paths(humvvex_lowtran, lowtran_cache, monkeypatch):
    """The paths tool asks for no sun (``solar=False``: no SPCTRL2, no LOWTRAN sun runs, no
    pvlib): its tables and grid are those of the full atmosphere, from the same cache."""
    sc, atm, _ = humvvex_lowtran
    monkeypatch.setenv(M.CACHE_ENV, str(lowtran_cache))
    before = lt.CALLS
    dark = M.atmosphere_for(sc, upstream_of(sc), solar=False)
    assert lt.CALLS == before
    np.testing.assert_array_equal(dark.wavelengths_um, atm.wavelengths_um)
    np.testing.assert_array_equal(dark.path_transmittance, atm.path_transmittance)
    np.testing.assert_array_equal(dark.path_radiance, atm.path_radiance)
    assert atm.solar.any() and not dark.solar.any() and not dark.diffuse_radiance.any()
    assert dark.ran["sun"].startswith("skipped")


@needs_lowtran
def test_transmittance_falls_with_humidity():
    spec = lt.spectral_case(8.0, 14.0, 20.0)
    taus = []
    for rh in (0.2, 0.5, 0.8):
        case = dict(
            lt.layer_case(293.15, rh, 101325.0, [0.0]), **spec, itype=1, iemsct=1, h1=0.0, range_km=1.0
        )
        taus.append(lt.run(case).transmittance.mean())
    assert taus[0] > taus[1] > taus[2]
    assert taus[0] - taus[2] > 0.05


@needs_lowtran
def test_direct_sun_in_mwir(humvvex_lowtran):
    sc, atm, _ = humvvex_lowtran
    wl = atm.wavelengths_um
    e = atm.solar_spectral_irradiance([0.0])[0]
    toa = np.pi * M.SUN_ANGULAR_RADIUS**2 * planck.spectral_radiance(wl, M.SUN_TEMPERATURE_K)
    mw = (wl >= 3.0) & (wl <= 5.0)
    ratio = e[mw] / toa[mw]
    assert np.all(ratio <= 1.1) and ratio.max() > 0.6  # 3.8 um window ~0.85 at 53 deg
    assert ratio[np.argmin(np.abs(wl[mw] - 4.3))] < 0.01  # CO2 band
    band = trapezoid(e[mw], wl[mw])
    assert 3.0 < band < 25.0  # ~10.6 W m-2 at humvvex
    eo = (wl >= 0.4) & (wl <= 0.7)
    sun = scenario_sun(sc, [0.0])
    assert 0.15 * sun.dni_w_m2[0] < trapezoid(e[eo], wl[eo]) < 0.6 * sun.dni_w_m2[0]


def test_lowtran_unavailable_falls_back_with_warning(humvvex_raw, monkeypatch, tmp_path, capsys):
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "lowtran7"
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path))

    def broken():
        raise lt.LowtranError("LOWTRAN7 unavailable: test")

    monkeypatch.setattr(lt, "_lowtran", broken)
    with pytest.warns(RuntimeWarning, match="analytic"):
        atm = _atmosphere_for(validate(raw))
    assert atm.source == "analytic" and atm.ran["lowtran7"].startswith("failed")
    t_air = raw["atmosphere"]["air_temperature_k"]
    bt = _band_bt(atm.wavelengths_um, atm.sky_spectral_radiance([0.0, 60.0, 89.0]))
    assert bt[0] < t_air - 5 and np.all(np.diff(bt) > 0)


def test_analytic_model_checks(humvvex_raw):
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "analytic"
    sc = validate(raw)
    atm = _atmosphere_for(sc)
    assert atm.source == "analytic"
    a = sc["atmosphere"]
    # hemispherical integral of the angular law returns the Berdahl-Martin emissivity
    mu = np.linspace(0, 1, 2001)
    eps = directional_sky_emissivity(np.degrees(np.arccos(mu)), atm.sky_emissivity)
    assert 2 * trapezoid(eps * mu, mu) == pytest.approx(atm.sky_emissivity, abs=2e-3)
    assert atm.sky_emissivity == pytest.approx(
        float(effective_sky_temperature(a["air_temperature_k"], a["relative_humidity"])[1])
    )
    tau, _ = atm.path(None, [10.0, 100.0, 1000.0])
    assert np.all(np.diff(tau, axis=0) <= 0)
    raw["atmosphere"]["relative_humidity"] = 0.9
    wet, _ = _atmosphere_for(validate(raw)).path(None, [1000.0])
    lw = (atm.wavelengths_um >= 8) & (atm.wavelengths_um <= 14)
    assert wet[0, lw].mean() < tau[2, lw].mean()


@needs_lowtran
def test_swir_paths_cross_the_water_bands(humvvex_raw, lowtran_cache, monkeypatch):
    """A SWIR sensor alone runs LOWTRAN7 for its paths (issue 24.3): the 1.38 um water vapour
    band is opaque over a 1 km horizontal path (why MODIS band 26 at 1.375 um sees no surface,
    Gao, Goetz & Wiscombe 1993, GRL 20:301) while the 1.25 and 1.6 um windows stay clear."""
    monkeypatch.setenv(M.CACHE_ENV, str(lowtran_cache))
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "lowtran7"
    raw["sensor"] = [dict(raw["sensor"][0], preset="swir_ingaas640", id="swir")]
    for key in ("band", "wavelength_um", "netd_k", "gain", "offset", "agc"):
        raw["sensor"][0].pop(key, None)
    atm = _atmosphere_for(validate(raw))
    assert atm.ran["lowtran7"] == "ran" and atm.wavelengths_um.max() < 2.0
    tau, _ = atm.path(ranges_m=[1000.0])
    at = {w: float(np.interp(w, atm.wavelengths_um, tau[0])) for w in (1.25, 1.38, 1.6)}
    assert at[1.38] < 0.05 and at[1.25] > 0.85 and at[1.6] > 0.85


def test_only_what_the_scene_needs(humvvex_raw, monkeypatch, tmp_path):
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path))
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "lowtran7"
    eo_only = copy.deepcopy(raw)
    eo_only["sensor"] = [s for s in raw["sensor"] if s.get("band", "LWIR") == "EO" or "eo" in s["id"]]
    assert eo_only["sensor"]
    before = lt.CALLS
    atm = _atmosphere_for(validate(eo_only))
    assert lt.CALLS == before  # no infrared sensor: no LOWTRAN
    assert atm.ran["lowtran7"] == "skipped: no infrared, NIR or SWIR sensor"
    assert atm.wavelengths_um.max() < 1.0
    none = copy.deepcopy(raw)
    none["sensor"] = []
    atm = _atmosphere_for(validate(none))
    assert atm.wavelengths_um.size == 0 and lt.CALLS == before
    # night: no sun term
    night = copy.deepcopy(eo_only)
    night["general"]["start"] = dt.datetime(2018, 10, 24, 23, 5)
    atm = _atmosphere_for(validate(night))
    assert not atm.solar.any() and not atm.diffuse_radiance.any()
    assert atm.ran["sun"].startswith("skipped")


def _stage(*layers):
    from humv_usd.pipeline.compose import compose_in_memory

    return compose_in_memory(list(layers), 30.0)


def test_layers_author_the_contract(humvvex_raw, monkeypatch, tmp_path):
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path))
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "analytic"  # fast; the LOWTRAN tables have the same shape
    raw["general"]["duration_s"] = 2.0 / 30.0  # three frames
    # no slab spin-up: the environment layer then holds the sun at the three frames only
    # (the spin-up's negative time codes are tested in test_environment.py)
    raw["thermal"] = dict(raw.get("thermal") or {}, surface_spin_up_s=0.0)
    sc = validate(raw)
    env, (atm_layer, paths) = environment_layer.build(sc), atmosphere_layers_of(sc)
    assert not _stage(atm_layer).GetPrimAtPath(PATHS)  # the sky layer has no paths
    stage = _stage(env, atm_layer, paths)
    e = stage.GetPrimAtPath("/World/Environment")
    sun = scenario_sun(sc, [0.0, 1 / 30, 2 / 30])
    for f in range(3):
        d = np.array(e.GetAttribute(S.ENVIRONMENT_SUN_DIRECTION).Get(f))
        np.testing.assert_allclose(d, sun.direction[f], atol=1e-6)
        assert e.GetAttribute(S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE).Get(f) == pytest.approx(
            sun.dni_w_m2[f], rel=1e-6
        )
    assert e.GetAttribute(S.ENVIRONMENT_SUN_ZENITH).GetNumTimeSamples() == 3
    assert not e.GetAttribute(S.ENVIRONMENT_AIR_TEMPERATURE).GetNumTimeSamples()  # constant
    a = stage.GetPrimAtPath("/World/Atmosphere")
    assert a.GetAttribute(S.ATMOSPHERE_MODEL).Get() == "analytic"
    wl = np.array(a.GetAttribute(S.ATMOSPHERE_WAVELENGTHS).Get())
    zen = np.array(a.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).Get())
    sky = np.array(a.GetAttribute(S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE).Get(0))
    solar = np.array(a.GetAttribute(S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE).Get(1))
    assert sky.size == zen.size * wl.size and solar.size == wl.size and zen[-1] <= 90
    assert a.GetAttribute(S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE).GetNumTimeSamples() == 3
    paths_ran = paths.customLayerData["humv:atmospherePaths:ran"]
    assert (
        paths_ran["model"] == "analytic" and f"tables for {len(sc['sensor'])} sensors" in paths_ran["paths"]
    )
    paths = stage.GetPrimAtPath(PATHS).GetChildren()
    # named apart from the cameras (Blender renamed the cameras "<sensor>.001")
    assert sorted(p.GetName() for p in paths) == sorted(f"{s['id']}_path" for s in sc["sensor"])
    for p in paths:
        assert p.HasAPI(S.ATMOSPHERE_PATH_API)
        assert (
            p.GetAttribute(S.ATMOSPHERE_PATH_SENSOR).Get()
            == f"/World/Sensors/{p.GetName().removesuffix('_path')}"
        )
        r = np.array(p.GetAttribute(S.ATMOSPHERE_PATH_RANGES).Get())
        tau = np.array(p.GetAttribute(S.ATMOSPHERE_PATH_TRANSMITTANCE).Get())
        assert r[0] <= 1.0 and r[-1] >= 30.0 and np.all(np.diff(r) > 0)  # beyond the 25 m scene
        assert tau.size == r.size * wl.size and tau.max() <= 1.0
    ran = atm_layer.customLayerData["humv:atmosphere:ran"]
    assert ran["lowtran7"].startswith("skipped") and "sky" in ran
    assert "sun" in env.customLayerData["humv:environment:ran"]


def test_paths_layer_refuses_a_stage_whose_wavelengths_differ(humvvex_raw, monkeypatch, tmp_path):
    """The render pairs each path table with the atmosphere layer's wavelength grid: a stage
    whose grid is not the one the tables are computed on is an error naming the attribute."""
    from pxr import Sdf, Usd, Vt

    from humv_usd.errors import InputError
    from humv_usd.scene import layer as scene_layer
    from humv_usd.sensors import layer as sensors_layer

    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path))
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "analytic"
    sc = validate(raw)
    sky, paths = atmosphere_layers_of(sc)
    sky_stage = _stage(sky)
    wl = np.array(sky_stage.GetPrimAtPath("/World/Atmosphere").GetAttribute(S.ATMOSPHERE_WAVELENGTHS).Get())
    edit = Sdf.Layer.CreateAnonymous(".usda")
    edit_stage = Usd.Stage.Open(edit)
    prim = edit_stage.OverridePrim("/World/Atmosphere")
    prim.CreateAttribute(S.ATMOSPHERE_WAVELENGTHS, Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray([float(w) for w in wl[:-1]])
    )
    base = [environment_layer.build(sc), sensors_layer.build(sc), scene_layer.build(sc), sky]
    assert layer_text(paths_layer.build(sc, _stage(*base))) == layer_text(paths)
    with pytest.raises(InputError, match=S.ATMOSPHERE_WAVELENGTHS):
        paths_layer.build(sc, _stage(*base, edit))


def test_night_layer_has_no_solar_term(humvvex_raw, monkeypatch, tmp_path):
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path))
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "analytic"
    raw["general"]["start"] = dt.datetime(2018, 10, 24, 23, 5)
    layer = atmosphere_layer_of(validate(raw))
    stage = _stage(layer)
    a = stage.GetPrimAtPath("/World/Atmosphere")
    assert not a.GetAttribute(S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE).HasAuthoredValue()
    assert "skipped" in layer.customLayerData["humv:atmosphere:ran"]["solar spectrum"]


@needs_lowtran
def test_direct_mwir_sun_dims_with_haze(humvvex_raw, lowtran_cache, monkeypatch):
    """The LOWTRAN runs have no aerosol; the visibility's aerosol (Koschmieder/Kruse over the
    1.2 km scale height, times the air mass) must dim the direct MWIR sun as Beer-Lambert says."""
    import pvlib

    from humv_usd.physics.sky import aerosol_extinction

    monkeypatch.setenv(M.CACHE_ENV, str(lowtran_cache))
    out = {}
    for vis in (23.0, 5.0):
        raw = copy.deepcopy(humvvex_raw)
        raw["atmosphere"].update(model="lowtran7", visibility_km=vis)
        atm = _atmosphere_for(validate(raw))
        out[vis] = (atm.wavelengths_um, atm.solar_spectral_irradiance([0.0])[0])
    wl, clear = out[23.0]
    _, hazy = out[5.0]
    zen = scenario_sun(validate(humvvex_raw), [0.0]).zenith_deg[0]
    m = float(pvlib.atmosphere.get_relative_airmass(zen, model="kasten1966"))
    at = np.argmin(np.abs(wl - 3.8))
    expected = np.exp(
        -(aerosol_extinction(wl[at], 5.0) - aerosol_extinction(wl[at], 23.0)) * M.AEROSOL_SCALE_HEIGHT_M * m
    )
    assert clear[at] > 0 and abs(hazy[at] / clear[at] - expected) < 1e-6
    assert expected < 0.97  # a visible effect at 5 km


@needs_lowtran
def test_layer_text_does_not_depend_on_the_cache(humvvex_raw, monkeypatch, tmp_path):
    """A cold-cache and a warm-cache compose write the same atmosphere layer (an unchanged
    scenario rewrites nothing); the cache's hit/miss is not in the layer."""
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path))
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"]["model"] = "lowtran7"
    raw["sensor"] = raw["sensor"][:1]
    sc = validate(raw)
    before = lt.CALLS
    cold = layer_text(atmosphere_layer_of(sc))
    assert lt.CALLS > before  # the cache was empty: LOWTRAN ran
    warm = layer_text(atmosphere_layer_of(sc))
    assert cold == warm and ": hit" not in cold and ": miss" not in cold


@needs_lowtran
def test_sky_and_paths_follow_an_hourly_weather_series(humvvex_raw, monkeypatch, tmp_path):
    """Humidity 0.2 -> 0.9 over 2 h (hourly CSV): the composed stage's LWIR path transmittance
    falls and the sky radiance rises from frame 0 to the last frame; one LOWTRAN batch per
    weather node (frame 0, the CSV's middle hour, the last frame), a rerun from the cache."""
    from humv_usd.render.export import StageExport
    from humv_usd.render.frame import path_table
    from humv_usd.sensors import layer as sensors_layer
    from humv_usd.thermal.sky import stage_longwave_table
    from humv_usd.usd.atmosphere import atmosphere_spectra

    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path / "cache"))
    csv = tmp_path / "w.csv"
    csv.write_text(
        "time,relative_humidity\n2018-10-24T14:05:00,0.2\n2018-10-24T15:05:00,0.55\n2018-10-24T16:05:00,0.9\n"
    )
    raw = copy.deepcopy(humvvex_raw)
    raw["atmosphere"].update(model="lowtran7", weather_csv=str(csv))
    raw["general"].update(duration_s=7200.0, fps=0.01)  # 73 frames, 100 s apart
    raw["sensor"] = [s for s in raw["sensor"] if s["id"] == "lwir640"]
    sc = validate(raw)
    before = lt.CALLS
    layer = atmosphere_layer_of(sc)
    runs = lt.CALLS - before
    from humv_usd.pipeline.compose import compose_in_memory

    before = lt.CALLS
    sky, paths = atmosphere_layers_of(sc)
    assert lt.CALLS == before  # the paths layer reads the LOWTRAN runs the sky layer cached
    assert layer_text(sky) == layer_text(layer)
    stage = compose_in_memory([sensors_layer.build(sc), sky, paths], 0.01)
    a = stage.GetPrimAtPath("/World/Atmosphere")
    p = stage.GetPrimAtPath(PATHS.AppendChild("lwir640_path"))
    tau_attr = p.GetAttribute(S.ATMOSPHERE_PATH_TRANSMITTANCE)
    assert tau_attr.GetTimeSamples() == [0.0, 36.0, 72.0]  # the weather nodes' frames
    wl = np.array(a.GetAttribute(S.ATMOSPHERE_WAVELENGTHS).Get())
    ranges = np.array(p.GetAttribute(S.ATMOSPHERE_PATH_RANGES).Get())
    band = (wl >= 8.0) & (wl <= 12.0)
    far = ranges.size - 1

    def tau(f):
        return np.array(tau_attr.Get(f)).reshape(ranges.size, wl.size)[far, band].mean()

    def sky_bt(f):
        sky = np.array(a.GetAttribute(S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE).Get(f))
        return _band_bt(wl, sky.reshape(-1, wl.size)[0])  # zenith

    assert tau(72) < tau(0) - 0.01  # wetter air, more absorption
    assert sky_bt(72) > sky_bt(0) + 2.0  # and a warmer (brighter) sky
    assert tau(0) > tau(18) > tau(36)  # USD: linear between nodes
    assert tau(18) == pytest.approx(0.5 * (tau(0) + tau(36)), rel=1e-5)
    # the render's reader gets the time samples
    reader = StageExport(stage)
    sensor = next(s for s in reader.sensors if s.name == "lwir640")
    table0, table72 = path_table(stage, sensor, 0.0), path_table(stage, sensor, 72.0)
    assert not np.allclose(table0.transmittance, table72.transmittance)
    spectra = atmosphere_spectra(stage, 72.0)
    np.testing.assert_allclose(
        spectra.sky_radiance.ravel(), a.GetAttribute(S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE).Get(72)
    )
    # broadband sky: samples for the render, frame-0 default for the thermal tool
    eps = a.GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY)
    assert eps.Get(72) > eps.Get(0) == eps.Get()
    _, lw0 = stage_longwave_table(stage)
    np.testing.assert_allclose(lw0, a.GetAttribute(S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE).Get(0))
    # LOWTRAN: 3 nodes x (sky 48 + paths 19 per interval) + sun once; then all from the cache
    assert 0 < runs <= 3 * (4 * M.SKY_ZENITH_DEG.size + M.PATH_RANGES_M.size) + 60
    before = lt.CALLS
    atmosphere_layer_of(sc)
    assert lt.CALLS == before
