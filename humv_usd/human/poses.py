"""Procedural poses and the transitions between them: sit (on the ground or a chair), crouch,
kneel, lie (prone, supine, on the side), wave, fall and get up.

An activity is a list of *key poses* with the time of each transition; a key pose gives the
root's orientation and every joint's anatomical angles (degrees) on our rig (the CMU rig of
:mod:`humv_usd.human.skeleton`: +Z up, the body faces -Y, +X is the person's left), the
*support* (the body parts that rest on the ground in that pose) and the *pinned* feet (those
planted on the ground in it). :func:`make_pose_motion` turns the list into a clip:

1. Joint angles are turned into local rotations (sign conventions of :mod:`humv_usd.human.gait`:
   hip flexion R_x(-(h - h0)), knee R_x(k - k0), trunk flexion R_x(+a), ankle dorsiflexion
   R_x(-a), toes R_x(-t)); between keys every rotation follows the geodesic (slerp) with a
   minimum-jerk time course (Flash & Hogan 1985, *J Neurosci* 5:1688-1703), and a key is held
   until the next transition starts.
2. The root: in every frame of a transition the *anchor* (the pinned foot kept from key to
   key, else the support the two keys share) keeps its horizontal position, so that the body
   turns about what it rests on instead of sliding over it; the root's height puts the lowest
   point of the current support on the ground (blended from key to key), and no point of the
   body (except the pinned feet, which the legs reach by IK) goes below the ground.
3. A foot pinned in a key and in the transitions around it is planted where it was at the
   first pinned frame (ankle position and foot/toe orientation frozen) and the legs are
   posed on it by the analytic two-bone IK of :mod:`humv_usd.human.contact` (the root is
   lowered where a planted foot would be out of reach).

Between sitting and hook lying (feet planted in both keys, the seat or back on the ground in
both) the root follows the rolling rule of the seat and back alone, the legs reaching the planted
feet: the buttocks no longer slide 5 cm as the back rolls down.

Hands that rest on the ground in a key (hands and knees) stay where they are while the body
moves in the transitions out of and into it: held for the part of the transition next to that
key (wrist and hand frozen, the arm by two-bone IK with the elbow on the designed side), then
lifted 4 cm and carried to the designed pose (:func:`_plant_hands`).

Contact is measured (:func:`body_contact_report`) on skinned body points (the body mesh's
vertices thinned to one per 3 cm cell, linear blend skinning with MakeHuman's weights): the
deepest penetration of any point below the ground, and the slip of every point while it stays
in contact (within 1 cm of the ground), as the foot report of the walk does.

Metabolic rates (Ainsworth et al. 2011 Compendium of Physical Activities, *Med Sci Sports
Exerc* 43:1575-1581): lying quietly 1.0 MET, sitting quietly 1.3 MET, standing quietly
1.3 MET. The Compendium has no entry for quiet crouching, kneeling or waving: the standing
value (1.3) is used for the first two and 'standing, light effort' 2.0 MET is assumed for
waving and for every transition (sitting down, lying down, falling, getting up).

Sources of the poses: joint ranges within the normal active ranges of motion (AAOS 1965 /
Norkin & White 2016, *Measurement of Joint Motion*: hip flexion 0-120, knee 0-135, ankle
dorsiflexion 0-20 (up to ~35 loaded in a deep squat), shoulder flexion 0-180, abduction
0-180, elbow 0-150 deg); transition durations: sit-to-stand and stand-to-sit about 1.5-2.5 s
in healthy adults (e.g. Janssen, Bussmann & Stam 2002, *Clin Biomech* 17:249-257, 1-3 s),
a fall from standing to the ground about 0.7-1.0 s (e.g. Hsiao & Robinovitch 1998,
*J Biomech* 31:1-9: ~0.7 s to hip impact). The poses are designed, not measured; no motion
capture data is used.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from humv_usd.human import contact as C
from humv_usd.human.gait import (
    align_matrix,
    axis_angle_matrix,
    fk_matrices,
    matrix_to_quat,
    quat_slerp,
    rig_info,
    rot_x,
    rot_y,
    rot_z,
)
from humv_usd.human.macro import obj_data
from humv_usd.human.skeleton import Skeleton, quat_to_matrix, skin_weights
from humv_usd.scenario.spec import POSE_ACTIVITIES  # noqa: F401 (the activities built here; the scenario keys allow them)

SIDES = C.SIDES
#: activities made of key poses (see :data:`SEQUENCES`)
#: MET of each held pose and of transitions (see the module doc)
MET_POSE = {
    "stand": 1.3,
    "sit": 1.3,
    "sitChair": 1.3,
    "crouch": 1.3,
    "kneel": 1.3,
    "kneelBoth": 1.3,
    "handsKnees": 1.3,
    "lieProne": 1.0,
    "lieSupine": 1.0,
    "hookLying": 1.0,
    "lieSide": 1.0,
    "wave": 2.0,
}
MET_TRANSITION = 2.0
#: how high a foot that moves in a transition is lifted at mid-transition [m]
STEP_LIFT_M = 0.05
#: contact tolerance [m] of the slip measure (as :func:`contact.contact_report`)
CONTACT_TOL = 0.01
#: waving: elbow swing [deg] and frequency [Hz] (a hand wave, about 2-3 Hz)
WAVE_AMPLITUDE_DEG = 25.0
WAVE_HZ = 2.2


# ------------------------------------------------------------------------- key poses
@dataclass(frozen=True)
class Key:
    """One key pose. Angles in degrees; per side ``hip`` (flexion, abduction), ``knee``,
    ``ankle`` (dorsiflexion), ``toe`` (extension), ``shoulder`` (flexion, abduction from the
    vertical), ``elbow`` (flexion); the root's ``pitch`` (+ = trunk forward), ``roll`` (+ =
    onto the left side) and ``yaw``; ``spine`` (+ = forward) spread over the three spine
    joints, ``spine_turn`` (+ = to the left), ``neck`` (+ = head forward/down), ``neck_turn``."""

    name: str
    support: tuple[str, ...]
    pinned: tuple[str, ...] = ()  # "Left"/"Right": feet planted in this key
    pitch: float = 0.0
    roll: float = 0.0
    yaw: float = 0.0
    spine: float = 0.0
    spine_turn: float = 0.0
    neck: float = 0.0
    neck_turn: float = 0.0
    legs: dict = field(default_factory=dict)  # side -> {"hip": (f, a), "knee", "ankle", "toe"}
    arms: dict = field(default_factory=dict)  # side -> {"shoulder": (f, a), "elbow"}


def _legs(hip=(0.0, 3.0), knee=5.0, ankle=None, toe=0.0, right=None) -> dict:
    """Both legs alike (``right``: overrides for the right leg). The ankle defaults to the
    value that keeps the foot flat for the root pitch given later (see :func:`_flat_ankle`)."""
    left = {"hip": hip, "knee": knee, "ankle": ankle, "toe": toe}
    return {"Left": left, "Right": {**left, **(right or {})}}


def _arms(shoulder=(0.0, 8.0), elbow=15.0, right=None) -> dict:
    left = {"shoulder": shoulder, "elbow": elbow}
    return {"Left": left, "Right": {**left, **(right or {})}}


FEET = ("LeftFoot", "RightFoot")
STAND = Key("stand", FEET, ("Left", "Right"), legs=_legs(), arms=_arms())
#: deep squat, heels down: thigh ~90 deg forward of the pelvis line, knees ~120, ankles ~30
#: deg dorsiflexed (loaded), trunk forward, forearms over the knees
CROUCH = Key(
    "crouch",
    FEET,
    ("Left", "Right"),
    pitch=20.0,
    spine=15.0,
    neck=-25.0,
    legs=_legs(hip=(105.0, 12.0), knee=118.0),
    arms=_arms(shoulder=(45.0, 12.0), elbow=45.0),
)
#: sitting on the ground, knees up, feet flat, arms around the knees
SIT = Key(
    "sit",
    ("Seat", "LeftFoot", "RightFoot"),
    ("Left", "Right"),
    pitch=-15.0,
    spine=18.0,
    neck=5.0,
    legs=_legs(hip=(110.0, 8.0), knee=115.0),
    arms=_arms(shoulder=(55.0, 12.0), elbow=60.0),
)
#: sitting on a chair: thighs level, shanks upright, hands on the thighs
SIT_CHAIR = Key(
    "sitChair",
    ("Seat",),
    ("Left", "Right"),
    pitch=-5.0,
    spine=5.0,
    neck=0.0,
    legs=_legs(hip=(88.0, 6.0), knee=88.0),
    arms=_arms(shoulder=(25.0, 8.0), elbow=55.0),
)
#: kneeling on the right knee ("taking a knee"): left foot flat ahead, right knee and toes
#: on the ground
KNEEL = Key(
    "kneel",
    ("RightKnee", "RightToes"),
    ("Left",),
    pitch=5.0,
    spine=5.0,
    neck=-5.0,
    legs=_legs(
        hip=(80.0, 6.0), knee=85.0, right={"hip": (-5.0, 4.0), "knee": 95.0, "ankle": 63.0, "toe": 55.0}
    ),
    arms=_arms(shoulder=(20.0, 10.0), elbow=50.0),
)
#: kneeling on both knees, toes tucked, sitting up
KNEEL_BOTH = Key(
    "kneelBoth",
    ("LeftKnee", "RightKnee", "LeftToes", "RightToes"),
    pitch=0.0,
    spine=5.0,
    legs=_legs(hip=(0.0, 6.0), knee=92.0, ankle=50.0, toe=55.0),
    arms=_arms(shoulder=(10.0, 10.0), elbow=30.0),
)
#: on hands and knees
HANDS_KNEES = Key(
    "handsKnees",
    ("LeftKnee", "RightKnee", "LeftHand", "RightHand"),
    pitch=75.0,
    spine=-5.0,
    neck=-50.0,
    legs=_legs(hip=(80.0, 6.0), knee=90.0, ankle=-30.0, toe=0.0),
    arms=_arms(shoulder=(75.0, 10.0), elbow=25.0),
)
#: prone: face down, head turned to the right, arms beside the body
LIE_PRONE = Key(
    "lieProne",
    ("Trunk", "LeftUpLeg", "RightUpLeg"),
    pitch=90.0,
    neck=-10.0,
    neck_turn=-60.0,
    legs=_legs(hip=(0.0, 8.0), knee=5.0, ankle=-20.0),
    arms=_arms(shoulder=(-5.0, 12.0), elbow=10.0),
)
#: supine, knees up and feet flat (hook lying)
HOOK_LYING = Key(
    "hookLying",
    ("Trunk", "LeftFoot", "RightFoot"),
    ("Left", "Right"),
    pitch=-88.0,
    neck=5.0,
    legs=_legs(hip=(75.0, 6.0), knee=105.0),
    arms=_arms(shoulder=(0.0, 20.0), elbow=10.0),
)
#: supine, legs straight, arms beside the body
LIE_SUPINE = Key(
    "lieSupine",
    ("Trunk", "LeftLeg", "RightLeg"),
    pitch=-91.0,
    neck=5.0,
    legs=_legs(hip=(0.0, 8.0), knee=3.0, ankle=-25.0),
    arms=_arms(shoulder=(0.0, 20.0), elbow=10.0),
)
#: lying on the left side, knees bent (a recovery-like position)
LIE_SIDE = Key(
    "lieSide",
    ("Trunk", "LeftUpLeg", "LeftLeg"),
    roll=88.0,
    spine=10.0,
    neck=0.0,
    legs=_legs(hip=(45.0, 5.0), knee=60.0, right={"hip": (60.0, 0.0), "knee": 80.0}),
    arms=_arms(shoulder=(90.0, 0.0), elbow=60.0, right={"shoulder": (40.0, 10.0), "elbow": 40.0}),
)
#: standing, right arm raised to wave (upper arm out and up, forearm up)
WAVE = Key(
    "wave",
    FEET,
    ("Left", "Right"),
    legs=_legs(),
    arms=_arms(right={"shoulder": (20.0, 110.0), "elbow": 95.0}),
)

#: activity -> ((key, transition duration [s] into it), ...); the first key has duration 0
SEQUENCES = {
    "crouch": ((STAND, 0.0), (CROUCH, 1.5)),
    "sit": ((STAND, 0.0), (CROUCH, 1.4), (SIT, 1.2)),
    "sitChair": ((STAND, 0.0), (SIT_CHAIR, 1.8)),
    "kneel": ((STAND, 0.0), (KNEEL, 1.6)),
    "lieSupine": ((STAND, 0.0), (CROUCH, 1.4), (SIT, 1.2), (HOOK_LYING, 1.5), (LIE_SUPINE, 1.2)),
    "lieProne": ((STAND, 0.0), (KNEEL_BOTH, 1.8), (HANDS_KNEES, 1.2), (LIE_PRONE, 1.5)),
    "lieSide": ((STAND, 0.0), (CROUCH, 1.4), (SIT, 1.2), (HOOK_LYING, 1.5), (LIE_SIDE, 1.5)),
    "wave": ((STAND, 0.0), (WAVE, 0.8)),
    "fall": ((STAND, 0.0), (KNEEL_BOTH, 0.45), (HANDS_KNEES, 0.35), (LIE_PRONE, 0.5)),
    "getUp": ((LIE_SUPINE, 0.0), (HOOK_LYING, 1.0), (SIT, 1.5), (CROUCH, 1.4), (STAND, 1.5)),
}


def final_key(activity: str) -> Key:
    """The key pose ``activity`` ends in (``stand`` and ``getUp``: standing)."""
    return STAND if activity == "stand" else SEQUENCES[activity][-1][0]


def _edges() -> dict:
    """Undirected key graph of the designed transitions: name -> {name: duration [s]} (the
    fall's fast collapse is left out: it is taken only when falling from standing; sitting on
    the chair connects to standing only)."""
    out: dict = {}
    for activity, seq in SEQUENCES.items():
        if activity == "fall":
            continue
        for (a, _), (b, d) in zip(seq[:-1], seq[1:]):
            for x, y in ((a.name, b.name), (b.name, a.name)):
                out.setdefault(x, {})[y] = min(d, out.get(x, {}).get(y, np.inf))
    return out


KEYS = {k.name: k for seq in SEQUENCES.values() for k, _ in seq}


def route(current: str, activity: str) -> list:
    """[(key, duration [s]), ...]: the transitions from the key named ``current`` into
    ``activity``'s final pose: from standing the activity's own :data:`SEQUENCES` entry
    (e.g. a fall), else the quickest chain of designed transitions (Dijkstra over the key
    graph: sit -> lie supine goes sit, hook lying, supine; prone -> standing reverses the
    lying down). Empty when already there."""
    goal = final_key(activity).name
    if current == goal:
        return []
    if current == "stand" and activity not in ("stand", "getUp"):
        return [(k, d) for k, d in SEQUENCES[activity][1:]]
    edges = _edges()
    best, prev, todo = {current: 0.0}, {}, {current}
    while todo:
        u = min(todo, key=best.get)
        todo.discard(u)
        if u == goal:
            break
        for v, d in edges.get(u, {}).items():
            if best[u] + d < best.get(v, np.inf):
                best[v], prev[v] = best[u] + d, u
                todo.add(v)
    if goal not in prev:
        raise ValueError(f"no transition from {current!r} to {activity!r}")
    chain, v = [], goal
    while v != current:
        chain.append((KEYS[v], edges[prev[v]][v]))
        v = prev[v]
    return chain[::-1]


# ------------------------------------------------------------------------- body points
@dataclass(frozen=True)
class BodyPoints:
    """Skinned sample points of the body surface: ``rest`` (n, 3), ``indices``/``weights``
    (n, 4), and the contact group each point belongs to (``groups``: name -> index array)."""

    rest: np.ndarray
    indices: np.ndarray
    weights: np.ndarray
    groups: dict
    source: str

    def posed(self, world_rot: np.ndarray, world_pos: np.ndarray, skeleton: Skeleton) -> np.ndarray:
        """(F, n, 3) points for world joint rotations (F, J, 3, 3) and positions (F, J, 3)."""
        rest_j = skeleton.rest_positions
        rel = self.rest[None, :, None, :] - rest_j[self.indices][None]  # (1, n, k, 3)
        r = world_rot[:, self.indices]  # (F, n, k, 3, 3)
        p = np.einsum("fnkij,fnkj->fnki", r, np.broadcast_to(rel, r.shape[:-1]))
        p = p + world_pos[:, self.indices]
        return np.einsum("nk,fnki->fni", self.weights, p)


_GROUP_JOINTS = {
    "LeftFoot": ("LeftFoot", "LeftToeBase"),
    "RightFoot": ("RightFoot", "RightToeBase"),
    "LeftToes": ("LeftToeBase",),
    "RightToes": ("RightToeBase",),
    "LeftKnee": ("LeftLeg",),
    "RightKnee": ("RightLeg",),
    "LeftLeg": ("LeftLeg", "LeftFoot", "LeftToeBase"),
    "RightLeg": ("RightLeg", "RightFoot", "RightToeBase"),
    "LeftUpLeg": ("LeftUpLeg",),
    "RightUpLeg": ("RightUpLeg",),
    "Seat": ("Hips", "LHipJoint", "RHipJoint", "LeftUpLeg", "RightUpLeg"),
    "Trunk": ("Hips", "LHipJoint", "RHipJoint", "LowerBack", "Spine", "Spine1", "Neck", "Neck1", "Head"),
    "LeftHand": ("LeftHand", "LThumb", "LeftFingerBase", "LeftHandFinger1"),
    "RightHand": ("RightHand", "RThumb", "RightFingerBase", "RightHandFinger1"),
}


def body_points(skeleton: Skeleton, full_points: np.ndarray | None = None, cell: float = 0.03) -> BodyPoints:
    """Sample points of the body: the body mesh's vertices (``full_points``: the FULL base.obj
    vertex list, e.g. ``Body.points``), one per ``cell`` [m] grid cell, with their MakeHuman
    skin weights; without a body, points on capsules around the bones (radius 4 cm, rigid)."""
    if full_points is None:
        return _capsule_points(skeleton)
    _, groups = obj_data()
    used = np.unique(groups["body"])
    P = np.asarray(full_points, dtype=np.float64)[used]
    cells = np.floor(P / cell).astype(np.int64)
    _, first = np.unique(cells, axis=0, return_index=True)
    ids = used[np.sort(first)]
    idx, w = skin_weights(skeleton, ids)
    return BodyPoints(
        np.asarray(full_points, dtype=np.float64)[ids],
        idx,
        w.astype(np.float64),
        _groups(skeleton, idx),
        "body",
    )


def _groups(skeleton: Skeleton, idx: np.ndarray) -> dict:
    dominant = np.array(skeleton.names)[idx[:, 0]]
    out = {}
    for name, joints in _GROUP_JOINTS.items():
        out[name] = np.flatnonzero(np.isin(dominant, joints))
    out["Body"] = np.arange(len(idx))
    return out


def _capsule_points(skeleton: Skeleton, radius: float = 0.04) -> BodyPoints:
    rest = skeleton.rest_positions
    pts, joints = [], []
    ang = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    for j in range(len(skeleton.names)):
        a, b = rest[j], skeleton.tail_positions[j]
        d = b - a
        L = np.linalg.norm(d)
        if L < 1e-6:
            continue
        u = d / L
        e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        for t in np.linspace(0.0, 1.0, max(int(L / 0.04), 2)):
            for g in ang:
                pts.append(a + t * d + radius * (np.cos(g) * e1 + np.sin(g) * e2))
                joints.append(j)
    idx = np.zeros((len(pts), 4), np.int32)
    idx[:, 0] = joints
    w = np.zeros((len(pts), 4))
    w[:, 0] = 1.0
    pts = np.array(pts)
    pts[:, 2] -= pts[:, 2].min()  # the capsules' soles on z = 0
    return BodyPoints(pts, idx, w, _groups(skeleton, idx), "capsules")


# ------------------------------------------------------------------------- key -> rotations
def key_rotations(skeleton: Skeleton, key: Key) -> tuple[np.ndarray, np.ndarray]:
    """(root rotation (3, 3), local rotations (J, 3, 3)) of a key pose."""
    info = rig_info(skeleton)
    ix = info.index
    J = len(skeleton.names)
    local = np.tile(np.eye(3), (J, 1, 1))
    root = rot_z(np.radians(key.yaw)) @ rot_y(np.radians(key.roll)) @ rot_x(np.radians(key.pitch))
    for name, w in (("LowerBack", 0.3), ("Spine", 0.35), ("Spine1", 0.35)):
        local[ix[name]] = rot_z(np.radians(w * key.spine_turn)) @ rot_x(np.radians(w * key.spine))
    for name, w in (("Neck", 0.4), ("Neck1", 0.3), ("Head", 0.3)):
        local[ix[name]] = rot_z(np.radians(w * key.neck_turn)) @ rot_x(np.radians(w * key.neck))
    for side in SIDES:
        sign = 1.0 if side == "Left" else -1.0
        leg = key.legs.get(side, {"hip": (0.0, 3.0), "knee": 5.0, "ankle": None, "toe": 0.0})
        h, a = np.radians(leg["hip"])
        k = np.radians(leg["knee"])
        local[ix[f"{side}UpLeg"]] = rot_y(-sign * (a - info.rest_abd[side])) @ rot_x(
            -(h - info.rest_hip[side])
        )
        local[ix[f"{side}Leg"]] = rot_x(k - info.rest_knee[side])
        ankle = leg.get("ankle")
        if ankle is None:  # the foot flat for this root pitch (sagittal chain, see gait.py)
            d = key.pitch - np.degrees(h - info.rest_hip[side]) + np.degrees(k - info.rest_knee[side])
        else:  # dorsiflexion from the rest angle (the rest foot is flat when standing)
            d = ankle
        local[ix[f"{side}Foot"]] = rot_x(-np.radians(d))
        local[ix[f"{side}ToeBase"]] = rot_x(-np.radians(leg.get("toe", 0.0)))
        arm = key.arms.get(side, {"shoulder": (0.0, 8.0), "elbow": 15.0})
        f, ab = np.radians(arm["shoulder"])
        j = ix[f"{side}Arm"]
        rest_dir = skeleton.rest_positions[ix[f"{side}ForeArm"]] - skeleton.rest_positions[j]
        down = np.array([0.0, 0.0, -1.0])
        want = rot_x(-f) @ rot_y(-sign * ab) @ down
        # the upper arm's minimal turn from its rest direction, in the (rest-aligned) chest frame
        local[j] = align_matrix(rest_dir, want)
        local[ix[f"{side}ForeArm"]] = axis_angle_matrix(
            info.elbow_axis[side], np.radians(arm["elbow"]) - info.elbow_rest[side]
        )
    return root, local


# ------------------------------------------------------------------------- the clip
def _minjerk(x) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10 - 15 * x + 6 * x * x)


@dataclass(frozen=True)
class Timeline:
    """Per frame: the key before (``k0``), after (``k1``) and the blend ``s`` (0..1)."""

    k0: np.ndarray
    k1: np.ndarray
    s: np.ndarray
    u: np.ndarray  # the transition's linear time fraction (s = minimum-jerk of u)
    starts: np.ndarray  # start time [s] of each transition (key i >= 1)


def timeline(durations, fps: float, frames: int, start_s: float) -> Timeline:
    """Transitions one after another from ``start_s``; the last key is held to the end."""
    t = np.arange(frames) / fps
    n = len(durations)
    starts = start_s + np.r_[0.0, np.cumsum(durations[1:])][: n - 1] if n > 1 else np.zeros(0)
    k0 = np.zeros(frames, int)
    k1 = np.zeros(frames, int)
    s = np.zeros(frames)
    u = np.zeros(frames)
    for i in range(1, n):
        a = starts[i - 1]
        d = max(durations[i], 1e-9)
        after = t >= a
        k0[after] = i - 1
        k1[after] = i
        u[after] = np.clip((t[after] - a) / d, 0.0, 1.0)
        s[after] = _minjerk(u[after])
    return Timeline(k0, k1, s, u, np.asarray(starts))


def _lift_needed(ground: C.Ground, pts: np.ndarray) -> np.ndarray:
    """(F,) height by which points (F, n, 3) must rise so that none is below the ground."""
    if pts.shape[1] == 0:
        return np.full(pts.shape[0], -np.inf)
    g = ground.height(pts[..., :2])
    return np.max(g - pts[..., 2], axis=1)


def make_pose_motion(
    activity: str,
    skeleton: Skeleton,
    fps: float,
    frames: int,
    *,
    start_xy=None,
    heading: float = 0.0,
    ground: C.Ground | None = None,
    feet: dict | None = None,
    points: BodyPoints | None = None,
    start_s: float | None = None,
    plan=None,
) -> dict:
    """Root translations (F, 3), local rotations (F, J, 3, 3), per-frame contact masks and
    the contact report of a pose activity (one of :data:`POSE_ACTIVITIES`).

    start_xy: the Hips' ground position at the start (default: rest); heading [rad] about +Z;
    ground: :class:`contact.Ground` (default flat); feet: foot contact points
    (:func:`contact.foot_points_from_joints` by default); points: :func:`body_points`;
    start_s: when the first transition starts (default min(0.5 s, 10 % of the clip));
    plan: ((key, transition duration [s] into it), ...) instead of the activity's
    :data:`SEQUENCES` entry (a key following itself is held for that time), e.g. from
    :func:`route` (motion sequences, :mod:`humv_usd.human.sequence`).
    """
    ground = ground or C.Ground(None)
    feet = feet or C.foot_points_from_joints(skeleton)
    points = points or body_points(skeleton)
    seq = SEQUENCES[activity] if plan is None else tuple(plan)
    keys = [k for k, _ in seq]
    durations = [d for _, d in seq]
    if start_s is None:
        start_s = min(0.5, 0.1 * frames / fps)
    tl = timeline(durations, fps, frames, start_s)
    # per-key rotations and the points relative to the root (root at the origin)
    rots = [key_rotations(skeleton, k) for k in keys]
    qroot = np.array([matrix_to_quat(r) for r, _ in rots])
    qloc = np.array([matrix_to_quat(loc) for _, loc in rots])
    root_q = quat_slerp(qroot[tl.k0], qroot[tl.k1], tl.s)
    loc_q = quat_slerp(qloc[tl.k0], qloc[tl.k1], tl.s[:, None])
    waving = np.array([k.name == "wave" for k in keys])
    if waving.any():
        loc_q = _wave(skeleton, loc_q, tl, fps, waving)
    root_rot = rot_z(heading) @ quat_to_matrix(root_q)
    local = quat_to_matrix(loc_q)
    zero = np.zeros((frames, 3))
    wrot, wpos = fk_matrices(skeleton, local, root_rot, zero)
    rel = points.posed(wrot, wpos, skeleton)  # (F, n, 3) relative to the root
    # the anchor of each transition keeps its horizontal place: a foot pinned in both keys,
    # else the support the two keys share, else the first key's support
    start = skeleton.rest_positions[0, :2] if start_xy is None else np.asarray(start_xy, float)
    root_xy = np.empty((frames, 2))
    anchor_of = []
    for i in range(len(keys)):
        if i == 0:
            anchor_of.append(None)
            continue
        a, b = keys[i - 1], keys[i]
        both = [s for s in SIDES if s in a.pinned and s in b.pinned]
        if both:
            anchor_of.append(tuple(f"{s}Foot" for s in both))
        else:
            shared = tuple(g for g in a.support if g in b.support)
            anchor_of.append(shared or a.support)
    anchor_world = None
    prev_group = None
    for f in range(frames):
        i = int(tl.k1[f])
        group = anchor_of[i] if i > 0 else keys[0].support
        ids = np.unique(np.concatenate([points.groups[g] for g in group]))
        here = rel[f, ids, :2].mean(axis=0)
        if anchor_world is None:
            root_xy[f] = start
            anchor_world = start + here
        elif group != prev_group:
            # a new transition: its anchor starts where the body is now
            anchor_world = root_xy[f - 1] + rel[f - 1, ids, :2].mean(axis=0)
            root_xy[f] = anchor_world - here
        else:
            root_xy[f] = anchor_world - here
        prev_group = group
    pinned = _pinned_masks(keys, tl)
    chair = None
    on_chair = np.flatnonzero(np.array([k.name == SIT_CHAIR.name for k in keys])[tl.k1])
    if len(on_chair):  # sitChair (or a sequence's): the seat under the pose once it sits
        seated = on_chair[tl.s[on_chair] >= 1.0]
        f = int(seated[0] if len(seated) else on_chair[-1])
        chair = _chair_box(skeleton, SIT_CHAIR, points, rel[f], root_xy[f], heading, ground)
        ground = C.Ground(_with_box(ground, chair))
    z = _root_heights(ground, keys, tl, points, rel, root_xy, pinned)
    # transitions without a planted foot: the body rolls over what touches the ground
    free = (tl.s > 0) & (tl.s < 1) & ~(pinned["Left"] | pinned["Right"])
    if free.any():
        root_xy = _rolling_xy(ground, rel, root_xy, z, free)
        z = _root_heights(ground, keys, tl, points, rel, root_xy, pinned)
    # the seat or back that rests on the ground in both keys while the feet stay planted (sitting
    # <-> hook lying) rolls without sliding too; the legs reach the planted feet
    seated = np.array([any(g in ("Seat", "Trunk") for g in k.support) for k in keys])
    rolls = (tl.s > 0) & (tl.s < 1) & seated[tl.k0] & seated[tl.k1] & (pinned["Left"] | pinned["Right"])
    if rolls.any():
        feet_pts = np.zeros(len(points.rest), bool)
        for g in ("LeftLeg", "RightLeg"):
            feet_pts[points.groups[g]] = True
        root_xy = _rolling_xy(ground, rel, root_xy, z, rolls, exclude=feet_pts)
        z = _root_heights(ground, keys, tl, points, rel, root_xy, pinned)
    root_pos = np.column_stack([root_xy, z])
    # plant the pinned feet and pose the legs on them
    swing = {side: ~pinned[side] & (tl.s > 0) & (tl.s < 1) for side in SIDES}
    # on the linear time: the foot is off the ground before it moves along (minimum jerk)
    lift = STEP_LIFT_M * np.sin(np.pi * tl.u)
    local, root_pos = _plant_feet(skeleton, ground, feet, local, root_rot, root_pos, pinned, swing, lift)
    local = _plant_hands(skeleton, keys, tl, local, root_rot, root_pos)
    wrot, wpos = fk_matrices(skeleton, local, root_rot, root_pos)
    posed = points.posed(wrot, wpos, skeleton)
    report = body_contact_report(ground, posed, fps)
    report.update(C.contact_report(ground, feet, wrot, wpos, pinned))
    report["body_max_penetration_m"] = report.pop("body_penetration_m")
    local[:, 0] = root_rot
    held = np.array([k.name for k in keys])[tl.k0] == np.array([k.name for k in keys])[tl.k1]
    met = np.where(
        tl.s >= 1.0,
        np.array([MET_POSE.get(k.name, MET_TRANSITION) for k in keys])[tl.k1],
        np.where(
            (tl.s <= 0) | held, np.array([MET_POSE.get(k.name, 1.3) for k in keys])[tl.k0], MET_TRANSITION
        ),
    )
    return {
        "root": root_pos,
        "local": local,
        "pinned": pinned,
        "report": report,
        "met": met,
        "keys": [k.name for k in keys],
        "transition_start_s": tl.starts,
        "support_points": points.source,
        "chair": chair,
    }


def _chair_box(skeleton, key, points, rel_last, root_xy, heading, ground) -> dict:
    """A seat box under the sitting pose: its top at the height the pose's thighs have above
    its soles (thighs level, shanks upright), its front edge 4 cm behind the knees' backs,
    0.42 m deep and 0.46 m wide (a common chair seat, e.g. BIFMA X5.1 seat heights
    0.38-0.53 m), turned with the person."""
    seat = rel_last[points.groups["Seat"]]
    soles = rel_last[np.r_[points.groups["LeftFoot"], points.groups["RightFoot"]]]
    height = float(seat[:, 2].min() - soles[:, 2].min())
    c, s_ = np.cos(heading), np.sin(heading)
    to_body = np.array([[c, s_], [-s_, c]])  # world -> heading frame (x lateral, y back)
    low = seat[seat[:, 2] < seat[:, 2].min() + 0.03, :2] @ to_body.T
    front = float(low[:, 1].min()) + 0.04  # -Y is forward
    depth, width = 0.42, 0.46
    centre_h = np.array([float(np.mean(low[:, 0])), front + depth / 2])
    centre = root_xy + centre_h @ to_body
    g0 = float(np.asarray(ground.height(centre[None]))[0])
    return {
        "center_m": [float(centre[0]), float(centre[1]), g0 + height / 2],
        "size_m": [width, depth, height],
        "yaw_rad": float(heading),
    }


def _with_box(ground: C.Ground, box: dict):
    """The ground's height function with a box standing on it."""
    cx, cy, cz = box["center_m"]
    w, d, h = box["size_m"]
    c, s_ = np.cos(box["yaw_rad"]), np.sin(box["yaw_rad"])
    top = cz + h / 2

    def height(x, y):
        dx, dy = np.asarray(x) - cx, np.asarray(y) - cy
        u, v = c * dx + s_ * dy, -s_ * dx + c * dy
        inside = (np.abs(u) <= w / 2) & (np.abs(v) <= d / 2)
        g = ground.height(np.stack([np.asarray(x, float), np.asarray(y, float)], -1))
        return np.where(inside, np.maximum(g, top), g)

    return height


