"""Weather, sun and sky read from the stage (issue 11, edit (b)): the environment layer is the one
place that computes them, the thermal tool reads them back (spin-up included) and sees the same
long-wave sky as the render at every frame of an hourly weather series; a hand edit of the
environment layer changes the thermal result."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Sdf, Usd

from humv_usd.atmosphere import layer as atmosphere_layer
from humv_usd.atmosphere import lowtran as lt
from humv_usd.atmosphere import model as M
from humv_usd.atmosphere import paths as paths_layer
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.environment import layer as environment_layer
from humv_usd.environment.sun import scenario_sun
from humv_usd.environment.weather import scenario_weather
from humv_usd.materials import layer as materials_layer
from humv_usd.physics.sky import hemispherical_irradiance
from humv_usd.pipeline.compose import compose_in_memory
from humv_usd.scenario import validate
from humv_usd.scene import layer as scene_layer
from humv_usd.sensors import layer as sensors_layer
from humv_usd.thermal import layer as thermal_layer
from humv_usd.thermal.surfaces import forcing_at, with_sky_table
from humv_usd.usd import environment as E
from humv_usd.usd import schemas as S
from humv_usd.usd.atmosphere import longwave_sky, sky_temperature

FPS = 0.01  # 100 s per frame
SPIN_S = 3600.0

#: 14:05 .. 17:05 local: warmer, wetter and clouding over
CSV = (
    "time,air_temperature_k,relative_humidity,cloud_cover\n"
    "2018-10-24T14:05:00,285.0,0.30,0.0\n"
    "2018-10-24T15:05:00,290.0,0.55,0.4\n"
    "2018-10-24T16:05:00,294.0,0.80,0.9\n"
    "2018-10-24T17:05:00,294.0,0.80,0.9\n"
)


def _scenario(humvvex_raw, tmp_path, csv: bool, spin_s: float = SPIN_S):
    raw = copy.deepcopy(humvvex_raw)
    raw["human"], raw["placement"] = [], []  # no people: fast (the slabs carry the weather)
    raw["general"].update(duration_s=7200.0, fps=FPS)  # 73 frames, 2 h
    # LOWTRAN7 (cached) when built: its sky does not follow the analytic law's changes, so the
    # frame-0 table rescaled analytically (the thermal tool before) misses frame 72 by ~2 %
    raw["atmosphere"]["model"] = "lowtran7" if lt.available() else "analytic"
    raw["sensor"] = [s for s in raw["sensor"] if s["id"] == "lwir640"]
    raw["thermal"].update(model="fixed", surface_spin_up_s=spin_s, radiation_step_s=3600.0)
    raw["scene"]["ground"].pop("temperature_k", None)  # a slab: the weather matters
    # the hour before the series holds its first row (the diurnal cycle: tests/test_diurnal.py)
    raw["atmosphere"]["diurnal_range_k"] = 0.0
    if csv:
        path = tmp_path / "weather.csv"
        path.write_text(CSV)
        raw["atmosphere"]["weather_csv"] = str(path)
    return validate(raw)


def _upstream(sc, *extra):
    layers = [
        environment_layer.build(sc),
        *extra,
        materials_layer.build(sc),
        scene_layer.build(sc),
        sensors_layer.build(sc),
    ]
    layers.append(atmosphere_layer.build(sc, compose_in_memory(layers, FPS)))
    layers.append(paths_layer.build(sc, compose_in_memory(layers, FPS)))
    return layers, compose_in_memory(layers, FPS)


@pytest.fixture(scope="module")
def hourly(humvvex_raw, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hourly")
    mp = pytest.MonkeyPatch()
    mp.setenv(M.CACHE_ENV, str(tmp / "cache"))
    sc = _scenario(humvvex_raw, tmp, csv=True)
    layers, upstream = _upstream(sc)
    thermal = thermal_layer.build(sc, upstream)
    yield sc, upstream, thermal, compose_in_memory(layers + [thermal], FPS)
    mp.undo()


def test_environment_layer_holds_the_spin_up_at_negative_time_codes(hourly):
    sc, upstream, _, _ = hourly
    spin_t = np.arange(-SPIN_S, 0.0, 600.0)
    codes = E.time_codes(upstream, spin_t)
    assert_allclose(codes, spin_t * FPS)
    env = upstream.GetPrimAtPath("/World/Environment")
    samples = env.GetAttribute(S.ENVIRONMENT_SUN_ZENITH).GetTimeSamples()
    assert_allclose(samples[: spin_t.size], codes)  # then the frames 0 .. 72
    assert samples[spin_t.size] == 0.0 and samples[-1] == 72.0
    # the spin-up hour before the series starts holds its first row; the sun follows the clock
    w = E.read_weather(upstream, codes)
    assert_allclose(w.air_temperature_k, 285.0)
    assert_allclose(w.cloud_cover, 0.0)
    sun = E.read_sun(upstream, codes)
    ref = scenario_sun(sc, spin_t, scenario_weather(sc, np.zeros_like(spin_t)))
    assert_allclose(sun.zenith_deg, ref.zenith_deg, atol=1e-4)
    assert_allclose(sun.dni_w_m2, ref.dni_w_m2, rtol=1e-5, atol=1e-3)
    # at the frames, the layer's weather is the series (USD: linear between the frame samples)
    w = E.read_weather(upstream, [0.0, 36.0, 72.0])
    assert_allclose(w.air_temperature_k, [285.0, 290.0, 294.0], atol=1e-4)
    assert_allclose(w.cloud_cover, [0.0, 0.4, 0.9], atol=1e-6)
    assert E.read_site(upstream).start_time.startswith("2018-10-24T14:05:00")


def test_spin_up_samples_leave_frames_unchanged(humvvex_raw, tmp_path):
    """Readers at frames >= 0 (the render) see the same sun and weather with and without the
    spin-up samples."""
    with_spin = compose_in_memory([environment_layer.build(_scenario(humvvex_raw, tmp_path, True))], FPS)
    without = compose_in_memory(
        [environment_layer.build(_scenario(humvvex_raw, tmp_path, True, spin_s=0.0))], FPS
    )
    assert not any(
        c < 0
        for c in without.GetPrimAtPath("/World/Environment")
        .GetAttribute(S.ENVIRONMENT_SUN_ZENITH)
        .GetTimeSamples()
    )
    frames = [0.0, 0.5, 17.0, 72.0]
    assert_allclose(E.read_sun(with_spin, frames).direction, E.read_sun(without, frames).direction, atol=1e-7)
    for key in ("air_temperature_k", "relative_humidity", "cloud_cover"):
        assert_allclose(
            getattr(E.read_weather(with_spin, frames), key), getattr(E.read_weather(without, frames), key)
        )
    for f in frames:  # the render reads these through the same usd.environment readers
        assert_allclose(E.sun_direction(with_spin, f), E.sun_direction(without, f), atol=1e-7)
        assert E.direct_normal_irradiance(with_spin, f) == E.direct_normal_irradiance(without, f)


def test_thermal_and_render_see_the_same_sky_hours_apart(hourly):
    """Issue 11 (b): at frames 0 and 72 (2 h apart) the thermal tool's long-wave sky is the
    table the stage holds at that frame, whose irradiance is the render's sky temperature
    (sigma T_sky^4); the two frames' skies differ (warmer, wetter, cloudier)."""
    sc, upstream, thermal, stage = hourly
    th = sc["thermal"]
    samples = list(range(0, sc.frame_count, int(round(th["radiation_step_s"] * FPS))))
    assert samples == [0, 36, 72]
    spin_t = np.arange(-SPIN_S, 0.0, 600.0)
    # exactly what the thermal tool's build uses: the tables at the samples' time codes
    tables = thermal_layer.sky_tables(upstream, samples)
    forcing = with_sky_table(
        forcing_at(upstream, np.r_[spin_t, np.asarray(samples) / FPS]), tables, spin_t.size
    )
    irradiance = {}
    for k, frame in enumerate(samples):
        zen, rad = longwave_sky(stage, float(frame))  # the usd reader on the final stage
        assert_allclose(tables[k][0], zen)
        assert_allclose(tables[k][1], rad)
        attr = stage.GetPrimAtPath("/World/Atmosphere").GetAttribute(S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE)
        assert_allclose(rad, np.asarray(attr.Get(frame), float))
        e = float(forcing.sky_longwave[spin_t.size + k])
        assert e == pytest.approx(hemispherical_irradiance(zen, rad), rel=1e-12)
        # the render's broadband sky at the same frame: same irradiance (the atmosphere's own
        # quadrature of the table differs from the exact one by ~0.2 %)
        t_sky = sky_temperature(stage, float(frame))
        assert e == pytest.approx(STEFAN_BOLTZMANN * t_sky**4, rel=3e-3)
        irradiance[frame] = e
    assert irradiance[72] > irradiance[0] + 60.0  # 9 K warmer, wetter, 90 % clouds
    # the layer's report (frame 0) says the same
    report = dict(thermal.customLayerData["humv:thermal"]["sky"])
    assert report["longwaveIrradiance_W_m2"] == pytest.approx(irradiance[0], rel=1e-6)
    assert report["source"].startswith("atmosphere layer")


