"""The avatar's skeleton: MakeHuman's CMU MotionBuilder rig (31 joints, CMU BVH joint names).

Why this rig: its joint names and hierarchy are those of the CMU motion-capture BVH files, so
CMU-style BVH motion maps one to one; MakeHuman ships CC0 skin weights for it
(``rigs/standard/weights.cmu_mb.json``).

Conventions (the contract between the rig, motion and USD writers):

* Joint order is topological (every parent before its children), root ``Hips`` first.
* Rest frames are **world-aligned**: every joint's rest rotation is the identity and its rest
  local transform is a pure translation (as in BVH). A joint's local rotation therefore turns
  its children about axes that, at rest, are the world axes of our avatar frame: +Z up, the
  body faces -Y, so +X is the person's left. Hip/knee/shoulder flexion is about X, abduction
  about Y (the forward axis), axial rotation about Z for upright segments.
* Quaternions are (w, x, y, z), unit, active rotations.
* Joint positions come from MakeHuman's joint cubes (``joint-*`` groups of base.obj) on the
  fitted body, so they follow the macro targets.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from humv_usd.assets import makehuman_file

RIG = "cmu_mb"


@dataclass(frozen=True)
class Skeleton:
    names: tuple[str, ...]  # joint names, topological order
    parents: np.ndarray  # (J,) parent index, -1 for the root
    rest_positions: np.ndarray  # (J, 3) joint (head) positions at rest, world [m]
    tail_positions: np.ndarray  # (J, 3) bone tail positions at rest, world [m]

    @property
    def paths(self) -> list[str]:
        """UsdSkel joint paths ("Hips/LowerBack/Spine")."""
        out: list[str] = []
        for j, name in enumerate(self.names):
            p = self.parents[j]
            out.append(name if p < 0 else f"{out[p]}/{name}")
        return out

    def index(self, name: str) -> int:
        return self.names.index(name)

    @property
    def rest_local_translations(self) -> np.ndarray:
        """(J, 3) rest translation of each joint relative to its parent (root: absolute)."""
        t = self.rest_positions.copy()
        has_parent = self.parents >= 0
        t[has_parent] -= self.rest_positions[self.parents[has_parent]]
        return t


@lru_cache(maxsize=2)
def rig_definition(rig: str = RIG) -> dict:
    with open(makehuman_file(f"rigs/standard/rig.{rig}.json"), encoding="utf-8") as fh:
        return json.load(fh)


@lru_cache(maxsize=2)
def rig_weights(rig: str = RIG) -> dict[str, list]:
    with open(makehuman_file(f"rigs/standard/weights.{rig}.json"), encoding="utf-8") as fh:
        return json.load(fh)["weights"]


def _topological(rig: dict) -> list[str]:
    order: list[str] = []
    pending = dict(rig)
    while pending:
        ready = sorted(n for n, b in pending.items() if not b["parent"] or b["parent"] in order)
        if not ready:
            raise ValueError(f"rig has a cycle or missing parents: {sorted(pending)}")
        order.extend(ready)
        for n in ready:
            del pending[n]
    return order


def _end_position(end: dict, points: np.ndarray, groups) -> np.ndarray:
    """Position of a bone end by MakeHuman's strategies: CUBE (joint cube centre), MEAN
    (mean of listed vertices), VERTEX (one vertex)."""
    strategy = end["strategy"]
    if strategy == "CUBE":
        return points[np.unique(groups[end["cube_name"]])].mean(axis=0)
    if strategy == "MEAN":
        return points[np.asarray(end["vertex_indices"])].mean(axis=0)
    if strategy == "VERTEX":
        return points[int(end["vertex_index"])]
    raise ValueError(f"unknown joint strategy {strategy!r}")


def skeleton_for(points: np.ndarray, groups, rig: str = RIG) -> Skeleton:
    """The rig's joints placed on a body: ``points`` is the FULL base.obj vertex list in our
    frame (e.g. :attr:`humv_usd.human.body.Body.points`), ``groups`` its OBJ groups."""
    definition = rig_definition(rig)
    names = _topological(definition)
    index = {n: i for i, n in enumerate(names)}
    parents = np.array([index[definition[n]["parent"]] if definition[n]["parent"] else -1 for n in names])
    heads = np.array([_end_position(definition[n]["head"], points, groups) for n in names])
    tails = np.array([_end_position(definition[n]["tail"], points, groups) for n in names])
    return Skeleton(tuple(names), parents, heads, tails)


def skin_weights(
    skeleton: Skeleton, vertex_ids: np.ndarray, max_influences: int = 4, rig: str = RIG
) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex joint indices and weights for the vertices ``vertex_ids`` of the full list.

    Keeps the ``max_influences`` largest weights per vertex and renormalizes them to sum 1;
    vertices without any weight are bound rigidly to the root. Returns (indices (n, k) int32,
    weights (n, k) float32) with k = max_influences (unused slots: index 0, weight 0).
    """
    table = rig_weights(rig)
    n_all = int(max(vertex_ids.max() + 1, 1))
    dense = np.zeros((n_all, len(skeleton.names)), dtype=np.float64)
    for name, pairs in table.items():
        if name not in skeleton.names or not pairs:
            continue
        arr = np.asarray(pairs, dtype=np.float64)
        vid = arr[:, 0].astype(np.int64)
        keep = vid < n_all
        dense[vid[keep], skeleton.index(name)] += arr[keep, 1]
    sub = dense[np.asarray(vertex_ids)]
    k = max_influences
    order = np.argsort(-sub, axis=1)[:, :k]
    weights = np.take_along_axis(sub, order, axis=1)
    total = weights.sum(axis=1, keepdims=True)
    unbound = total[:, 0] <= 0
    weights = np.where(total > 0, weights / np.where(total > 0, total, 1.0), 0.0)
    order[unbound] = 0
    weights[unbound] = 0.0
    weights[unbound, 0] = 1.0
    order = np.where(weights > 0, order, 0)
    return order.astype(np.int32), weights.astype(np.float32)