def _root_heights(ground, keys, tl, points, rel, root_xy, pinned) -> np.ndarray:
    """Root heights (F,): the current support's lowest point on the ground, blended between
    keys, and nothing but the shanks and feet of pinned legs below the ground."""
    frames = len(root_xy)
    zk = np.empty((len(keys), frames))
    for i, key in enumerate(keys):
        # pinned feet are reached by the legs' IK: the rest of the support sets the height
        rest = [g for g in key.support if g not in {f"{s}Foot" for s in key.pinned}]
        ids = np.unique(np.concatenate([points.groups[g] for g in rest or key.support]))
        pts = rel[:, ids] + np.column_stack([root_xy, np.zeros(frames)])[:, None, :]
        zk[i] = _lift_needed(ground, pts)
    z = (1 - tl.s) * zk[tl.k0, np.arange(frames)] + tl.s * zk[tl.k1, np.arange(frames)]
    root_pos = np.column_stack([root_xy, z])
    lift = _lift_needed(ground, rel + root_pos[:, None, :])
    for both in (True, False):
        for side in SIDES if not both else ("",):
            rows = (pinned["Left"] & pinned["Right"]) if both else (pinned[side] & ~pinned[_other(side)])
            if not rows.any():
                continue
            legs = ("LeftLeg", "RightLeg") if both else (f"{side}Leg",)
            keep = np.ones(len(points.rest), bool)
            for g in legs:
                keep[points.groups[g]] = False
            lift[rows] = _lift_needed(ground, rel[rows][:, keep] + root_pos[rows, None, :])
    return z + np.maximum(lift, 0.0)


