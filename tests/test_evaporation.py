"""Latent heat in the surface balance (issue 30.2/30.4): physics/evaporation.py and the slab's
latent term, against closed forms (psychrometer, Penman-Monteith, Stull's wet bulb) and an
independent root solve."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics import evaporation as ev
from humv_usd.physics import slab

P0 = 101325.0


def _steady(absorbed, sky, t_air, h, eps, rh, rs, wet=0.0, pressure=P0):
    """Steady surface temperature of a slab with an adiabatic back (no conduction at steady
    state): the surface balance alone."""
    beta = ev.evaporation_efficiency(h, rs, pressure, t_air, wet)
    ea = rh * ev.saturation_vapour_pressure(t_air)
    t, res = slab.step_many(
        np.full((1, 5), t_air),
        np.inf,
        slab.uniform_layers(0.05, 4),
        0.5,
        2e6,
        absorbed,
        sky,
        t_air,
        h,
        eps,
        evaporation_beta=beta,
        vapour_pressure_pa=ea,
        pressure_pa=pressure,
    )
    return float(t[0, 0]), float(res[0])


def test_saturation_vapour_pressure_table():
    # FAO-56 Annex 2, Table 2.3: e_s(20 degC) = 2.338 kPa, e_s(30 degC) = 4.243 kPa
    assert_allclose(ev.saturation_vapour_pressure([293.15, 303.15]), [2338.0, 4243.0], rtol=2e-3)
    # FAO-56 Table 2.4: Delta(20 degC) = 0.145 kPa/K
    assert_allclose(ev.saturation_slope(293.15), 145.0, rtol=5e-3)
    assert_allclose(ev.psychrometric_constant(P0), 67.3, rtol=0.02)  # FAO-56 Table 2.2: 0.067 kPa/K


@pytest.mark.parametrize("t_c", [5.0, 20.0, 35.0, 45.0])  # Stull: not for cold and dry together
@pytest.mark.parametrize("rh", [0.1, 0.4, 0.7, 0.95])
def test_wet_bulb_against_stull(t_c, rh):
    tw = ev.wet_bulb_temperature(t_c + 273.15, rh)
    # Stull (2011): within -1 / +0.65 K of the psychrometric value over his range
    assert -1.2 <= float(ev.stull_wet_bulb(t_c + 273.15, rh) - tw) <= 0.8
    assert tw <= t_c + 273.15 + 1e-9


def test_wet_surface_without_radiation_is_the_wet_bulb():
    # emissivity 0, no sun: convection feeds evaporation alone, the psychrometer equation
    for t_air, rh in ((303.15, 0.3), (283.15, 0.8), (313.15, 0.1)):
        t, res = _steady(0.0, 0.0, t_air, 12.0, 0.0, rh, rs=0.0)
        assert_allclose(t, ev.wet_bulb_temperature(t_air, rh), atol=1e-6)
        assert abs(res) < 1e-6


def test_latent_balance_against_root_solve_and_penman_monteith():
    t_air, rh, h, eps, rs = 300.15, 0.5, 8.0, 0.97, 60.0
    absorbed, sky = 600.0, 350.0
    t, _ = _steady(absorbed, sky, t_air, h, eps, rh, rs)
    beta = ev.evaporation_efficiency(h, rs, P0, t_air)
    ea = rh * ev.saturation_vapour_pressure(t_air)

    def balance(ts):
        le = beta * h / ev.psychrometric_constant(P0, t_air) * (ev.saturation_vapour_pressure(ts) - ea)
        return absorbed + eps * (sky - STEFAN_BOLTZMANN * ts**4) + h * (t_air - ts) - le

    assert_allclose(t, brentq(balance, 250.0, 400.0, xtol=1e-12), atol=1e-7)
    # Penman-Monteith: the same balance linearized about the air temperature (isothermal net
    # radiation, radiative conductance in parallel with convection; Monteith & Unsworth ch. 13)
    rc = ev.air_heat_capacity(P0, t_air)
    r_hr = rc / (h + 4 * eps * STEFAN_BOLTZMANN * t_air**3)
    rn_iso = absorbed + eps * (sky - STEFAN_BOLTZMANN * t_air**4)
    le_pm = ev.penman_monteith(rn_iso, t_air, rh, r_hr, rc / h + rs - r_hr)
    le_slab = beta * h / ev.psychrometric_constant(P0, t_air) * (ev.saturation_vapour_pressure(t) - ea)
    assert_allclose(le_slab, le_pm, rtol=0.08)  # e_s linearized over T_s - T_air of several K


def test_surface_resistance_light_and_soil():
    night = ev.surface_resistance(35.0, 0.0)
    noon = ev.surface_resistance(35.0, 850.0)
    assert_allclose(night, ev.MAX_SURFACE_RESISTANCE_S_M)
    # ASCE hourly reference grass by day: r_s = 50 s/m (Allen et al. 2006)
    assert 40.0 <= float(noon) <= 60.0
    assert float(ev.surface_resistance(35.0, 850.0, soil_moisture=0.25)) == pytest.approx(4 * float(noon))
    assert float(ev.surface_resistance(35.0, 850.0, soil_moisture=0.0)) == ev.MAX_SURFACE_RESISTANCE_S_M


def test_extreme_grid_finite_and_monotonic():
    t_air = np.array([233.15, 273.15, 300.15, 328.15])
    for ta in t_air:
        for wind in (0.0, 5.0, 30.0):
            h = 2.8 + 3.0 * wind
            for sun in (0.0, 600.0, 1200.0):
                for rh in (0.0, 0.5, 1.0):
                    temps = [
                        _steady(0.8 * sun, 0.8 * STEFAN_BOLTZMANN * ta**4, ta, h, 0.95, rh, rs)[0]
                        for rs in (np.inf, 500.0, 50.0, 0.0)
                    ]
                    assert np.all(np.isfinite(temps))
                    # more open stomata / wetter surface: never warmer where the dry surface is
                    # above the dew point; never cooler below it (dew warms it)
                    sign = (
                        1.0
                        if ev.saturation_vapour_pressure(temps[0]) >= rh * ev.saturation_vapour_pressure(ta)
                        else -1.0
                    )
                    assert np.all(sign * np.diff(temps) <= 1e-6), (ta, wind, sun, rh, temps)
                drier = [_steady(0.8 * sun, 300.0, ta, h, 0.95, rh, 0.0)[0] for rh in (0.0, 0.5, 1.0)]
                assert np.all(np.diff(drier) >= -1e-6)  # moister air: less evaporative cooling


def test_rain_wets_and_the_surface_dries():
    # a concrete-like slab under a constant noon sun: 1 h of 5 mm/h rain, then 6 h of drying
    step = 600.0
    times = np.arange(0.0, 8 * 3600.0 + 1, step)
    rain = ev.rain_schedule(times - 8 * 3600.0, 5.0, end_before_s=7 * 3600.0, duration_s=3600.0)
    t_air, rh, h = 298.15, 0.5, 10.0
    kw = dict(
        forcing_times_s=times,
        absorbed_solar=450.0,
        sky_longwave=330.0,
        air_temperature_k=t_air,
        h_conv=h,
        layer_thickness_m=slab.uniform_layers(0.1, 8),
        conductivity=1.4,
        volumetric_heat_capacity=2.0e6,
        emissivity=0.92,
        initial_temperature_k=t_air,
    )
    dry, _ = slab.simulate_many(**kw)
    wet, _, frac = slab.simulate_many(
        **kw,
        surface_resistance_s_m=np.inf,
        vapour_pressure_pa=rh * ev.saturation_vapour_pressure(t_air),
        pressure_pa=P0,
        rain_kg_m2_s=rain[:, None],
        water_capacity_kg_m2=0.5,
        return_wet_fraction=True,
    )
    raining = rain > 0
    assert frac[raining][-1, 0] == pytest.approx(1.0)  # fully wet at the end of the shower
    assert frac[-1, 0] == 0.0  # dried by the end
    i_end = np.flatnonzero(raining)[-1]
    # while wet the surface is cooler than the dry one, and above the wet bulb (the sun heats it)
    assert wet[i_end, 0] < dry[i_end, 0] - 5.0
    assert wet[i_end, 0] > ev.wet_bulb_temperature(t_air, rh)
    # once dry it warms back towards the dry surface
    assert abs(wet[-1, 0] - dry[-1, 0]) < 2.0
    # without rain and without a surface resistance the result is the dry model's
    same, _ = slab.simulate_many(**kw, surface_resistance_s_m=np.inf, vapour_pressure_pa=1000.0)
    assert_allclose(same, dry, atol=1e-9)
