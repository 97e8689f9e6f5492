"""DeepMimic humanoid clips (as shipped with pybullet) converted to CMU-named BVH motion.

Source and licence (checked 2026-11-27, recorded with the fetched files by
``tools/fetch_mocap.py``): the clips ``humanoid3d_*.txt`` of Peng et al. (2018) "DeepMimic:
example-guided deep reinforcement learning of physics-based character skills", ACM TOG 37(4):143,
as shipped in pybullet 3.2.7's source distribution on PyPI
(``examples/pybullet/gym/pybullet_data/data/motions``; the humanoid in ``.../humanoid/
humanoid.urdf``). pybullet's ``LICENSE.txt``: "The files in this repository are licensed under
the zlib license, except for the files under 'Extras' and examples/ThirdPartyLibs" - the
motions folder is neither and carries no licence file of its own (unlike ``bicycle``,
``franka_panda``, ``laikago`` there). The DeepMimic code (pybullet's stablePDPlugin) is MIT,
Copyright (c) 2018 Xue Bin Peng. Upstream, the clips were retargeted from public motion-capture
databases (CMU Graphics Lab: "free for all uses", "you may not resell this data directly, even
in converted form"; SFU); the DeepMimic author states he no longer knows each clip's source
recording (xbpeng/DeepMimic issue #176). So: the clips are fetched at set-up from PyPI under
pybullet's zlib licence (not shipped in this repository), converted locally, used, never resold.

Format of a clip: JSON ``{"Loop": "wrap"|"none", "Frames": [[...44 values...], ...]}``, each
frame = duration [s], root position (3) [m], root rotation (w, x, y, z), then the local
rotations of chest, neck, right hip (w, x, y, z), right knee (angle [rad] about z), right ankle
(4), right shoulder (4), right elbow (1), left hip (4), left knee (1), left ankle (4), left
shoulder (4), left elbow (1) (pybullet ``humanoid_pose_interpolator.py``). Frame: Y up, the
character faces +X, its right is +Z; the rest pose stands with the arms straight down; the
joint offsets are the URDF's ``origin xyz`` times its 0.25 scaling (DeepMimic's humanoid is
1.6 m tall).

Conversion (:func:`clip_to_bvh`): the frame is turned to CMU's convention (Y up, facing +Z,
left +X: a -90 deg turn about Y, applied to the root and, by conjugation, to every local
rotation, since all rest frames are world-aligned); joints get CMU names (chest -> Spine, neck
-> Neck, hips -> Up legs, knees -> Legs, ankles -> Feet, shoulders -> Arms, elbows -> ForeArms,
wrists -> Hands) and rotation channels ``Zrotation Yrotation Xrotation``; a ``wrap`` clip can be
repeated, each cycle moved on by the root's travel over one cycle. The BVH is then retargeted
onto our rig by :func:`humv_usd.human.bvh.motion_from_bvh` (limb rest corrections, scale by hip
height, feet settled on the ground): a scenario uses it with ``human.bvh``.
"""

from __future__ import annotations

import json

import numpy as np
from scipy.spatial.transform import Rotation

from humv_usd.errors import InputError
from humv_usd.human.bvh import BVH, BVHJoint

#: the clips fetched at set-up (the issue's walk, run, jump, crawl, get-up)
CLIPS = ("walk", "run", "jump", "crawl", "getup_faceup", "getup_facedown")
URDF_SCALE = 0.25
#: (our CMU name, DeepMimic parent name, URDF joint origin (unscaled), value slice in a frame,
#: kind) in BVH (depth-first) order; kind 'q' = quaternion wxyz, 'z' = angle about z [rad]
JOINTS = (
    ("Hips", None, (0.0, 0.0, 0.0), slice(4, 8), "q"),
    ("Spine", "Hips", (0.0, 0.944604, 0.0), slice(8, 12), "q"),
    ("Neck", "Spine", (0.0, 0.895576, 0.0), slice(12, 16), "q"),
    ("RightArm", "Spine", (-0.0962, 0.974, 0.73244), slice(25, 29), "q"),
    ("RightForeArm", "RightArm", (0.0, -1.099152, 0.0), slice(29, 30), "z"),
    ("RightHand", "RightForeArm", (0.0, -1.035788, 0.0), None, "fixed"),
    ("LeftArm", "Spine", (-0.0962, 0.974, -0.73244), slice(39, 43), "q"),
    ("LeftForeArm", "LeftArm", (0.0, -1.099152, 0.0), slice(43, 44), "z"),
    ("LeftHand", "LeftForeArm", (0.0, -1.035788, 0.0), None, "fixed"),
    ("RightUpLeg", "Hips", (0.0, 0.0, 0.339548), slice(16, 20), "q"),
    ("RightLeg", "RightUpLeg", (0.0, -1.686184, 0.0), slice(20, 21), "z"),
    ("RightFoot", "RightLeg", (0.0, -1.63948, 0.0), slice(21, 25), "q"),
    ("LeftUpLeg", "Hips", (0.0, 0.0, -0.339548), slice(30, 34), "q"),
    ("LeftLeg", "LeftUpLeg", (0.0, -1.686184, 0.0), slice(34, 35), "z"),
    ("LeftFoot", "LeftLeg", (0.0, -1.63948, 0.0), slice(35, 39), "q"),
)
#: end sites (unscaled, DeepMimic frame): top of the neck link, the hands, the toes (the foot
#: box spans x 0-0.36 at y -0.09 about the ankle, URDF ``right_ankle`` link)
END_SITES = {
    "Neck": (0.0, 0.7, 0.0),
    "RightHand": (0.0, -0.3, 0.0),
    "LeftHand": (0.0, -0.3, 0.0),
    "RightFoot": (0.36, -0.18, 0.0),
    "LeftFoot": (0.36, -0.18, 0.0),
}
FRAME_VALUES = 44
#: BVH rotation channels (R = Rz Ry Rx): the middle axis Y is a limb's twist, which stays far
#: from +-90 deg, while hip flexion (about X) reaches 90 deg in crawling and getting up
ROTATION_ORDER = "ZYX"
#: DeepMimic (Y up, facing +X, right +Z) -> CMU BVH (Y up, facing +Z, left +X): -90 deg about Y
TO_CMU = Rotation.from_euler("y", -90.0, degrees=True).as_matrix()


