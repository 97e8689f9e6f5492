"""Leg length against the trunk: the sitting-height ratio (human/proportions.py, population.py)."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdSkel

from humv_usd.assets import MissingAssetError, makehuman_file

try:
    makehuman_file("3dobjs/base.obj")
except MissingAssetError as exc:  # pragma: no cover - data fetched by `make setup`
    pytest.skip(str(exc), allow_module_level=True)

from humv_usd.clothing.person import FIT_DATA, fit_sitting_height_ratio  # noqa: E402
from humv_usd.human.body import build_body  # noqa: E402
from humv_usd.human.population import ANSUR2_SITTING_HEIGHT_RATIO, PIGMENTED_HAIR, sample_people  # noqa: E402
from humv_usd.physics.hair_optics import HAIR_COLOURS  # noqa: E402
from humv_usd.usd.paths import human_path  # noqa: E402

#: ANSUR II public data files: mean sitting height - (stature - crotch height) [m]
OFFSET = {"male": 0.0080, "female": 0.0105}


def _crotch_height(body) -> float:
    """Independent of the fit's candidate list: the lowest body-mesh point within 2 mm of the
    mid-plane, between 35 % and 55 % of the stature (the fork of the legs)."""
    p = body.body_mesh().points
    z = p[:, 2] / body.stature_m
    near = p[(np.abs(p[:, 0]) < 0.002) & (z > 0.35) & (z < 0.55)]
    return float(near[:, 2].min())


@pytest.mark.parametrize("sex,ratio", [("male", 0.50), ("male", 0.55), ("female", 0.5262)])
def test_requested_sitting_height_ratio_is_met(sex, ratio):
    h, m = (1.76, 80.0) if sex == "male" else (1.63, 62.0)
    b = build_body(sex, 30.0, h, m, sitting_height_ratio=ratio)
    sitting = h - _crotch_height(b) + OFFSET[sex]
    assert sitting / h == pytest.approx(ratio, abs=2e-3)
    assert b.stature_m == pytest.approx(h, rel=1e-4) and b.mass_kg == pytest.approx(m, rel=1e-4)


def test_longer_legs_for_a_lower_ratio():
    def leg(b):
        j = {n: b.points[np.unique(b.groups[f"joint-{n}"])].mean(axis=0) for n in ("l-upper-leg", "l-ankle")}
        return float(np.linalg.norm(j["l-upper-leg"] - j["l-ankle"]))

    own = build_body("female", 30.0, 1.63, 62.0)
    longer = build_body("female", 30.0, 1.63, 62.0, sitting_height_ratio=0.50)
    assert own.legs == 0.0 and longer.legs > 0
    # MakeHuman's young woman sits ~1 SD above ANSUR II's women (0.5262): she is short-legged
    assert own.sitting_height_ratio > 0.5262 + 0.01
    assert leg(longer) > leg(own) + 0.04
    with pytest.raises(ValueError, match="sitting_height_ratio"):
        build_body("male", 30.0, 1.8, 80.0, sitting_height_ratio=0.7)


def test_population_draws_ansur_ratios():
    people = sample_people(3000, seed=7, age_yr=(20.0, 60.0))
    for sex, (mean, sd) in {"male": (0.5231, 0.0135), "female": (0.5262, 0.0141)}.items():
        r = np.array([p["sitting_height_ratio"] for p in people if p["sex"] == sex])
        h = np.array([p["stature_m"] for p in people if p["sex"] == sex])
        assert r.mean() == pytest.approx(mean, abs=0.0015) and r.std() == pytest.approx(sd, rel=0.1)
        assert -0.45 < np.corrcoef(r, h)[0, 1] < -0.2  # ANSUR II: -0.34 men, -0.37 women
        a, b, _ = ANSUR2_SITTING_HEIGHT_RATIO[sex]
        assert a + b * 1.7 == pytest.approx(mean, abs=0.01)


def test_children_draw_and_default_to_the_dutch_reference_ratio():
    """s8, issue 29.1: children's legs against the trunk follow Fredriks et al. (2005)'s LMS
    references (numbers typed from the paper's table: boys at 10 yr M 0.5204, S 0.0259; girls
    0.5224, 0.0271), drawn with their own z; a child without the key gets the median, where
    MakeHuman's age macro gave a 12-yr-old boy 0.538 (2 SD long in the trunk)."""
    from humv_usd.human.proportions import child_sitting_height_ratio

    people = sample_people(4000, seed=11, age_yr=(9.9, 10.1))
    for sex, (m, s_) in {"male": (0.5204, 0.0259), "female": (0.5224, 0.0271)}.items():
        r = np.array([p["sitting_height_ratio"] for p in people if p["sex"] == sex])
        assert np.median(r) == pytest.approx(m, abs=0.001)
        assert r.std() == pytest.approx(m * s_, rel=0.08)
    # a toddler's median (0.648 at 1 yr) is clipped to the accepted range
    assert child_sitting_height_ratio("female", 1.0) == 0.60
    assert child_sitting_height_ratio("male", 12.0) == pytest.approx(0.5126, abs=1e-6)
    boy = build_body("male", 12.0, 1.491, 41.0)
    assert boy.sitting_height_ratio == pytest.approx(0.5126, abs=2e-3)
    assert boy.requested["sitting_height_ratio"] is None  # the request stays the user's
    assert build_body("male", 30.0, 1.78, 80.0).sitting_height_ratio > 0.52  # adults: MakeHuman's


def test_population_hair_colours_grey_with_age():
    young = sample_people(400, seed=3, age_yr=(20.0, 35.0))
    old = sample_people(400, seed=3, age_yr=(75.0, 90.0))
    assert not any(p["hair_color"] == "grey" for p in young)
    assert {p["hair_color"] for p in young} == set(PIGMENTED_HAIR)
    grey = np.mean([p["hair_color"] == "grey" for p in old])
    assert 0.7 < grey < 0.9  # min(0.8, (age - 40) / 40) = 0.8 from 72 yr on
    assert set(PIGMENTED_HAIR) | {"grey"} == set(HAIR_COLOURS)


def test_clothing_reads_the_requested_ratio():
    stage = Usd.Stage.CreateInMemory()
    prim = UsdSkel.Root.Define(stage, human_path("p1")).GetPrim()
    assert fit_sitting_height_ratio(stage, "p1") is None
    prim.SetCustomDataByKey(FIT_DATA, {"sittingHeightRatioRequested": 0.51})
    assert fit_sitting_height_ratio(stage, "p1") == 0.51
    prim.SetCustomDataByKey(FIT_DATA, {"sittingHeightRatioRequested": 2.0})
    assert fit_sitting_height_ratio(stage, "p1") is None
    assert fit_sitting_height_ratio(stage, "nobody") is None
