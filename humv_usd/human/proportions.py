"""Leg length against the trunk: the sitting-height ratio on MakeHuman's leg-height targets.

The ratio of sitting height to stature (Cormic index) is the commonest measure of how long the
legs are for a person's height. MakeHuman's macros fix it by sex and age (its young man ~0.525,
its young woman ~0.541, i.e. shorter-legged than ANSUR II's women by about one SD). A requested
ratio is reached with a *leg axis* L of the CC0 targets ``legs/upperlegs-height-{incr,decr}`` and
``legs/lowerlegs-height-{incr,decr}`` (equal weights |L|; L > 0 longer legs), while the height
macro keeps the stature and the weight/fat axis the volume (:func:`humv_usd.human.body.build_body`).

On the standing mesh the sitting height is measured as ``stature - crotch height + offset``:
the crotch is the lowest point of the body's mid-plane between the legs, and the offset is
ANSUR II's mean of ``sittingheight - (stature - crotchheight)``, 8.0 mm for men and 10.5 mm for
women (SD 16.6 / 14.6 mm; the two measures correlate at r = 0.77 / 0.81). ANSUR II: Gordon CC et
al. (2014) "2012 Anthropometric Survey of U.S. Army Personnel: Methods and Summary Statistics",
NATICK/TR-15/007, computed from the public data files (``ANSUR II MALE/FEMALE Public.csv``).
"""

from __future__ import annotations

import gzip
from functools import cache

import numpy as np

from humv_usd.assets import makehuman_dir
from humv_usd.human.basemesh import _MH_TO_USD
from humv_usd.human.macro import obj_data, parse_target

#: ANSUR II mean sittingheight - (stature - crotchheight) [m] per sex (module doc)
SITTING_MINUS_UPPER_BODY_M = {"male": 0.0080, "female": 0.0105}
LEG_TARGETS = ("legs/upperlegs-height-{d}", "legs/lowerlegs-height-{d}")
#: the leg axis stays within MakeHuman's slider range
MAX_LEG = 1.0
#: accepted requests [-]: ANSUR II's adults span 0.47-0.58 (men and women, min-max)
SITTING_HEIGHT_RATIO_RANGE = (0.45, 0.60)


#: Children's sitting height / stature by age (Cole's LMS, the Fourth Dutch Growth Study): Fredriks
#: AM, van Buuren S, van Heel WJM, Dijkman-Neerincx RHM, Verloove-Vanhorick SP, Wit JM (2005)
#: "Nationwide age references for sitting height, leg length, and sitting height/height ratio,
#: and their diagnostic value for disproportionate growth disorders", Arch Dis Child 90:807-812;
#: the yearly rows (ages 0-21 yr) of the published LMS table as the AGD R package (van Buuren)
#: ships it (``nl4.shh``; ``references/data/slnj.txt`` boys, ``slnm.txt`` girls): L constant
#: per sex, then M and S at ages 0, 1, ..., 21 yr.
CHILD_SITTING_HEIGHT_RATIO_LMS = {
    "male": (
        5.2236,
        (
            0.692,
            0.6481,
            0.6036,
            0.5719,
            0.5548,
            0.5459,
            0.5406,
            0.5359,
            0.5308,
            0.5255,
            0.5204,
            0.516,
            0.5126,
            0.509,
            0.5077,
            0.5097,
            0.5118,
            0.5133,
            0.5149,
            0.5164,
            0.516,
            0.513,
        ),
        (
            0.0335,
            0.0337,
            0.0337,
            0.0333,
            0.0325,
            0.0314,
            0.0302,
            0.0289,
            0.0277,
            0.0267,
            0.0259,
            0.0254,
            0.0252,
            0.0253,
            0.0256,
            0.0261,
            0.0267,
            0.0273,
            0.0279,
            0.0284,
            0.029,
            0.0295,
        ),
    ),
    "female": (
        4.723,
        (
            0.6926,
            0.6484,
            0.6013,
            0.5679,
            0.5526,
            0.5462,
            0.5413,
            0.5357,
            0.5306,
            0.5263,
            0.5224,
            0.5187,
            0.5161,
            0.5159,
            0.5184,
            0.5218,
            0.5239,
            0.5244,
            0.5244,
            0.5251,
            0.5256,
            0.5263,
        ),
        (
            0.036,
            0.0361,
            0.0356,
            0.0348,
            0.0336,
            0.0322,
            0.0307,
            0.0294,
            0.0283,
            0.0275,
            0.0271,
            0.0269,
            0.0269,
            0.0269,
            0.027,
            0.0269,
            0.0269,
            0.0269,
            0.0268,
            0.0268,
            0.0267,
            0.0267,
        ),
    ),
}
#: below this age [yr] a body without a requested ratio takes the children's reference median
#: (MakeHuman's age macro gave legs too short for the trunk: a 12-yr-old boy 0.538 against 0.513)
CHILD_RATIO_MAX_AGE_YR = 20.0