def _rolling_xy(ground, rel, root_xy, z, free, tol=CONTACT_TOL, exclude=None) -> np.ndarray:
    """Root ground positions in which the body points that stay in contact from one frame to
    the next do not move horizontally on average (in the ``free`` frames: transitions with no
    planted foot); elsewhere the given steps are kept. ``exclude``: points left out (e.g. the
    planted legs, which the IK holds)."""
    steps = np.diff(root_xy, axis=0)
    pos = rel + np.column_stack([root_xy, z])[:, None, :]
    touch = pos[..., 2] - ground.height(pos[..., :2]) <= tol
    if exclude is not None:
        touch &= ~exclude
    for f in np.flatnonzero(free[1:]) + 1:
        common = touch[f - 1] & touch[f]
        if common.any():
            steps[f - 1] = -np.mean(rel[f, common, :2] - rel[f - 1, common, :2], axis=0)
    return root_xy[0] + np.r_[np.zeros((1, 2)), np.cumsum(steps, axis=0)]


def _other(side: str) -> str:
    return "Right" if side == "Left" else "Left"


def _pinned_masks(keys, tl: Timeline) -> dict:
    """A foot is pinned in a frame when it is pinned in the key(s) that frame lies between."""
    out = {}
    for side in SIDES:
        p = np.array([side in k.pinned for k in keys])
        out[side] = np.where(tl.s <= 0, p[tl.k0], np.where(tl.s >= 1, p[tl.k1], p[tl.k0] & p[tl.k1]))
    return out


