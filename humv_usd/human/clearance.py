"""Arm clearance: the arms kept out of the trunk in any motion (issue 25, deliverable 2).

Why: the procedural motions hang the arms 9-12 deg (walk, run) or 18 deg (stand) from the
vertical, the key poses and motion-capture clips have their own arm angles, and bodies differ
(a heavy body's arm meets its trunk at a larger angle). Where the skeleton's upper arm passes
close to the trunk, the skinned arm goes into it. ``humv-usd bench skinning``
(:mod:`humv_usd.bench.skinning`) on the demo body over a 3 s walk: 92 body vertices (1 mm off
their own skin) inside the body, 52 of them on the arms, and 40 T-shirt triangle centres inside
the body; after :func:`clear_arms` 28, 7 and 0. Dual quaternion skinning (Kavan et al. 2008;
:func:`humv_usd.human.skeleton.dual_quaternion_skinning`) removes linear blending's volume loss
but not this: 92 and 47 on the arms (the bench prints both for every activity; 0-20 % fewer,
sitting more), because the pose *places* the arm in the trunk; the blend does not collapse it
there. A real arm rests against the trunk and
the soft tissue flattens. A surface model without contact deformation has to hold the arm off.

What :func:`clear_arms` does, per checked frame and side:

1. Test points: the skin vertices bound to the ``{side}Arm`` and ``{side}ForeArm`` joints by
   more than :data:`ARM_WEIGHT` (not the hand, which may rest on the body; not those inside the
   body at rest), each moved :data:`MARGIN` along its normal.
2. A test point is inside the trunk when the first trunk surface along its path is
   hit from inside (the ray leaves through an outward face). The trunk is the body's vertices
   bound to the trunk joints (:data:`TRUNK`) and to neither arm. The abduction path is the
   tangent ``a x (p - shoulder)``, where ``a`` is the forward axis of the parent
   ``{side}Shoulder`` joint, which follows the trunk.
3. The angle still needed is the largest hit distance over its lever ``|a x (p - shoulder)|``.
   Points nearer the axis than :data:`MIN_LEVER`, and hits farther than :data:`MAX_DEPTH` (the
   ray left through the trunk's opening at the shoulder), are ignored.
4. The arm is abducted by that angle (at most :data:`MAX_STEP` per round) about ``a``, by
   premultiplying the ``{side}Arm`` joint's local rotation, and the test repeats, at most
   :data:`ITERATIONS` times and up to :data:`MAX_ABDUCTION`.

Arms whose hands hold something (the box of the ``carry`` activity, the rifle carry, a held
prop) are turned the same way about another axis (``mode="swivel"``): the shoulder-wrist line,
signed so that the elbow moves out to the side. The ``{side}Hand`` joint's local rotation is
turned back by the same angle, so the wrist stays where it was and the hand keeps its world
rotation (the grip is exact; only the elbow swings out, as a person carrying a box holds the
elbows off the sides).

Frames are checked every ``1 / CHECK_HZ`` s. The angles are dilated by one checked frame on
each side, interpolated linearly in time and applied to every frame, so the arm moves smoothly
(a walking arm swings at ~1 Hz). Frames whose arms clear the trunk, and which are not next to
one that does not, keep their rotations bit for bit.

Everything is a joint rotation, so every consumer (the render, the thermal tool, the labels,
Blender) skins the same arms with UsdSkel's linear blend.

Not done:

- Points the swivel moves along the trunk rather than out of it (the back of the armpit, near
  the shoulder-wrist line) stay.
- Flexion creases are contact that needs soft-tissue deformation (pose-space corrective shapes),
  not a joint angle: the belly against the thighs in a deep sit or crouch (1-5 cm deep), calf
  against thigh in a kneel, the inner elbow of a flexed arm, the armpit's own fold (< 2 mm).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from humv_usd.geometry.mesh import vertex_normals
from humv_usd.geometry.raycast import RayCaster
from humv_usd.human.skeleton import (
    Skeleton,
    forward_kinematics,
    skinning_matrices,
)

#: Skin clearance kept between the upper arm and the trunk [m]: two garment layers compressed to
#: their minimum gap (:data:`humv_usd.catalog.garments.MINIMUM_GAP`, 2 mm) plus their fabric.
MARGIN = 0.005
#: A vertex is tested when its weight on the ``{side}Arm`` and ``{side}ForeArm`` joints exceeds
#: this (the upper arm and the forearm; not the hand, which may rest on the body).
ARM_WEIGHT = 0.5
#: Largest abduction added [rad] (a heavy body walking needs ~10 deg more than a slim one).
MAX_ABDUCTION = np.radians(30.0)
#: Test-and-abduct rounds per checked frame.
ITERATIONS = 4
#: Rate [Hz] at which frames are checked (the angles are interpolated between).
CHECK_HZ = 5.0
SIDES = ("Left", "Right")


#: Joints of the trunk the arms are kept off (the surface hit for the depth); its vertices bound
#: to an arm by more than :data:`ARM_WEIGHT` are left out.
TRUNK = ("Hips", "LowerBack", "Spine", "Spine1", "LeftShoulder", "RightShoulder")
#: Upper-arm test points closer than this to the abduction axis [m] are not tested: the
#: armpit's own fold turns about the joint, and abducting cannot open it.
MIN_LEVER = 0.04
#: A trunk surface farther than this along the path [m] is not a penetration (the ray left
#: through the trunk's opening at the shoulder; the arms measured go <= 1.5 cm deep).
MAX_DEPTH = 0.03
#: Largest angle added per round [rad]: one stray ray cannot swing the arm out at once.
MAX_STEP = np.radians(10.0)


@dataclasses.dataclass(frozen=True)
class ArmBody:
    """What :func:`clear_arms` needs of a body: its rest mesh, skin binding and the arm sets."""

    points: np.ndarray  # (V, 3) rest points of the skinned body mesh [m]
    normals: np.ndarray  # (V, 3) rest vertex normals
    indices: np.ndarray  # (V, k) joint indices
    weights: np.ndarray  # (V, k) joint weights
    arm: dict  # side -> vertex ids of the upper arm (tested)
    trunk_vertices: np.ndarray  # vertex ids of the trunk (no weight on either arm)
    trunk_triangles: np.ndarray  # (T', 3) trunk triangles, indices into trunk_vertices


def arm_body(skeleton: Skeleton, points, triangles, indices, weights) -> ArmBody:
    """The :class:`ArmBody` of a skinned body mesh (rest points, triangles, skin binding)."""
    points = np.asarray(points, dtype=np.float64)
    triangles = np.asarray(triangles, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    idx = np.asarray(indices)
    normals = vertex_normals(points, triangles)
    rest_inside = RayCaster(points, triangles).inside(points + MARGIN * normals)
    dominant = idx[np.arange(len(idx)), np.argmax(w, axis=1)]
    arm, on_arms = {}, np.zeros(len(points), dtype=bool)
    for side in SIDES:
        j = skeleton.index(f"{side}Arm")
        chain = [k for k in range(len(skeleton.names)) if _descends(skeleton, k, j)]
        limb = [j, skeleton.index(f"{side}ForeArm")]
        on_arm = np.sum(np.where(np.isin(idx, limb), w, 0.0), axis=1)
        on_arms |= np.sum(np.where(np.isin(idx, chain), w, 0.0), axis=1) > ARM_WEIGHT
        arm[side] = np.flatnonzero((on_arm > ARM_WEIGHT) & ~rest_inside)
    is_trunk = np.isin(dominant, [skeleton.index(n) for n in TRUNK]) & ~on_arms
    keep = is_trunk[triangles].all(axis=1)
    verts = np.unique(triangles[keep])
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[verts] = np.arange(len(verts))
    return ArmBody(points, normals, idx, w, arm, verts, remap[triangles[keep]])


def _descends(skeleton: Skeleton, k: int, j: int) -> bool:
    while k >= 0:
        if k == j:
            return True
        k = int(skeleton.parents[k])
    return False


def _quat_axis(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions of rotations by ``angle`` (n,) about unit ``axis`` (n, 3)."""
    h = 0.5 * np.asarray(angle, dtype=np.float64)[:, None]
    return np.concatenate([np.cos(h), np.sin(h) * axis], -1)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    return np.concatenate(
        [aw * bw - np.sum(av * bv, -1, keepdims=True), aw * bv + bw * av + np.cross(av, bv)], -1
    )


