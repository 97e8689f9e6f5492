"""A two-handed rifle carry (low port arms) applied on top of any motion.

:func:`apply_rifle_carry` overrides the rotations of both arms (Shoulder, Arm, ForeArm, Hand
of each side) in every frame; legs, spine, head and the root keep the motion's values.

The carry is defined in the Hips joint's frame (rest-aligned axes: +Z up, the body faces -Y,
+X is the person's left; origin at the Hips joint), scaled by the body's hip height:

* the rifle's pose (:func:`rifle_frame`) is constant in that frame: its grip (the right
  hand's grasp point) in front of the right hip at waist height, its length axis running
  up, forward and to the person's left, so the left hand's grasp point on the handguard is
  :data:`GRIP_SPAN` ahead/left of the right one at low chest height;
* each hand keeps a constant orientation in that frame (the rifle is bound rigidly to the
  right hand, so it stays fixed in the Hips' frame); its grasp point is the hand bone's tail
  (the finger base, the palm's centre);
* the wrist is put where that grasp point lands on its target by a two-bone IK per arm
  (shoulder -> elbow -> wrist, law of cosines), the elbow bent down and out (pole vector);
  each segment takes the minimal rotation from its rest direction.

Clearance (with the person's body, :func:`clear_rifle`): the fixed carry can cut into a
bent trunk or a raised thigh (a squat, a bow, a high knee in a run or a BVH clip). Per frame
the rifle is then translated in the Hips' frame, with both hands, until every body vertex
except the holding hands and forearms is :data:`CLEARANCE` off the rifle's solid (its boxes
and cylinders, closed-form distance :func:`prop_signed_distance`), and the arms' IK is
re-solved; offsets are smoothed over time. The clothing layer measures the result on the
authored motion per frame (customData ``humv:prop``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from humv_usd.catalog.garments import RIFLE
from humv_usd.human import labels as L
from humv_usd.human.skeleton import Skeleton, forward_kinematics, skin_weights, skinning_matrices

#: The rifle's own frame (see :data:`humv_usd.catalog.garments.RIFLE`): x to the muzzle,
#: origin at the pistol grip's top. Right-hand grasp on the grip, left on the handguard axis.
RIFLE_GRIP = np.array([0.0, 0.0, -0.065])
RIFLE_HANDGUARD_Z = 0.015
#: Right grasp point in the Hips' frame, as fractions of the hip height (x, y, z).
_RIGHT_GRASP = np.array([-0.10, -0.30, 0.06]) / 0.957
#: Direction from the right grasp point to the left one (Hips' frame) and its length [m].
_SPAN_DIR = np.array([0.30, -0.13, 0.20])
GRIP_SPAN = 0.38
#: The hands' wrist->finger-base directions in the Hips' frame.
_RIGHT_HAND_DIR = np.array([0.25, -1.0, -0.35])
_LEFT_HAND_DIR = np.array([-0.45, -1.0, -0.15])
#: Elbow pole directions (down, out, a little back).
_POLES = {"Right": np.array([-0.6, 0.3, -1.0]), "Left": np.array([0.6, 0.3, -1.0])}
ARM_JOINTS = tuple(f"{s}{j}" for s in ("Right", "Left") for j in ("Shoulder", "Arm", "ForeArm", "Hand"))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the smallest rotations taking directions ``a`` to ``b``."""
    a, b = _unit(np.asarray(a, float)), _unit(np.asarray(b, float))
    a, b = np.broadcast_arrays(a, b)
    v = np.cross(a, b)
    c = np.einsum("...i,...i->...", a, b)
    k = np.zeros(a.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    scale = 1.0 / np.maximum(1.0 + c, 1e-9)
    return np.eye(3) + k + (k @ k) * scale[..., None, None]


def _matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions (w, x, y, z), w >= 0."""
    m = np.asarray(m, float)
    w = np.sqrt(np.maximum(0.0, 1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2])) / 2
    x = np.sqrt(np.maximum(0.0, 1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2])) / 2
    y = np.sqrt(np.maximum(0.0, 1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2])) / 2
    z = np.sqrt(np.maximum(0.0, 1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2])) / 2
    x = np.copysign(x, m[..., 2, 1] - m[..., 1, 2])
    y = np.copysign(y, m[..., 0, 2] - m[..., 2, 0])
    z = np.copysign(z, m[..., 1, 0] - m[..., 0, 1])
    return _unit(np.stack([w, x, y, z], -1))


def _hand_rotation(skeleton: Skeleton, side: str, direction: np.ndarray) -> np.ndarray:
    """Constant hand rotation in the Hips' frame: the rest hand bone turned onto ``direction``."""
    j = skeleton.index(f"{side}Hand")
    return _min_rotation(skeleton.tail_positions[j] - skeleton.rest_positions[j], direction)


def grasp_offsets(skeleton: Skeleton) -> dict[str, np.ndarray]:
    """Rest offset wrist -> grasp point (the hand bone's tail) per side."""
    return {
        s: skeleton.tail_positions[skeleton.index(f"{s}Hand")]
        - skeleton.rest_positions[skeleton.index(f"{s}Hand")]
        for s in ("Right", "Left")
    }


def rifle_frame(skeleton: Skeleton) -> np.ndarray:
    """4x4 transform rifle frame -> Hips' frame (origin at the Hips joint, rest axes)."""
    hip_height = skeleton.rest_positions[0, 2]
    right = _RIGHT_GRASP * hip_height
    left = right + GRIP_SPAN * _unit(_SPAN_DIR)
    # the handguard point at GRIP_SPAN from the grip point, in the rifle's frame
    dz = RIFLE_HANDGUARD_Z - RIFLE_GRIP[2]
    guard = np.array([np.sqrt(GRIP_SPAN**2 - dz**2), 0.0, RIFLE_HANDGUARD_Z])
    local_axis = _unit(guard - RIFLE_GRIP)
    # rifle axes: x along the barrel; y (its side) towards the body (+Y) as far as possible
    world_axis = _unit(left - right)
    # rotate the rifle about its y so the grip->guard line becomes the barrel-ish axis
    x = _unit(world_axis)
    y = np.array([0.0, 1.0, 0.0]) - x * x[1]
    y = _unit(y)
    z = np.cross(x, y)
    frame = np.stack([x, y, z], 1)  # rifle-line frame -> Hips' frame
    tilt = _min_rotation(local_axis, np.array([1.0, 0.0, 0.0]))  # rifle -> line frame
    rot = frame @ tilt
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = right - rot @ RIFLE_GRIP
    return out


def grasp_targets(skeleton: Skeleton) -> dict[str, np.ndarray]:
    """The hands' grasp points in the Hips' frame: grip and the handguard point."""
    m = rifle_frame(skeleton)
    dz = RIFLE_HANDGUARD_Z - RIFLE_GRIP[2]
    guard = np.array([np.sqrt(GRIP_SPAN**2 - dz**2), 0.0, RIFLE_HANDGUARD_Z])
    return {"Right": m[:3, :3] @ RIFLE_GRIP + m[:3, 3], "Left": m[:3, :3] @ guard + m[:3, 3]}


def _two_bone(s, t, l1, l2, pole):
    """Elbow positions (F, 3) for shoulders ``s`` and wrist targets ``t`` (F, 3)."""
    d_vec = t - s
    d = np.linalg.norm(d_vec, axis=1)
    d = np.clip(d, abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4)
    u = _unit(d_vec)
    a = (l1**2 - l2**2 + d**2) / (2 * d)
    h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
    v = pole - u * np.einsum("fi,fi->f", pole, u)[:, None]
    v = _unit(v)
    return s + a[:, None] * u + h[:, None] * v


def _solve_arms(
    motion,
    skeleton: Skeleton,
    offsets: np.ndarray | None = None,
    targets: dict | None = None,
    hand_dirs: dict | None = None,
    poles: dict | None = None,
    sides: tuple[str, ...] = ("Right", "Left"),
    frame_joint: str = "Hips",
) -> np.ndarray:
    """(F, J, 4) local rotations: ``motion``'s with both arms in the carry; ``offsets``
    (F, 3) translate the rifle (and so both grasp points) per frame in the Hips' frame.
    ``targets``/``hand_dirs``/``poles``: grasp points, hand directions (or full 3x3 hand
    rotations) and elbow poles per side in the Hips' frame (default: the rifle's); ``sides``:
    the arms solved (the others keep the motion's rotations); ``frame_joint``: the joint whose
    frame (origin at the joint, rest-aligned axes) the targets are given in, instead of the Hips."""
    q = np.array(motion.local_rotations, dtype=float, copy=True)
    names = skeleton.names
    for name in ARM_JOINTS:  # clavicles at rest, the rest solved below
        if name.startswith(sides):
            q[:, names.index(name)] = (1.0, 0.0, 0.0, 0.0)
    world = forward_kinematics(skeleton, q, motion.root_translation)
    f = names.index(frame_joint)
    hips_r, hips_p = world[:, f, :3, :3], world[:, f, :3, 3]
    targets = grasp_targets(skeleton) if targets is None else targets
    offsets = np.zeros((len(q), 3)) if offsets is None else np.asarray(offsets, float)
    grasp_offset = grasp_offsets(skeleton)
    hand_dirs = {"Right": _RIGHT_HAND_DIR, "Left": _LEFT_HAND_DIR} if hand_dirs is None else hand_dirs
    poles = _POLES if poles is None else poles
    rest = skeleton.rest_positions
    for side in sides:
        arm, fore, hand = (names.index(f"{side}{j}") for j in ("Arm", "ForeArm", "Hand"))
        hand_dir = np.asarray(hand_dirs[side], float)
        hand_local = hand_dir if hand_dir.shape == (3, 3) else _hand_rotation(skeleton, side, hand_dir)
        hand_world = hips_r @ hand_local  # (F, 3, 3)
        grasp = hips_p + np.einsum("fij,fj->fi", hips_r, targets[side] + offsets)
        wrist = grasp - hand_world @ grasp_offset[side]
        shoulder = world[:, arm, :3, 3]
        upper, lower = rest[fore] - rest[arm], rest[hand] - rest[fore]
        elbow = _two_bone(shoulder, wrist, np.linalg.norm(upper), np.linalg.norm(lower), hips_r @ poles[side])
        parent = world[:, skeleton.parents[arm], :3, :3]
        arm_world = _min_rotation(upper, elbow - shoulder)
        fore_world = _min_rotation(arm_world @ lower, wrist - elbow) @ arm_world
        q[:, arm] = _matrix_to_quat(np.swapaxes(parent, 1, 2) @ arm_world)
        q[:, fore] = _matrix_to_quat(np.swapaxes(arm_world, 1, 2) @ fore_world)
        q[:, hand] = _matrix_to_quat(np.swapaxes(fore_world, 1, 2) @ hand_world)
    return q


def apply_rifle_carry(
    motion,
    skeleton: Skeleton,
    body=None,
    *,
    clearance: float | None = None,
    report: dict | None = None,
    prop=None,
):
    """``motion`` with both arms in the rifle carry in every frame (see module doc).

    ``body``: the person's :class:`humv_usd.human.body.Body` (or its :class:`CarryBody`):
    the carry is then moved per frame until the rifle clears the body by ``clearance`` [m]
    (default :data:`CLEARANCE`; :func:`clear_rifle`); ``report`` (a dict) receives the
    clearance before/after per frame. Without ``body`` the carry is fixed in the Hips' frame
    (no collision check). ``prop``: the long gun (default the rifle; see :func:`clear_rifle`).
    """
    if body is None:
        q = _solve_arms(motion, skeleton)
    else:
        cb = body if isinstance(body, CarryBody) else carry_body(body, skeleton)
        q, rep = clear_rifle(motion, skeleton, cb, CLEARANCE if clearance is None else clearance, prop)
        if report is not None:
            report.update(rep)
    return dataclasses.replace(motion, local_rotations=q)


# ---------------------------------------------------------------------------- a box in both hands
#: A box carried in front with both hands (the ``carry`` activity): its centre in the Hips'
#: frame as fractions of the hip height (ahead, at the navel), its default width [m]; the palms
#: press on its sides, fingers forward, elbows bent down and a little out.
BOX_CENTRE = np.array([0.0, -0.33, 0.17]) / 0.957
BOX_WIDTH_M = 0.36
_BOX_HAND_DIRS = {"Right": np.array([0.25, -1.0, 0.0]), "Left": np.array([-0.25, -1.0, 0.0])}
_BOX_POLES = {"Right": np.array([-0.4, 0.5, -1.0]), "Left": np.array([0.4, 0.5, -1.0])}


def box_grasp_targets(skeleton: Skeleton, width_m: float = BOX_WIDTH_M) -> dict[str, np.ndarray]:
    """The palms' grasp points (Hips' frame) on the two sides of the carried box."""
    centre = BOX_CENTRE * skeleton.rest_positions[0, 2]
    half = np.array([width_m / 2, 0.0, 0.0])
    return {"Right": centre - half, "Left": centre + half}


def apply_box_carry(motion, skeleton: Skeleton, width_m: float = BOX_WIDTH_M):
    """``motion`` with both arms holding a box of ``width_m`` in front of the body in every
    frame (two-bone arm IK to grasp points fixed in the Hips' frame, as the rifle carry; no
    prop is authored and no clearance is checked)."""
    q = _solve_arms(
        motion,
        skeleton,
        targets=box_grasp_targets(skeleton, width_m),
        hand_dirs=_BOX_HAND_DIRS,
        poles=_BOX_POLES,
    )
    return dataclasses.replace(motion, local_rotations=q)


@dataclasses.dataclass
class _Still:
    """A one-frame motion (what :func:`_solve_arms` poses)."""

    local_rotations: np.ndarray
    root_translation: np.ndarray


def _rest_frame(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """Identity joint rotations (1, J, 4) and the rest root position (1, 3) of one frame."""
    q = np.zeros((1, len(skeleton.names), 4))
    q[..., 0] = 1.0
    return q, skeleton.rest_positions[:1].copy()


def carry_rest_transform(skeleton: Skeleton) -> np.ndarray:
    """4x4 transform rifle frame -> rest pose such that, bound rigidly to RightHand, the rifle
    is at the carry pose's hands (computed on frame 0 of a standing rest motion; the rifle is
    then fixed in the Hips' frame in every frame of any motion)."""

    q, root = _rest_frame(skeleton)
    q = _solve_arms(_Still(q, root), skeleton)
    world = forward_kinematics(skeleton, q, root)[0]
    j = skeleton.index("RightHand")
    skin = world[j].copy()  # world pose times the inverse rest pose
    skin[:3, 3] -= world[j, :3, :3] @ skeleton.rest_positions[j]
    return np.linalg.inv(skin) @ world[0] @ rifle_frame(skeleton)


# ---------------------------------------------------------------------------- clearance
#: Default rifle-body clearance [m] (skin to the rifle's surface): clears the outermost
#: garment (a uniform jacket over a shirt ends ~25 mm off the skin) with a few mm to spare.
CLEARANCE = 0.03
#: Body regions that may touch the rifle: the gripping hands and the forearms along it.
HOLDING_REGIONS = ("leftHand", "rightHand", "leftLowerArm", "rightLowerArm")
#: Search passes per clearance round (each moves the violating frames' carry once).
CLEAR_PASSES = 4
#: Shifts tried [m] along each of :data:`_SHIFT_DIRECTIONS` (and the distance gradient).
SHIFT_STEPS = 0.005 * 2.0 ** (np.arange(14) / 2)  # 5 mm .. 0.45 m
#: Unit directions (Hips' frame) to the faces, edges and corners of a cube.
_SHIFT_DIRECTIONS = np.array(
    [[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if (x, y, z) != (0, 0, 0)],
    dtype=float,
)
_SHIFT_DIRECTIONS /= np.linalg.norm(_SHIFT_DIRECTIONS, axis=1, keepdims=True)
#: Gaussian smoothing of the per-frame carry offsets over time [s] (no popping).
SMOOTH_S = 0.1
_FRAME_CHUNK = 32


@dataclasses.dataclass(frozen=True)
class CarryBody:
    """The body vertices the rifle must clear (all but :data:`HOLDING_REGIONS`), rest pose,
    with their skinning."""

    points: np.ndarray  # (n, 3) [m]
    joint_indices: np.ndarray  # (n, k)
    joint_weights: np.ndarray  # (n, k)


def carry_body(body, skeleton: Skeleton) -> CarryBody:
    """:class:`CarryBody` of a :class:`humv_usd.human.body.Body` (the avatar layer's
    skinning and body-region labels)."""
    mesh = body.body_mesh()
    idx, w = skin_weights(skeleton, mesh.vertex_ids, 4)
    return carry_body_of(mesh, idx, w, L.body_regions(mesh, skeleton, idx, w))


def carry_body_of(mesh, joint_indices, joint_weights, face_regions) -> CarryBody:
    """:class:`CarryBody` of a body mesh (``face_counts``, ``face_indices``, ``points``) with
    its skinning and per-face body regions."""
    counts = np.asarray(mesh.face_counts)
    face_of = np.repeat(np.arange(len(counts)), counts)
    holding = np.isin(face_regions, [L.REGION_ID[r] for r in HOLDING_REGIONS])
    keep = np.zeros(len(mesh.points), dtype=bool)
    keep[np.asarray(mesh.face_indices)[~holding[face_of]]] = True
    return CarryBody(
        np.asarray(mesh.points)[keep], np.asarray(joint_indices)[keep], np.asarray(joint_weights)[keep]
    )


def prop_signed_distance(points: np.ndarray, prop=None) -> np.ndarray:
    """Signed distance [m] of ``points`` (prop frame) to a prop's solid (default the rifle):
    the union of its boxes and x-axis cylinders, < 0 inside. Exact for each convex shape
    (box: Quilez's box distance; cylinder: the same in (axial, radial) coordinates); the
    union is the minimum, exact outside. The mesh's octagonal cylinders lie within the
    round ones (inscribed; at most 0.08 r inside them), so this errs on the safe side."""
    if prop is None:
        prop = RIFLE
    p = np.asarray(points, dtype=np.float64)
    out = np.full(p.shape[:-1], np.inf)
    for s in prop.shapes:
        d = p - np.asarray(s.centre)
        if s.radius <= 0:
            q = np.abs(d) - np.asarray(s.size) / 2
        else:
            q = np.stack([np.abs(d[..., 0]) - s.size[0] / 2, np.hypot(d[..., 1], d[..., 2]) - s.radius], -1)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
        inside = np.minimum(q.max(axis=-1), 0.0)
        out = np.minimum(out, outside + inside)
    return out


def _in_rifle_frame(cb: CarryBody, skin: np.ndarray, to_rifle: np.ndarray) -> np.ndarray:
    """(f, n, 3) the posed body vertices (linear blend skinning) in the rifle's frame."""
    dense = np.zeros((len(cb.points), skin.shape[1]))  # (n, J) skin weights
    np.add.at(
        dense,
        (np.repeat(np.arange(len(cb.points)), cb.joint_indices.shape[1]), cb.joint_indices.ravel()),
        cb.joint_weights.astype(np.float64).ravel(),
    )
    joint = (to_rifle[:, None] @ skin)[..., :3, :].reshape(len(skin), -1, 12)
    blended = (dense @ joint).reshape(len(skin), -1, 3, 4)
    return np.einsum("fvij,vj->fvi", blended[..., :3], cb.points) + blended[..., 3]


def _union_distance(local: np.ndarray, prop) -> np.ndarray:
    """(f, n) :func:`prop_signed_distance`, exact wherever it can be a frame's minimum or
    negative; elsewhere the (lower) distance to the prop's bounding box. The box distance
    bounds the solid's from below, so a point whose box distance exceeds the exact distance
    of the frame's box-nearest point cannot be the closest one."""
    lo, hi = _prop_box(prop)
    q = np.abs(local - (lo + hi) / 2) - (hi - lo) / 2
    out = np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)
    rows = np.arange(len(local))
    near = np.argmin(out, axis=1)
    bound = prop_signed_distance(local[rows, near], prop)
    f, v = np.nonzero(out <= bound[:, None])
    out[f, v] = prop_signed_distance(local[f, v], prop)
    return out


def _prop_box(prop) -> tuple[np.ndarray, np.ndarray]:
    if prop is None:
        prop = RIFLE
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for s in prop.shapes:
        half = (
            np.asarray(s.size, float) / 2 if s.radius <= 0 else np.array([s.size[0] / 2, s.radius, s.radius])
        )
        c = np.asarray(s.centre, float)
        lo, hi = np.minimum(lo, c - half), np.maximum(hi, c + half)
    return lo, hi


def rifle_world(skeleton: Skeleton, skin: np.ndarray) -> np.ndarray:
    """(F, 4, 4) rifle frame -> skeleton space per frame, for skinning matrices ``skin``
    (F, J, 4, 4): the rifle is bound rigidly to RightHand at :func:`carry_rest_transform`."""
    return skin[:, skeleton.index("RightHand")] @ carry_rest_transform(skeleton)


def rifle_clearance(
    cb: CarryBody, skeleton: Skeleton, skin: np.ndarray, prop=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame: (min signed distance [m] of the body's non-holding vertices to the rifle
    solid, number of them inside it, the rifle-frame position of the closest one)."""
    skin = np.asarray(skin, dtype=np.float64)
    to_rifle = np.linalg.inv(rifle_world(skeleton, skin))
    frames = len(skin)
    dmin, inside, worst = np.empty(frames), np.empty(frames, dtype=int), np.empty((frames, 3))
    for a in range(0, frames, _FRAME_CHUNK):
        b = min(a + _FRAME_CHUNK, frames)
        local = _in_rifle_frame(cb, skin[a:b], to_rifle[a:b])
        d = _union_distance(local, prop)
        k = np.argmin(d, axis=1)
        dmin[a:b] = d[np.arange(b - a), k]
        inside[a:b] = (d < 0).sum(axis=1)
        worst[a:b] = local[np.arange(b - a), k]
    return dmin, inside, worst


def prop_distance_gradient(p: np.ndarray, prop=None, eps: float = 1e-4) -> np.ndarray:
    """(F, 3) unit gradients of :func:`prop_signed_distance` at ``p`` (central differences)."""
    g = np.stack(
        [
            prop_signed_distance(p + eps * e, prop) - prop_signed_distance(p - eps * e, prop)
            for e in np.eye(3)
        ],
        -1,
    )
    n = np.linalg.norm(g, axis=-1, keepdims=True)
    return np.where(n > 0, g / np.maximum(n, 1e-12), [0.0, 1.0, 0.0])


def _best_shift(
    local: np.ndarray, to_local: np.ndarray, worst: np.ndarray, clearance: float, prop=None
) -> np.ndarray:
    """The shortest Hips-frame shift of the rifle (:data:`SHIFT_STEPS` along the distance
    gradient at the closest body vertex or any of :data:`_SHIFT_DIRECTIONS`) after which
    every body point ``local`` (rifle frame) is ``clearance`` off the solid (of the shifts of
    that length that do, the one leaving the most room); if none clears, the one that leaves
    the largest clearance. A shift of length s can only bring points nearer than
    s + clearance to the rifle's bounding box into play: only those are checked."""
    grad_local = prop_distance_gradient(worst[None], prop)[0]  # body -> out, rifle frame
    dirs = np.vstack([-(to_local.T @ grad_local), _SHIFT_DIRECTIONS])
    lo, hi = _prop_box(prop)
    q = np.abs(local - (lo + hi) / 2) - (hi - lo) / 2
    box = np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(axis=-1), 0.0)
    best, best_d = dirs[0] * SHIFT_STEPS[-1], -np.inf
    for step in SHIFT_STEPS:
        near = local[box < step + clearance + 1e-3]
        shifts = step * dirs  # Hips' frame
        if not len(near):
            return shifts[0]
        moved = near[None] - (shifts @ to_local.T)[:, None, :]
        d = _union_distance(moved, prop).min(axis=1)
        k = int(np.argmax(d))
        if d[k] >= clearance + 1e-3:
            return shifts[k]
        if d[k] > best_d:
            best, best_d = shifts[k], d[k]
    return best


def clear_rifle(
    motion, skeleton: Skeleton, cb: CarryBody, clearance: float = CLEARANCE, prop=None
) -> tuple[np.ndarray, dict]:
    """Arms in the carry with the rifle at least ``clearance`` off the body in every frame.

    Start from the fixed carry. Where a frame's closest non-holding body vertex is nearer
    than ``clearance`` to the rifle solid (:func:`rifle_clearance`), translate that frame's
    rifle (the carry, in the Hips' frame) by the shortest shift that clears every body
    vertex (:func:`_best_shift`: along the solid's distance gradient at the closest vertex
    or 26 cube directions, lengths :data:`SHIFT_STEPS`) and re-solve both arms' IK (the
    rifle is rigid with the right hand, so the re-solved pose is re-checked, not assumed);
    up to :data:`CLEAR_PASSES` passes. The offsets are then smoothed over :data:`SMOOTH_S`
    and the passes repeated on frames the smoothing left too close, so the rifle moves ahead
    of a contact instead of popping. Limits: translation only (no re-orientation of the
    rifle); a frame that still fails (e.g. out of the arms' reach: ``graspErrorMax_m``) is
    reported, not hidden. Returns (local rotations, report: per-frame min distance and
    vertices inside before/after, offset length, the hands' worst grasp error). ``prop``: the
    long gun carried (default the rifle; any :class:`~humv_usd.catalog.garments.Prop` in the
    rifle's frame, e.g. the shotgun).
    """
    frames = len(motion.local_rotations)
    fps = float(getattr(motion, "fps", 30.0))
    offsets = np.zeros((frames, 3))

    def solve(off):
        q = _solve_arms(motion, skeleton, off)
        world = forward_kinematics(skeleton, q, motion.root_translation)
        return q, world, rifle_clearance(cb, skeleton, skinning_matrices(skeleton, world), prop)

    def push(off, q, world, check):
        for _ in range(CLEAR_PASSES):
            d = check[0]
            bad = np.flatnonzero(d < clearance)
            if not len(bad):
                break
            skin = skinning_matrices(skeleton, world[bad])
            rifle = rifle_world(skeleton, skin)
            local = _in_rifle_frame(cb, skin, np.linalg.inv(rifle))
            # rifle-frame axes of the Hips' frame: a Hips-frame shift delta moves the rifle by
            # to_local @ delta in its own frame
            to_local = np.swapaxes(rifle[:, :3, :3], 1, 2) @ world[bad, 0, :3, :3]
            for k, f in enumerate(bad):
                off[f] += _best_shift(local[k], to_local[k], check[2][f], clearance, prop)
            q, world, check = solve(off)
        return off, q, world, check

    q, world, check = solve(offsets)
    before = check[0].copy(), check[1].copy()
    offsets, q, world, check = push(offsets, q, world, check)
    if np.any(offsets) and frames > 2:
        from scipy.ndimage import gaussian_filter1d

        for _ in range(2):  # a push after smoothing can leave a step where the smoothed dip was
            offsets = gaussian_filter1d(offsets, max(SMOOTH_S * fps, 1e-3), axis=0, mode="nearest")
            q, world, check = solve(offsets)
            offsets, q, world, check = push(offsets, q, world, check)
    # how well the hands still reach their grasp points (an out-of-reach push shows here)
    targets = grasp_targets(skeleton)
    reach = {}
    for side in ("Right", "Left"):
        j = skeleton.index(f"{side}Hand")
        grasp = world[:, j, :3, 3] + np.einsum(
            "fij,j->fi", world[:, j, :3, :3], grasp_offsets(skeleton)[side]
        )
        target = world[:, 0, :3, 3] + np.einsum("fij,fj->fi", world[:, 0, :3, :3], targets[side] + offsets)
        reach[side] = float(np.linalg.norm(grasp - target, axis=1).max())
    report = {
        "clearance_m": clearance,
        "minDistanceBefore_m": before[0],
        "insideBefore": before[1],
        "minDistanceAfter_m": check[0],
        "insideAfter": check[1],
        "offset_m": np.linalg.norm(offsets, axis=1),
        "graspErrorMax_m": reach,
    }
    return q, report


# ---------------------------------------------------------------------------- props held in one hand
#: Placements of props held in the right hand (:data:`humv_usd.catalog.garments.HELD_PROPS`):
#: ``held_front`` a phone read in front of the chest, ``held_ear`` a phone at the right ear,
#: ``by_handle`` a bag carried by its handle with the arm hanging.
HELD_PLACEMENTS = ("held_front", "held_ear", "by_handle")
#: Gap [m] between the hand's skin and a held prop: the prop is moved along the palm's normal
#: until its closest hand vertex is this far off it (contact, no penetration).
PALM_GAP = 0.002
#: Gap [m] between the phone at the ear and the head (no vertex of the head closer).
EAR_GAP = 0.003
#: Clearance [m] of a bag carried by its handle from the thigh and hip beside it.
BAG_CLEARANCE = 0.04
#: The phone at the ear: its length axis tilted this far [deg] from vertical, the bottom forward
#: (towards the mouth); the ear 1/3 of the way down the phone's length from its top.
EAR_TILT_DEG = 35.0
#: The phone read in front of the chest: its screen tilted this far [deg] from vertical towards
#: the eyes; its centre ahead of the right shoulder (x: towards the mid-line, y: forward, z: up),
#: as fractions of the arm's length (shoulder to wrist).
READ_TILT_DEG = 40.0
_READ_CENTRE = np.array([0.10, -0.62, -0.30])
#: Elbow poles per hold (in the frame the hold is given in).
_HOLD_POLES = {
    "held_front": np.array([-0.7, 0.3, -1.0]),
    "held_ear": np.array([-0.6, -0.4, -1.0]),
    "by_handle": np.array([-0.3, 0.3, -1.0]),
}
_HOLD_FRAME = {"held_front": "Hips", "held_ear": "Head", "by_handle": "Hips"}
#: The ear's height above the Head joint, as a fraction of the head's height above it.
EAR_HEIGHT = 0.30
#: The bag's hand hangs this far below the shoulder, as a fraction of the arm's length.
HANG_DROP = 0.92


def hand_points(points, face_counts, face_indices, face_regions, side: str = "right") -> np.ndarray:
    """Rest points of the body faces labelled ``{side}Hand`` (``face_regions`` per face)."""
    counts = np.asarray(face_counts)
    face_of = np.repeat(np.arange(len(counts)), counts)
    faces = np.asarray(face_regions) == L.REGION_ID[f"{side}Hand"]
    return np.asarray(points)[np.unique(np.asarray(face_indices)[faces[face_of]])]


def body_regions_of(body, skeleton: Skeleton):
    """(body mesh, per-face region ids) as the avatar tool labels them."""
    mesh = body.body_mesh()
    idx, w = skin_weights(skeleton, mesh.vertex_ids, 4)
    return mesh, L.body_regions(mesh, skeleton, idx, w)


@dataclasses.dataclass(frozen=True)
class Palm:
    """The right palm in the rest pose: the grasp point (the hand bone's tail), the palm's
    normal (out of the palm), the fingers' direction (in the palm's plane) and across (normal x
    fingers)."""

    grasp: np.ndarray
    normal: np.ndarray
    fingers: np.ndarray
    across: np.ndarray

    @property
    def rotation(self) -> np.ndarray:
        """Columns (normal, fingers, across): palm frame -> rest."""
        return np.stack([self.normal, self.fingers, self.across], 1)


def palm_frame(skeleton: Skeleton, hand_pts: np.ndarray, side: str = "Right") -> Palm:
    """:class:`Palm` of a hand (``side`` "Right" or "Left"; ``hand_pts`` that hand's rest
    points): the normal is the least-variance axis of the hand's points within 6 cm of the grasp
    point, signed towards the fingertips' curl (the fingers of MakeHuman's rest hand flex a
    little towards the palm)."""
    j = skeleton.index(f"{side}Hand")
    head, tail = skeleton.rest_positions[j], skeleton.tail_positions[j]
    near = hand_pts[np.linalg.norm(hand_pts - tail, axis=1) < 0.06]
    n = np.linalg.svd(near - near.mean(axis=0))[2][2]
    f = _unit((tail - head) - n * ((tail - head) @ n))
    d = hand_pts - tail
    along = d @ f
    tips = d[along >= np.percentile(along, 97)]
    if (tips @ n).mean() < 0:
        n = -n
    return Palm(tail, n, f, np.cross(n, f))


def _grip_rotation(grip) -> np.ndarray:
    """Rotation prop frame -> palm frame (normal, fingers, across) of a prop's grip."""
    _, normal, fingers = (np.asarray(v, float) for v in grip)
    into = -_unit(normal)  # from the palm into the prop, in the prop's frame
    along = _unit(fingers - into * (fingers @ into))
    prop_axes = np.stack([into, along, np.cross(into, along)], 1)  # palm frame -> prop frame
    return prop_axes.T


def held_rest_transform(skeleton: Skeleton, hand_pts: np.ndarray, prop) -> np.ndarray:
    """4x4 transform prop frame -> rest pose of a prop held in the right hand (``prop.grip``):
    the prop's contact point over the grasp point, its outward normal there against the palm's
    normal, its finger direction along the fingers; then moved along the palm's normal until the
    hand's closest vertex is :data:`PALM_GAP` off the prop (exact box distances, so the hand is
    not inside it; the bisection ends within 1e-10 m of it)."""
    palm = palm_frame(skeleton, hand_pts)
    rot = palm.rotation @ _grip_rotation(prop.grip)  # prop -> rest
    contact = np.asarray(prop.grip[0], float)
    m = np.eye(4)
    m[:3, :3] = rot

    def gap(h: float) -> float:
        local = (hand_pts - (palm.grasp + palm.normal * h - rot @ contact)) @ rot
        return float(prop_signed_distance(local, prop).min()) - PALM_GAP

    # the hand is thicker than the palm over the grasp point (thenar, hypothenar, the thumb): the
    # prop rests on the highest of them; bisection on the offset along the palm's normal
    lo, hi = -0.02, 0.12
    if gap(lo) >= 0 or gap(hi) < 0:
        raise ValueError(f"{prop.placement}: no contact offset for the palm in [{lo}, {hi}] m")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) < 0 else (lo, mid)
    m[:3, 3] = palm.grasp + palm.normal * hi - rot @ contact
    return m


def _hold_pose(
    skeleton: Skeleton, body_pts: np.ndarray, prop, rest_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The held prop's wanted pose (rotation prop -> rest, translation) in rest coordinates for
    its placement; ``body_pts``: the rest body's points less the right arm and hand."""
    sh = skeleton.rest_positions[skeleton.index("RightArm")]
    fore, hand = skeleton.index("RightForeArm"), skeleton.index("RightHand")
    arm_len = float(
        np.linalg.norm(skeleton.rest_positions[fore] - sh)
        + np.linalg.norm(skeleton.rest_positions[hand] - skeleton.rest_positions[fore])
    )
    if prop.placement == "held_front":
        a = np.radians(READ_TILT_DEG)
        screen = np.array([0.0, np.sin(a), np.cos(a)])  # the phone's +x: up and back, to the eyes
        top = np.array([0.0, -np.cos(a), np.sin(a)])  # its +z: forward and up
        return np.stack([screen, np.cross(top, screen), top], 1), sh + _READ_CENTRE * arm_len
    if prop.placement == "held_ear":
        a = np.radians(EAR_TILT_DEG)
        screen = np.array([1.0, 0.0, 0.0])  # towards the head
        top = np.array([0.0, np.sin(a), np.cos(a)])  # up and back: the bottom towards the mouth
        rot = np.stack([screen, np.cross(top, screen), top], 1)
        head_z = skeleton.rest_positions[skeleton.index("Head")][2]
        head = body_pts[body_pts[:, 2] > head_z]
        band = head[np.abs(head[:, 2] - (head_z + EAR_HEIGHT * (head[:, 2].max() - head_z))) < 0.01]
        ear = band[np.argmin(band[:, 0])]  # the head's outermost point on the right
        half = max(sh_.size[2] for sh_ in prop.shapes) / 2
        t = ear - top * (half / 3)  # the ear a third of the way down from the phone's top
        t[0] = ear[0] - 0.004 - EAR_GAP
        for _ in range(6):  # the screen EAR_GAP off the head
            gap = float(prop_signed_distance((head - t) @ rot, prop).min())
            if abs(gap - EAR_GAP) < 1e-5:
                break
            t[0] -= EAR_GAP - gap
        return rot, t
    if prop.placement == "by_handle":
        # handle along -y (front to back), the palm's side of it (+y) towards the body, z up
        rot = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        grasp = rest_m[:3, :3].T @ (skeleton.tail_positions[hand] - rest_m[:3, 3])  # prop frame
        t = sh + np.array([0.0, 0.0, -HANG_DROP * arm_len]) - rot @ grasp  # the grasp below the shoulder
        lo, hi = _prop_box(prop)
        side = body_pts[
            (body_pts[:, 2] > t[2] + lo[2]) & (body_pts[:, 2] < t[2] + hi[2]) & (body_pts[:, 0] < 0)
        ]
        t[0] = side[:, 0].min() - BAG_CLEARANCE - hi[1]  # the bag's inner face clear of hip and thigh
        return rot, t
    raise ValueError(f"not a held placement: {prop.placement!r}")


def hold_targets(skeleton: Skeleton, body_pts: np.ndarray, hand_pts: np.ndarray, prop):
    """(frame joint, grasp point, hand rotation, elbow pole) in that joint's frame (origin at the
    joint, rest-aligned axes) that put the right hand, and the prop rigid on it at
    :func:`held_rest_transform`, at the prop's wanted pose (:func:`_hold_pose`)."""
    rest_m = held_rest_transform(skeleton, hand_pts, prop)
    rot_d, t_d = _hold_pose(skeleton, body_pts, prop, rest_m)
    r_h = rot_d @ rest_m[:3, :3].T  # hand rotation (rest -> wanted)
    j = skeleton.index("RightHand")
    head, tail = skeleton.rest_positions[j], skeleton.tail_positions[j]
    wrist = t_d - r_h @ (rest_m[:3, 3] - head)
    grasp = wrist + r_h @ (tail - head)
    frame = _HOLD_FRAME[prop.placement]
    return frame, grasp - skeleton.rest_positions[skeleton.index(frame)], r_h, _HOLD_POLES[prop.placement]


def _rest_parts(body, skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """(body points less the right arm and hand, right-hand points), rest pose."""
    mesh, regions = body_regions_of(body, skeleton)
    pts = np.asarray(mesh.points)
    counts = np.asarray(mesh.face_counts)
    face_of = np.repeat(np.arange(len(counts)), counts)
    vid = np.asarray(mesh.face_indices)
    arm = np.isin(regions, [L.REGION_ID[r] for r in ("rightUpperArm", "rightLowerArm", "rightHand")])
    return pts[np.unique(vid[~arm[face_of]])], hand_points(pts, counts, vid, regions)


def apply_hold(motion, skeleton: Skeleton, body, prop):
    """``motion`` with the right arm holding ``prop`` (a held prop: phone read in front, phone at
    the ear, bag by its handle) in every frame: two-bone IK of the right arm to the grasp point
    and hand rotation of :func:`hold_targets`, fixed in the Hips' (front, bag) or the Head's
    (ear) frame; the left arm keeps the motion's rotations."""
    body_pts, hand_pts = _rest_parts(body, skeleton)
    frame, grasp, r_h, pole = hold_targets(skeleton, body_pts, hand_pts, prop)
    q = _solve_arms(
        motion,
        skeleton,
        targets={"Right": grasp},
        hand_dirs={"Right": r_h},
        poles={"Right": pole},
        sides=("Right",),
        frame_joint=frame,
    )
    return dataclasses.replace(motion, local_rotations=q)


# ---------------------------------------------------------------------------- the carried box
#: The box of the ``carry`` activity (authored by the avatar tool as a wooden crate, rigid on the
#: Hips like the hands' grasp points): depth and height [m]; its width is set by the hands.
BOX_DEPTH_M = 0.30
BOX_HEIGHT_M = 0.25
#: Its back face this far [m] in front of the trunk.
BOX_BODY_CLEARANCE = 0.02


def carried_box(skeleton: Skeleton, body) -> tuple[np.ndarray, np.ndarray]:
    """(centre, size) [m] of the box carried in both hands, in rest coordinates (bound to the
    Hips, it stays between the hands in every frame: the carry's grasp points are fixed in the
    Hips' frame). Centred at :data:`BOX_CENTRE`; its width such that the closest vertex of either
    hand in the carry pose is :data:`PALM_GAP` off its sides (bisection; no hand vertex inside);
    its back face :data:`BOX_BODY_CLEARANCE` in front of the trunk within its width and height."""

    q, root = _rest_frame(skeleton)
    mesh, regions = body_regions_of(body, skeleton)
    q = _solve_arms(
        _Still(q, root),
        skeleton,
        targets=box_grasp_targets(skeleton),
        hand_dirs=box_hand_rotations(skeleton, mesh, regions),
        poles=_BOX_POLES,
    )
    skin = skinning_matrices(skeleton, forward_kinematics(skeleton, q, root))[0]
    idx, w = skin_weights(skeleton, mesh.vertex_ids, 4)
    blend = np.einsum("vk,vkab->vab", w.astype(float), skin[idx])
    posed = np.einsum("vab,vb->va", blend[:, :3, :3], np.asarray(mesh.points, float)) + blend[:, :3, 3]
    counts = np.asarray(mesh.face_counts)
    face_of = np.repeat(np.arange(len(counts)), counts)
    vid = np.asarray(mesh.face_indices)

    def verts(names):
        sel = np.isin(regions, [L.REGION_ID[r] for r in names])
        return posed[np.unique(vid[sel[face_of]])]

    hands = verts(("rightHand", "leftHand"))  # in the carry pose with the palms on the box
    trunk = verts(("chest", "abdomen", "pelvis", "back", "rightUpperLeg", "leftUpperLeg"))
    centre = skeleton.rest_positions[0] + BOX_CENTRE * skeleton.rest_positions[0, 2]
    half = np.array([0.0, BOX_DEPTH_M / 2, BOX_HEIGHT_M / 2])
    # the back face in front of the trunk (the person faces -y)
    near = trunk[
        (np.abs(trunk[:, 0] - centre[0]) < BOX_WIDTH_M / 2) & (np.abs(trunk[:, 2] - centre[2]) < half[2])
    ]
    front_y = centre[1] - half[1]
    back_y = (
        min(centre[1] + half[1], float(near[:, 1].min()) - BOX_BODY_CLEARANCE)
        if len(near)
        else centre[1] + half[1]
    )
    centre[1], half[1] = (front_y + back_y) / 2, (back_y - front_y) / 2

    def gap(hw: float) -> float:
        h = half.copy()
        h[0] = hw
        d = np.abs(hands - centre) - h
        return (
            float((np.linalg.norm(np.maximum(d, 0.0), axis=1) + np.minimum(d.max(axis=1), 0.0)).min())
            - PALM_GAP
        )

    lo, hi = 0.02, BOX_WIDTH_M
    if gap(lo) < 0:
        raise ValueError("the hands in the box carry are closer than the smallest box")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) >= 0 else (lo, mid)
    half[0] = lo
    return centre, 2 * half


#: The fingers' direction on the carried box's sides (forward, a little down), Hips' frame.
_BOX_FINGERS = np.array([0.0, -1.0, -0.2])


def box_hand_rotations(skeleton: Skeleton, mesh, regions) -> dict[str, np.ndarray]:
    """Hand rotations (Hips' frame) of the box carry: each palm (:func:`palm_frame`) facing the
    box (the right one +x, the left one -x), the fingers forward along its side."""
    pts = np.asarray(mesh.points)
    out = {}
    for side, inward in (("Right", 1.0), ("Left", -1.0)):
        palm = palm_frame(
            skeleton,
            hand_points(pts, mesh.face_counts, mesh.face_indices, regions, side.lower()),
            side,
        )
        n = np.array([inward, 0.0, 0.0])
        f = _unit(_BOX_FINGERS - n * (_BOX_FINGERS @ n))
        out[side] = np.stack([n, f, np.cross(n, f)], 1) @ palm.rotation.T
    return out


def apply_box_hold(motion, skeleton: Skeleton, body):
    """``motion`` with both palms on the carried box's sides in every frame (:func:`carried_box`;
    the box carry of :func:`apply_box_carry` with the hands turned by :func:`box_hand_rotations`)."""
    mesh, regions = body_regions_of(body, skeleton)
    q = _solve_arms(
        motion,
        skeleton,
        targets=box_grasp_targets(skeleton),
        hand_dirs=box_hand_rotations(skeleton, mesh, regions),
        poles=_BOX_POLES,
    )
    return dataclasses.replace(motion, local_rotations=q)
