"""Physiology: two-node (Gagge), JOS-3 (pythermalcomfort), heart rate, per-face skin mapping."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from humv_usd.human.labels import JOS3_SEGMENTS
from humv_usd.human.motion import epoc_met
from humv_usd.thermal import physiology as P

K = 273.15
HEIGHT, MASS, AGE = 1.75, 75.0, 30.0
AREA = P.dubois_area(HEIGHT, MASS)
MET_W = P.MET_W_M2 * AREA  # 1 met for this body [W]
HOUR = np.arange(0.0, 3601.0, 60.0)  # 1 h at 60 s steps
SEG = {name: i for i, name in enumerate(JOS3_SEGMENTS)}
TRUNK = [SEG[s] for s in ("Chest", "Back", "Pelvis")]
EXTREMITIES = [SEG[s] for s in ("LHand", "RHand", "LFoot", "RFoot")]

pythermalcomfort = pytest.importorskip("pythermalcomfort")


def run(model, air_c=29.0, met=1.0, rh=0.5, v=0.1, clo=0.5, times=HOUR, mrt_c=None, **kw):
    """``met`` in met units, scalar or per step."""
    mrt_c = air_c if mrt_c is None else mrt_c
    return P.simulate_physiology(
        times,
        np.asarray(met) * MET_W,
        air_c + K,
        mrt_c + K,
        rh,
        v,
        clo,
        model=model,
        height_m=HEIGHT,
        mass_kg=MASS,
        age_years=AGE,
        **kw,
    )


def exercise_schedule():
    """1 met for 10 min, 4 met for 30 min, then the avatar's post-exercise decay for 60 min."""
    t = np.arange(0.0, 100 * 60.0 + 1.0, 60.0)
    met = np.where(t < 600.0, 1.0, 4.0)
    after = t >= 2400.0
    met[after] = epoc_met(t[after] - 2400.0, 4.0, rest_met=1.0)
    return t, met


@pytest.fixture(scope="module")
def jos3_runs():
    """All JOS-3 runs of this module, computed once (numba compiles on the first, ~10 s)."""
    t, met = exercise_schedule()
    return {
        "neutral": run("jos3"),
        "pmv0": run("jos3", air_c=25.5),
        "cold": run("jos3", air_c=10.0),
        "exercise": run("jos3", met=met, times=t),
    }


# ----------------------------------------------------------------------------- heart rate
def test_heart_rate_rest_and_exercise():
    hr = P.heart_rate(np.array([1.0, 1.3, 5.0]) * MET_W, mass_kg=MASS, age_years=AGE)
    assert 60.0 <= hr[0] <= 80.0 and 60.0 <= hr[1] <= 80.0
    assert 110.0 <= hr[2] <= 150.0
    # %HRR = %VO2R: at VO2max the heart rate is HRmax = 208 - 0.7 age (Tanaka 2001)
    vo2max_w = 40.0 * MASS * P.J_PER_ML_O2 / 60.0
    assert_allclose(P.heart_rate(vo2max_w, MASS, AGE), 208.0 - 0.7 * AGE)
    assert_allclose(P.heart_rate(0.0, MASS, AGE), P.FITNESS["average"]["resting_hr_bpm"])


def test_heart_rate_fitness_and_validation():
    m = 5.0 * MET_W
    low, avg, high = (P.heart_rate(m, MASS, AGE, fitness=f) for f in ("low", "average", "high"))
    assert low > avg > high
    assert P.heart_rate(m, MASS, 60.0) > avg  # older: lower HRmax but lower VO2max too
    assert np.all(np.diff(P.heart_rate(np.linspace(50, 2000, 50), MASS, AGE)) >= 0)
    with pytest.raises(ValueError):
        P.heart_rate(m, fitness="elite")


# ----------------------------------------------------------------------------- two-node
def test_two_node_neutral():
    r = run("two_node")
    assert 33.0 <= r.mean_skin_temperature_k[-1] - K <= 34.5
    assert 36.8 <= r.core_temperature_k[-1] - K <= 37.2
    # spin-up: already steady at the first output
    assert abs(r.mean_skin_temperature_k[-1] - r.mean_skin_temperature_k[0]) < 0.05
    assert r.segment_skin_temperature_k.shape == (len(HOUR), 17)
    assert_array_equal(r.segment_skin_temperature_k[:, 5], r.mean_skin_temperature_k)
    assert np.isnan(r.cardiac_output_l_h).all()