def _plant_feet(skeleton, ground, feet, local, root_rot, root_pos, pinned, swing, lift):
    """Freeze each pinned foot at its first pinned frame (position on the ground, orientation)
    and solve the legs by IK; the root drops where a planted foot is out of reach. A foot
    that moves in a transition (``swing`` frames) is lifted by ``lift`` (F,) [m] above its
    designed path, so that it leaves and meets the ground without scraping over it."""
    frames = len(root_pos)
    wrot, wpos = fk_matrices(skeleton, local, root_rot, root_pos)
    targets = {}
    for side in SIDES:
        fp = feet[side]
        ankle = wpos[:, fp.foot].copy()
        frot = wrot[:, fp.foot].copy()
        trot = wrot[:, fp.toe].copy()
        for a, b in C.intervals(pinned[side]):
            pts = fp.world(wrot[a : a + 1], wpos[a : a + 1])[0]
            drop = float(np.min(pts[:, 2] - ground.height(pts[:, :2])))
            # the foot set down on the ground where it is (only its height changes)
            ankle[a:b] = wpos[a, fp.foot] - [0.0, 0.0, drop]
            frot[a:b] = wrot[a, fp.foot]
            trot[a:b] = wrot[a, fp.toe]
        ankle[swing[side], 2] += lift[swing[side]]
        targets[side] = C.FootTargets(ankle, frot, trot, np.zeros(frames))
    need = np.zeros(frames)
    for side in SIDES:
        chain = C.leg_chain(skeleton, side)
        m = pinned[side]
        if m.any():
            need[m] = np.maximum(
                need[m], C.reach_drop(chain, root_pos[m], root_rot[m], targets[side].ankle[m])
            )
    root_pos = root_pos.copy()
    root_pos[:, 2] -= C.smooth_drop(need, 1.0)
    local = local.copy()
    for side in SIDES:
        m = pinned[side] | swing[side]
        if not m.any():
            continue
        chain = C.leg_chain(skeleton, side)
        hip, knee, ankle, toe = C.leg_ik(chain, root_pos, root_rot, local[:, chain.hip], targets[side])
        for j, r in ((chain.hip, hip), (chain.knee, knee), (chain.ankle, ankle), (chain.toe, toe)):
            local[m, j] = r[m]
    return local, root_pos