def child_sitting_height_ratio(sex: str, age_yr: float, z: float = 0.0) -> float:
    """Sitting height / stature of a child of ``age_yr`` at z-score ``z`` (Fredriks et al. 2005,
    :data:`CHILD_SITTING_HEIGHT_RATIO_LMS`, linear in age between the yearly rows), M (1 + L S
    z)^(1/L) (Cole 1990), clipped to :data:`SITTING_HEIGHT_RATIO_RANGE` (toddlers below ~2 yr
    exceed 0.60)."""
    lam, m_rows, s_rows = CHILD_SITTING_HEIGHT_RATIO_LMS[sex]
    ages = np.arange(len(m_rows), dtype=float)
    m = float(np.interp(age_yr, ages, m_rows))
    s = float(np.interp(age_yr, ages, s_rows))
    value = m * max(1.0 + lam * s * float(z), 1e-9) ** (1.0 / lam)
    lo, hi = SITTING_HEIGHT_RATIO_RANGE
    return float(np.clip(value, lo, hi))


@cache
def leg_delta(direction: str) -> np.ndarray:
    """Sum of the two leg-height targets (``direction`` 'incr' or 'decr') as full base.obj
    offsets (19158, 3) in MakeHuman units."""
    verts, _ = obj_data()
    out = np.zeros_like(verts)
    for name in LEG_TARGETS:
        raw = gzip.decompress(
            (makehuman_dir() / "targets" / f"{name.format(d=direction)}.target.gz").read_bytes()
        )
        idx, delta = parse_target(raw)
        out[idx] += delta
    out.flags.writeable = False
    return out


@cache
def crotch_candidates() -> np.ndarray:
    """Body vertex ids on the mid-plane (|x| < 0.1 mm in base.obj) between 30 % and 60 % of the
    body's height: the crotch is the lowest of them on any body (shared topology)."""
    verts, groups = obj_data()
    body = np.unique(groups["body"])
    p = verts[body] @ _MH_TO_USD.T
    z = (p[:, 2] - p[:, 2].min()) / np.ptp(p[:, 2])
    ids = body[(np.abs(p[:, 0]) < 1e-4) & (z > 0.3) & (z < 0.6)]
    ids.flags.writeable = False
    return ids


def sitting_height_m(points: np.ndarray, body_ids: np.ndarray, sex: str) -> float:
    """Sitting height [m] of a standing body in our frame (Z up, metres): stature - crotch
    height + ANSUR II's offset (module doc). ``points`` the full base.obj vertex list."""
    zb = points[body_ids, 2]
    crotch = points[crotch_candidates(), 2].min()
    return float(zb.max() - crotch + SITTING_MINUS_UPPER_BODY_M[sex])


def check_sitting_height_ratio(value: float) -> float:
    lo, hi = SITTING_HEIGHT_RATIO_RANGE
    v = float(value)
    if not lo <= v <= hi:
        raise ValueError(f"sitting_height_ratio must be in [{lo}, {hi}], not {value}")
    return v