def test_two_node_cold_and_hot():
    neutral, cold, hot = (run("two_node", air_c=a) for a in (29.0, 10.0, 40.0))
    assert cold.mean_skin_temperature_k[-1] < neutral.mean_skin_temperature_k[-1] - 3.0
    assert cold.skin_blood_flow_l_h[-1] < neutral.skin_blood_flow_l_h[-1]
    assert hot.sweat_rate_g_s[-1] > neutral.sweat_rate_g_s[-1] + 0.05
    assert hot.mean_skin_temperature_k[-1] > neutral.mean_skin_temperature_k[-1]


def test_two_node_exercise_and_recovery():
    t, met = exercise_schedule()
    r = run("two_node", met=met, times=t)
    i_rest, i_end, i_rec = 9, 40, len(t) - 1
    core = r.core_temperature_k
    assert core[i_end] - core[i_rest] > 0.2
    assert core[i_rec] < core[i_end] - 0.1  # recovering
    assert r.heart_rate_bpm[i_end] > r.heart_rate_bpm[i_rest] + 30
    assert r.heart_rate_bpm[i_rec] < r.heart_rate_bpm[i_rest] + 5


@pytest.mark.parametrize("dt", [1.0, 10.0, 30.0])
def test_two_node_time_step_independence(dt):
    """1 h from the neutral state into cold air while exercising: same result at any step."""
    ref = run("two_node", air_c=10.0, met=3.0, spin_up_s=0.0)
    times = np.arange(0.0, 3600.0 + dt / 2, dt)
    r = run("two_node", air_c=10.0, met=3.0, spin_up_s=0.0, times=times)
    assert_allclose(r.core_temperature_k[-1], ref.core_temperature_k[-1], atol=0.1)
    assert_allclose(r.mean_skin_temperature_k[-1], ref.mean_skin_temperature_k[-1], atol=0.1)


@pytest.mark.slow
def test_two_node_extreme_grid_finite():
    for air, rh, v, clo, met in itertools.product(
        (-40.0, 0.0, 25.0, 40.0, 55.0), (0.0, 0.5, 1.0), (0.0, 5.0, 30.0), (0.0, 1.5), (1.0, 6.0)
    ):
        r = run("two_node", air_c=air, rh=rh, v=v, clo=clo, met=met)
        for a in (r.core_temperature_k, r.mean_skin_temperature_k, r.skin_blood_flow_l_h, r.sweat_rate_g_s):
            assert np.isfinite(a).all(), (air, rh, v, clo, met)
        # no frost model: bare skin in -40 °C at 30 m/s goes far below 0 °C, but not below the
        # air (evaporation can cool it below a warm, dry air: wet-bulb effect)
        assert r.mean_skin_temperature_k.min() > min(air, 0.0) + K - 2.0


def test_two_node_bad_input():
    with pytest.raises(ValueError):
        P.two_node([0.0, 60.0, 30.0], 100.0, 300.0, 300.0, 0.5, 0.1, 0.5)
    with pytest.raises(ValueError):
        P.two_node(HOUR, np.ones(3), 300.0, 300.0, 0.5, 0.1, 0.5)


# ----------------------------------------------------------------------------- JOS-3
@pytest.mark.slow
def test_jos3_neutral(jos3_runs):
    r = jos3_runs["neutral"]  # 29 °C, 0.5 clo, 1 met: PMV +1.1 (ISO 7730), slightly warm
    assert 36.8 <= r.core_temperature_k[-1] - K <= 37.2
    assert 33.0 <= r.mean_skin_temperature_k[-1] - K <= 35.5
    r0 = jos3_runs["pmv0"]  # 25.5 °C: PMV ~ 0 for 0.5 clo
    assert 33.0 <= r0.mean_skin_temperature_k[-1] - K <= 35.0
    assert 36.8 <= r0.core_temperature_k[-1] - K <= 37.2
    assert r.segment_skin_temperature_k.shape == (len(HOUR), 17)
    assert np.isfinite(r.cardiac_output_l_h).all() and 150 < r.cardiac_output_l_h[-1] < 600
    assert abs(r.mean_skin_temperature_k[-1] - r.mean_skin_temperature_k[0]) < 0.1  # spun up


