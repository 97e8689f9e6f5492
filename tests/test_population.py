"""Population sampler (humv_usd.human.population) against its sources: CDC 2000 growth charts
(the CDC's own percentile columns) and ANSUR II summary statistics."""

import numpy as np
import pytest

from humv_usd.human import population as P
from humv_usd.scenario.spec import HUMAN

Z95 = 1.6448536269514722  # standard normal 95th percentile


@pytest.mark.parametrize(
    "table, sex, months, z, published",
    [
        # CDC bmiagerev.csv P50 / P95 columns (independent of the L, M, S we tabulate)
        (P.CDC_BMI, "male", 24.0, 0.0, 16.57502768),
        (P.CDC_BMI, "male", 24.0, Z95, 19.33801062),
        (P.CDC_BMI, "female", 120.5, Z95, 22.98257733),
        (P.CDC_BMI, "female", 120.5, -Z95, 14.03535405),
        # CDC statage.csv P95 / P5 columns [cm]
        (P.CDC_STATURE, "male", 24.0, Z95, 92.19687928),
        (P.CDC_STATURE, "female", 240.0, -Z95, 152.6507234),
    ],
)
def test_lms_reproduces_cdc_percentiles(table, sex, months, z, published):
    value = float(P.lms_value(*P.lms_at(table, sex, months / 12.0), z))
    assert value == pytest.approx(published, rel=2e-3)


def test_adults_match_ansur2():
    rng = np.random.default_rng(7)
    for sex, (mu_h, sd_h, mu_b, sd_b) in P.ANSUR2.items():
        n = 4000
        people = [
            P.sample_person(rng, age_yr=(20, 58), p_male=1.0 if sex == "male" else 0.0) for _ in range(n)
        ]
        h = np.array([p["stature_m"] for p in people])
        bmi = np.array([p["mass_kg"] / p["stature_m"] ** 2 for p in people])
        assert all(p["sex"] == sex for p in people)
        assert abs(h.mean() - mu_h) < 4 * sd_h / np.sqrt(n)
        assert abs(h.std() - sd_h) < 0.05 * sd_h
        assert abs(np.median(np.log(bmi)) - mu_b) < 4 * 1.25 * sd_b / np.sqrt(n)
        assert abs(np.corrcoef(h, np.log(bmi))[0, 1]) < 0.1  # independent, as in ANSUR II
        assert P.BMI_MIN - 0.01 <= bmi.min() and bmi.max() <= P.BMI_MAX + 0.01  # mass rounded to 10 g


def test_children_follow_growth_chart_medians():
    rng = np.random.default_rng(3)
    kids = [P.sample_person(rng, age_yr=(10.0, 10.0), p_male=1.0) for _ in range(2000)]
    h = np.median([k["stature_m"] for k in kids])
    assert h == pytest.approx(1.388, abs=0.01)  # CDC stature-for-age M at 120.5 months: 138.8 cm


def test_seeded_and_independent_of_count():
    a = P.sample_people(5, seed=11, age_yr=(2, 90))
    b = P.sample_people(8, seed=11, age_yr=(2, 90))
    assert a == b[:5]
    assert a != P.sample_people(5, seed=12, age_yr=(2, 90))
    assert [p["id"] for p in a] == ["p0", "p1", "p2", "p3", "p4"]
    assert all(p["skin_tone"] in P.SKIN_TONES and p["clothing"][0].startswith("hair_") for p in b)


@pytest.mark.parametrize(
    "kwargs",
    [{"age_yr": (1.0, 30.0)}, {"age_yr": (40.0, 30.0)}, {"p_male": 1.5}, {"skin_tones": ("VII",)}],
)
def test_bad_input(kwargs):
    with pytest.raises(ValueError):
        P.sample_people(2, **kwargs)


@pytest.mark.parametrize(
    "sex, age, h_p25_p75_cm, bmi_p25_p75",
    [
        # NHANES Aug 2021-Aug 2023 (Fryar et al. 2025, Vital Health Stat 3(50)) Tables 7 and 10:
        # the 25th/75th percentiles, which the draw does not use (it uses mean, P10, P50, P90)
        ("male", 64.5, (169.7, 179.8), (25.2, 32.1)),
        ("female", 64.5, (155.6, 165.1), (24.8, 34.5)),
        ("male", 85.0, (166.1, 175.0), (24.6, 30.2)),
        ("female", 85.0, (151.2, 161.9), (23.6, 31.3)),
    ],
)
def test_older_adults_follow_nhanes(sex, age, h_p25_p75_cm, bmi_p25_p75):
    rng = np.random.default_rng(17)
    people = [P.sample_person(rng, age_yr=(age, age), p_male=float(sex == "male")) for _ in range(4000)]
    h = np.array([p["stature_m"] for p in people]) * 100.0
    bmi = np.array([p["mass_kg"] / p["stature_m"] ** 2 for p in people])
    assert np.percentile(h, [25, 75]) == pytest.approx(h_p25_p75_cm, abs=1.0)
    assert np.percentile(bmi, [25, 75]) == pytest.approx(bmi_p25_p75, rel=0.04)


def test_stature_declines_with_age_and_ansur_range_is_unchanged():
    for sex in ("male", "female"):
        assert P.adult_stature_bmi_params(sex, 40.0) == pytest.approx(P.ANSUR2[sex])
        assert P.adult_stature_bmi_params(sex, 58.0) == pytest.approx(P.ANSUR2[sex])
        h = [P.adult_stature_bmi_params(sex, a)[0] for a in (64.5, 74.5, 85.0, 90.0)]
        assert h[0] > h[1] > h[2] == h[3]


def test_children_bmi_lower_tail_is_not_clipped():
    """At 6 yr the CDC BMI-for-age 5th percentile (~13.7) is below the adults' clip (15): the draw
    keeps it (before, ~40 % of 6-year-olds sat at BMI 15 exactly)."""
    rng = np.random.default_rng(5)
    kids = [P.sample_person(rng, age_yr=(6.0, 6.0), p_male=1.0) for _ in range(3000)]
    bmi = np.array([k["mass_kg"] / k["stature_m"] ** 2 for k in kids])
    p5 = float(P.lms_value(*P.lms_at(P.CDC_BMI, "male", 6.0), -Z95))
    assert np.percentile(bmi, 5) == pytest.approx(p5, rel=0.02)
    assert np.mean(np.abs(bmi - P.BMI_MIN) < 0.01) < 0.02


def test_smallest_drawn_children_are_valid_scenario_people():
    for sex in ("male", "female"):
        h, bmi = P.stature_bmi(sex, 2.0, -9.0, -9.0)  # z limited to -3
        assert h >= HUMAN.keys["stature_m"].lo and bmi * h * h >= HUMAN.keys["mass_kg"].lo


def test_children_bmi_above_the_97th_percentile_stays_bounded():
    """The CDC 2000 LMS curve is not valid above its 97th percentile (z = 3 gave BMI 131 at 10 yr):
    the draw continues it linearly in z, continuous and increasing."""
    for sex in ("male", "female"):
        for age in (2.0, 6.0, 10.0, 14.0):
            at = [P.stature_bmi(sex, age, 0.0, z)[1] for z in (P.Z97 - 1e-6, P.Z97 + 1e-6, 2.5, 3.0)]
            assert at[1] - at[0] < 1e-3 and at[0] < at[2] < at[3] < P.BMI_MAX