def test_hand_edited_air_temperature_changes_the_thermal_layer(humvvex_raw, tmp_path, monkeypatch):
    """A stronger layer that overrides the environment's air temperature (+8 K at every time
    code) warms the slab ground: the thermal tool reads the layer back, not the scenario."""
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path / "cache"))
    sc = _scenario(humvvex_raw, tmp_path, csv=False)
    override = Sdf.Layer.CreateAnonymous(".usda")
    edit = Usd.Stage.Open(override)
    prim = edit.OverridePrim("/World/Environment")
    t_air = float(sc["atmosphere"]["air_temperature_k"])
    prim.CreateAttribute(S.ENVIRONMENT_AIR_TEMPERATURE, Sdf.ValueTypeNames.Float).Set(t_air + 8.0)
    ground = {}
    for name, extra in (("as built", ()), ("edited", (override,))):
        _, upstream = _upstream(sc, *extra)
        assert E.read_weather(upstream, [0.0]).air_temperature_k[0] == pytest.approx(
            t_air + (8.0 if extra else 0.0), abs=1e-4
        )
        layer = thermal_layer.build(sc, upstream)
        stage = compose_in_memory([layer], FPS)
        values = stage.GetPrimAtPath("/World/Scene/Ground").GetAttribute(S.TEMPERATURE_PRIMVAR).Get(0)
        ground[name] = float(np.mean(values))
    assert ground["edited"] > ground["as built"] + 1.0