@pytest.mark.parametrize("case,air_c", [("neutral", 29.0), ("pmv0", 25.5)])
def test_two_node_vs_jos3(jos3_runs, case, air_c):
    two = run("two_node", air_c=air_c)
    assert abs(two.mean_skin_temperature_k[-1] - jos3_runs[case].mean_skin_temperature_k[-1]) < 1.0
    assert abs(two.core_temperature_k[-1] - jos3_runs[case].core_temperature_k[-1]) < 0.5


def test_jos3_cold(jos3_runs):
    cold, neutral = jos3_runs["cold"], jos3_runs["neutral"]
    assert cold.mean_skin_temperature_k[-1] < neutral.mean_skin_temperature_k[-1] - 3.0
    seg = cold.segment_skin_temperature_k[-1]
    assert seg[EXTREMITIES].max() < seg[TRUNK].min() - 2.0


def test_jos3_exercise_and_recovery(jos3_runs):
    r = jos3_runs["exercise"]
    i_rest, i_end, i_rec = 9, 40, len(r.times_s) - 1
    core = r.core_temperature_k
    assert core[i_end] - core[i_rest] > 0.2
    assert core[i_rec] < core[i_end] - 0.1
    assert r.cardiac_output_l_h[i_end] > r.cardiac_output_l_h[i_rest]
    assert r.heart_rate_bpm[i_end] > r.heart_rate_bpm[i_rest] + 30
    assert r.heart_rate_bpm[i_rec] < r.heart_rate_bpm[i_rest] + 5


def test_jos3_per_segment_mrt(jos3_runs):
    mrt = np.full(17, 29.0 + K)
    mrt[SEG["Head"]] = 60.0 + K  # sun on the head only
    r = P.jos3(HOUR[:11], MET_W, 29.0 + K, mrt, 0.5, 0.1, 0.5, height_m=HEIGHT, mass_kg=MASS)
    base = jos3_runs["neutral"].segment_skin_temperature_k[10]
    d = r.segment_skin_temperature_k[-1] - base
    assert d[SEG["Head"]] > 1.0 and d[SEG["Head"]] == d.max()


@pytest.mark.slow
def test_jos3_extreme_grid_finite(jos3_runs):
    for air, rh, v in itertools.product((-40.0, 55.0), (0.0, 1.0), (0.0, 30.0)):
        r = run("jos3", air_c=air, rh=rh, v=v, times=HOUR[:31], spin_up_s=1800.0)
        for a in (r.core_temperature_k, r.segment_skin_temperature_k, r.cardiac_output_l_h):
            assert np.isfinite(a).all(), (air, rh, v)


# ----------------------------------------------------------------------------- dispatch, faces
def test_simulate_physiology_model_selection():
    with pytest.raises(ValueError, match="invalid model selection"):
        run("icda")
    r = run("two_node", times=HOUR[:3], mrt_c=np.full(17, 29.0))  # per-segment MRT → mean
    assert r.model == "two_node"


def test_skin_temperature_per_face():
    ids = np.random.default_rng(0).integers(0, 17, 1000)
    seg = 300.0 + np.arange(17) * 0.25
    assert_array_equal(P.skin_temperature_per_face(ids, seg), seg[ids])
    series = np.stack([seg, seg + 1.0])
    out = P.skin_temperature_per_face(ids, series)
    assert out.shape == (2, 1000)
    assert_array_equal(out[1], seg[ids] + 1.0)
    with pytest.raises(ValueError):
        P.skin_temperature_per_face(np.array([0, 17]), seg)
    with pytest.raises(ValueError):
        P.skin_temperature_per_face(np.array([-1, 3]), seg)
    with pytest.raises(ValueError):
        P.skin_temperature_per_face(ids, seg[:16])