# ------------------------------------------------------------------------- kinematics
def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (w, x, y, z) -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def forward_kinematics(
    skeleton: Skeleton, local_rotations: np.ndarray, root_translation: np.ndarray
) -> np.ndarray:
    """World joint transforms for each frame.

    local_rotations: (F, J, 4) quaternions (w, x, y, z) of each joint relative to its parent
    (identity = rest); root_translation: (F, 3) world position of the root joint [m].
    Returns (F, J, 4, 4) column-vector matrices (x_world = M @ [x, 1]).
    """
    rot = quat_to_matrix(local_rotations)
    frames, joints = rot.shape[:2]
    local_t = skeleton.rest_local_translations
    world = np.zeros((frames, joints, 4, 4))
    world[..., 3, 3] = 1.0
    for j in range(joints):
        p = skeleton.parents[j]
        if p < 0:
            world[:, j, :3, :3] = rot[:, j]
            world[:, j, :3, 3] = root_translation
        else:
            world[:, j, :3, :3] = world[:, p, :3, :3] @ rot[:, j]
            world[:, j, :3, 3] = world[:, p, :3, :3] @ local_t[j] + world[:, p, :3, 3]
    return world


def skinning_matrices(skeleton: Skeleton, world: np.ndarray) -> np.ndarray:
    """(F, J, 4, 4) world pose times the inverse rest pose (rest frames are translations)."""
    inv_rest = np.tile(np.eye(4), (len(skeleton.names), 1, 1))
    inv_rest[:, :3, 3] = -skeleton.rest_positions
    return world @ inv_rest


def linear_blend_skinning(
    rest_points: np.ndarray, indices: np.ndarray, weights: np.ndarray, skin: np.ndarray
) -> np.ndarray:
    """Linear blend skinning (Magnenat-Thalmann et al. 1988) of rest points for one frame.

    rest_points (V, 3); indices/weights (V, k); skin (J, 4, 4) from :func:`skinning_matrices`.
    """
    mats = skin[indices]  # (V, k, 4, 4)
    blended = np.einsum("vk,vkij->vij", weights.astype(np.float64), mats)
    return np.einsum("vij,vj->vi", blended[:, :3, :3], rest_points) + blended[:, :3, 3]


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (..., 4) quaternions (w, x, y, z)."""
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    return np.concatenate(
        [aw * bw - np.sum(av * bv, -1, keepdims=True), aw * bv + bw * av + np.cross(av, bv)], -1
    )


def dual_quaternions(skin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(J, 4, 4) rigid skinning matrices -> unit dual quaternions: real parts (J, 4) (the
    rotation, w >= 0) and dual parts (J, 4) = ½ (0, t) q (Kavan et al. 2008, eq. 1)."""
    skin = np.asarray(skin, dtype=np.float64)
    xyzw = Rotation.from_matrix(skin[..., :3, :3]).as_quat()
    real = np.concatenate([xyzw[..., 3:], xyzw[..., :3]], -1)
    real *= np.where(real[..., :1] < 0, -1.0, 1.0)
    t = np.concatenate([np.zeros(skin.shape[:-2] + (1,)), skin[..., :3, 3]], -1)
    return real, 0.5 * _quat_mul(t, real)


def dual_quaternion_skinning(
    rest_points: np.ndarray, indices: np.ndarray, weights: np.ndarray, skin: np.ndarray
) -> np.ndarray:
    """Dual quaternion skinning (Kavan, Collins, Žára & O'Sullivan 2008, "Geometric skinning
    with approximate dual quaternion blending", ACM TOG 27(4) 105) of rest points for one frame.

    Same arguments as :func:`linear_blend_skinning`. Each influence's dual quaternion enters the
    blend with the sign of its real part's dot product with the largest influence's (the
    shortest arc; Kavan et al. §4); the blend is divided by its real part's norm and applied as
    a rotation plus translation.
    """
    real, dual = dual_quaternions(skin)
    w = weights.astype(np.float64)
    r, d = real[indices], dual[indices]  # (V, k, 4)
    pivot = r[np.arange(len(w)), np.argmax(w, axis=1)]
    w = w * np.where(np.einsum("vkc,vc->vk", r, pivot) < 0, -1.0, 1.0)
    br = np.einsum("vk,vkc->vc", w, r)
    bd = np.einsum("vk,vkc->vc", w, d)
    norm = np.linalg.norm(br, axis=1, keepdims=True)
    br, bd = br / norm, bd / norm
    rw, rv = br[:, :1], br[:, 1:]
    dw, dv = bd[:, :1], bd[:, 1:]
    p = np.asarray(rest_points, dtype=np.float64)
    rotated = p + 2 * np.cross(rv, np.cross(rv, p) + rw * p)
    return rotated + 2 * (rw * dv - dw * rv + np.cross(rv, dv))
