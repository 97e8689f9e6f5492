"""Skinning bench: where the posed body and its garments intersect the body, per activity.

Issue 25, deliverable 2 ("armpits without intersections"). For each activity over a motion
clip (the built-in activities and the motion-capture clips fetched at set-up), at ``samples``
frames spread evenly inside it (not on the clearance's checked frames), three ways of posing the same body:

- ``lbs``: the activity's motion, linear blend skinning (what UsdSkel, the render, the thermal
  tool, the labels and Blender compute: ``skel:skinningMethod`` is the default
  ``classicLinear``);
- ``dqs``: the same motion, dual quaternion skinning (Kavan et al. 2008;
  :func:`humv_usd.human.skeleton.dual_quaternion_skinning`, which is what UsdSkel computes for
  ``skel:skinningMethod = "dualQuaternion"``);
- ``cleared``: the motion after :func:`humv_usd.human.clearance.clear_arms` (what the avatar
  tool authors), linear blend skinning.

Measures, each the largest over the sampled frames:

- ``body_inside``: body vertices moved 1 mm out along their normal that lie inside the posed
  body (generalized winding number > ½ by signed ray crossings, three directions, median),
  less those inside already at rest (the base mesh's own folds at the lips, ears and toes);
  ``by_part``: the same at the worst frame, by the vertex's dominant joint (arm, trunk, leg,
  head);
- ``garment_inside`` (``lbs`` and ``cleared``): per garment, triangle centres of the dressed and
  fixed garment (:func:`humv_usd.clothing.collide.simulate`, as the clothing tool) inside the
  posed body.

``humv-usd bench skinning [--activities walk,sit] [--samples 6] [--no-garments]`` prints the
table; :func:`bench_skinning` returns it as a dict.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh
from trimesh.ray.ray_pyembree import RayMeshIntersector

from humv_usd.assets import mocap_dir
from humv_usd.clothing.collide import dress, simulate
from humv_usd.clothing.fit import prepare
from humv_usd.geometry.mesh import vertex_normals
from humv_usd.human.body import build_body
from humv_usd.human.bvh import motion_from_bvh
from humv_usd.human.carry import apply_rifle_carry
from humv_usd.human.clearance import arm_body, clear_arms
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import (
    dual_quaternion_skinning,
    forward_kinematics,
    linear_blend_skinning,
    skinning_matrices,
)

#: built-in activities measured by default (``<activity>+rifle``: with the rifle carry), then
#: the motion-capture clips (``bvh:<name>``)
ACTIVITIES = (
    "stand",
    "standTurn",
    "walk",
    "run",
    "carry",
    "walk+rifle",
    "sit",
    "sitChair",
    "crouch",
    "kneel",
    "wave",
    "bvh:deepmimic_walk",
    "bvh:deepmimic_run",
    "bvh:deepmimic_jump",
    "bvh:deepmimic_getup_faceup",
)
OUTFIT = ("tshirt_white", "shorts", "shoes")
#: directions of the signed ray crossings (median of the three winding numbers)
_DIRECTIONS = np.array([[0.267, 0.534, 0.802], [-0.577, 0.577, -0.577], [0.802, -0.267, 0.534]])
PARTS = {
    "arm": ("Arm", "ForeArm", "Hand", "Finger", "Thumb", "Index"),
    "leg": ("UpLeg", "Leg", "Foot", "Toe"),
    "head": ("Neck", "Head"),
}


def winding_numbers(points: np.ndarray, verts: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Winding number of each point w.r.t. the closed triangle mesh: the signed count of
    crossings of a ray (+1 leaving through an outward face), median of three directions. Counts
    2 inside two overlapping parts, where a parity test says 0."""
    mesh = trimesh.Trimesh(verts, triangles, process=False)
    caster = RayMeshIntersector(mesh)
    normals = mesh.face_normals
    out = []
    for d in _DIRECTIONS / np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True):
        tri, ray = caster.intersects_id(points, np.tile(d, (len(points), 1)), multiple_hits=True)[:2]
        out.append(np.bincount(ray, weights=np.sign(normals[tri] @ d), minlength=len(points)))
    return np.median(np.stack(out), axis=0)


def _part(name: str) -> str:
    for part, keys in PARTS.items():
        if any(k in name for k in keys):
            return part
    return "trunk"


def _motion(activity: str, skeleton, body, fps: float, frames: int):
    if activity.endswith("+rifle"):  # the activity with the two-handed rifle carry
        motion = _motion(activity.removesuffix("+rifle"), skeleton, body, fps, frames)
        return apply_rifle_carry(motion, skeleton, body)
    if activity.startswith("bvh:"):
        return motion_from_bvh(
            mocap_dir() / f"{activity[4:]}.bvh",
            skeleton,
            fps,
            frames,
            mass_kg=body.mass_kg,
            body_points=body.points,
        )
    return make_motion(activity, skeleton, fps, frames, mass_kg=body.mass_kg, body_points=body.points)


