"""Clothing benchmark: fit an outfit, walk it, report intersection counts, air gaps and times.

``bench_outfit(["tshirt_white", "trousers", "jacket", "cap"])`` returns a dict (JSON-able):
per garment the vertex count, the max over frames of the vertices inside the skin / closer than
the minimum gap / closer than the layering requires, before and after the fix, and the min /
median air gap; and the median per-frame times of the whole frame (pose, check, fix, air gap,
inverse skinning) and of the check + fix alone. Speed targets belong here, not in unit tests.

Also: ``unrefined`` — the same counts with the garments on the helpers' resolution (without
:func:`humv_usd.clothing.fit.refine`), to show what the finer mesh over the neck and pelvis
changes; for a loose garment (``robe``) ``drape``: the hem's lag behind the skinned shape and
the edge strain, draped vs skinned; with the ``rifle``: ``carry`` — the rifle's clearance from
the body before/after :func:`humv_usd.human.carry.clear_rifle` and per frame after the fix;
``surface_misses`` (:func:`surface_misses`): refined (the default fix, vertices and
:func:`humv_usd.clothing.collide.push_between`), ``vertex_fix_only`` (before that pass),
``between_layers`` (the pass also off the inner garments) and unrefined, with the fix times.
The fix's CPU time (all threads) is reported next to the wall time (a loaded machine).
"""

from __future__ import annotations

import time

import numpy as np

from humv_usd.catalog.garments import garment
from humv_usd.clothing.collide import (
    LAYER_RADIUS,
    SHELL_COS,
    _flat_normals,
    apply,
    blend_transforms,
    drapes_of,
    dress,
    simulate,
)
from humv_usd.clothing.fit import prepare
from humv_usd.geometry.mesh import Surface
from humv_usd.human.body import build_body
from humv_usd.human.carry import apply_rifle_carry
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import forward_kinematics, skinning_matrices


def _counts(sim) -> dict:
    out = {}
    for a in sim.garments:
        c = a.counts
        out[a.name] = {
            "vertices": a.fitted.vertex_count,
            "before": {
                "inside": max(x.inside_before for x in c),
                "close": max(x.close_before for x in c),
                "layered": max(x.layered_before for x in c),
                "prop": max(x.prop_before for x in c),
            },
            "after": {
                "inside": max(x.inside_after for x in c),
                "close": max(x.close_after for x in c),
                "layered": max(x.layered_after for x in c),
                "prop": max(x.prop_after for x in c),
            },
            "air_gap_min_m": float(a.air_gap.min()),
            "air_gap_median_m": float(np.median(a.air_gap)),
        }
    return out


def surface_misses(rig, skin: np.ndarray, sim) -> dict:
    """Between the vertices: per garment, the max over frames of the surface samples (edge
    midpoints and fan-triangle centroids of the fixed mesh) inside the body, closer to it
    than the minimum gap, and inside a garment under it (over its faces, as
    :func:`humv_usd.clothing.collide.push_off_shell` defines "over", closer than its
    thickness). The fix checks vertices only: these are what a coarse mesh misses."""
    out = {
        a.name: {"samples": 0, "inside": 0, "close": 0, "layered": 0}
        for a in sim.garments
        if not a.fitted.garment.is_prop
    }
    for f in range(len(skin)):
        body = apply(blend_transforms(rig.joint_indices, rig.joint_weights, skin[f]), rig.mesh.points)
        surface = Surface(body, rig.triangles)
        inner: list = []
        for a in sim.garments:
            g = a.fitted
            if g.garment.is_prop:
                continue
            p = a.posed[f]
            e = np.unique(
                np.sort(np.stack([g.triangles, np.roll(g.triangles, -1, 1)], -1).reshape(-1, 2), axis=1),
                axis=0,
            )
            samples = np.concatenate([p[e].mean(axis=1), p[g.triangles].mean(axis=1)])
            d = surface.closest(samples).signed
            layered = np.zeros(len(samples), dtype=bool)
            for shell, flat, thickness in inner:
                near = shell.closest(samples)
                off = samples - near.point
                dist = np.linalg.norm(off, axis=1)
                along = np.abs(np.einsum("ij,ij->i", off, flat[near.triangle]))
                over = (dist < LAYER_RADIUS) & (along >= SHELL_COS * dist)
                layered |= over & (near.signed < thickness)
            r = out[a.name]
            r["samples"] = len(samples)
            r["inside"] = max(r["inside"], int(np.sum(d < 0)))
            r["close"] = max(r["close"], int(np.sum((d >= 0) & (d < g.garment.minimum_gap))))
            r["layered"] = max(r["layered"], int(layered.sum()))
            inner.append((Surface(p, g.triangles), _flat_normals(p, g.triangles), g.garment.thickness))
    return out


