"""Population sampler (humv_usd.human.population) against its sources: CDC 2000 growth charts
(the CDC's own percentile columns) and ANSUR II summary statistics."""

import numpy as np
import pytest

from humv_usd.human import population as P

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
