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

The knees are held by :func:`lock_knees` before the hands: a supporting knee rolls without
slipping on the ground as a hand does (its lowest point keeps its place, on the ground). The
thigh's length fixes the knee's distance from the hip, so turning the thigh alone cannot hold it
(s7: the knee on the ground but sliding 86-114 mm per support run); the root is re-planned over
the supporting knees: per frame the least root shift (a horizontal move weighing
:data:`ROOT_HORIZONTAL_WEIGHT` times a vertical one) that puts each supporting knee's hip at the
thigh's length from its planted knee (Gauss-Newton on the weighted norm with the knees as stiff
springs, eased in and out over the fades), the hips no lower than the rest of the body allows
(above the ground), then the thigh turned onto the knee and the shin held still in the run (its
mean orientation: the trailing foot stays put), each foot lifted clear of the ground by turning
its shin about the knee. The hands are locked after, on the re-planned root. Knee runs
that overlap a locked foot (a get-up standing up) are left as they are (the root shift would
move the planted foot).
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
    ground: C.Ground,
    pts: np.ndarray,
    mask: np.ndarray,
    fps: float,
    floor: np.ndarray | None = None,
    lift_m: float = LIFT_M,
) -> np.ndarray:
    """(F, 3) corrections of a body part (its points ``pts`` (F, n, 3)) that keep its lowest point
    in place horizontally over each run of ``mask`` (planted at the run's mean place) and on the
    ground, blended between runs and faded out beyond them; between runs it clears the ground
    by up to ``lift_m``."""
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
    clear = lift_m * np.clip(since / LIFT_S, 0.0, 1.0) ** 2 * (3 - 2 * np.clip(since / LIFT_S, 0.0, 1.0))
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


#: the thigh's and shin's points this close to the knee joint in the rest pose rest on the ground
#: with the knee [m] (the knee group alone left the front of the lower thigh, which a low crawl
#: lays nearly flat, up to 25 mm under the ground)
KNEE_REACH_M = 0.10


def knee_points(skeleton: Skeleton, points: BodyPoints, side: str) -> np.ndarray:
    """Indices of the sample points of ``side``'s knee and of the thigh and shin next to it."""
    near = np.linalg.norm(points.rest - skeleton.rest_positions[skeleton.index(f"{side}Leg")], axis=1)
    main = points.indices[np.arange(len(points.indices)), np.argmax(points.weights, axis=1)]
    leg = np.isin(main, [skeleton.index(f"{side}UpLeg"), skeleton.index(f"{side}Leg")])
    return np.union1d(points.groups[f"{side}Knee"], np.flatnonzero((near < KNEE_REACH_M) & leg))


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
            ids = (
                hand_points(skeleton, points, side) if part == "Hand" else knee_points(skeleton, points, side)
            )
            q = posed[:, ids]
            low = (q[..., 2] - ground.height(q[..., :2])).min(axis=1)
            m = low <= near
            if part == "Hand":
                w = wpos[:, skeleton.index(f"{side}Hand"), :2]
                speed = np.linalg.norm(np.gradient(w, axis=0), axis=1) * fps
                m &= speed <= C.LOCK_SPEED_M_S
            out[f"{side}{part}"] = C.clean_stance(m, fps)
    return out


#: passes of the knee correction (each re-reads the pivots after the thigh turned)
KNEE_PASSES = 3
#: a horizontal root shift costs this many times a vertical one (the hips bob over a planted
#: knee rather than the crawl's progress changing)
ROOT_HORIZONTAL_WEIGHT = 1.0
#: stiffness of a supporting knee's reach in the root shift's least squares [m^-2]: in a run
#: the hip ends within ~1e-4 m of the thigh's length from the knee; over a fade of weight w the
#: stiffness is KNEE_STIFFNESS ** sqrt(w) - 1 (0 out of support; linear in w let the knee go
#: only in the fade's last frame: a 42 mm root step against the clip's 28 mm, 38 mm now)
KNEE_STIFFNESS = 1.0e6
#: Gauss-Newton steps of the root shift per pass
ROOT_STEPS = 6
#: passes of the trailing feet's lift off the ground after the knees
FOOT_PASSES = 3


def _ramp(mask: np.ndarray, fade: int) -> np.ndarray:
    """(F,) 1 on ``mask``, easing to 0 over ``fade`` frames on either side (minimum jerk)."""
    on = np.flatnonzero(mask)
    if not len(on):
        return np.zeros(len(mask))
    dist = np.min(np.abs(np.arange(len(mask))[:, None] - on[None, :]), axis=1)
    u = np.clip(1.0 - dist / (fade + 1.0), 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u * u)


