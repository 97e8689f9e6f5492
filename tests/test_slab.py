"""1-D slab conduction with a surface energy balance against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.special import erf

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.physics.slab import (
    diurnal_spin_up,
    held_temperature,
    simulate_many,
    step,
    step_many,
    surface_flux,
    uniform_layers,
)


def test_uniform_layers():
    assert_allclose(uniform_layers(0.5, 4), [0.125] * 4)


def test_surface_flux():
    assert_allclose(
        surface_flux(300.0, 500.0, 350.0, 290.0, 10.0, 0.9),
        500.0 + 0.9 * (350.0 - SIGMA * 300.0**4) - 100.0,
        rtol=1e-12,
    )


def test_steady_linear_profile_fixed_bottom():
    # linear surface (eps = 0): q = (T_air + aG/h - T_b) / (1/h + L/k), linear T(z)
    dz = uniform_layers(0.5, 10)
    t, res = step(
        np.full(11, 290.0),
        np.inf,
        dz,
        0.8,
        2e6,
        500.0,
        0.0,
        290.0,
        10.0,
        emissivity=0.0,
        bottom="fixed",
        deep_temperature_k=285.0,
    )
    q = (290.0 + 50.0 - 285.0) / (0.1 + 0.5 / 0.8)
    assert_allclose(t, 285.0 + q * (0.5 - np.arange(11) * 0.05) / 0.8, rtol=0, atol=1e-10)
    assert abs(res) < 1e-9


def test_steady_two_materials_piecewise_linear():
    dz = np.array([0.02, 0.02, 0.1, 0.1])  # 4 cm of k=0.2 over 20 cm of k=1.6
    k = np.array([0.2, 0.2, 1.6, 1.6])
    t, _ = step(
        np.full(5, 300.0),
        np.inf,
        dz,
        k,
        1e6,
        0.0,
        0.0,
        300.0,
        20.0,
        emissivity=0.0,
        bottom="fixed",
        deep_temperature_k=280.0,
    )
    q = 20.0 / (1 / 20.0 + 0.04 / 0.2 + 0.2 / 1.6)
    assert_allclose(
        t,
        [
            280 + q * (0.2 / 1.6 + 0.04 / 0.2),
            280 + q * (0.2 / 1.6 + 0.02 / 0.2),
            280 + q * 0.2 / 1.6,
            280 + q * 0.1 / 1.6,
            280.0,
        ],
        atol=1e-10,
    )


def test_step_surface_temperature_semi_infinite_erfc():
    # T(z,t) = T_s + (T_i - T_s) erf(z / 2 sqrt(alpha t)), surface held by h -> infinity
    dz = uniform_layers(1.0, 100)
    alpha = 1.0 / 1e6
    t = np.full(101, 280.0)
    for _ in range(360):
        t, _ = step(t, 60.0, dz, 1.0, 1e6, 0.0, 0.0, 300.0, 1e7, emissivity=0.0)
    z = np.arange(101) * 0.01
    theta = (t - 300.0) / (280.0 - 300.0)
    assert_allclose(theta, erf(z / (2.0 * np.sqrt(alpha * 6 * 3600.0))), rtol=0, atol=2e-3)


def test_radiative_surface_newton_converges_and_closes():
    dz = uniform_layers(0.3, 15)
    t, res = step(
        np.full(16, 300.0),
        np.inf,
        dz,
        1.0,
        2e6,
        800.0,
        300.0,
        295.0,
        5.0,
        emissivity=0.95,
        bottom="fixed",
        deep_temperature_k=290.0,
    )
    assert abs(res) < 1e-8
    q_s = surface_flux(t[0], 800.0, 300.0, 295.0, 5.0, 0.95)
    assert_allclose(q_s, 1.0 / 0.3 * (t[0] - 290.0), rtol=1e-10)


def test_crank_nicolson_second_order():
    dz = uniform_layers(0.2, 20)
    args = (dz, 1.0, 2e6, 600.0, 320.0, 295.0, 8.0)

    def run(dt, theta):
        t = np.full(21, 285.0)
        for _ in range(int(round(600.0 / dt))):
            t, _ = step(t, dt, *args, theta=theta)
        return t

    ref = run(0.5, 0.5)
    err_be = np.abs(run(10.0, 1.0) - ref).max()
    err_cn = np.abs(run(10.0, 0.5) - ref).max()
    assert err_be < 0.05
    assert err_cn < err_be / 10.0


def _diurnal(n=144):
    hours = np.arange(1, n + 1) * 24.0 / n
    sun = np.maximum(0.0, np.sin((hours - 6.0) / 12.0 * np.pi)) * 900.0
    t_air = 288.0 + 8.0 * np.sin((hours - 9.0) / 24.0 * 2 * np.pi)
    return sun, 0.8 * SIGMA * t_air**4, t_air


def test_diurnal_spin_up_ten_minute_steps_periodic():
    sun, lw, t_air = _diurnal()
    dz = uniform_layers(0.5, 25)
    ts, nodes, res = diurnal_spin_up(288.0, 600.0, dz, 1.0, 2e6, 0.7 * sun, lw, t_air, 10.0, n_cycles=4)
    assert np.all(np.isfinite(nodes)) and res < 1e-6
    assert 270.0 < ts.min() < ts.max() < 340.0
    assert ts.argmax() in range(60, 100)  # early afternoon
    # spun up: one more day repeats the last one
    ts5, _, _ = diurnal_spin_up(nodes[-1], 600.0, dz, 1.0, 2e6, 0.7 * sun, lw, t_air, 10.0)
    assert_allclose(ts5, ts, atol=0.3)


def test_held_temperature_and_bad_bottom():
    assert_allclose(held_temperature(323.15, 4), [323.15] * 4)
    with pytest.raises(ValueError, match="invalid model selection open"):
        step(np.full(3, 290.0), 60.0, uniform_layers(0.1, 2), 1.0, 1e6, 0, 0, 290, 5, bottom="open")


@pytest.mark.parametrize("dt", [60.0, 3600.0, np.inf])
@pytest.mark.parametrize("bottom", ["adiabatic", "fixed"])
def test_step_many_equals_step_per_slab(dt, bottom):
    rng = np.random.default_rng(4)
    dz = np.r_[np.full(5, 0.02), np.full(3, 0.1)]  # two materials
    k, rc = np.r_[np.full(5, 1.4), np.full(3, 0.5)], np.r_[np.full(5, 2.0e6), np.full(3, 3.0e6)]
    t0 = 290.0 + 5.0 * rng.random((6, 9))
    a, lw = rng.uniform(0, 700, 6), rng.uniform(250, 420, 6)
    ta, h = rng.uniform(260, 320, 6), rng.uniform(2, 40, 6)
    eps = rng.uniform(0.1, 1.0, 6)
    t, res = step_many(t0, dt, dz, k, rc, a, lw, ta, h, eps, bottom, 285.0)
    for i in range(6):
        ref, r = step(t0[i], dt, dz, k, rc, a[i], lw[i], ta[i], h[i], eps[i], bottom, 285.0)
        assert_allclose(t[i], ref, rtol=0, atol=1e-8)
    assert np.all(np.abs(res) < 1e-6)


def test_simulate_many_plate_equilibrium_and_history():
    # constant forcing: the start (mean-forcing steady state) is already the answer; a thin
    # adiabatic-back plate satisfies alpha G + eps (L - sigma T^4) = h (T - T_air)
    from scipy.optimize import brentq

    times = np.arange(0.0, 7200.0, 600.0)
    a, lw, ta, h, eps = 500.0, 300.0, 290.0, 8.0, 0.9
    t, res = simulate_many(times, a, lw, ta, h, [0.6e-3 / 4] * 4, 50.0, 3.7e6, emissivity=eps)
    t_eq = brentq(lambda x: a + eps * (lw - SIGMA * x**4) - h * (x - ta), 200.0, 500.0)
    assert_allclose(t, t_eq, rtol=0, atol=1e-6)
    assert res < 1e-6
    # varying forcing for two slabs = two scalar histories with step()
    a2 = np.stack([np.linspace(0, 800, len(times)), np.zeros(len(times))], axis=1)
    dz = uniform_layers(0.1, 6)
    t2, _ = simulate_many(times, a2, lw, ta, h, dz, 1.0, 2e6, emissivity=eps, initial_temperature_k=295.0)
    for j in range(2):
        nodes = np.full(7, 295.0)
        for i in range(1, len(times)):
            nodes, _ = step(nodes, 600.0, dz, 1.0, 2e6, a2[i, j], lw, ta, h, eps)
            assert_allclose(t2[i, j], nodes[0], atol=1e-8)