def test_hand_edited_cloud_cover_changes_the_atmosphere_layer(humvvex_raw, tmp_path, monkeypatch):
    """The atmosphere tool reads the environment layer too: a stronger layer setting the cloud
    cover to 1 makes the sky it authors a blackbody at the air temperature (Crawford & Duchon)."""
    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path / "cache"))
    sc = _scenario(humvvex_raw, tmp_path, csv=False)
    assert sc["atmosphere"]["cloud_cover"] == 0.0
    override = Sdf.Layer.CreateAnonymous(".usda")
    edit = Usd.Stage.Open(override)
    prim = edit.OverridePrim("/World/Environment")
    prim.CreateAttribute(S.ENVIRONMENT_CLOUD_COVER, Sdf.ValueTypeNames.Float).Set(1.0)
    emissivity = {}
    for name, extra in (("as built", ()), ("overcast", (override,))):
        layers, stage = _upstream(sc, *extra)
        emissivity[name] = (
            stage.GetPrimAtPath("/World/Atmosphere").GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY).Get()
        )
    assert emissivity["as built"] < 0.9
    assert emissivity["overcast"] == pytest.approx(1.0, abs=1e-6)


def test_path_ranges_reach_a_hand_made_mesh_of_the_stage(humvvex_raw, tmp_path, monkeypatch):
    """The path table's ranges come from the scene on the stage: they reach the farthest ground
    the camera sees (the horizon rings' corners, [scene.ground] horizon_m: square rings, so
    sqrt(2) horizon_m from the origin), and, on a ground that ends at size_m (horizon_m = 0), a
    mast 3 km away added by a stronger layer (not in the scenario) stretches the sensor's table
    to 1.5 x its distance."""
    from pxr import UsdGeom

    from humv_usd.atmosphere.model import PATH_RANGES_M
    from humv_usd.usd.atmosphere import PATHS

    monkeypatch.setenv(M.CACHE_ENV, str(tmp_path / "cache"))
    extra = Sdf.Layer.CreateAnonymous(".usda")
    edit = Usd.Stage.Open(extra)
    mast = UsdGeom.Mesh.Define(edit, "/World/Scene/far_mast")
    mast.CreatePointsAttr([(3000.0, 0.0, 0.0), (3001.0, 0.0, 0.0), (3000.0, 0.0, 20.0)])
    mast.CreateFaceVertexCountsAttr([3])
    mast.CreateFaceVertexIndicesAttr([0, 1, 2])
    mast.CreateExtentAttr([(3000.0, 0.0, 0.0), (3001.0, 0.0, 20.0)])
    far, scenarios = {}, {}
    for name, horizon_m, layers in (
        ("horizon", None, ()),
        ("as built", 0.0, ()),
        ("with mast", 0.0, (extra,)),
    ):
        raw = copy.deepcopy(humvvex_raw)
        if horizon_m is not None:
            raw["scene"]["ground"]["horizon_m"] = horizon_m
        sc = scenarios[name] = _scenario(raw, tmp_path, csv=False)
        _, stage = _upstream(sc, *layers)
        ranges = (
            stage.GetPrimAtPath(PATHS.AppendChild("lwir640_path"))
            .GetAttribute(S.ATMOSPHERE_PATH_RANGES)
            .Get()
        )
        far[name] = float(ranges[-1])
    cam = np.asarray(scenarios["horizon"]["sensor"][0]["position_m"], float)
    h = scenarios["horizon"]["scene"]["ground"]["horizon_m"]
    assert h == 20000.0  # the default: the ground reaches the horizon
    ground_corners = np.array([(sx * h, sy * h, 0.0) for sx in (-1, 1) for sy in (-1, 1)])
    farthest = float(np.max(np.linalg.norm(ground_corners - cam, axis=1)))
    assert farthest <= far["horizon"] <= float(PATH_RANGES_M[-1])
    corner = np.array([3001.0, 0.0, 20.0])
    assert far["as built"] < 1000.0
    assert far["with mast"] == pytest.approx(1.5 * np.linalg.norm(corner - cam), rel=1e-5)