def test_time_step_bench_two_node_first_order():
    from humv_usd.bench.thermal_steps import skin_time_steps as bench_time_steps

    rows = bench_time_steps("two_node", steps_s=(5.0, 20.0, 60.0), duration_s=1800.0)
    err = [r["max_error_k"] for r in rows]
    assert err[0] < err[1] < err[2] < 0.5  # explicit Euler: error grows with the step


# ----------------------------------------------------------------------------- hot and humid
@pytest.mark.slow
@pytest.mark.parametrize("air_c, rh", [(40.0, 0.9), (60.0, 0.5)])
def test_jos3_hot_humid_condensation_not_evaporative_cooling(air_c, rh):
    """Air more humid than the skin: no negative wettedness, no evaporative cooling. Reference:
    Gagge's two-node model with condensation (E = E_max < 0 while p_a > p_sk,s), which
    pythermalcomfort 4.8.1's JOS-3 alone misses by 2-7 K (wettedness -1.7 to -3.4)."""
    ref = run("two_node", air_c=air_c, rh=rh, v=0.5, clo=0.5, met=100.0 / MET_W, spin_up_s=0.0)
    r = run("jos3", air_c=air_c, rh=rh, v=0.5, clo=0.5, met=100.0 / MET_W, spin_up_s=0.0)
    assert r.wettedness.min() >= 0.06 - 1e-12 and r.wettedness.max() <= 1.0 + 1e-12
    # closed form: while the ambient vapour pressure exceeds the skin's saturation pressure
    # the latent flux is a heat gain (condensation), never a loss
    p_a = rh * P._p_sat_kpa(air_c)
    psk = np.vectorize(P._p_sat_kpa)(r.segment_skin_temperature_k - K)
    humid = psk < p_a
    assert humid.any() and np.all(r.segment_latent_w_m2[humid] <= 0.0)
    assert_allclose(r.mean_skin_temperature_k[-1], ref.mean_skin_temperature_k[-1], atol=1.0)
    assert_allclose(r.core_temperature_k[-1], ref.core_temperature_k[-1], atol=1.0)
    # the body gains heat: core and skin rise over the hour
    assert r.core_temperature_k[-1] > r.core_temperature_k[0] + 1.0


@pytest.mark.slow
def test_condensation_guard_restores_pythermalcomfort():
    from pythermalcomfort.models import jos3 as module

    before = module.threg
    with P.condensation_guard():
        assert module.threg is not before and module.threg.antoine is before.antoine
    assert module.threg is before


def test_guarded_evaporation_closed_form():
    def upstream(**kw):  # the 4.8.1 formula with E_max of either sign
        e_sweat, e_max = np.array([10.0, 10.0]), np.array([50.0, -20.0])
        wet = np.minimum(0.06 + 0.94 * e_sweat / e_max, 1.0)
        return wet, wet * e_max, e_max, (wet - 0.06) / 0.94 * e_max

    wet, e_sk, e_max, e_sweat = P.guarded_evaporation(upstream)()
    assert_allclose(wet, [0.06 + 0.94 * 0.2, 1.0])
    assert_allclose(e_sk, [0.06 * 50.0 + 0.94 * 10.0, -20.0])  # condensation: a heat gain
    assert_allclose(e_sweat, [10.0, 0.0])


def test_two_node_huge_substep_is_stable():
    """The substep argument cannot drive the explicit two-node model unstable: each substep is
    capped by the nodes' C/G; a 1e6 s substep gives the same hour as 1 s substeps."""
    for air_c, v, rh in ((10.0, 30.0, 0.5), (45.0, 30.0, 0.2), (29.0, 0.1, 0.5)):
        ref = run("two_node", air_c=air_c, v=v, rh=rh, met=3.0, clo=0.0, spin_up_s=0.0, max_substep_s=1.0)
        r = run("two_node", air_c=air_c, v=v, rh=rh, met=3.0, clo=0.0, spin_up_s=0.0, max_substep_s=1e6)
        assert np.isfinite(r.mean_skin_temperature_k).all()
        # stable (bounded, no oscillation) but first order: the fast first minutes err by ~1 K
        assert_allclose(r.mean_skin_temperature_k, ref.mean_skin_temperature_k, atol=1.5)
        assert_allclose(r.mean_skin_temperature_k[-10:], ref.mean_skin_temperature_k[-10:], atol=0.2)
        assert_allclose(r.core_temperature_k, ref.core_temperature_k, atol=0.2)
        ref_sign, sign = (
            np.sign(np.diff(ref.mean_skin_temperature_k)),
            np.sign(np.diff(r.mean_skin_temperature_k)),
        )
        assert np.count_nonzero(sign != ref_sign) <= 3


