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
