"""The person's own body in JOS-3: body fat from BMI, age and sex (thermal/physiology.py)."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.thermal import physiology as P

K = 273.15


def test_own_body_fat_is_deurenberg():
    """None -> Deurenberg et al. (1991): 1.20 BMI + 0.23 age - 10.8 sex - 5.4 (adults)."""
    bmi = 45.0
    h, m, age, fat = P.jos3_body(1.78, bmi * 1.78**2, 30, "male", None)
    assert fat == pytest.approx(1.20 * bmi + 0.23 * 30 - 10.8 - 5.4)
    assert P.jos3_body(1.63, 17 * 1.63**2, 30, "female", None)[3] == pytest.approx(1.2 * 17 + 6.9 - 5.4)


def test_jos3_tissue_conductance_falls_with_fat():
    """JOS-3 (Kobayashi & Tanabe 2013) picks its core-skin conductance table by body fat: the
    obese man's own 44.7 % insulates more than the 15 % reference man's, at the same size."""
    from pythermalcomfort.models import JOS3

    g = {}
    for fat in (10.0, 15.0, 44.7):
        g[fat] = P.jos3_tissue_conductance(JOS3(height=1.78, weight=142.6, fat=fat, age=30, sex="male"))
    assert np.all(g[44.7] <= g[15.0]) and g[44.7].sum() < 0.95 * g[15.0].sum()  # 8 % less
    assert g[10.0].sum() > g[15.0].sum()


@pytest.mark.extended
def test_own_fat_core_inside_the_resting_range():
    """29 °C, 0.5 clo, 1 met (test_physiology's neutral case) with the 1.75 m / 75 kg man's
    own 20.1 % fat: core within the normal resting rectal range 36.3-37.8 °C (Sund-Levander,
    Forsberg & Wahren 2002, Scand J Caring Sci 16:122), within 0.1 K of the 15 % run."""
    t = np.arange(0.0, 1801.0, 300.0)
    met = 58.15 * P.dubois_area(1.75, 75.0)
    runs = {
        fat: P.simulate_physiology(
            t, met, 29.0 + K, 29.0 + K, 0.5, 0.1, 0.5, model="jos3", body_fat_percent=fat
        )
        for fat in (15.0, None)
    }
    core = {k: r.core_temperature_k[-1] - K for k, r in runs.items()}
    assert 36.3 <= core[None] <= 37.8
    assert abs(core[None] - core[15.0]) < 0.1
