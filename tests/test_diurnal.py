"""Diurnal forcing of the scene-surface spin-up (issue 14 deliverable 7): the Campbell & Norman
cycle in humv_usd.physics.weather and the environment layer's spin-up weather."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd

from humv_usd.environment import layer as environment_layer
from humv_usd.environment.weather import solar_hours
from humv_usd.physics.sky import water_vapour_pressure
from humv_usd.physics.weather import (
    campbell_norman_shape,
    diurnal_air_temperature,
    relative_humidity_at_constant_vapour_pressure,
)
from humv_usd.scenario import validate
from humv_usd.usd.environment import read_weather, time_codes


def test_campbell_norman_shape_spans_0_to_1_with_dawn_minimum_and_afternoon_maximum():
    h = np.linspace(0.0, 24.0, 24001)
    g = campbell_norman_shape(h)
    assert g.min() == pytest.approx(0.0, abs=1e-6) and g.max() == pytest.approx(1.0, abs=1e-6)
    assert 4.0 < h[g.argmin()] < 5.5  # minimum near sunrise
    assert 13.5 < h[g.argmax()] < 15.0  # maximum in the early afternoon
    np.testing.assert_allclose(campbell_norman_shape(h + 24.0), g, atol=1e-12)  # 24 h periodic
    # the published two-harmonic form, rescaled: Gamma(12 h) from Campbell & Norman (1998) Eq. 2.2
    w = np.pi / 12 * 12.0
    published = 0.44 - 0.46 * np.sin(w + 0.9) + 0.11 * np.sin(2 * w + 0.9)
    lo, hi = 0.025327354917349054, 0.9974285701625725
    assert campbell_norman_shape(12.0) == pytest.approx((published - lo) / (hi - lo), rel=1e-9)


def test_cycle_passes_through_the_anchor_and_spans_the_range():
    h = np.arange(0.0, 24.0, 0.01)
    t = diurnal_air_temperature(h, 13.4, 289.0, 11.0)
    assert diurnal_air_temperature(13.4, 13.4, 289.0, 11.0) == pytest.approx(289.0, abs=1e-12)
    assert np.ptp(t) == pytest.approx(11.0, abs=1e-3)
    assert diurnal_air_temperature(h, 13.4, 289.0, 0.0) == pytest.approx(289.0)
    with pytest.raises(ValueError):
        diurnal_air_temperature(h, 13.4, 289.0, float("nan"))


def test_constant_dew_point_keeps_the_vapour_pressure():
    t = np.array([280.0, 285.0, 289.0, 295.0])
    rh = relative_humidity_at_constant_vapour_pressure(t, 289.0, 0.45)
    e = water_vapour_pressure(t, rh)
    np.testing.assert_allclose(e, water_vapour_pressure(289.0, 0.45), rtol=1e-12)
    assert rh[0] > rh[-1]  # humid at night
    assert relative_humidity_at_constant_vapour_pressure(250.0, 289.0, 0.9) == 1.0  # dew: capped


def _spin_up_weather(raw):
    sc = validate(raw)
    stage = Usd.Stage.Open(environment_layer.build(sc))
    t = np.arange(-86400.0, 1.0, 600.0)
    return sc, t, read_weather(stage, time_codes(stage, t))


def test_environment_spin_up_follows_the_diurnal_cycle(raw):
    raw["atmosphere"]["diurnal_range_k"] = 11.0
    sc, t, w = _spin_up_weather(raw)
    a = sc["atmosphere"]
    assert w.air_temperature_k[-1] == pytest.approx(a["air_temperature_k"], abs=1e-4)  # frame 0 kept
    assert np.ptp(w.air_temperature_k) == pytest.approx(11.0, abs=0.05)
    coldest = solar_hours(sc, t[np.argmin(w.air_temperature_k)])[0]
    assert 3.5 < coldest < 5.5  # the night minimum just before sunrise
    e = water_vapour_pressure(w.air_temperature_k, w.relative_humidity)
    np.testing.assert_allclose(
        e, water_vapour_pressure(a["air_temperature_k"], a["relative_humidity"]), rtol=1e-5
    )


def test_zero_range_keeps_the_old_constant_spin_up(raw):
    raw["atmosphere"]["diurnal_range_k"] = 0.0
    sc, _, w = _spin_up_weather(raw)
    assert np.ptp(w.air_temperature_k) == 0.0 and np.ptp(w.relative_humidity) == 0.0


def test_a_weather_series_covering_the_day_is_used_as_it_is(raw, tmp_path):
    # an hourly series over the whole spin-up day: no model cycle, the data's own values
    rows = ["time,air_temperature_k,relative_humidity"]
    for k in range(-26, 2):
        hour = (14 + k) % 24
        day = 24 + (14 + k) // 24
        rows.append(f"2018-10-{day:02d}T{hour:02d}:05:00,{280.0 + 0.25 * (k + 26):.3f},0.5")
    path = tmp_path / "w.csv"
    path.write_text("\n".join(rows) + "\n")
    raw["atmosphere"]["weather_csv"] = str(path)
    raw["atmosphere"]["diurnal_range_k"] = 15.0
    _, t, w = _spin_up_weather(raw)
    # the series is linear in time: 280 K at -26 h, +0.25 K per hour
    np.testing.assert_allclose(w.air_temperature_k, 280.0 + 0.25 * (t / 3600.0 + 26.0), atol=1e-3)
