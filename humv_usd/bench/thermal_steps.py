"""Time-step benches of the thermal models (``humv-usd bench thermal``): the garment balance's
implicit step against a stiff reference ODE solve, and the skin models' internal step against
the same model at a fine step."""

from __future__ import annotations

import time as _time

import numpy as np
from scipy.integrate import solve_ivp

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics.convection import mitchell
from humv_usd.physics.garment import areal_heat_capacity, net_flux, steady_state, transient_step
from humv_usd.thermal.physiology import simulate_physiology


def garment_time_steps(steps_s=(10.0, 60.0, 300.0, 600.0, 1800.0), duration_s=3600.0):
    """Garment temperature error of the implicit step against the time step.

    Cases: a thin shirt (0.5 mm, 1 cm gap) and a thick jacket (5 mm, 2 cm gap) over 306 K skin,
    starting at equilibrium in shade at 10 degC with 2 m/s wind; the absorbed sun ramps up by
    500 W m^-2 over the first 15 min and the wind drops to 0.5 m/s over 30-40 min. Reference:
    the same ODE C dT/dt = net_flux(T) by scipy's Radau (rtol 1e-10). Error: the largest
    |T - T_ref| over the step ends, and at the times every largest step ("common").

    Returns a list of dicts: case, step_s, max_error_k, common_error_k, seconds.
    """
    cases = {
        "shirt 0.5 mm": (0.5e-3, 0.01, 0.04, areal_heat_capacity(300.0, 1300.0, 0.5e-3)),
        "jacket 5 mm": (5e-3, 0.02, 0.04, areal_heat_capacity(150.0, 1400.0, 5e-3)),
    }
    t_air, t_skin, q_sky = 283.15, 306.15, 0.9 * STEFAN_BOLTZMANN * 265.0**4

    def forcing(t):
        sun = 500.0 * min(max(t / 900.0, 0.0), 1.0)
        wind = 2.0 - 1.5 * min(max((t - 1800.0) / 600.0, 0.0), 1.0)
        return q_sky + sun, mitchell(wind)

    rows = []
    common = max(steps_s)
    for name, (thick, gap, k_f, cap) in cases.items():
        kw = dict(
            fabric_thickness_m=thick,
            fabric_conductivity=k_f,
            air_gap_m=gap,
            skin_temperature_k=t_skin,
            air_temperature_k=t_air,
        )
        t0 = float(steady_state(absorbed_radiation=q_sky, h_forced=mitchell(2.0), **kw).outer_temperature_k)

        def rhs(t, y):
            q, h = forcing(t)
            return [float(net_flux(y[0], absorbed_radiation=q, h_forced=h, **kw)) / cap]

        ref = solve_ivp(
            rhs,
            (0.0, duration_s),
            [t0],
            method="Radau",
            rtol=1e-10,
            atol=1e-10,
            dense_output=True,
            max_step=60.0,
        )
        for dt in steps_s:
            tic = _time.perf_counter()
            t, now, err, err_common = t0, 0.0, 0.0, 0.0
            while now < duration_s - 1e-9:
                now += dt
                q, h = forcing(now - 1e-9)
                t = float(
                    transient_step(t, dt, cap, absorbed_radiation=q, h_forced=h, **kw).outer_temperature_k
                )
                e = abs(t - float(ref.sol(now)[0]))
                err = max(err, e)
                if abs(now / common - round(now / common)) < 1e-9:
                    err_common = max(err_common, e)
            rows.append(
                {
                    "case": name,
                    "step_s": float(dt),
                    "max_error_k": err,
                    "common_error_k": err_common,
                    "seconds": _time.perf_counter() - tic,
                }
            )
    return rows


def skin_time_steps(
    model: str = "jos3", steps_s=None, reference_step_s=None, duration_s: float = 3600.0
) -> list[dict]:
    """Mean-skin-temperature error against the internal time step (an exercise bout and rest).

    The schedule: 100 W standing, 450 W from 10 to 30 min, 100 W after, at 20 degC, MRT 20 degC,
    RH 50 %, 0.5 m/s, 0.6 clo; outputs every 5 min. Each run uses ``max_substep_s`` = step;
    the error is the largest |mean skin - reference| over the outputs, the reference being the
    same model at ``reference_step_s``.

    Returns a list of dicts: model, step_s, max_error_k, seconds (run time).
    """
    if steps_s is None:
        steps_s = (30.0, 60.0, 120.0, 300.0) if model == "jos3" else (5.0, 10.0, 30.0, 60.0)
    if reference_step_s is None:
        reference_step_s = 10.0 if model == "jos3" else 1.0
    times = np.arange(0.0, duration_s + 1.0, 300.0)
    rate = np.where((times >= 600.0) & (times < 1800.0), 450.0, 100.0)
    args = (times, rate, 293.15, 293.15, 0.5, 0.5, 0.6)

    def run(step):
        t0 = _time.perf_counter()
        r = simulate_physiology(*args, model=model, spin_up_s=0.0, max_substep_s=step)
        return np.asarray(r.mean_skin_temperature_k, dtype=float), _time.perf_counter() - t0

    ref, _ = run(reference_step_s)
    rows = []
    for step in steps_s:
        t, sec = run(step)
        err = float(np.max(np.abs(t - ref))) if np.all(np.isfinite(t)) else float("inf")
        rows.append({"model": model, "step_s": float(step), "max_error_k": err, "seconds": sec})
    return rows
