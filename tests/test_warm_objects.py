"""Warm clutter physics (humv_usd.physics.warm_objects): closed forms, an independent root
finder for the nonlinear balances, and the cited field ranges (idling hood, parked cabin)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics import warm_objects as W
from humv_usd.physics.convection import churchill_bernstein, watmuff


def test_lumped_response_closed_form():
    # one time constant of running: 1 - 1/e of the steady excess; then one of cooling: x 1/e
    assert_allclose(W.lumped_response(100.0, 0.0, 50.0, 100.0, 200.0), 50.0 * (1 - np.exp(-1)))
    assert_allclose(W.lumped_response(100.0, 200.0, 50.0, 100.0, 200.0), 50.0 * (1 - np.exp(-1)) / np.e)
    assert W.lumped_response(0.0, 0.0, 50.0, 100.0, 200.0) == 0.0
    assert_allclose(W.lumped_response(1e9, 0.0, 50.0, 100.0, 200.0), 50.0)


@pytest.mark.parametrize("h_i,h_o,eps", [(8.0, 5.8, 0.9), (2.0, 40.0, 0.95), (20.0, 3.0, 0.5)])
def test_sheet_temperature_solves_its_balance(h_i, h_o, eps):
    ti, ta = 330.0, 285.0
    t = W.sheet_temperature(ti, ta, h_i, h_o, eps)
    ref = brentq(lambda x: h_i * (ti - x) - h_o * (x - ta) - eps * STEFAN_BOLTZMANN * (x**4 - ta**4), ta, ti)
    assert t == pytest.approx(ref, abs=1e-6)
    # without radiation: series resistances (Incropera Eq. 3.1)
    assert W.sheet_temperature(ti, ta, h_i, h_o, 0.0) == pytest.approx((h_i * ti + h_o * ta) / (h_i + h_o))


@pytest.mark.parametrize("air_c", [15.0, 20.0, 25.0])
@pytest.mark.parametrize("minutes", [30, 60])  # warmed up: 3 and 6 idle warm-up time constants
def test_idling_hood_in_the_field_range(air_c, minutes):
    """A warmed-up idling car's hood: 30-50 °C at 15-25 °C air in still air, between the air and
    the engine-bay air (50-80 °C in service: Fournier & Bayne 2007, SAE 2007-01-1393; ~54 °C
    logged above a running engine, mygolfmk7 2023)."""
    air = air_c + 273.15
    t = W.vehicle_part_temperatures(air, W.VehicleState(run_s=60.0 * minutes), wind_m_s=1.0)
    assert 30.0 <= t["hood"] - 273.15 <= 50.0
    assert air < t["hood"] < t["bay"] < t["engine"] <= W.ENGINE_COOLANT_K + 1e-9
    assert 50.0 <= t["bay"] - 273.15 <= 80.0


def test_driving_cools_the_hood_warms_the_tyres_and_stopping_cools_everything():
    air = 293.15
    idle = W.vehicle_part_temperatures(air, W.VehicleState(run_s=1800.0), wind_m_s=1.0)
    drive = W.vehicle_part_temperatures(air, W.VehicleState(run_s=1800.0, speed_m_s=14.0), wind_m_s=1.0)
    assert drive["hood"] < idle["hood"] and drive["tyre"] > idle["tyre"] == pytest.approx(air)
    assert drive["exhaust"] > idle["exhaust"]
    assert 15.0 <= drive["tyre"] - air <= 30.0  # Gent & Walter (2006): 15-30 K in service
    later = [
        W.vehicle_part_temperatures(air, W.VehicleState(run_s=1800.0, off_s=off), wind_m_s=1.0)
        for off in (0.0, 600.0, 3600.0, 12 * 3600.0)
    ]
    for key in ("hood", "exhaust", "engine"):
        values = [t[key] for t in later]
        assert values == sorted(values, reverse=True), key
    assert later[-1]["engine"] - air < 0.05  # a 12 h soak is a cold start
    # a car parked 10 min ago arrived driving: its tyres are still warm, cooling with tau 30 min
    parked = later[1]["tyre"] - air
    assert parked == pytest.approx(
        W.TYRE_EXCESS_K["drive"] * (1 - np.exp(-1800 / 1200)) * np.exp(-600 / 1800)
    )


def test_parked_cabin_follows_mclaren_2005():
    """McLaren et al. (2005): a closed car in clear-sky sun (~900 W m-2) warms ~22 K above air
    in 60 min, 80 % of the rise in the first 30 min."""
    air = 295.0
    target = W.vehicle_part_temperatures(air, W.VehicleState(off_s=1.0e6), global_w_m2=900.0)["cabin"] - air
    assert target == pytest.approx(22.0, abs=1.0)
    after = {
        m: W.vehicle_part_temperatures(air, W.VehicleState(run_s=1.0e5, off_s=60.0 * m), global_w_m2=900.0)[
            "cabin"
        ]
        for m in (30, 60)
    }
    start = W.CABIN_SET_POINT_K
    share_30 = (after[30] - start) / (air + target - start)
    share_60 = (after[60] - start) / (air + target - start)
    assert 0.75 <= share_30 <= 0.85 and share_60 > 0.95


@pytest.mark.parametrize("name", sorted(W.ANIMALS))
def test_coat_surface_solves_its_balance_and_lies_between_air_and_skin(name):
    a = W.ANIMALS[name]
    air, wind = 288.15, 2.0
    t = float(W.coat_surface_temperature(a.skin_k, air, a.coat_depth_m, a.trunk_diameter_m, wind))
    h_c = max(
        float(churchill_bernstein(wind * a.trunk_diameter_m / 1.5e-5)) * 0.026 / a.trunk_diameter_m, 2.5
    )
    k = W.FUR_CONDUCTIVITY_W_MK / a.coat_depth_m
    ref = brentq(
        lambda x: k * (a.skin_k - x) - h_c * (x - air) - 0.98 * STEFAN_BOLTZMANN * (x**4 - air**4),
        air,
        a.skin_k,
    )
    assert t == pytest.approx(ref, abs=1e-6)
    assert air < t < a.skin_k
    # no coat: the skin; a deeper coat or more wind: a cooler surface
    assert W.coat_surface_temperature(a.skin_k, air, 0.0, a.trunk_diameter_m) == pytest.approx(
        a.skin_k, abs=1e-3
    )
    assert W.coat_surface_temperature(a.skin_k, air, 2 * a.coat_depth_m, a.trunk_diameter_m, wind) < t
    assert W.coat_surface_temperature(a.skin_k, air, a.coat_depth_m, a.trunk_diameter_m, 8.0) < t


def test_window_balance_uses_watmuff_floor():
    assert watmuff(0.0) == pytest.approx(W.GLASS_OUTER_STILL_W_M2K)


def test_engine_mode_is_checked():
    with pytest.raises(ValueError, match="invalid model selection"):
        W.engine_temperature(290.0, 10.0, mode="race")