#: Abduction axis sign per side: Left about -Y, Right about +Y (away from the midline).
_AXIS = {"Left": -1.0, "Right": 1.0}
#: How :func:`clear_arms` moves an arm: ``abduct`` (about the shoulder's forward axis: the hand
#: moves out too) or ``swivel`` (about the shoulder-wrist line: the elbow swings out, the wrist
#: stays where it is and the hand keeps its world orientation, for hands that hold something).
MODES = ("abduct", "swivel")


def arm_axes(skeleton: Skeleton, world: np.ndarray, mode: str) -> dict:
    """Per side the unit world axis (F, 3) about which a positive angle moves the arm away from
    the trunk, for world joint transforms ``world`` (F, J, 4, 4) of the pose before clearing."""
    out = {}
    for side, sign in _AXIS.items():
        j = skeleton.index(f"{side}Arm")
        parent = world[:, int(skeleton.parents[j]), :3, :3]
        if mode == "abduct":
            out[side] = sign * parent[:, :, 1]
            continue
        shoulder = world[:, j, :3, 3]
        line = world[:, skeleton.index(f"{side}Hand"), :3, 3] - shoulder
        axis = line / np.maximum(np.linalg.norm(line, axis=1, keepdims=True), 1e-9)
        elbow = world[:, skeleton.index(f"{side}ForeArm"), :3, 3] - shoulder
        outward = -sign * parent[:, :, 0]  # the side's lateral direction (Left: +X)
        turn = np.einsum("fi,fi->f", np.cross(axis, elbow), outward)
        out[side] = axis * np.where(turn < 0, -1.0, 1.0)[:, None]
    return out


