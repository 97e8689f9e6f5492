"""Hands on the ground of imported motion held where they support the body (a crawl).

:func:`humv_usd.human.contact.lock_feet` plants the feet of a motion-capture clip; a crawl also
rests on its knees and hands. Retargeted onto our body, the DeepMimic crawl's support hands
hovered 3-10 cm above the ground (the DeepMimic humanoid's hands are spheres at the wrists, ours
are MakeHuman hands with fingers): the hands never touched it.

:func:`lock_hands` finds the support runs of each knee and hand from the body's skinned
sample points (:func:`humv_usd.human.poses.body_points`, groups ``<side>Knee`` and
``<side>Hand``, the hand with the forearm's end at the wrist): a knee rests where its lowest point is within :data:`KNEE_NEAR_M` of the ground,
a hand where its lowest point is within :data:`HAND_NEAR_M` and the wrist moves slower than
:data:`humv_usd.human.contact.LOCK_SPEED_M_S` (runs shorter than 0.1 s dropped, gaps up to
0.07 s bridged: :func:`humv_usd.human.contact.clean_stance`). Within a hand's run the hand *rolls
without slipping*, as a locked foot does: from frame to frame its lowest point (the pivot) keeps
its horizontal place, the run is planted at its mean place, and the lowest point is put on the
ground in every frame; the hand is first laid flat, its palm (:func:`humv_usd.human.carry.palm_frame`)
turned to face the ground by the least rotation; the corrections are blended in and out by minimum jerk
(:func:`humv_usd.human.contact._bridge`, 0.25 s fades), never below the ground between runs, and
reached by the two-bone arm IK (:func:`humv_usd.human.poses.arm_ik`, the hand's orientation and
the elbow's side kept).

The knees are found but not moved: holding a knee in place needs the hips to move over it (the
thigh's length fixes the knee's distance from the hip; turning the thigh alone put the knee on the
ground but left it sliding 86-114 mm within a support run, the clip's own 169 mm). That needs the
root re-planned, which is not done.
"""

from __future__ import annotations

import numpy as np

from humv_usd.human import contact as C
from humv_usd.human.carry import palm_frame
from humv_usd.human.gait import align_matrix, fk_matrices, matrix_to_quat, quat_slerp
from humv_usd.human.poses import BodyPoints, arm_ik
from humv_usd.human.skeleton import Skeleton, quat_to_matrix

#: a knee rests on the ground where its lowest point is this close to it [m] (as a foot:
#: contact.LOCK_NEAR_M)
KNEE_NEAR_M = C.LOCK_NEAR_M
#: a hand supports where its lowest point is this close to the ground [m] and its wrist is slow
#: (retargeted DeepMimic crawl: support hands 6-10 cm above the ground, swinging hands 15-25 cm)
HAND_NEAR_M = 0.12
#: a hand leaving or reaching the ground clears it by up to LIFT_M [m], reached LIFT_S [s] from
#: its support run (as the poses' hands: humv_usd.human.poses.HAND_LIFT_M)
LIFT_M = 0.04
LIFT_S = 0.1
#: passes of the hand correction
HAND_PASSES = 3


def _pivot_offsets(
    ground: C.Ground, pts: np.ndarray, mask: np.ndarray, fps: float, floor: np.ndarray | None = None
) -> np.ndarray:
    """(F, 3) corrections of a body part (its points ``pts`` (F, n, 3)) that keep its lowest point
    in place horizontally over each run of ``mask`` (planted at the run's mean place) and on the
    ground, blended between runs and faded out beyond them."""
    frames = len(pts)
    h = pts[..., 2] - ground.height(pts[..., :2])
    off = np.zeros((frames, 3))
    for a, b in C.intervals(mask):
        for f in range(a + 1, b):
            k = int(np.argmin(h[f]))  # the pivot stays where it was in the frame before
            off[f, :2] = off[f - 1, :2] - (pts[f, k, :2] - pts[f - 1, k, :2])
        off[a:b, :2] -= off[a:b, :2].mean(axis=0)
        off[a:b, 2] = -h[a:b].min(axis=1)
    fade, longest = C._fade_frames(fps)
    off = C._bridge(off, mask, fade, longest)
    # between runs lifted off the ground as it leaves and before it lands (LIFT_M within
    # LIFT_S of a run), never below it
    idx = np.arange(frames)
    on = np.flatnonzero(mask)
    since = np.min(np.abs(idx[:, None] - on[None, :]), axis=1) / fps if len(on) else np.full(frames, np.inf)
    clear = LIFT_M * np.clip(since / LIFT_S, 0.0, 1.0) ** 2 * (3 - 2 * np.clip(since / LIFT_S, 0.0, 1.0))
    moved = pts + off[:, None, :]
    dip = np.max(ground.height(moved[..., :2]) - moved[..., 2], axis=1)
    own = np.max(ground.height(pts[..., :2]) - pts[..., 2], axis=1)
    want = clear
    off[:, 2] += np.where(mask, 0.0, np.maximum(dip + want, 0.0))
    if floor is not None:  # other points moved with the part (the forearm) kept off the ground
        moved = floor + off[:, None, :]
        dip = np.max(ground.height(moved[..., :2]) - moved[..., 2], axis=1)
        own = np.max(ground.height(floor[..., :2]) - floor[..., 2], axis=1)
        off[:, 2] += np.maximum(dip - np.maximum(own, 0.0), 0.0)
    return off


