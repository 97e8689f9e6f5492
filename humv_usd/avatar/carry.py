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
"""
from __future__ import annotations

import dataclasses

import numpy as np

from humv_usd.avatar.skeleton import Skeleton, forward_kinematics

#: The rifle's own frame (see :data:`humv_usd.clothing.garments.RIFLE`): x to the muzzle,
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
ARM_JOINTS = tuple(f"{s}{j}" for s in ("Right", "Left")
                   for j in ("Shoulder", "Arm", "ForeArm", "Hand"))


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
    return {s: skeleton.tail_positions[skeleton.index(f"{s}Hand")]
            - skeleton.rest_positions[skeleton.index(f"{s}Hand")] for s in ("Right", "Left")}


def rifle_frame(skeleton: Skeleton) -> np.ndarray:
    """4x4 transform rifle frame -> Hips' frame (origin at the Hips joint, rest axes)."""
    hip_height = skeleton.rest_positions[0, 2]
    right = _RIGHT_GRASP * hip_height
    left = right + GRIP_SPAN * _unit(_SPAN_DIR)
    # the handguard point at GRIP_SPAN from the grip point, in the rifle's frame
    dz = RIFLE_HANDGUARD_Z - RIFLE_GRIP[2]
    guard = np.array([np.sqrt(GRIP_SPAN ** 2 - dz ** 2), 0.0, RIFLE_HANDGUARD_Z])
    local_axis = _unit(guard - RIFLE_GRIP)
    # rifle axes: x along the barrel; y (its side) towards the body (+Y) as far as possible
    world_axis = _unit(left - right)
    # rotate the rifle about its y so the grip->guard line becomes the barrel-ish axis
    x = _unit(world_axis)
    y = np.array([0.0, 1.0, 0.0]) - x * x[1]
    y = _unit(y)
    z = np.cross(x, y)
    frame = np.stack([x, y, z], 1)                 # rifle-line frame -> Hips' frame
    tilt = _min_rotation(local_axis, np.array([1.0, 0.0, 0.0]))   # rifle -> line frame
    rot = frame @ tilt
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = right - rot @ RIFLE_GRIP
    return out


def grasp_targets(skeleton: Skeleton) -> dict[str, np.ndarray]:
    """The hands' grasp points in the Hips' frame: grip and the handguard point."""
    m = rifle_frame(skeleton)
    dz = RIFLE_HANDGUARD_Z - RIFLE_GRIP[2]
    guard = np.array([np.sqrt(GRIP_SPAN ** 2 - dz ** 2), 0.0, RIFLE_HANDGUARD_Z])
    return {"Right": m[:3, :3] @ RIFLE_GRIP + m[:3, 3], "Left": m[:3, :3] @ guard + m[:3, 3]}


def _two_bone(s, t, l1, l2, pole):
    """Elbow positions (F, 3) for shoulders ``s`` and wrist targets ``t`` (F, 3)."""
    d_vec = t - s
    d = np.linalg.norm(d_vec, axis=1)
    d = np.clip(d, abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4)
    u = _unit(d_vec)
    a = (l1 ** 2 - l2 ** 2 + d ** 2) / (2 * d)
    h = np.sqrt(np.maximum(l1 ** 2 - a ** 2, 0.0))
    v = pole - u * np.einsum("fi,fi->f", pole, u)[:, None]
    v = _unit(v)
    return s + a[:, None] * u + h[:, None] * v


def apply_rifle_carry(motion, skeleton: Skeleton):
    """``motion`` with both arms in the rifle carry in every frame (see module doc)."""
    q = np.array(motion.local_rotations, dtype=float, copy=True)
    names = skeleton.names
    for name in ARM_JOINTS:                      # clavicles at rest, the rest solved below
        q[:, names.index(name)] = (1.0, 0.0, 0.0, 0.0)
    world = forward_kinematics(skeleton, q, motion.root_translation)
    hips_r, hips_p = world[:, 0, :3, :3], world[:, 0, :3, 3]
    targets = grasp_targets(skeleton)
    offsets = grasp_offsets(skeleton)
    hand_dirs = {"Right": _RIGHT_HAND_DIR, "Left": _LEFT_HAND_DIR}
    rest = skeleton.rest_positions
    for side in ("Right", "Left"):
        arm, fore, hand = (names.index(f"{side}{j}") for j in ("Arm", "ForeArm", "Hand"))
        hand_local = _hand_rotation(skeleton, side, hand_dirs[side])      # in Hips' frame
        hand_world = hips_r @ hand_local                                  # (F, 3, 3)
        grasp = hips_p + hips_r @ targets[side]
        wrist = grasp - hand_world @ offsets[side]
        shoulder = world[:, arm, :3, 3]
        upper, lower = rest[fore] - rest[arm], rest[hand] - rest[fore]
        elbow = _two_bone(shoulder, wrist, np.linalg.norm(upper), np.linalg.norm(lower),
                          hips_r @ _POLES[side])
        parent = world[:, skeleton.parents[arm], :3, :3]
        arm_world = _min_rotation(upper, elbow - shoulder)
        fore_world = _min_rotation(arm_world @ lower, wrist - elbow) @ arm_world
        q[:, arm] = _matrix_to_quat(np.swapaxes(parent, 1, 2) @ arm_world)
        q[:, fore] = _matrix_to_quat(np.swapaxes(arm_world, 1, 2) @ fore_world)
        q[:, hand] = _matrix_to_quat(np.swapaxes(fore_world, 1, 2) @ hand_world)
    return dataclasses.replace(motion, local_rotations=q)


def carry_rest_transform(skeleton: Skeleton) -> np.ndarray:
    """4x4 transform rifle frame -> rest pose such that, bound rigidly to RightHand, the rifle
    is at the carry pose's hands (computed on frame 0 of a standing rest motion; the rifle is
    then fixed in the Hips' frame in every frame of any motion)."""
    @dataclasses.dataclass
    class _Still:
        local_rotations: np.ndarray
        root_translation: np.ndarray
    q = np.zeros((1, len(skeleton.names), 4))
    q[..., 0] = 1.0
    root = skeleton.rest_positions[:1].copy()
    q = apply_rifle_carry(_Still(q, root), skeleton).local_rotations
    world = forward_kinematics(skeleton, q, root)[0]
    j = skeleton.index("RightHand")
    skin = world[j].copy()                          # world pose times the inverse rest pose
    skin[:3, 3] -= world[j, :3, :3] @ skeleton.rest_positions[j]
    return np.linalg.inv(skin) @ world[0] @ rifle_frame(skeleton)