def _root_shift(hips: np.ndarray, knees: np.ndarray, lengths: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(F, 3) least root shift d minimising d' W d + KNEE_STIFFNESS sum_i w_i (|hip_i + d - knee_i|
    - L_i)^2, W = diag(h, h, 1) with h = ROOT_HORIZONTAL_WEIGHT: ``hips``, ``knees`` (F, k, 3) the
    hip joints and the knee targets, ``lengths`` (k,) the thighs, ``weights`` (F, k) in [0, 1]."""
    frames = len(hips)
    d = np.zeros((frames, 3))
    w_mat = np.diag([ROOT_HORIZONTAL_WEIGHT, ROOT_HORIZONTAL_WEIGHT, 1.0])
    for _ in range(ROOT_STEPS):
        v = hips + d[:, None, :] - knees  # (F, k, 3)
        dist = np.maximum(np.linalg.norm(v, axis=2), 1e-9)
        g = v / dist[..., None]
        c = dist - lengths[None, :]
        k = KNEE_STIFFNESS ** np.sqrt(weights) - 1.0  # (F, k): 0 out of support, stiff in it, eased between
        a = w_mat[None] + np.einsum("fk,fki,fkj->fij", k, g, g)
        b = -(d @ w_mat) - np.einsum("fk,fki,fk->fi", k, g, c)
        d = d + np.linalg.solve(a, b[..., None])[..., 0]
    return d


def _thigh_onto(skeleton: Skeleton, side: str, wrot, wpos, out: np.ndarray, rows, target, shin) -> None:
    """Turn ``side``'s thigh (UpLeg) on frames ``rows`` so that its knee (the Leg joint) points at
    ``target`` (n, 3), the shin's world rotation ``shin`` (n, 3, 3); writes UpLeg and Leg local
    rotations."""
    up, leg = skeleton.index(f"{side}UpLeg"), skeleton.index(f"{side}Leg")
    rest = skeleton.rest_positions
    ru = wrot[rows, up]
    thigh = align_matrix(ru @ (rest[leg] - rest[up]), target - wpos[rows, up]) @ ru
    parent = wrot[rows, skeleton.parents[up]]
    out[rows, up] = np.swapaxes(parent, 1, 2) @ thigh
    out[rows, leg] = np.swapaxes(thigh, 1, 2) @ shin


def _held_shin(wrot_leg: np.ndarray, mask: np.ndarray, fps: float) -> np.ndarray:
    """(F, 3, 3) shin world rotations held still over each run of ``mask`` (the run's mean
    orientation: the shin lies on the ground with the knee, so the trailing foot stays put),
    blended from and to the motion's by minimum jerk over the fades."""
    q = matrix_to_quat(wrot_leg)
    held = np.zeros_like(q)
    last = None
    for a, b in C.intervals(mask):
        run = q[a:b] * np.where(q[a:b] @ q[a] < 0, -1.0, 1.0)[:, None]
        mean = run.mean(axis=0)
        mean /= np.linalg.norm(mean)
        if last is not None and mean @ last < 0:  # one hemisphere, so that runs blend
            mean = -mean
        held[a:b] = last = mean
    fade, longest = C._fade_frames(fps)
    w = C._bridge(np.ones(len(mask)), mask, fade, longest)
    # between two runs from one held orientation to the next, faded from and to the motion's
    target = C._bridge(held, mask, fade, longest)
    norm = np.linalg.norm(target, axis=1, keepdims=True)
    target = np.where(norm > 1e-12, target / np.maximum(norm, 1e-12), q)
    return quat_to_matrix(quat_slerp(q, target, w))