def parse_clip(text: str, path: str = "<clip>") -> tuple[np.ndarray, bool]:
    """(frames (F, 44), wraps) of a DeepMimic clip's JSON text."""
    try:
        doc = json.loads(text)
        frames = np.asarray(doc["Frames"], dtype=float)
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path}: not a DeepMimic clip (JSON with 'Frames'): {exc}") from None
    if frames.ndim != 2 or frames.shape[1] != FRAME_VALUES or len(frames) < 2:
        raise InputError(f"{path}: expected >= 2 frames of {FRAME_VALUES} values, got shape {frames.shape}")
    return frames, doc.get("Loop") == "wrap"


def _local_matrices(frames: np.ndarray, sl: slice | None, kind: str) -> np.ndarray:
    F = len(frames)
    if kind == "fixed":
        return np.tile(np.eye(3), (F, 1, 1))
    v = frames[:, sl]
    if kind == "z":
        return Rotation.from_euler("z", v[:, :1]).as_matrix()
    q = v / np.linalg.norm(v, axis=1, keepdims=True)
    return Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # wxyz -> scipy's xyzw


def clip_to_bvh(frames: np.ndarray, wraps: bool = False, cycles: int = 1, path: str = "<clip>") -> BVH:
    """A CMU-convention BVH (metres, Y up, facing +Z) of DeepMimic frames; see the module doc.
    ``cycles`` > 1 repeats a wrapping clip (root moved on by its travel per cycle)."""
    if cycles < 1 or (cycles > 1 and not wraps):
        raise InputError(f"{path}: cycles = {cycles}: expected 1, or >= 1 for a wrapping clip")
    dt = frames[:-1, 0]
    if np.ptp(dt) > 1e-4 or dt[0] <= 0:
        raise InputError(
            f"{path}: frame durations differ ({dt.min():g}-{dt.max():g} s): expected one frame time"
        )
    if cycles > 1:
        travel = frames[-1, 1:4] - frames[0, 1:4]
        travel[1] = 0.0  # horizontal only
        parts = [frames[:-1] + 0.0]
        for k in range(1, cycles):
            nxt = frames[:-1].copy() if k < cycles - 1 else frames.copy()
            nxt[:, 1:4] += k * travel
            parts.append(nxt)
        frames = np.vstack(parts)
    names = [j[0] for j in JOINTS]
    A = TO_CMU
    joints, columns, first = [], [], 0
    for name, parent, origin, sl, kind in JOINTS:
        offset = A @ (np.asarray(origin) * URDF_SCALE)
        end = END_SITES.get(name)
        end = None if end is None else A @ (np.asarray(end) * URDF_SCALE)
        local = A @ _local_matrices(frames, sl, kind) @ A.T
        euler = Rotation.from_matrix(local).as_euler(ROTATION_ORDER, degrees=True)
        channels = [f"{c}rotation" for c in ROTATION_ORDER]
        if parent is None:
            channels = ["Xposition", "Yposition", "Zposition", *channels]
            euler = np.column_stack([frames[:, 1:4] @ A.T, euler])
        joints.append(
            BVHJoint(name, -1 if parent is None else names.index(parent), offset, channels, end, first)
        )
        first += len(channels)
        columns.append(euler)
    return BVH(joints, float(dt[0]), np.column_stack(columns), path=path, meta={"source": "DeepMimic"})