#: the wrist's end of the forearm rests on the ground with the hand (points this close to the
#: wrist joint in the rest pose count as the hand's) [m]
WRIST_REACH_M = 0.08


def hand_points(skeleton: Skeleton, points: BodyPoints, side: str) -> np.ndarray:
    """Indices of the sample points of ``side``'s hand and of its forearm next to the wrist."""
    near = np.linalg.norm(points.rest - skeleton.rest_positions[skeleton.index(f"{side}Hand")], axis=1)
    return np.union1d(points.groups[f"{side}Hand"], np.flatnonzero(near < WRIST_REACH_M))


def forearm_points(skeleton: Skeleton, points: BodyPoints, side: str) -> np.ndarray:
    """Indices of the sample points skinned mostly to ``side``'s ForeArm joint."""
    main = points.indices[np.arange(len(points.indices)), np.argmax(points.weights, axis=1)]
    return np.flatnonzero(main == skeleton.index(f"{side}ForeArm"))


def support_runs(
    skeleton: Skeleton, ground: C.Ground, points: BodyPoints, posed: np.ndarray, wpos: np.ndarray, fps: float
) -> dict[str, np.ndarray]:
    """Per knee and hand (``LeftKnee``, ..., ``RightHand``): (F,) bool, where it supports the body."""
    out = {}
    for side in C.SIDES:
        for part, near in (("Knee", KNEE_NEAR_M), ("Hand", HAND_NEAR_M)):
            ids = hand_points(skeleton, points, side) if part == "Hand" else points.groups[f"{side}Knee"]
            q = posed[:, ids]
            low = (q[..., 2] - ground.height(q[..., :2])).min(axis=1)
            m = low <= near
            if part == "Hand":
                w = wpos[:, skeleton.index(f"{side}Hand"), :2]
                speed = np.linalg.norm(np.gradient(w, axis=0), axis=1) * fps
                m &= speed <= C.LOCK_SPEED_M_S
            out[f"{side}{part}"] = C.clean_stance(m, fps)
    return out


def lock_hands(
    skeleton: Skeleton,
    ground: C.Ground,
    points: BodyPoints,
    local: np.ndarray,
    root_rot: np.ndarray,
    root_pos: np.ndarray,
    fps: float,
) -> tuple[np.ndarray, dict]:
    """New local rotations (F, J, 3, 3) with the supporting hands held on the ground, and the
    support runs of the knees and hands (name -> (F,) bool; the knees are found, not moved)."""
    out = local.copy()
    wrot, wpos = fk_matrices(skeleton, out, root_rot, root_pos)
    posed = points.posed(wrot, wpos, skeleton)
    runs = support_runs(skeleton, ground, points, posed, wpos, fps)
    # a supporting hand is laid flat, its palm facing the ground (the clip's hand turned by the
    # least rotation that does it, blended in and out as the corrections are)
    fade, longest = C._fade_frames(fps)
    down = np.array([0.0, 0.0, -1.0])
    for side in C.SIDES:
        m = runs[f"{side}Hand"]
        if not m.any():
            continue
        j = skeleton.index(f"{side}Hand")
        normal = palm_frame(skeleton, points.rest[points.groups[f"{side}Hand"]], side).normal
        w = C._bridge(np.ones(len(m)), m, fade, longest)
        rows = np.flatnonzero(w > 0)
        flat = align_matrix(wrot[rows, j] @ normal, np.broadcast_to(down, (len(rows), 3))) @ wrot[rows, j]
        q = quat_slerp(matrix_to_quat(wrot[rows, j]), matrix_to_quat(flat), w[rows])
        arm_ik(skeleton, side, wrot, wpos, out, rows, wpos[rows, j], quat_to_matrix(q))
    wrot, wpos = fk_matrices(skeleton, out, root_rot, root_pos)
    posed = points.posed(wrot, wpos, skeleton)
    # the wrist moved by the correction, the arm by IK, the hand's orientation kept; the
    # forearm's end turns with the IK, so each pass corrects what the one before left
    for _ in range(HAND_PASSES):
        for side in C.SIDES:
            m = runs[f"{side}Hand"]
            if not m.any():
                continue
            j = skeleton.index(f"{side}Hand")
            off = _pivot_offsets(
                ground,
                posed[:, hand_points(skeleton, points, side)],
                m,
                fps,
                posed[:, forearm_points(skeleton, points, side)],
            )
            rows = np.flatnonzero(np.linalg.norm(off, axis=1) > 1e-6)
            arm_ik(skeleton, side, wrot, wpos, out, rows, wpos[rows, j] + off[rows], wrot[rows, j])
        wrot, wpos = fk_matrices(skeleton, out, root_rot, root_pos)
        posed = points.posed(wrot, wpos, skeleton)
    return out, runs
