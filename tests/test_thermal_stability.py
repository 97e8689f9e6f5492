"""Stiff thermal equations over the DESIGN.md extreme grid: finite, closed, monotonic, stable."""

from __future__ import annotations

import numpy as np

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.physics.convection import mitchell
from humv_usd.physics.garment import (
    areal_heat_capacity,
    extreme_grid_counts,
    net_flux,
    steady_state,
    transient_step,
)
from humv_usd.physics.slab import step, uniform_layers


def test_extreme_grid_counts():
    c = extreme_grid_counts()
    assert c["steady_cases"] == 5 * 5 * 3 * 5 * 3
    assert c["transient_cases"] == 6 * c["steady_cases"]
    assert c["cases"] == 7 * c["steady_cases"]
    assert c["nonfinite"] == 0
    assert c["max_residual"] <= 1e-6
    assert c["monotonic_air_violations"] == 0
    assert c["monotonic_wind_violations"] == 0
    assert c["max_iterations"] <= 40


def _grid():
    t_air = 273.15 + np.array([-40.0, 0.0, 55.0])
    wind = np.array([0.0, 3.0, 30.0])
    sun = np.array([0.0, 1200.0])
    gap = np.array([0.0, 2e-3, 50e-3])
    fabric = np.array([0.1e-3, 10e-3])
    ta, v, g, d, l = (x.ravel() for x in np.meshgrid(t_air, wind, sun, gap, fabric, indexing="ij"))
    q = 0.7 * g + 0.9 * SIGMA * (ta - 25.0) ** 4
    return dict(
        skin_temperature_k=306.15,
        air_temperature_k=ta,
        absorbed_radiation=q,
        h_forced=mitchell(v),
        air_gap_m=d,
        fabric_thickness_m=l,
    ), l


def test_backward_euler_never_overshoots_the_steady_state():
    kw, l = _grid()
    ss = steady_state(**kw).outer_temperature_k
    c = areal_heat_capacity(300.0, 1300.0, l)
    for dt in (1.0, 60.0, 600.0):
        for t0 in (ss - 60.0, ss + 60.0):
            r = transient_step(t0, dt, c, **kw)
            assert np.all(np.isfinite(r.outer_temperature_k))
            assert np.max(np.abs(r.residual)) <= 1e-6
            lo, hi = np.minimum(t0, ss), np.maximum(t0, ss)
            t1 = r.outer_temperature_k
            assert np.all((t1 >= lo - 1e-7) & (t1 <= hi + 1e-7))


def test_stiff_case_explicit_fails_implicit_holds():
    # thin fabric in contact, strong wind, 10 min steps: dt (k/l + h + 4 eps sigma T^3) / C ~ 1e4
    kw = dict(
        skin_temperature_k=306.15,
        air_temperature_k=263.15,
        absorbed_radiation=250.0,
        h_forced=mitchell(30.0),
        air_gap_m=0.0,
        fabric_thickness_m=0.1e-3,
    )
    c = areal_heat_capacity(300.0, 1300.0, 0.1e-3)
    dt = 600.0
    t_eq = float(steady_state(**kw).outer_temperature_k)
    t_exp = np.empty(8)
    t_imp = np.empty(8)
    te = ti = 283.15
    with np.errstate(all="ignore"):
        for i in range(8):
            te = te + dt / c * float(net_flux(te, **kw))
            ti = float(transient_step(ti, dt, c, **kw).outer_temperature_k)
            t_exp[i], t_imp[i] = te, ti
    dev = t_exp - t_eq
    diverged = (~np.isfinite(t_exp)).any() or np.abs(dev[np.isfinite(dev)]).max() > 100.0
    oscillates = (np.sign(dev[:3]) == -np.sign(dev[1:4])).all()
    assert diverged or oscillates
    # implicit: monotonic approach from below, at equilibrium within one step
    assert np.all(np.diff(t_imp) >= -1e-9)
    assert np.all(t_imp <= t_eq + 1e-7)
    assert abs(t_imp[0] - t_eq) < 0.01
    assert abs(t_imp[-1] - t_eq) < 1e-7


def test_slab_extreme_forcing_ten_minute_steps():
    dz = uniform_layers(0.5, 50)  # 1 cm layers: explicit limit dz^2/(2 alpha) = 50 s
    rng = np.random.default_rng(0)
    t = np.full(51, 288.0)
    for _ in range(144):
        t_air = rng.uniform(233.15, 328.15)
        t, res = step(
            t,
            600.0,
            dz,
            1.0,
            1e6,
            rng.uniform(0.0, 1200.0),
            0.8 * SIGMA * t_air**4,
            t_air,
            rng.uniform(0.0, 100.0),
        )
        assert np.all(np.isfinite(t)) and abs(res) < 1e-6
        assert 180.0 < t.min() and t.max() < 400.0
    # the explicit scheme at the same step blows up
    g = 1.0 / 0.01
    cap = 1e6 * 0.01
    te = np.full(51, 288.0)
    te[0] = 300.0
    with np.errstate(all="ignore"):
        for _ in range(20):
            q = np.zeros_like(te)
            f = g * (te[1:] - te[:-1])
            q[:-1] += f
            q[1:] -= f
            te = te + 600.0 / cap * q * np.r_[2.0, np.ones(49), 2.0]
    assert not np.all(np.abs(te - 288.0) < 50.0)