def lock_knees(
    skeleton: Skeleton,
    ground: C.Ground,
    points: BodyPoints,
    local: np.ndarray,
    root_rot: np.ndarray,
    root_pos: np.ndarray,
    runs: dict[str, np.ndarray],
    fps: float,
    locked: dict[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """New local rotations (F, J, 3, 3) and root positions (F, 3) with the supporting knees
    (``runs``: ``<side>Knee`` masks, :func:`support_runs`) rolling without slipping on the
    ground; see the module doc. ``locked``: the feet's locked masks (``<side>``); a knee run
    overlapping one is left alone."""
    out, r = local.copy(), np.asarray(root_pos, dtype=float).copy()
    fade, _ = C._fade_frames(fps)
    busy = np.zeros(len(r), dtype=bool)
    for m in (locked or {}).values():
        busy |= np.asarray(m, dtype=bool)
    masks = {}
    for side in C.SIDES:
        m = np.asarray(runs.get(f"{side}Knee", np.zeros(len(r), bool)), dtype=bool).copy()
        for a, b in C.intervals(m):
            if busy[max(a - fade, 0) : b + fade].any():
                m[a:b] = False
        if m.any():
            masks[side] = m
    if not masks:
        return out, r
    sides = list(masks)
    rest = skeleton.rest_positions
    ups = [skeleton.index(f"{s}UpLeg") for s in sides]
    legs = [skeleton.index(f"{s}Leg") for s in sides]
    lengths = np.array([np.linalg.norm(rest[lg] - rest[u]) for u, lg in zip(ups, legs)])
    weights = np.stack([_ramp(masks[s], fade) for s in sides], axis=1)
    wrot, _ = fk_matrices(skeleton, out, root_rot, r)
    shins = {s: _held_shin(wrot[:, lg], masks[s], fps) for s, lg in zip(sides, legs)}
    # body points other than the knees, hands, forearms and feet (each held or lifted itself)
    own = [knee_points(skeleton, points, s) for s in C.SIDES]
    own += [hand_points(skeleton, points, s) for s in C.SIDES]
    own += [forearm_points(skeleton, points, s) for s in C.SIDES]
    own += [points.groups[f"{s}Foot"] for s in C.SIDES]
    others = np.setdiff1d(np.arange(len(points.rest)), np.concatenate(own))
    for _ in range(KNEE_PASSES):
        wrot, wpos = fk_matrices(skeleton, out, root_rot, r)
        posed = points.posed(wrot, wpos, skeleton)
        offs = [
            _pivot_offsets(ground, posed[:, knee_points(skeleton, points, s)], masks[s], fps, lift_m=0.0)
            for s in sides
        ]
        targets = np.stack([wpos[:, lg] + o for lg, o in zip(legs, offs)], axis=1)
        shift = _root_shift(wpos[:, ups], targets, lengths, weights)
        # the hips go no lower than the rest of the body allows (a low crawl's upper thigh and
        # belly near the ground): there the knee stays short of its target instead
        rest_h = posed[:, others, 2] - ground.height(posed[:, others, :2])
        shift[:, 2] = np.maximum(shift[:, 2], -np.maximum(rest_h.min(axis=1), 0.0))
        r = r + shift
        wpos = wpos + shift[:, None, :]
        for i, s in enumerate(sides):
            rows = np.flatnonzero((np.linalg.norm(offs[i], axis=1) > 1e-6) | (weights[:, i] > 0))
            shin = shins[s][rows]
            _thigh_onto(skeleton, s, wrot, wpos, out, rows, targets[rows, i], shin)
    # the lowered knees would push the trailing feet into the ground (the shin's orientation
    # kept): each shin turned up about its knee until its foot clears the ground
    for _ in range(FOOT_PASSES):
        wrot, wpos = fk_matrices(skeleton, out, root_rot, r)
        posed = points.posed(wrot, wpos, skeleton)
        for side in C.SIDES:
            q = posed[:, points.groups[f"{side}Foot"]]
            h = q[..., 2] - ground.height(q[..., :2])
            low = np.argmin(h, axis=1)
            rows = np.flatnonzero(h[np.arange(len(h)), low] < 0.0)
            if not len(rows):
                continue
            leg = skeleton.index(f"{side}Leg")
            arm = q[rows, low[rows]] - wpos[rows, leg]  # knee -> the foot's lowest point
            up = arm.copy()
            up[:, 2] -= h[rows, low[rows]]
            up *= (np.linalg.norm(arm, axis=1) / np.maximum(np.linalg.norm(up, axis=1), 1e-12))[:, None]
            shin = align_matrix(arm, up) @ wrot[rows, leg]
            out[rows, leg] = np.swapaxes(wrot[rows, skeleton.parents[leg]], 1, 2) @ shin
    return out, r


def lock_supports(
    skeleton: Skeleton,
    ground: C.Ground,
    points: BodyPoints,
    local: np.ndarray,
    root_rot: np.ndarray,
    root_pos: np.ndarray,
    fps: float,
    locked: dict[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, dict]:
    """The knees (:func:`lock_knees`), then the hands (:func:`lock_hands`) that support the body,
    their runs found once on the motion as given: (local rotations, root positions, runs)."""
    wrot, wpos = fk_matrices(skeleton, local, root_rot, root_pos)
    runs = support_runs(skeleton, ground, points, points.posed(wrot, wpos, skeleton), wpos, fps)
    local, root_pos = lock_knees(skeleton, ground, points, local, root_rot, root_pos, runs, fps, locked)
    local, runs = lock_hands(skeleton, ground, points, local, root_rot, root_pos, fps, runs)
    return local, root_pos, runs


def lock_hands(
    skeleton: Skeleton,
    ground: C.Ground,
    points: BodyPoints,
    local: np.ndarray,
    root_rot: np.ndarray,
    root_pos: np.ndarray,
    fps: float,
    runs: dict[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, dict]:
    """New local rotations (F, J, 3, 3) with the supporting hands held on the ground, and the
    support runs of the knees and hands (name -> (F,) bool; found here unless ``runs`` gives
    them; the knees are held by :func:`lock_knees`)."""
    out = local.copy()
    wrot, wpos = fk_matrices(skeleton, out, root_rot, root_pos)
    posed = points.posed(wrot, wpos, skeleton)
    if runs is None:
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