@pytest.mark.parametrize(
    "kw",
    [
        dict(max_substep_s=0.0),
        dict(max_substep_s=float("nan")),
        dict(height_m=float("nan")),
        dict(mass_kg=-1.0),
    ],
)
def test_two_node_rejects_non_physical_arguments(kw):
    args = dict(height_m=HEIGHT, mass_kg=MASS) | kw
    with pytest.raises(ValueError, match=next(iter(kw))):
        P.two_node(HOUR, MET_W, 300.0, 300.0, 0.5, 0.1, 0.5, **args)


# ----------------------------------------------------------------------------- local skin
def test_local_skin_temperature_closed_form():
    """Two facets of one segment, one sunlit (absorbs 300 W m^-2 more): each facet's balance
    K (T_b - T_f) = q(T_f) + E holds with one T_b, the area mean is the segment's skin
    temperature and the sunlit facet is warmer by 300 / (K + g)."""
    seg = np.array([2, 2, 5])
    area = np.array([0.01, 0.03, 0.02])
    t0 = np.array([306.0, 306.0, 305.0])
    g = np.array([20.0, 20.0, 15.0])
    q0 = np.array([100.0 - 300.0, 100.0, 80.0])  # sunlit facet: 300 W m^-2 more absorbed
    k = np.full(17, 12.0)
    latent = np.full(17, 10.0)
    t_seg = np.full(17, 305.5)
    t_f, q = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0)
    assert_allclose(q, q0 + g * (t_f - t0))
    for s in (2, 5):
        m = seg == s
        assert_allclose(np.average(t_f[m], weights=area[m]), 305.5, atol=1e-12)
        t_inner = t_f[m] + (q[m] + latent[s]) / k[s]
        assert_allclose(t_inner, t_inner[0], atol=1e-9)  # one inner temperature per segment
    assert_allclose(t_f[0] - t_f[1], 300.0 / (12.0 + 20.0), rtol=1e-12)


def test_radiant_temperature_for_sensible_loss_inverts_the_dry_exchange():
    hc, hr, rt = np.array([4.0, 9.0]), np.array([4.7, 4.5]), np.array([0.12, 0.2])
    t_sk, t_a, target = np.array([306.0, 303.0]), 289.0, np.array([35.0, -12.0])
    tr = P.radiant_temperature_for_sensible_loss(t_sk, target, t_a, hc, hr, rt)
    t_o = (hc * t_a + hr * tr) / (hc + hr)
    assert_allclose((t_sk - t_o) / rt, target, rtol=1e-12)


def _bare_segment_facets(rng, n=40):
    """Facets of one bare segment: areas, and the linearised loss of bare skin
    h (T - T_a) + eps sigma T^4 - q_abs around 305 K with a spread of absorbed flux."""
    area = rng.uniform(1e-4, 1e-3, n)
    t0 = np.full(n, 305.0)
    g = rng.uniform(8.0, 30.0, n)
    q0 = rng.uniform(-250.0, 400.0, n)
    return area, t0, g, q0