def _rotated(local: np.ndarray, skeleton: Skeleton, world: np.ndarray, axes: dict, angles: dict, mode: str):
    """``local`` (F, J, 4) with each side's arm turned by ``angles[side]`` (F,) about the world
    axis ``axes[side]`` (F, 3) through the shoulder; ``world`` is the unturned pose's (F, J, 4, 4).
    In ``swivel`` mode the hand's local rotation is turned back, so its world rotation stays."""
    out = local.copy()
    for side in SIDES:
        j = skeleton.index(f"{side}Arm")
        parent = world[:, int(skeleton.parents[j]), :3, :3]
        in_parent = np.einsum("fji,fj->fi", parent, axes[side])
        out[:, j] = _quat_mul(_quat_axis(in_parent, angles[side]), local[:, j])
        if mode == "swivel":
            h = skeleton.index(f"{side}Hand")
            forearm = world[:, int(skeleton.parents[h]), :3, :3]
            in_forearm = np.einsum("fji,fj->fi", forearm, axes[side])
            out[:, h] = _quat_mul(_quat_axis(in_forearm, -angles[side]), local[:, h])
    return out


def _skin(body: ArmBody, ids: np.ndarray, skin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear-blend skinned points and (rotated rest) normals of the vertices ``ids``."""
    w = body.weights[ids]
    blended = np.einsum("vk,vkij->vij", w, skin[body.indices[ids]])
    p = np.einsum("vij,vj->vi", blended[:, :3, :3], body.points[ids]) + blended[:, :3, 3]
    n = np.einsum("vij,vj->vi", blended[:, :3, :3], body.normals[ids])
    return p, n / np.linalg.norm(n, axis=1, keepdims=True)


def arm_penetration(body: ArmBody, skeleton: Skeleton, world: np.ndarray, axes: dict) -> dict:
    """Per side for one frame's world joint transforms (J, 4, 4) and arm axes (side -> (3,),
    :func:`arm_axes`): the arm's test points (skin + :data:`MARGIN` along the normal) inside the
    trunk, as (points, lever vectors ``a x (p - shoulder)``, distance to the trunk's surface
    along them [m])."""
    skin = skinning_matrices(skeleton, world[None])[0]
    tp, _ = _skin(body, body.trunk_vertices, skin)
    trunk = RayCaster(tp, body.trunk_triangles)
    out = {}
    for side in SIDES:
        p, n = _skin(body, body.arm[side], skin)
        test = p + MARGIN * n
        lever = np.cross(axes[side], test - world[skeleton.index(f"{side}Arm"), :3, 3])
        r = np.linalg.norm(lever, axis=1)
        d = lever / np.maximum(r, 1e-9)[:, None]
        face = trunk.intersects_first(test, d)
        hit = face >= 0
        exits = np.zeros(len(test), dtype=bool)
        if hit.any():
            a, b, c = (trunk.points[trunk.triangles[face[hit], k]] for k in range(3))
            exits[hit] = np.einsum("ij,ij->i", np.cross(b - a, c - a), d[hit]) > 0
        inside = exits & (r > MIN_LEVER)
        depth = trunk.hit_distance(test, d) if inside.any() else np.full(len(test), np.inf)
        inside &= depth < MAX_DEPTH
        out[side] = (test[inside], lever[inside], depth[inside])
    return out


def needed_angles(
    body: ArmBody, skeleton: Skeleton, local: np.ndarray, root: np.ndarray, mode: str = "abduct"
) -> dict:
    """Per side, the angle [rad] each frame of (``local`` (F, J, 4), ``root`` (F, 3)) needs its
    arm turned (``mode``, :data:`MODES`) to clear the trunk by :data:`MARGIN` (0 where it does)."""
    frames = len(local)
    world0 = forward_kinematics(skeleton, local, root)
    axes = arm_axes(skeleton, world0, mode)
    out = {s: np.zeros(frames) for s in SIDES}
    for f in range(frames):
        angle = {s: np.zeros(1) for s in SIDES}
        frame_axes = {s: axes[s][f : f + 1] for s in SIDES}
        for _ in range(ITERATIONS):
            q = _rotated(local[f : f + 1], skeleton, world0[f : f + 1], frame_axes, angle, mode)
            world = forward_kinematics(skeleton, q, root[f : f + 1])[0]
            pen = arm_penetration(body, skeleton, world, {s: axes[s][f] for s in SIDES})
            more = False
            for side in SIDES:
                _, lever, depth = pen[side]
                if not len(depth) or angle[side][0] >= MAX_ABDUCTION:
                    continue
                step = depth / np.linalg.norm(lever, axis=1)
                add = min(float(step.max()) + np.radians(0.25), MAX_STEP)
                angle[side] = np.minimum(angle[side] + add, MAX_ABDUCTION)
                more = True
            if not more:
                break
        for s in SIDES:
            out[s][f] = angle[s][0]
    return out


def clear_arms(motion, skeleton: Skeleton, body: ArmBody, report: dict | None = None, mode: str = "abduct"):
    """``motion`` (``local_rotations`` (F, J, 4), ``root_translation`` (F, 3), ``fps``) with
    each arm turned out where it would enter the trunk (see the module doc): abducted (``mode``
    "abduct") or, for hands that hold something, swivelled about the shoulder-wrist line with
    the hand kept in place ("swivel"). Frames that clear the trunk are unchanged. ``report`` (a
    dict) receives per side the largest angle added [deg] and the number of frames changed."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    local = np.asarray(motion.local_rotations, dtype=np.float64)
    root = np.asarray(motion.root_translation, dtype=np.float64)
    frames = len(local)
    step = max(int(round(float(getattr(motion, "fps", CHECK_HZ)) / CHECK_HZ)), 1)
    checked = np.unique(np.r_[np.arange(0, frames, step), frames - 1])
    need = needed_angles(body, skeleton, local[checked], root[checked], mode)
    angles = {}
    for side in SIDES:
        a = need[side]
        if len(a) > 1:  # dilate by one checked frame: the swing between two checks is covered
            a = np.maximum(a, np.maximum(np.r_[a[1:], a[-1]], np.r_[a[0], a[:-1]]))
        angles[side] = np.interp(np.arange(frames), checked, a)
        if report is not None:
            report[side] = {
                "max_deg": round(float(np.degrees(angles[side].max())), 3),
                "frames": int(np.count_nonzero(angles[side])),
            }
    if not any(np.any(a > 0) for a in angles.values()):
        return motion
    world = forward_kinematics(skeleton, local, root)
    out = _rotated(local, skeleton, world, arm_axes(skeleton, world, mode), angles, mode)
    keep = np.all([angles[s] == 0 for s in SIDES], axis=0)
    out[keep] = local[keep]
    if hasattr(motion, "local_rotations") and dataclasses.is_dataclass(motion):
        return dataclasses.replace(motion, local_rotations=out)
    return dataclasses.replace(motion, rotations=out)