#: share of a transition during which a hand that rests on the ground in one key stays planted
#: (leaving: its first part; arriving: its last part), and its lift when it moves [m]
HAND_PLANTED_SHARE = 0.35
HAND_LIFT_M = 0.04


def _plant_hands(skeleton, keys, tl: Timeline, local, root_rot, root_pos) -> np.ndarray:
    """Hands that rest on the ground in a key (its support holds ``<side>Hand``) stay where
    they are while the body moves: in a transition out of such a key the hand is held (wrist
    and hand orientation frozen, the arm by two-bone IK, the elbow on the designed side) for
    the first :data:`HAND_PLANTED_SHARE` of it, then lifted and carried to the designed pose;
    into such a key it is put down early and held for the last share. (Lowering from hands
    and knees to prone slid the hands 0.11 m over the ground.)"""
    frames = len(root_pos)
    names = skeleton.names
    wrot, wpos = fk_matrices(skeleton, local, root_rot, root_pos)
    out = local.copy()
    for side in SIDES:
        group = f"{side}Hand"
        arm, fore, hand = (names.index(f"{side}{j}") for j in ("Arm", "ForeArm", "Hand"))
        target = wpos[:, hand].copy()
        hrot = wrot[:, hand].copy()
        touched = np.zeros(frames, bool)
        for i in range(1, len(keys)):
            leave = group in keys[i - 1].support and group not in keys[i].support
            arrive = group not in keys[i - 1].support and group in keys[i].support
            if not (leave or arrive):
                continue
            rows = np.flatnonzero((tl.k1 == i) & (tl.u > 0) & (tl.u < 1))
            if len(rows) < 2:
                continue
            u = tl.u[rows]
            if leave:  # held from the transition's first frame, then carried off
                anchor = rows[0] - 1 if rows[0] > 0 else rows[0]
                w = _minjerk((u - HAND_PLANTED_SHARE) / (1 - HAND_PLANTED_SHARE))
            else:  # carried to where the key puts it, then held
                anchor = min(rows[-1] + 1, frames - 1)
                w = 1 - _minjerk(u / (1 - HAND_PLANTED_SHARE))
            # w: 0 = held at the anchor, 1 = the designed motion
            q0 = matrix_to_quat(np.broadcast_to(wrot[anchor, hand], (len(rows), 3, 3)))
            target[rows] = (1 - w)[:, None] * wpos[anchor, hand] + w[:, None] * wpos[rows, hand]
            target[rows, 2] += HAND_LIFT_M * np.sin(np.pi * w)
            hrot[rows] = quat_to_matrix(quat_slerp(q0, matrix_to_quat(wrot[rows, hand]), w))
            touched[rows] = True
        if not touched.any():
            continue
        rows = np.flatnonzero(touched)
        arm_ik(skeleton, side, wrot, wpos, out, rows, target[rows], hrot[rows])
    return out