@pytest.mark.parametrize("seed", range(6))
def test_local_skin_never_above_the_segment_core(seed):
    """Large losses on a weakly conducting segment (the bare head at -15 degC needed an inner
    temperature of 56 degC): with the core bound no facet is above its segment's core, the area
    mean is still the physiology's skin temperature, and the unbounded closed form did exceed
    the core (so the bound is what is tested)."""
    rng = np.random.default_rng(seed)
    area, t0, g, q0 = _bare_segment_facets(rng)
    seg = rng.integers(0, 3, len(area))
    k = np.array([3.0, 6.0, 15.0] + [12.0] * 14)
    latent = np.full(17, 8.0)
    core = np.full(17, 310.0) - rng.uniform(0.0, 1.0, 17)
    target = core - rng.uniform(1.0, 6.0, 17)
    free, _ = P.local_skin_temperature(target, k, latent, seg, area, q0, g, t0)
    t_f, q = P.local_skin_temperature(target, k, latent, seg, area, q0, g, t0, segment_core_k=core)
    assert (free > core[seg] + 0.5).any()
    assert (t_f <= core[seg] + 1e-9).all()
    assert_allclose(q, q0 + g * (t_f - t0))
    for s in np.unique(seg):
        m = seg == s
        assert_allclose(np.average(t_f[m], weights=area[m]), target[s], atol=1e-8)
        # a core-skin shell: one inner temperature <= the core at the segment's conductance,
        # or the inner node at the core with one raised conductance (vasodilation)
        free_facets = m & (t_f < core[seg] - 1e-6)
        heat = q[free_facets] + latent[s]
        t_b = t_f[free_facets] + heat / k[s]
        k_raised = heat / (core[s] - t_f[free_facets])
        if np.ptp(t_b) < 1e-6:
            assert t_b.max() <= core[s] + 1e-9
        else:
            assert_allclose(k_raised, k_raised[0], rtol=1e-6)
            assert k_raised[0] >= k[s]


def test_local_skin_bound_keeps_the_closed_form_where_it_holds():
    """Facets all below the core and an inner temperature below it: the bounded model is the
    closed form of issue 14 exactly (the JOS-3 conductance and one inner temperature)."""
    seg = np.array([2, 2, 5])
    area = np.array([0.01, 0.03, 0.02])
    t0 = np.array([306.0, 306.0, 305.0])
    g = np.array([20.0, 20.0, 15.0])
    q0 = np.array([0.0, 100.0, 80.0])
    k, latent, t_seg = np.full(17, 30.0), np.full(17, 10.0), np.full(17, 305.5)
    free = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0)[0]
    bounded = P.local_skin_temperature(
        t_seg, k, latent, seg, area, q0, g, t0, segment_core_k=np.full(17, 310.0)
    )[0]
    q = q0 + g * (free - t0)
    assert free.max() < 310.0 and (free + (q + 10.0) / 30.0).max() < 310.0  # facets and inner node
    assert_allclose(bounded, free, rtol=0, atol=0)


def test_local_skin_sunlit_facet_held_at_the_core():
    """A facet that gains heat even at the core temperature (strong sun) stays at the core; the
    others carry the segment's mean with one inner temperature <= the core."""
    seg = np.array([0, 0, 0])
    area = np.array([0.01, 0.01, 0.02])
    t0 = np.full(3, 306.0)
    g = np.full(3, 20.0)
    q0 = np.array([-600.0, 60.0, 80.0])  # the first facet: 660 W m^-2 more absorbed
    k, latent = np.full(17, 40.0), np.full(17, 10.0)
    core, t_seg = np.full(17, 310.0), np.full(17, 307.0)
    free = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0)[0]
    t_f = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0, segment_core_k=core)[0]
    assert free[0] > 310.0 and t_f[0] == pytest.approx(310.0, abs=1e-9)
    assert np.average(t_f, weights=area) == pytest.approx(307.0, abs=1e-8)
    # the two others share one inner temperature T_b = T_f + (q_f + E) / K, at most the core
    q = q0 + g * (t_f - t0)
    t_b = t_f[1:] + (q[1:] + 10.0) / 40.0
    assert_allclose(t_b, t_b[0], atol=1e-7)
    assert t_b[0] <= 310.0 + 1e-9


