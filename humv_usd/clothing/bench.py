"""Clothing benchmark: fit an outfit, walk it, report intersection counts, air gaps and times.

``bench_outfit(["tshirt_white", "trousers", "jacket", "cap"])`` returns a dict (JSON-able):
per garment the vertex count, the max over frames of the vertices inside the skin / closer than
the minimum gap / closer than the layering requires, before and after the fix, and the min /
median air gap; and the median per-frame times of the whole frame (pose, check, fix, air gap,
inverse skinning) and of the check + fix alone. Speed targets belong here, not in unit tests.
"""
from __future__ import annotations

import time

import numpy as np

from humv_usd.avatar.body import build_body
from humv_usd.avatar.skeleton import forward_kinematics, skinning_matrices
from humv_usd.clothing.collide import dress, simulate
from humv_usd.clothing.fit import prepare


def bench_outfit(garments, sex: str = "male", stature_m: float = 1.78, mass_kg: float = 80.0,
                 activity: str = "walk", fps: float = 30.0, frames: int = 30) -> dict:
    t0 = time.perf_counter()
    body = build_body(sex, 30.0, stature_m, mass_kg)
    rig = prepare(body)
    from humv_usd.avatar.motion import make_motion
    motion = make_motion(activity, rig.skeleton, fps, frames, mass_kg=mass_kg,
                         body_points=body.points)
    skin = skinning_matrices(rig.skeleton, forward_kinematics(
        rig.skeleton, motion.local_rotations, motion.root_translation))
    t1 = time.perf_counter()
    outfit = dress(rig, garments)
    t2 = time.perf_counter()
    sim = simulate(outfit, skin)
    out = {"body": {"sex": sex, "stature_m": stature_m, "mass_kg": mass_kg},
           "activity": activity, "frames": frames,
           "seconds": {"body_and_motion": t1 - t0, "fit": t2 - t1,
                       "frame_median": float(np.median(sim.frame_seconds)),
                       "fix_median": float(np.median(sim.fix_seconds))},
           "garments": {}}
    for a in sim.garments:
        c = a.counts
        out["garments"][a.name] = {
            "vertices": a.fitted.vertex_count,
            "before": {"inside": max(x.inside_before for x in c),
                       "close": max(x.close_before for x in c),
                       "layered": max(x.layered_before for x in c)},
            "after": {"inside": max(x.inside_after for x in c),
                      "close": max(x.close_after for x in c),
                      "layered": max(x.layered_after for x in c)},
            "air_gap_min_m": float(a.air_gap.min()),
            "air_gap_median_m": float(np.median(a.air_gap)),
        }
    return out