def arm_ik(skeleton: Skeleton, side: str, wrot, wpos, out: np.ndarray, rows, target, hand_rot) -> None:
    """Two-bone IK of one arm on frames ``rows``: the wrist (``<side>Hand`` joint) on ``target``
    (n, 3) with the hand's world rotation ``hand_rot`` (n, 3, 3), the elbow on the side the
    motion had it; writes the Arm, ForeArm and Hand local rotations into ``out`` (F, J, 3, 3)
    (``wrot``/``wpos``: the motion's world joint rotations and positions)."""
    names = skeleton.names
    rest = skeleton.rest_positions
    arm, fore, hand = (names.index(f"{side}{j}") for j in ("Arm", "ForeArm", "Hand"))
    shoulder = wpos[rows, arm]
    l1 = np.linalg.norm(rest[fore] - rest[arm])
    l2 = np.linalg.norm(rest[hand] - rest[fore])
    d_vec = target - shoulder
    d = np.clip(np.linalg.norm(d_vec, axis=1), abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4)
    u_ = d_vec / np.linalg.norm(d_vec, axis=1, keepdims=True)
    a = (l1**2 - l2**2 + d**2) / (2 * d)
    h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
    pole = wpos[rows, fore] - shoulder  # the designed elbow's side
    v = pole - u_ * np.sum(pole * u_, axis=1, keepdims=True)
    v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-9)
    elbow = shoulder + a[:, None] * u_ + h[:, None] * v
    to_hand = target - elbow
    wrist = elbow + l2 * to_hand / np.maximum(np.linalg.norm(to_hand, axis=1, keepdims=True), 1e-9)
    # world rotations: the upper arm turned onto the elbow, the elbow's own bend kept and
    # the forearm turned onto the wrist, the hand as held
    ra, rf = wrot[rows, arm], wrot[rows, fore]
    arm_w = align_matrix(ra @ (rest[fore] - rest[arm]), elbow - shoulder) @ ra
    fore_w = arm_w @ np.swapaxes(ra, 1, 2) @ rf
    fore_w = align_matrix(fore_w @ (rest[hand] - rest[fore]), wrist - elbow) @ fore_w
    parent = wrot[rows, skeleton.parents[arm]]
    out[rows, arm] = np.swapaxes(parent, 1, 2) @ arm_w
    out[rows, fore] = np.swapaxes(arm_w, 1, 2) @ fore_w
    out[rows, hand] = np.swapaxes(fore_w, 1, 2) @ hand_rot