def test_local_skin_frames_together_equal_frame_by_frame():
    """All frames in one call (the thermal tool's coupling) give exactly what each frame gives
    alone: segment sums do not mix frames, and each (frame, segment) is bounded on its own
    (frames with free, core-held and raised-conductance segments side by side)."""
    rng = np.random.default_rng(7)
    frames, faces = 5, 400
    seg = np.concatenate([np.arange(17), rng.integers(0, 17, faces - 17)])
    area = rng.uniform(1e-4, 1e-3, faces)
    t_seg = rng.uniform(300.0, 309.0, (frames, 17))
    core = t_seg + rng.uniform(-1.0, 3.0, (frames, 17))  # some segments above their core
    k, latent = rng.uniform(5.0, 40.0, (frames, 17)), rng.uniform(0.0, 30.0, (frames, 17))
    q0 = rng.normal(50.0, 150.0, (frames, faces))  # sunlit facets gain heat, others lose a lot
    g, t0 = rng.uniform(-1.0, 20.0, (frames, faces)), rng.uniform(298.0, 310.0, (frames, faces))
    for bound in (None, core):
        both = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0, segment_core_k=bound)
        for f in range(frames):
            alone = P.local_skin_temperature(
                t_seg[f], k[f], latent[f], seg, area, q0[f], g[f], t0[f], None if bound is None else bound[f]
            )
            assert_array_equal(both[0][f], alone[0])
            assert_array_equal(both[1][f], alone[1])
    held = both[0] == core[:, seg]
    assert held.any() and not held.all()


def test_local_skin_hot_segment_left_unbounded():
    """Skin at or above the core (air above body temperature: heat flows in): the closed form."""
    seg = np.array([1, 1])
    area = np.array([0.01, 0.01])
    t0, g, q0 = np.full(2, 311.0), np.full(2, 20.0), np.array([-150.0, -50.0])
    k, latent = np.full(17, 12.0), np.full(17, 60.0)
    core, t_seg = np.full(17, 310.0), np.full(17, 310.5)
    free = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0)[0]
    t_f = P.local_skin_temperature(t_seg, k, latent, seg, area, q0, g, t0, segment_core_k=core)[0]
    assert_allclose(t_f, free, rtol=0, atol=0)


def test_lagged_skin_relaxes_exponentially_and_keeps_the_segment_mean():
    """A step in two facets' steady departures: each approaches its new steady value as
    exp(-t / tau), tau = C / (K + g), exactly; the area mean stays the segment's skin."""
    frames, dt = 40, 1.0 / 30.0
    seg = np.array([3, 3])
    area = np.array([0.02, 0.02])
    mean = np.full((frames, 17), 305.0)
    steady = np.tile([305.0, 305.0], (frames, 1))
    steady[1:] = [306.0, 304.0]  # a sun edge crosses the segment at frame 1
    cap = np.full(17, 6000.0)
    cond = np.full((frames, 2), 30.0)
    out = P.lagged_skin(steady, mean, cap, cond, dt, seg, area)
    t = np.arange(frames) * dt
    assert_allclose(out[:, 0], 306.0 - np.exp(-t * 30.0 / 6000.0), rtol=0, atol=1e-12)
    assert_allclose(out.mean(axis=1), 305.0, atol=1e-12)
    assert np.abs(np.diff(out, axis=0)).max() < 30.0 * dt / 6000.0 * 1.0 + 1e-12  # C dT/dt <= (K+g) dT


def test_sample_interpolation_is_linear_between_samples():
    from humv_usd.thermal.human import sample_interpolation

    at = sample_interpolation([0, 10, 20], 25)
    v = at(np.array([[0.0, 1.0], [10.0, 3.0], [40.0, 5.0]]))
    assert_allclose(v[:, 0], np.r_[np.arange(11.0), 10.0 + 3.0 * np.arange(1.0, 11.0), np.full(4, 40.0)])
    assert_allclose(v[5, 1], 2.0)


def test_jos3_module_imports_jos3_alone_and_the_package_later():
    """A fresh interpreter: jos3_module() loads JOS-3 without pythermalcomfort.models' other
    models (the one-shot compose's import cost), and a later plain import of the package works
    and holds the same module and class (the condensation guard patches that module)."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from humv_usd.thermal.physiology import jos3_module\n"
        "m = jos3_module()\n"
        "assert 'pythermalcomfort.models' not in sys.modules\n"
        "assert 'pythermalcomfort.models.utci' not in sys.modules\n"
        "from pythermalcomfort.models import JOS3, jos3, utci\n"
        "assert JOS3 is m.JOS3 and jos3 is m and callable(utci)\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "ok"
