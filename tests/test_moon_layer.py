"""The moon in the environment layer (issue 24.4): position, phase and illuminance per frame on a
UsdLux DistantLight /World/Environment/Moon, which the render's night light reads instead of
computing the moon itself; the night light is the same as before (PyEphem at render time)."""

from __future__ import annotations

import datetime as dt

import ephem
import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from humv_usd.environment import layer as environment_layer
from humv_usd.physics import nightsky
from humv_usd.render.nightlight import frame_moon, night_light
from humv_usd.scenario import validate
from humv_usd.usd import environment as E

#: Dayton, Ohio, 2018-10-24 23:30 EDT: full moon (2018-10-24 16:45 UTC), high in the south-east
RAW = {
    "general": {
        "name": "moon",
        "start": dt.datetime(2018, 10, 24, 23, 30),
        "utc_offset_h": -4.0,
        "latitude_deg": 39.76,
        "longitude_deg": -84.19,
        "fps": 0.01,  # three frames 100 s apart
        "duration_s": 200.0,
    },
}
WL = np.linspace(0.4, 0.7, 31)


@pytest.fixture(scope="module")
def stage():
    return Usd.Stage.Open(environment_layer.build(validate(RAW)))


def test_the_moon_is_authored_per_frame_as_pyephem_gives_it(stage):
    light = UsdLux.DistantLight(stage.GetPrimAtPath(str(E.MOON_LIGHT_PATH)))
    assert light and light.GetNormalizeAttr().Get() is True
    for frame in range(3):
        m = E.read_moon(stage, frame)
        # PyEphem directly (another call path: its own Observer, the topocentric apparent place)
        obs = ephem.Observer()
        obs.lat, obs.lon, obs.elevation = "39.76", "-84.19", 0.0
        obs.pressure, obs.temp = 1013.25, 15.0  # the standard atmosphere moon_at refracts with
        obs.date = ephem.Date(dt.datetime(2018, 10, 25, 3, 30) + dt.timedelta(seconds=100.0 * frame))
        moon = ephem.Moon(obs)
        assert m.elevation_deg == pytest.approx(np.degrees(float(moon.alt)), abs=1e-6)
        assert m.azimuth_deg == pytest.approx(np.degrees(float(moon.az)), abs=1e-6)
        assert (
            m.illuminated_fraction == pytest.approx(float(moon.moon_phase), abs=1e-9)
            and m.illuminated_fraction > 0.99
        )
        assert 30.0 < m.elevation_deg < 70.0
        lux = nightsky.moon_illuminance_lux(m.elevation_deg, m.phase_angle_deg, m.distance_km)
        assert m.illuminance_lux == pytest.approx(float(lux), rel=1e-12)
        assert 0.2 < m.illuminance_lux < 0.4  # a full moon high up: about 0.27 lx at the zenith (USNO)
        # UsdLux: normalized intensity = beam-normal illuminance, shining along -direction
        assert light.GetIntensityAttr().Get(frame) == pytest.approx(m.illuminance_lux, rel=1e-6)
        travel = UsdGeom.Xformable(light).ComputeLocalToWorldTransform(frame).TransformDir(Gf.Vec3d(0, 0, -1))
        assert_allclose(np.array(travel), -m.direction, atol=1e-6)


def test_the_night_light_reads_the_stage_and_is_unchanged(stage):
    """The render's night light from the stage's moon equals the one computed at render time
    from the site and clock (the previous code path, kept for stages without a moon)."""
    bare = Sdf.Layer.CreateAnonymous(".usda")
    bare.TransferContent(stage.GetRootLayer())
    without = Usd.Stage.Open(bare)
    without.RemovePrim(E.MOON_LIGHT_PATH)
    assert E.read_moon(without, 0) is None
    for frame in range(3):
        sun = E.read_sun(stage, [frame]).direction[0]
        assert sun[2] < 0.0
        got, src = frame_moon(stage, frame), frame_moon(without, frame)
        assert "environment layer" in got[1] and "PyEphem at" in src[1]
        a, b = night_light(stage, frame, sun, WL), night_light(without, frame, sun, WL)
        assert_allclose(a.moon_direction, b.moon_direction, rtol=0, atol=1e-12)
        assert_allclose(a.moon_irradiance, b.moon_irradiance, rtol=1e-12)
        assert_allclose(a.sky, b.sky, rtol=1e-12)
        assert a.moon_irradiance.max() > 0.0


def test_a_moon_below_the_horizon_gives_no_light(stage):
    raw = {**RAW, "general": {**RAW["general"], "start": dt.datetime(2018, 10, 24, 16, 0)}}  # moon not yet up
    day = Usd.Stage.Open(environment_layer.build(validate(raw)))
    m = E.read_moon(day, 0)
    assert m.elevation_deg < 0.0
    assert UsdLux.DistantLight(day.GetPrimAtPath(str(E.MOON_LIGHT_PATH))).GetIntensityAttr().Get(0) == 0.0


def test_the_frames_light_read_carries_the_night_sources_once(stage):
    """The render reads the moon and the cloud cover once per frame with the rest of the light
    (render.light.FrameLight.night); every reflective pass derives its night light from that read
    (nightlight.frame_night_light), not from the stage again; by day nothing is read."""
    from humv_usd.render.light import read_frame_light
    from humv_usd.render.nightlight import frame_night_light

    copy = Sdf.Layer.CreateAnonymous(".usda")
    copy.TransferContent(stage.GetRootLayer())
    night = Usd.Stage.Open(copy)
    light = read_frame_light(night, 1)
    assert light.night.moon.elevation_deg == pytest.approx(E.read_moon(stage, 1).elevation_deg, abs=1e-9)
    expected = night_light(stage, 1, light.sun_direction, WL)
    # the stage changes after the frame's read (the moon's illuminance halved): the frame keeps its moon
    attr = night.GetPrimAtPath(E.MOON_LIGHT_PATH).GetAttribute(E.MOON_ILLUMINANCE)
    attr.Set(0.5 * light.night.moon.illuminance_lux, 1.0)
    assert E.read_moon(night, 1).illuminance_lux == pytest.approx(0.5 * light.night.moon.illuminance_lux)
    got = frame_night_light(light, WL)
    assert_allclose(got.moon_irradiance, expected.moon_irradiance, rtol=1e-12)
    assert_allclose(got.sky, expected.sky, rtol=1e-12)
    raw = {**RAW, "general": {**RAW["general"], "start": dt.datetime(2018, 10, 24, 13, 0)}}
    day = read_frame_light(Usd.Stage.Open(environment_layer.build(validate(raw))), 0)
    assert day.sun_direction[2] > 0.0 and day.night is None and frame_night_light(day, WL) is None
