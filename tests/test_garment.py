"""Garment energy balance (seed Eq. 5-9) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.physics.garment import (
    air_conductivity,
    air_gap_flux,
    areal_heat_capacity,
    grey_plates_exchange_factor,
    hollands_nusselt,
    net_flux,
    steady_state,
    transient_step,
)


def test_air_conductivity_incropera_table():
    # Incropera Table A.4: 250 K 22.3e-3, 300 K 26.3e-3, 350 K 30.0e-3 W/m/K
    assert_allclose(air_conductivity([250.0, 300.0, 350.0]), [22.3e-3, 26.3e-3, 30.0e-3], rtol=0.01)


def test_grey_plates_exchange_factor():
    assert_allclose(
        grey_plates_exchange_factor([1.0, 0.9, 0.0, 0.0], [1.0, 0.9, 0.5, 0.0]),
        [1.0, 0.9 / 1.1, 0.0, 0.0],
        rtol=1e-12,
    )


def test_hollands_nusselt():
    assert_allclose(hollands_nusselt([0.0, 1000.0, 1708.0]), 1.0, rtol=0, atol=0)
    ra = 1e5
    assert_allclose(
        hollands_nusselt(ra), 1.0 + 1.44 * (1.0 - 1708.0 / ra) + (ra / 5830.0) ** (1 / 3) - 1.0, rtol=1e-12
    )
    ras = np.linspace(1.0, 1e6, 10001)
    assert np.all(np.diff(hollands_nusselt(ras)) >= 0.0)


def test_air_gap_flux_conduction_convection_radiation():
    q_cd, q_r = air_gap_flux(306.0, 304.0, 2e-3, 0.98, 0.9)
    assert_allclose(q_cd, air_conductivity(305.0) / 2e-3 * 2.0, rtol=1e-12)  # Ra << 1708
    assert_allclose(q_r, grey_plates_exchange_factor(0.98, 0.9) * SIGMA * (306.0**4 - 304.0**4), rtol=1e-12)
    # a 50 mm gap heated from below convects; heated from above (fabric warmer) it does not
    up, _ = air_gap_flux(306.0, 296.0, 50e-3)
    down, _ = air_gap_flux(296.0, 306.0, 50e-3)
    cond = air_conductivity(301.0) / 50e-3 * 10.0
    assert up > 1.5 * cond
    assert_allclose(down, -cond, rtol=1e-12)
    with pytest.raises(ValueError, match="invalid model selection x"):
        air_gap_flux(306.0, 296.0, 1e-3, model="x")


@pytest.mark.parametrize(
    "t_air,h,q_abs",
    [(233.15, 5.0, 150.0), (293.15, 20.0, 900.0), (328.15, 0.5, 1500.0), (273.15, 100.0, 0.0)],
)
def test_plate_in_radiative_convective_equilibrium(t_air, h, q_abs):
    eps = 0.9
    r = steady_state(
        306.0, t_air, q_abs, h, 0.0, 1e-3, fabric_conductivity=0.0, fabric_emissivity=eps, natural_floor=False
    )
    ref = brentq(lambda t: eps * SIGMA * t**4 + h * (t - t_air) - q_abs, 1.0, 1000.0, xtol=1e-13, rtol=1e-15)
    # residual <= 1e-6 W m^-2 over a slope >= 4 eps sigma T^3 + h > 1 W m^-2 K^-1
    assert_allclose(r.outer_temperature_k, ref, rtol=0, atol=1e-7)
    assert abs(r.residual) <= 1e-6
    assert r.q_in == 0.0


def test_series_resistances_without_radiation():
    t_skin, t_air, h = 306.0, 263.15, 12.0
    gap = np.array([0.0, 1e-3, 3e-3, 6e-3])
    thick = np.array([0.1e-3, 1e-3, 5e-3, 10e-3])
    k_f = 0.05
    r = steady_state(
        t_skin, t_air, 0.0, h, gap, thick, fabric_conductivity=k_f, fabric_emissivity=0.0, natural_floor=False
    )
    t_mean = 0.5 * (t_skin + r.inner_temperature_k)
    r_gap = gap / air_conductivity(t_mean)
    q = (t_skin - t_air) / (r_gap + thick / k_f + 1.0 / h)
    for flux in (r.q_in, r.q_fabric, r.q_conv):
        assert_allclose(flux, q, rtol=1e-9)
    assert np.all(r.q_gap_radiation == 0.0) and np.all(r.q_emit == 0.0)
    # all Rayleigh numbers below onset: the answer is pure conduction
    assert np.all(r.inner_temperature_k > t_air)


def test_contact_gap_zero_is_exact_series():
    # gap 0: q = (T_skin - T_air) / (l/k + 1/h) with no property dependence at all
    r = steady_state(
        306.0,
        283.0,
        0.0,
        8.0,
        0.0,
        2e-3,
        fabric_conductivity=0.04,
        fabric_emissivity=0.0,
        natural_floor=False,
    )
    assert_allclose(r.q_conv, 23.0 / (0.05 + 0.125), rtol=1e-10)
    assert r.inner_temperature_k == 306.0


def test_balance_closes_on_every_facet():
    rng = np.random.default_rng(5)
    n = 4000
    t_air = rng.uniform(233.15, 328.15, n)
    q_rad = rng.uniform(100.0, 1400.0, n)
    h = rng.uniform(0.0, 60.0, n)
    gap = rng.choice([0.0, 1e-4, 2e-3, 1e-2, 5e-2], n)
    thick = rng.uniform(1e-4, 1e-2, n)
    eps = rng.uniform(0.5, 0.98, n)
    r = steady_state(306.0, t_air, q_rad, h, gap, thick, fabric_emissivity=eps)
    assert np.all(np.isfinite(r.outer_temperature_k))
    assert np.max(np.abs(r.residual)) <= 1e-6
    # recompute every term from the returned temperatures
    t = r.outer_temperature_k
    dt = t - t_air
    q_conv = np.maximum(h, 2.38 * np.abs(dt) ** 0.25) * dt
    q_emit = eps * SIGMA * t**4
    assert_allclose(r.q_conv, q_conv, rtol=1e-12)
    assert_allclose(r.q_emit, q_emit, rtol=1e-12)
    assert np.max(np.abs(r.q_in + q_rad - q_conv - q_emit)) <= 1e-6
    # inner surface: what crosses the gap goes through the fabric
    assert np.max(np.abs(r.q_in - r.q_fabric)) <= 1e-6
    assert_allclose(
        net_flux(t, 306.0, t_air, q_rad, h, gap, thick, fabric_emissivity=eps), r.residual, atol=1e-9
    )


def test_transient_backward_euler_linear_closed_form():
    # insulated, non-emitting plate: C (T - T0)/dt = q - h (T - T_air)
    c, dt, t0, q, h, ta = 400.0, 30.0, 280.0, 200.0, 10.0, 290.0
    r = transient_step(
        t0,
        dt,
        c,
        306.0,
        ta,
        q,
        h,
        0.0,
        1e-3,
        fabric_conductivity=0.0,
        fabric_emissivity=0.0,
        natural_floor=False,
    )
    # residual <= 1e-6 W m^-2 over a slope c/dt + h = 23.3 W m^-2 K^-1
    assert_allclose(r.outer_temperature_k, (c / dt * t0 + q + h * ta) / (c / dt + h), rtol=0, atol=1e-7)
    assert_allclose(r.q_storage, c / dt * (r.outer_temperature_k - t0), rtol=1e-12)


def test_transient_relaxes_to_steady_state():
    args = (306.0, 268.0, 350.0, 6.0, 5e-3, 1e-3)
    ss = steady_state(*args)
    assert_allclose(
        transient_step(250.0, np.inf, 50.0, *args).outer_temperature_k, ss.outer_temperature_k, atol=1e-9
    )
    c = areal_heat_capacity(300.0, 1300.0, 1e-3)
    assert_allclose(c, 390.0)
    t = 250.0
    for _ in range(200):
        t = transient_step(t, 60.0, c, *args).outer_temperature_k
    assert_allclose(t, ss.outer_temperature_k, atol=1e-6)


def test_invalid_gap_model():
    with pytest.raises(ValueError, match="invalid model selection nope"):
        steady_state(306.0, 290.0, 300.0, 5.0, 1e-3, 1e-3, gap_model="nope")


def test_time_step_bench_converges_to_the_radau_reference():
    from humv_usd.bench.thermal_steps import garment_time_steps as bench_time_steps

    rows = bench_time_steps(steps_s=(60.0, 600.0), duration_s=1800.0)
    for case in {r["case"] for r in rows}:
        fine, coarse = [r for r in rows if r["case"] == case]
        assert fine["common_error_k"] < coarse["common_error_k"]
        assert fine["max_error_k"] < 0.5 and np.isfinite(coarse["max_error_k"])


@pytest.mark.parametrize(
    "name, index, value",
    [
        ("skin_temperature_k", 0, float("nan")),
        ("air_temperature_k", 1, -5.0),
        ("absorbed_radiation", 2, float("inf")),
        ("h_forced", 3, -1.0),
        ("air_gap_m", 4, float("nan")),
        ("fabric_thickness_m", 5, -1e-3),
    ],
)
def test_garment_balance_rejects_nan_and_non_physical_inputs(name, index, value):
    args = [306.0, 290.0, 300.0, 6.0, 5e-3, 1e-3]
    args[index] = np.array([args[index], value])
    with pytest.raises(ValueError, match=name):
        steady_state(*args)


def test_garment_transient_rejects_bad_step_and_emissivity():
    from humv_usd.physics.garment import transient_step

    args = (306.0, 290.0, 300.0, 6.0, 5e-3, 1e-3)
    with pytest.raises(ValueError, match="time_step_s"):
        transient_step(300.0, float("nan"), 500.0, *args)
    with pytest.raises(ValueError, match="time_step_s"):
        transient_step(300.0, 0.0, 500.0, *args)
    with pytest.raises(ValueError, match="fabric_emissivity"):
        steady_state(*args, fabric_emissivity=1.2)
    assert np.isfinite(transient_step(300.0, np.inf, 500.0, *args).outer_temperature_k)