def _wave(skeleton: Skeleton, loc_q: np.ndarray, tl: Timeline, fps: float, waving) -> np.ndarray:
    """Swing the right forearm about the elbow while the arm is up (a hand wave); ``waving``
    marks the wave keys."""
    info = rig_info(skeleton)
    j = info.index["RightForeArm"]
    t = np.arange(len(tl.s)) / fps
    up = waving[tl.k1] * tl.s + waving[tl.k0] * (1 - tl.s) * (tl.k1 > 0)
    swing = up**2 * np.radians(WAVE_AMPLITUDE_DEG) * np.sin(2 * np.pi * WAVE_HZ * (t - t[np.argmax(up > 0)]))
    extra = matrix_to_quat(axis_angle_matrix(info.elbow_axis["Right"], swing))
    out = loc_q.copy()
    out[:, j] = matrix_to_quat(quat_to_matrix(loc_q[:, j]) @ quat_to_matrix(extra))
    return out


# ------------------------------------------------------------------------- contact measure
def body_contact_report(ground: C.Ground, posed: np.ndarray, fps: float, tol: float = CONTACT_TOL) -> dict:
    """Penetration and slip of skinned body points (F, n, 3).

    * body_penetration_m: depth of the deepest point below the ground over the clip;
    * body_max_slip_m: for every point, the largest horizontal distance it travels from where
      it came into contact (within ``tol`` of the ground) while it stays in contact (a rolling
      body part moves its contact from point to point and so does not count as slip);
    * body_contact_points: the most points in contact in one frame.
    """
    h = posed[..., 2] - ground.height(posed[..., :2])
    touch = h <= tol
    slip = 0.0
    for j in np.flatnonzero(touch.any(axis=0)):
        for a, b in C.intervals(touch[:, j]):
            xy = posed[a:b, j, :2]
            if b - a > 1:
                slip = max(slip, float(np.max(np.linalg.norm(xy - xy[0], axis=1))))
    return {
        "body_penetration_m": float(max(-h.min(), 0.0)),
        "body_max_slip_m": slip,
        "body_contact_points": int(touch.sum(axis=1).max()),
    }