def bench_skinning(
    activities=ACTIVITIES,
    body_args=("male", 30.0, 1.78, 80.0),
    outfit=OUTFIT,
    seconds: float = 3.0,
    samples: int = 6,
    fps: float = 30.0,
    garments: bool = True,
) -> dict:
    """Intersection counts per activity and way of posing (see the module doc)."""
    body = build_body(*body_args)
    rig = prepare(body)
    skeleton = rig.skeleton
    rest = rig.mesh.points
    tris = rig.triangles
    idx, w = rig.joint_indices, rig.joint_weights
    rest_in = winding_numbers(rest + 1e-3 * vertex_normals(rest, tris), rest, tris) > 0.5
    dominant = idx[np.arange(len(idx)), np.argmax(w, axis=1)]
    part = np.array([_part(skeleton.names[j]) for j in dominant])
    arms = arm_body(skeleton, rest, tris, idx, w)
    outfit_fit = dress(rig, list(outfit)) if garments else None
    frames = int(round(seconds * fps)) + 1
    result = {"body": list(body_args), "outfit": list(outfit), "seconds": seconds, "samples": samples}
    for activity in activities:
        t0 = time.process_time()
        motion = _motion(activity, skeleton, body, fps, frames)
        report: dict = {}
        # hands on the box or the rifle keep their place: the avatar tool swivels those arms
        held = activity == "carry" or activity.endswith("+rifle")
        cleared = clear_arms(motion, skeleton, arms, report, mode="swivel" if held else "abduct")
        t_clear = time.process_time() - t0
        # frames inside the clip, off the clearance's 5 Hz checks (what the interpolation gives)
        last = len(motion.root_translation) - 1
        pick = (
            np.unique(np.linspace(0, last, samples + 2)[1:-1].round().astype(int))
            if last > 1
            else np.array([last])
        )
        row = {"arm_abduction_added_deg": {s: r["max_deg"] for s, r in report.items()}}
        row["clear_cpu_s"] = round(t_clear, 2)
        for how, m, skinner in (
            ("lbs", motion, linear_blend_skinning),
            ("dqs", motion, dual_quaternion_skinning),
            ("cleared", cleared, linear_blend_skinning),
        ):
            world = forward_kinematics(skeleton, m.local_rotations[pick], m.root_translation[pick])
            skin = skinning_matrices(skeleton, world)
            posed = np.stack([skinner(rest, idx, w, s) for s in skin])
            worst, worst_mask = -1, None
            for p in posed:
                inside = (winding_numbers(p + 1e-3 * vertex_normals(p, tris), p, tris) > 0.5) & ~rest_in
                if inside.sum() > worst:
                    worst, worst_mask = int(inside.sum()), inside
            entry = {
                "body_inside": worst,
                "by_part": {
                    k: int(np.sum(worst_mask & (part == k))) for k in ("arm", "trunk", "leg", "head")
                },
            }
            if garments and how != "dqs":
                sim = simulate(outfit_fit, skin, fps=fps * len(pick) / max(frames, 1))
                entry["garment_inside"] = {}
                for g in sim.garments:
                    t = g.fitted.triangles
                    most = 0
                    for f, p in enumerate(posed):
                        c = g.posed[f][t].mean(axis=1)
                        most = max(most, int(np.sum(winding_numbers(c, p, tris) > 0.5)))
                    entry["garment_inside"][g.name] = most
            row[how] = entry
        result[activity] = row
    return result


def table(result: dict) -> list[str]:
    """The bench's dict as text lines: one line per activity and way of posing."""
    lines = [
        f"body {result['body']}, outfit {', '.join(result['outfit'])}; the largest over "
        f"{result['samples']} frames of {result['seconds']} s",
        "activity                     how      body  (arm trunk leg head)  garment centres inside",
    ]
    for activity, row in result.items():
        if not isinstance(row, dict) or "lbs" not in row:
            continue
        for how in ("lbs", "dqs", "cleared"):
            e = row[how]
            parts = " ".join(f"{e['by_part'][k]:>3}" for k in ("arm", "trunk", "leg", "head"))
            garm = ", ".join(f"{k} {v}" for k, v in e.get("garment_inside", {}).items())
            lines.append(f"{activity:<28} {how:<8} {e['body_inside']:>4}  ({parts})  {garm}")
        add = ", ".join(f"{s} {v:.1f}" for s, v in row["arm_abduction_added_deg"].items())
        lines.append(
            f"{'':<28} arms turned out (abducted, or swivelled with the hands held) by up to {add} deg; clear_arms {row['clear_cpu_s']} CPU-s"
        )
    return lines
