"""Layered garments in series and wet fabric (issue 25, deliverable 5) against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.physics.garment import (
    LEWIS_RATIO_K_PA,
    air_conductivity,
    air_gap_flux,
    fabric_evaporation,
    gap_temperature_for_flux,
    grey_plates_exchange_factor,
    saturation_vapour_pressure,
    stack_steady_state,
    stack_transient_step,
    steady_state,
)
from humv_usd.physics.sky import effective_sky_temperature

T_SKIN = 306.15


def _h_rad(f, t1, t2):
    """Radiative coefficient with F sigma (T1^4 - T2^4) = h_r (T1 - T2), exactly."""
    return f * SIGMA * (t1**2 + t2**2) * (t1 + t2)


def test_gap_inversion_round_trip():
    rng = np.random.default_rng(3)
    n = 5000
    t_cold = rng.uniform(233.0, 330.0, n)
    gap = rng.choice([0.0, 1e-4, 2e-3, 1e-2, 5e-2], n)
    q = rng.uniform(-400.0, 1500.0, n)
    eps_h, eps_c = rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    t_hot = gap_temperature_for_flux(q, t_cold, gap, eps_h, eps_c)
    q_cd, q_r = air_gap_flux(t_hot, t_cold, np.where(gap > 0, gap, 1.0), eps_h, eps_c)
    open_gap = gap > 0
    assert_allclose((q_cd + q_r)[open_gap], q[open_gap], rtol=1e-9, atol=1e-8)
    assert np.all(t_hot[~open_gap] == t_cold[~open_gap])  # contact: no difference
    assert np.all(
        np.sign(t_hot - t_cold)[open_gap & (np.abs(q) > 1e-3)] == np.sign(q)[open_gap & (np.abs(q) > 1e-3)]
    )


@pytest.mark.parametrize("gap", [0.0, 2e-3, 2e-2])
def test_one_layer_stack_is_the_single_garment(gap):
    t_air = np.array([233.15, 263.15, 293.15, 318.15])
    q_rad = np.array([180.0, 250.0, 700.0, 1100.0])
    single = steady_state(T_SKIN, t_air, q_rad, 6.0, gap, 1e-3, 0.05, 0.9)
    stack = stack_steady_state(T_SKIN, t_air, q_rad, 6.0, [gap], [1e-3], [0.05], [0.9])
    assert_allclose(stack.outer_temperature_k[0], single.outer_temperature_k, rtol=0, atol=1e-7)
    assert_allclose(stack.q_in, single.q_in, rtol=1e-7, atol=1e-6)


@pytest.mark.parametrize("gap_model", ["conduction", "hollands"])
def test_two_layer_flux_is_the_series_resistance_closed_form(gap_model):
    # surroundings at the air temperature (q_rad = eps sigma T_air^4): skin -> gap 0 -> fabric 0
    # -> gap 1 -> fabric 1 -> (convection + radiation to T_air), all in series
    t_air, h, eps = 268.15, 8.0, np.array([0.88, 0.92])
    gaps, thick, k_f = np.array([3e-3, 6e-3]), np.array([0.6e-3, 4e-3]), np.array([0.05, 0.035])
    r = stack_steady_state(
        T_SKIN,
        t_air,
        eps[1] * SIGMA * t_air**4,
        h,
        gaps,
        thick,
        k_f,
        eps,
        natural_floor=False,
        gap_model=gap_model,
    )
    assert abs(r.residual) <= 1e-6
    t_o, t_i = r.outer_temperature_k, r.inner_temperature_k
    warm = (T_SKIN, t_o[0])  # warm side of gap 0 and gap 1
    res = 0.0
    for i in range(2):
        f = grey_plates_exchange_factor(0.98 if i == 0 else eps[0], eps[i])
        t_m = 0.5 * (warm[i] + t_i[i])
        res += 1.0 / (air_conductivity(t_m) / gaps[i] + _h_rad(f, warm[i], t_i[i])) + thick[i] / k_f[i]
    res += 1.0 / (h + _h_rad(eps[1], t_o[1], t_air))
    q = (T_SKIN - t_air) / res
    # the gaps stay below the convective onset (Ra < 1708), so both models are conduction
    assert_allclose(r.q_in, q, rtol=1e-8)
    assert_allclose(r.q_gap, [q, q], rtol=1e-8)
    # and the same with radiation linearised once at the mean temperature, no solver at all
    t_m = 0.5 * (T_SKIN + t_air)
    lin = sum(
        1.0
        / (
            air_conductivity(t_m) / gaps[i]
            + 4 * grey_plates_exchange_factor((0.98, eps[0])[i], eps[i]) * SIGMA * t_m**3
        )
        + thick[i] / k_f[i]
        for i in range(2)
    ) + 1.0 / (h + 4 * eps[1] * SIGMA * t_m**3)
    assert_allclose(r.q_in, (T_SKIN - t_air) / lin, rtol=0.03)


def test_two_layers_are_colder_outside_than_one_on_a_clear_night():
    # a NYCO jacket (0.45 mm, 10 mm gap) over a cotton shirt (0.6 mm, 8 mm gap), -5 degC, calm
    t_air, h = 268.15, 3.0
    t_sky, _ = effective_sky_temperature(t_air, 0.6)
    eps = 0.88
    q_rad = eps * SIGMA * (0.5 * t_sky**4 + 0.5 * t_air**4)  # half sky, half ground at air
    two = stack_steady_state(
        T_SKIN, t_air, q_rad, h, [8e-3, 10e-3], [0.6e-3, 0.45e-3], [0.05, 0.06], [eps, eps]
    )
    # the jacket alone at the same distance from the skin (how it was coupled before)
    jacket = steady_state(T_SKIN, t_air, q_rad, h, 8e-3 + 0.6e-3 + 10e-3, 0.45e-3, 0.06, eps)
    shirt = steady_state(T_SKIN, t_air, q_rad, h, 8e-3, 0.6e-3, 0.05, eps)
    assert two.outer_temperature_k[1] < jacket.outer_temperature_k - 1.0
    assert two.outer_temperature_k[1] < shirt.outer_temperature_k - 1.0
    assert two.q_in < min(jacket.q_in, shirt.q_in)
    # the shirt under the jacket is warmer than the jacket and than the shirt alone
    assert shirt.outer_temperature_k < two.outer_temperature_k[0]
    assert two.outer_temperature_k[1] < two.outer_temperature_k[0] < T_SKIN


def test_stack_transient_is_the_linear_backward_euler_closed_form():
    # contact gaps, no emission, fixed h: two capacity nodes, a 2x2 linear system per step
    u0, u1, h, c0, c1 = 0.05 / 1e-3, 0.04 / 3e-3, 9.0, 400.0, 900.0
    t_s, t_a, dt = T_SKIN, 275.0, 20.0
    prev = np.array([300.0, 285.0])
    for _ in range(5):
        r = stack_transient_step(
            prev,
            dt,
            [c0, c1],
            t_s,
            t_a,
            0.0,
            h,
            [0.0, 0.0],
            [1e-3, 3e-3],
            [0.05, 0.04],
            [0.0, 0.0],
            natural_floor=False,
        )
        a = np.array([[c0 / dt + u0 + u1, -u1], [-u1, c1 / dt + u1 + h]])
        b = np.array([c0 / dt * prev[0] + u0 * t_s, c1 / dt * prev[1] + h * t_a])
        ref = np.linalg.solve(a, b)
        assert_allclose(r.outer_temperature_k, ref, rtol=0, atol=1e-7)
        prev = ref
    # an infinite step is the steady state
    inf = stack_transient_step(
        prev, np.inf, [c0, c1], t_s, t_a, 0.0, h, [0.0, 0.0], [1e-3, 3e-3], [0.05, 0.04], [0.0, 0.0]
    )
    st = stack_steady_state(t_s, t_a, 0.0, h, [0.0, 0.0], [1e-3, 3e-3], [0.05, 0.04], [0.0, 0.0])
    assert_allclose(inf.outer_temperature_k, st.outer_temperature_k, atol=1e-7)


def test_a_stiff_stack_stops_at_its_round_off_floor():
    # a walk's T-shirt over leggings at 15 fps (measured case): the outer layer's storage
    # C / dt = 67,000 W m^-2 K^-1 carried inward through the gaps makes the residual's slope
    # ~3e7 W m^-2 K^-1 in the outermost temperature, so one ulp of it (6e-14 K) moves the residual
    # by ~2e-6 W m^-2, above the 1e-7 tolerance: the solver stops when its Newton step is below
    # 4 ulps instead of bisecting the bracket down ulp by ulp (30+ iterations)
    dt = 1.0 / 15.0
    cap = np.array([324.1, 4491.0])
    thick, cond, eps = [6e-4, 1e-3], [0.05, 0.053], [0.9, 0.9]
    t_skin, t_air, h = 307.6, 289.0, 8.0
    q_rad = np.array([380.0, 420.0, 520.0])
    gaps = np.array([[7.1e-3, 7.2e-3, 7.0e-3], [3.1e-3, 2.3e-3, 3.9e-3]])
    prev = np.array([[302.2, 305.2, 304.0], [298.0, 303.7, 300.9]])
    r = stack_transient_step(prev, dt, cap, t_skin, t_air, q_rad, h, gaps, thick, cond, eps, tol=1e-7)
    assert r.iterations <= 12

    def residual(t_out, j):
        # the stack's balance from the public pieces: outer surface, storage, fabric, gap
        t_o = t_out
        q = h * (t_o - t_air) + 0.9 * SIGMA * t_o**4 - q_rad[j]  # h above the ISO 7730 floor here
        for i in (1, 0):
            q += cap[i] / dt * (t_o - prev[i, j])
            t_in = t_o + q * thick[i] / cond[i]
            if i == 1:
                t_o = float(gap_temperature_for_flux(q, t_in, gaps[1, j], eps[0], eps[1]))
        q_cd, q_r = air_gap_flux(t_skin, t_in, gaps[0, j], 0.98, eps[0])
        return float(q_cd + q_r) - q

    for j in range(3):
        ref = brentq(residual, 280.0, 320.0, args=(j,), xtol=1e-12, rtol=4 * np.finfo(float).eps)
        assert abs(r.outer_temperature_k[1, j] - ref) < 1e-9
        # the residual at the root is the slope times a few ulps, not more
        slope = (residual(ref + 1e-4, j) - residual(ref - 1e-4, j)) / 2e-4
        assert abs(r.residual[j]) <= 8 * np.finfo(float).eps * ref * abs(slope) + 1e-7


def test_a_deep_heavy_stack_balances_every_layer():
    # Table 1 v0066's uniform jacket over itself over a shirt at 30 fps (a captured face: C / dt
    # 4564 W m^-2 K^-1 per layer): shooting inward from the outermost temperature multiplies its
    # round-off by ~3e11 W m^-2 K^-1 at the skin (the shooting solver stopped at 0.08 W m^-2);
    # every node's balance, from the public pieces, holds to the tolerance
    dt, cap = 1.0 / 30.0, 152.145
    thick, cond, eps = 3e-4, 3e-4 * 133.33333, 0.88
    t_skin, t_air, q_rad, h = 309.08087, 289.0, 344.32047, 13.501033
    gaps = np.array([0.016167155, 0.0036399238, 0.0033012723, 0.0046768463])
    prev = np.array([301.34105, 300.49476, 299.8131, 291.98092])
    r = stack_transient_step(
        prev, dt, [cap] * 4, t_skin, t_air, q_rad, h, gaps, [thick] * 4, [cond] * 4, [eps] * 4
    )
    t, s = r.outer_temperature_k, r.inner_temperature_k
    q_fabric = cond / thick * (s - t)
    warm = np.concatenate([[t_skin], t[:-1]])
    q_cd, q_r = air_gap_flux(warm, s, gaps, np.r_[0.98, [eps] * 3], eps)
    assert_allclose(q_cd + q_r, q_fabric, rtol=0, atol=1e-6)  # each gap delivers what its fabric conducts
    out = h * (t[-1] - t_air) + eps * SIGMA * t[-1] ** 4 - q_rad  # h above the ISO 7730 floor here
    leaving = np.r_[q_fabric[1:], out]
    assert_allclose(q_fabric, cap / dt * (t - prev) + leaving, rtol=0, atol=1e-6)  # storage
    assert abs(r.residual) <= 1e-6
    assert_allclose(r.q_in, q_fabric[0], rtol=0, atol=1e-6)


def test_stack_over_the_extreme_grid():
    # DESIGN.md grid: -40..55 degC, wind-range h, sun 0-1200, gaps 0-50 mm, fabric 0.1-10 mm,
    # steps 1 s - 10 min; two and three layers
    ta, q, h, g, l = np.meshgrid(
        273.15 + np.array([-40.0, -10.0, 10.0, 30.0, 55.0]),
        np.array([0.0, 300.0, 1200.0]),
        np.array([0.0, 2.0, 10.0, 60.0]),
        np.array([0.0, 1e-3, 2e-2, 5e-2]),
        np.array([1e-4, 1e-3, 1e-2]),
        indexing="ij",
    )
    t_sky, _ = effective_sky_temperature(ta, 0.5)
    q_rad = 0.7 * q + 0.9 * SIGMA * t_sky**4
    for n in (2, 3):
        gaps = np.stack([g] * n)
        kw = dict(
            air_gaps_m=gaps,
            thicknesses_m=np.stack([l] * n),
            conductivities=[0.04] * n,
            emissivities=[0.9] * n,
        )
        st = stack_steady_state(T_SKIN, ta, q_rad, h, **kw)
        assert np.all(np.isfinite(st.outer_temperature_k))
        assert np.all(np.abs(st.residual) <= 1e-6 + 1e-9 * np.abs(st.q_gap).max(axis=0))
        # warmer air never makes any layer colder
        assert np.all(np.diff(st.outer_temperature_k, axis=1) >= -1e-6)
        # between skin and the outermost surface (no layer beyond both ends)
        lo = np.minimum(st.outer_temperature_k[-1], T_SKIN) - 1e-6
        hi = np.maximum(st.outer_temperature_k[-1], T_SKIN) + 1e-6
        assert np.all((st.outer_temperature_k >= lo) & (st.outer_temperature_k <= hi))
        for dt in (1.0, 60.0, 600.0):
            for offset in (-20.0, 20.0):
                tr = stack_transient_step(
                    np.stack([ta + offset] * n), dt, [300.0] * n, T_SKIN, ta, q_rad, h, **kw
                )
                assert np.all(np.isfinite(tr.outer_temperature_k))
                # round-off: the outermost temperature's bracket collapses to 1 ulp, and three
                # layers of 10 mm with 1 s steps amplify it to ~2e-6 W m^-2 at the skin
                assert np.all(np.abs(tr.residual) <= 1e-5 + 1e-9 * np.abs(tr.q_gap).max(axis=0))


def _wet_bulb_lewis(t_air, rh):
    """Psychrometric wet bulb of the Lewis relation: e_a = p_sat(T_w) - (T_a - T_w) / LR."""
    e_a = rh * saturation_vapour_pressure(t_air)
    return brentq(
        lambda t: saturation_vapour_pressure(t) - (t_air - t) / LEWIS_RATIO_K_PA - e_a, 150.0, t_air + 1e-9
    )


def _wet_bulb_stull(t_air, rh):
    """Stull (2011) J. Appl. Meteorol. Climatol. 50:2267, eq. 1 (degC, RH in %), +-1 K."""
    t, r = t_air - 273.15, rh * 100.0
    return 273.15 + (
        t * np.arctan(0.151977 * np.sqrt(r + 8.313659))
        + np.arctan(t + r)
        - np.arctan(r - 1.676331)
        + 0.00391838 * r**1.5 * np.arctan(0.023101 * r)
        - 4.686035
    )


@pytest.mark.parametrize("t_air,rh", [(303.15, 0.4), (313.15, 0.2), (293.15, 0.7), (283.15, 0.5)])
def test_wet_fabric_adiabatic_limit_is_the_wet_bulb(t_air, rh):
    # fully wet, no radiation, no heat from the skin: the surface sits at the wet bulb
    r = steady_state(T_SKIN, t_air, 0.0, 10.0, 0.0, 1e-3, 0.0, 0.0, wetted_fraction=1.0, relative_humidity=rh)
    assert_allclose(r.outer_temperature_k, _wet_bulb_lewis(t_air, rh), atol=1e-6)
    # Stull's fit of the thermodynamic wet bulb is good to +-1 K; the Lewis ratio 16.5 K/kPa
    # (h_e / h_c with Le^(2/3), ASHRAE) vs the sea-level psychrometer constant's 15.0 K/kPa puts
    # the wet fabric up to ~0.5 K below it at 40 degC, 20 %
    assert -1.5 < float(r.outer_temperature_k) - _wet_bulb_stull(t_air, rh) < 1.0


def test_fabric_evaporation_closed_form():
    assert_allclose(
        fabric_evaporation(305.0, 300.0, 0.5, 10.0, 0.4),
        0.4 * 16.5e-3 * 10.0 * (saturation_vapour_pressure(305.0) - 0.5 * saturation_vapour_pressure(300.0)),
        rtol=1e-12,
    )
    # Magnus at 20 degC: 2338 Pa (WMO tables 2337 Pa)
    assert_allclose(saturation_vapour_pressure(293.15), 2337.0, rtol=2e-3)


def test_wet_shirt_is_cooler_than_dry_and_never_below_the_wet_bulb():
    rng = np.random.default_rng(11)
    n = 3000
    t_air = rng.uniform(283.15, 318.15, n)
    rh = rng.uniform(0.05, 1.0, n)
    h = rng.uniform(2.0, 40.0, n)
    w = rng.uniform(0.05, 1.0, n)
    gap = rng.choice([0.0, 2e-3, 8e-3], n)
    q_rad = 0.9 * SIGMA * t_air**4 + rng.uniform(0.0, 400.0, n)  # surroundings at air + sun
    kw = dict(fabric_conductivity=0.05, fabric_emissivity=0.9, relative_humidity=rh)
    dry = steady_state(T_SKIN, t_air, q_rad, h, gap, 0.6e-3, **kw)
    wet = steady_state(T_SKIN, t_air, q_rad, h, gap, 0.6e-3, wetted_fraction=w, **kw)
    assert np.max(np.abs(wet.residual)) <= 1e-6
    # above the dew point the wet fabric evaporates and is cooler; in hot, humid air that is
    # warmer than the skin it can sit below the dew point and condensation warms it instead
    e_a = rh * saturation_vapour_pressure(t_air)
    dew = np.array([brentq(lambda t, e=e: saturation_vapour_pressure(t) - e, 150.0, 400.0) for e in e_a])
    evaporating = dry.outer_temperature_k > dew + 1e-6
    assert evaporating.mean() > 0.9
    assert np.all(wet.outer_temperature_k[evaporating] < dry.outer_temperature_k[evaporating])
    assert np.all(wet.q_evap[evaporating] > 0.0)
    assert np.all(wet.outer_temperature_k[~evaporating] >= dry.outer_temperature_k[~evaporating])
    t_wb = np.array([_wet_bulb_lewis(a, b) for a, b in zip(t_air, rh)])
    # with surroundings at air temperature (+ sun) nothing but the skin can take it below the
    # wet bulb, and only where the skin itself is colder (air above 33 degC)
    assert np.all(wet.outer_temperature_k >= np.minimum(t_wb, T_SKIN))
    assert np.all(wet.outer_temperature_k[t_wb <= T_SKIN] >= t_wb[t_wb <= T_SKIN])
    # the wetter, the closer to the wet bulb; the same in the stack's outer layer
    wetter = steady_state(
        T_SKIN, t_air, q_rad, h, gap, 0.6e-3, wetted_fraction=np.minimum(w + 0.2, 1.0), **kw
    )
    e = evaporating
    assert np.all(wetter.outer_temperature_k[e] <= wet.outer_temperature_k[e] + 1e-9)
    stack = stack_steady_state(
        T_SKIN, t_air, q_rad, h, [gap], [0.6e-3], [0.05], [0.9], wetted_fraction=w, relative_humidity=rh
    )
    assert_allclose(stack.outer_temperature_k[0], wet.outer_temperature_k, atol=1e-6)


def test_stack_rejects_bad_input():
    with pytest.raises(ValueError, match="conductivities"):
        stack_steady_state(T_SKIN, 280.0, 300.0, 5.0, [0.0, 1e-3], [1e-3, 1e-3], [0.05, 0.0], [0.9, 0.9])
    with pytest.raises(ValueError, match="wetted_fraction"):
        stack_steady_state(T_SKIN, 280.0, 300.0, 5.0, [1e-3], [1e-3], [0.05], [0.9], wetted_fraction=1.5)
    with pytest.raises(ValueError, match="invalid model selection x"):
        stack_steady_state(T_SKIN, 280.0, 300.0, 5.0, [1e-3], [1e-3], [0.05], [0.9], gap_model="x")


# ---------------------------------------------------------------------------- thermal layer
def _night_outfit(humvvex_raw, out, clothing, **atmosphere):
    import copy

    from pxr import Sdf, Usd

    from humv_usd.pipeline.compose import compose
    from humv_usd.scenario import validate
    from humv_usd.usd import schemas as S

    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"]["model"] = "jos3"
    raw["thermal"]["skin_detail"] = "segment"
    raw["thermal"]["radiation_rays"] = 16
    raw["general"]["start"] = raw["general"]["start"].replace(hour=2)  # clear night, no sun
    raw["atmosphere"].update(dict(air_temperature_k=268.15, cloud_cover=0.0, model="analytic"), **atmosphere)
    raw["scene"]["ground"]["temperature_k"] = 265.0
    raw["scene"]["object"][0]["temperature_k"] = 268.0
    raw["sensor"] = raw["sensor"][:1]
    raw["human"][0]["clothing"] = clothing
    compose(validate(raw), out)
    stage = Usd.Stage.Open(str(out / "stage.usda"))
    temps = {
        g: np.asarray(
            stage.GetPrimAtPath(f"/World/Humans/p1/Clothing/{g}").GetAttribute(S.TEMPERATURE_PRIMVAR).Get(0),
            dtype=float,
        )
        for g in clothing
    }
    report = Sdf.Layer.FindOrOpen(str(out / "layers" / "thermal.usda")).customLayerData
    return temps, dict(report["humv:thermal"]["p1"])


@pytest.mark.slow
def test_a_jacket_over_a_shirt_is_colder_outside_than_the_jacket_alone(humvvex_raw, tmp_path):
    """Clear night at -5 degC: the second layer insulates, so the jacket's outer surface cools
    (the garments coupled straight to the skin made it 1.2 K warmer instead)."""
    two, diag = _night_outfit(humvvex_raw, tmp_path / "two", ["tshirt_white", "jacket"])
    one, _ = _night_outfit(humvvex_raw, tmp_path / "one", ["jacket"])
    assert np.median(two["jacket"]) < np.median(one["jacket"]) - 0.5
    # the shirt under the jacket sits between skin and jacket
    assert np.median(two["tshirt_white"]) > np.median(two["jacket"]) + 5.0
    assert diag["garmentMaxResidual_W_m2"] <= 1e-6


@pytest.mark.slow
def test_a_running_person_in_the_heat_wets_the_shirt(humvvex_raw, tmp_path):
    """Hot and dry, running: the physiology sweats and the T-shirt evaporates some of it."""
    import copy

    raw = copy.deepcopy(humvvex_raw)
    raw["human"][0]["activity"] = "run"
    temps, diag = _night_outfit(
        raw, tmp_path, ["tshirt_white", "shorts"], air_temperature_k=308.15, relative_humidity=0.3
    )
    assert diag["garmentEvaporationMax_W_m2"] > 5.0
    # at night in 35 degC air, evaporation takes the wet shirt below the air somewhere
    assert temps["tshirt_white"].min() < 308.15


# ---------------------------------------------------------------------------- catalogue clo
#: The tights helper the fitted garments start from sits about 6 mm off the skin
#: (humv_usd.catalog.garments); a garment's mean air gap is that plus its ease.
HELPER_OFFSET_M = 0.006
#: Coverage of each JOS-3 segment (head, neck, chest, back, pelvis, shoulder, arm, hand, thigh,
#: leg, foot; both sides alike) by the catalogue cuts: the jacket cut ends below the hips with
#: a collar, the long-sleeve cut at the hip joints, trousers at the ankles.
_JACKET_CUT = dict(neck=0.6, chest=1.0, back=1.0, pelvis=0.6, shoulder=1.0, arm=0.95)
_CUTS = {
    "jeans": dict(pelvis=1.0, thigh=1.0, leg=0.96),
    "sweater": dict(chest=1.0, back=1.0, pelvis=0.3, shoulder=1.0, arm=0.93),
    "fleece_jacket": _JACKET_CUT,
    "winter_coat": _JACKET_CUT,
}
#: ASHRAE 55-2020 Table 5.2.2.2B garment (pythermalcomfort's copy of the table) for each
_ASHRAE = {
    "jeans": "Thick trousers",  # 0.24 clo
    "sweater": "Long sleeve shirt (thick)",  # 0.36: the table's long-sleeve thick sweater
    "fleece_jacket": "Long-sleeve sweat shirt",  # 0.34
    "winter_coat": "Double-breasted coat (thick)",  # 0.48: the table's heaviest jacket
}


def _covered_fraction(cut):
    from pythermalcomfort.models import JOS3

    bsa = JOS3(height=1.72, weight=74.43).bsa  # the standard body, 17 segments
    names = ["head", "neck", "chest", "back", "pelvis"] + ["shoulder", "arm", "hand"] * 2
    names += ["thigh", "leg", "foot"] * 2
    return sum(a * cut.get(n, 0.0) for a, n in zip(bsa, names)) / bsa.sum()


@pytest.mark.parametrize("name", list(_CUTS))
def test_insulating_garments_clo_from_their_fabric_brackets_ashrae(name):
    """A garment's clo from its fabric (thickness / conductivity) and fit (air gap = helper
    offset + ease): the tabulated value lies between the parallel and the serial whole-body
    estimates (Kuklane et al. 2007), the two limits of the manikin methods."""
    from pythermalcomfort.utilities import clo_individual_garments

    from humv_usd.catalog.garments import garment
    from humv_usd.catalog.materials import LIBRARY
    from humv_usd.physics.garment import garment_insulation, intrinsic_insulation

    g = garment(name)
    fabric = LIBRARY[g.fabric]
    r = intrinsic_insulation(
        HELPER_OFFSET_M + g.ease, fabric.thickness, fabric.conductivity, fabric.emissivity[-2]
    )
    f = _covered_fraction(_CUTS[name])
    low = garment_insulation(f, r, "parallel") / 0.155
    high = garment_insulation(f, r, "serial") / 0.155
    table = clo_individual_garments[_ASHRAE[name]]
    if name == "winter_coat":  # a down coat insulates more than any suit jacket of the table
        assert low >= 0.7 * table and high > 1.5 * table
    else:
        assert low <= table <= high, (low, table, high)


def test_coats_insulate_and_the_table_is_cited():
    from humv_usd.catalog.garments import garment
    from humv_usd.catalog.materials import INSULATION, LIBRARY
    from humv_usd.physics.garment import intrinsic_insulation

    def local(name):
        g = garment(name)
        m = LIBRARY[g.fabric]
        return intrinsic_insulation(HELPER_OFFSET_M + g.ease, m.thickness, m.conductivity)

    # the down coat holds ~3x the insulation of the uniform jacket where it covers, the
    # fabric alone (12 mm / 0.038) is 0.32 m^2 K/W = 2 clo
    assert local("winter_coat") > 2.5 * local("jacket")
    assert local("fleece_jacket") > local("jacket") and local("sweater") > local("longsleeve")
    for m in INSULATION.values():
        assert len(m.source) > 200 and ("Bankvall" in m.source or "Baxter" in m.source)
        assert 0.025 < m.conductivity < 0.08 and m.thickness <= 0.05  # schema range 0-0.05 m
        assert np.all((np.array(m.emissivity)[-3:] >= 0.85) & (np.array(m.emissivity)[-3:] <= 0.92))
        assert abs(m.spectral_solar_absorptivity - m.solar_absorptivity) < 0.05