def bench_outfit(
    garments,
    sex: str = "male",
    stature_m: float = 1.78,
    mass_kg: float = 80.0,
    activity: str = "walk",
    fps: float = 30.0,
    frames: int = 30,
) -> dict:
    t0 = time.perf_counter()
    body = build_body(sex, 30.0, stature_m, mass_kg)
    rig = prepare(body)
    motion = make_motion(
        activity, rig.skeleton, fps, max(frames, 2), mass_kg=mass_kg, body_points=body.points
    )
    carry = None
    if any(garment(n).is_prop for n in garments):
        carry = {}
        motion = apply_rifle_carry(motion, rig.skeleton, body, report=carry)
    skin = skinning_matrices(
        rig.skeleton, forward_kinematics(rig.skeleton, motion.local_rotations, motion.root_translation)
    )[:frames]
    t1 = time.perf_counter()
    outfit = dress(rig, garments)
    t2 = time.perf_counter()
    sim = simulate(outfit, skin, fps=fps)
    out = {
        "body": {"sex": sex, "stature_m": stature_m, "mass_kg": mass_kg},
        "activity": activity,
        "frames": frames,
        "seconds": {
            "body_and_motion": t1 - t0,
            "fit": t2 - t1,
            "frame_median": float(np.median(sim.frame_seconds)),
            "fix_median": float(np.median(sim.fix_seconds)),
            "fix_cpu_median": float(np.median(sim.fix_cpu_seconds)),
        },
        "garments": _counts(sim),
    }
    coarse = simulate(dress(rig, garments, refined=False), skin, fps=fps)
    out["unrefined"] = {
        k: {"vertices": v["vertices"], "before": v["before"], "after": v["after"]}
        for k, v in _counts(coarse).items()
    }
    out["unrefined"]["seconds"] = {
        "frame_median": float(np.median(coarse.frame_seconds)),
        "fix_median": float(np.median(coarse.fix_seconds)),
    }
    vertex_only = simulate(outfit, skin, fps=fps, between=False)
    layered = simulate(outfit, skin, fps=fps, between_layers=True)
    out["surface_misses"] = {
        "refined": surface_misses(rig, skin, sim),
        "vertex_fix_only": surface_misses(rig, skin, vertex_only),
        "between_layers": surface_misses(rig, skin, layered),
        "unrefined": surface_misses(rig, skin, coarse),
    }
    out["surface_misses"]["seconds"] = {
        "vertex_fix_only": {
            "fix_median": float(np.median(vertex_only.fix_seconds)),
            "fix_cpu_median": float(np.median(vertex_only.fix_cpu_seconds)),
        },
        "between_layers": {
            "fix_median": float(np.median(layered.fix_seconds)),
            "fix_cpu_median": float(np.median(layered.fix_cpu_seconds)),
        },
    }
    for a in sim.garments:
        if a.skinned is not None:
            for d in drapes_of(a.fitted):
                lag = np.linalg.norm(a.posed[:, d.vertices] - a.skinned[:, d.vertices], axis=2)
                z = a.fitted.points[d.vertices, 2]
                hem = (z - z.min()) / max(float(np.ptp(z)), 1e-9) < 0.25

                def strain(p):
                    e = d.edges
                    q = p[:, d.vertices]
                    return np.abs(np.linalg.norm(q[:, e[:, 0]] - q[:, e[:, 1]], axis=2) / d.rest_length - 1)

                s_draped, s_skinned = strain(a.posed), strain(a.skinned)
                out.setdefault("drape", {})[a.name] = {
                    "vertices": len(d.vertices),
                    "hem_lag_median_m": float(np.median(lag[:, hem])),
                    "lag_max_m": float(lag.max()),
                    "strain_median": {
                        "draped": float(np.median(s_draped)),
                        "skinned": float(np.median(s_skinned)),
                    },
                    "strain_p95": {
                        "draped": float(np.quantile(s_draped, 0.95)),
                        "skinned": float(np.quantile(s_skinned, 0.95)),
                    },
                }
        if a.clearance is not None:
            out["carry"] = {
                "clearance_m": carry["clearance_m"],
                "min_distance_before_m": float(carry["minDistanceBefore_m"].min()),
                "inside_before": int(carry["insideBefore"].max()),
                "min_distance_after_m": float(carry["minDistanceAfter_m"].min()),
                "inside_after": int(carry["insideAfter"].max()),
                "offset_max_m": float(carry["offset_m"].max()),
                "layer_min_distance_m": float(a.clearance.min()),
                "layer_inside": int(a.body_inside.max()),
            }
    return out
