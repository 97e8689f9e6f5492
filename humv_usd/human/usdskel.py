"""UsdSkel authoring for the avatar: Skeleton, Animation and the skinned body binding.

Maps the rig contract of :mod:`humv_usd.human.skeleton` one to one onto UsdSkel:

* ``Skeleton.joints`` = :attr:`Skeleton.paths` (topological order, ``Hips`` first);
* ``bindTransforms`` = the world (skeleton-space) rest transforms: pure translations to the
  joint heads, because our rest frames are world-aligned;
* ``restTransforms`` = the local rest transforms: pure translations relative to the parent;
* the Animation holds per joint the local translation (the rest translation; the root's is the
  motion's root translation), the rotation (our (w, x, y, z) quaternions as ``GfQuatf``) and a
  unit scale, time-sampled per frame (frame i of a motion at time code ``first_frame + i``).

With these, UsdSkel's skinning (``inverse(bind) * skel-space joint transform``, linear blend) is
exactly :func:`humv_usd.human.skeleton.linear_blend_skinning` of
:func:`~humv_usd.human.skeleton.skinning_matrices` (checked in ``tests/test_avatar_rig.py``).

A motion is any object with ``root_translation`` (F, 3) [m, avatar frame: the root joint's
position] and ``local_rotations`` (F, J, 4) (w, x, y, z) (``rotations`` is accepted as an
alias), e.g. ``humv_usd.human.motion.Motion``; :func:`rest_motion` is the standing rest pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from humv_usd.human.skeleton import Skeleton

#: Joint influences per vertex (``primvars:skel:jointIndices`` / ``jointWeights`` elementSize).
INFLUENCES = 4


@dataclass(frozen=True)
class Pose:
    """A joint motion in the rig contract's terms (what :func:`define_animation` authors)."""

    root_translation: np.ndarray  # (F, 3) root joint position [m], avatar frame
    local_rotations: np.ndarray  # (F, J, 4) unit quaternions (w, x, y, z), identity = rest

    @property
    def frame_count(self) -> int:
        return int(self.root_translation.shape[0])


def rest_motion(skeleton: Skeleton, frames: int = 1) -> Pose:
    """The standing rest pose for ``frames`` frames (identity rotations, root at rest)."""
    q = np.zeros((frames, len(skeleton.names), 4))
    q[..., 0] = 1.0
    return Pose(np.repeat(skeleton.rest_positions[:1], frames, axis=0), q)


def as_pose(motion, skeleton: Skeleton) -> Pose:
    """Validate a motion-like object against ``skeleton`` and return it as a :class:`Pose`."""
    if motion is None:
        return rest_motion(skeleton)
    rot = getattr(motion, "local_rotations", None)
    if rot is None:
        rot = getattr(motion, "rotations", None)
    root = getattr(motion, "root_translation", None)
    if rot is None or root is None:
        raise TypeError(
            "a motion needs root_translation (F, 3) and local_rotations (F, J, 4), "
            f"got {type(motion).__name__}"
        )
    rot = np.asarray(rot, dtype=np.float64)
    root = np.asarray(root, dtype=np.float64)
    joints = len(skeleton.names)
    if rot.ndim != 3 or rot.shape[1:] != (joints, 4) or rot.shape[0] < 1:
        raise ValueError(f"local_rotations must have shape (F, {joints}, 4), got {rot.shape}")
    if root.shape != (rot.shape[0], 3):
        raise ValueError(f"root_translation must have shape ({rot.shape[0]}, 3), got {root.shape}")
    norm = np.linalg.norm(rot, axis=-1, keepdims=True)
    if not (np.all(np.isfinite(rot)) and np.all(np.isfinite(root)) and np.all(norm > 1e-8)):
        raise ValueError("motion has non-finite values or zero quaternions")
    return Pose(root, rot / norm)


# ---------------------------------------------------------------------------- conversions
def _translations(t: np.ndarray) -> Vt.Matrix4dArray:
    out = np.tile(np.eye(4), (len(t), 1, 1))
    out[:, 3, :3] = t  # Gf matrices are row-vector: translation in row 3
    return Vt.Matrix4dArray.FromNumpy(out)


def quatf_array(q_wxyz: np.ndarray) -> Vt.QuatfArray:
    """(J, 4) (w, x, y, z) -> VtQuatfArray (GfQuatf stores imaginary first, real last)."""
    q = np.asarray(q_wxyz, dtype=np.float32)
    return Vt.QuatfArray.FromNumpy(np.ascontiguousarray(q[:, [1, 2, 3, 0]]))


# ---------------------------------------------------------------------------- authoring
def define_skeleton(stage: Usd.Stage, path, skeleton: Skeleton) -> UsdSkel.Skeleton:
    """A UsdSkel.Skeleton with our joints, bind (world rest) and rest (local) transforms."""
    skel = UsdSkel.Skeleton.Define(stage, path)
    skel.CreateJointsAttr(Vt.TokenArray(skeleton.paths))
    skel.CreateJointNamesAttr(Vt.TokenArray(list(skeleton.names)))
    skel.CreateBindTransformsAttr(_translations(skeleton.rest_positions))
    skel.CreateRestTransformsAttr(_translations(skeleton.rest_local_translations))
    return skel


def define_animation(
    stage: Usd.Stage, path, skeleton: Skeleton, pose: Pose, first_frame: int = 0
) -> UsdSkel.Animation:
    """A UsdSkel.Animation of ``pose``: frame i at time code ``first_frame + i``.

    Scales are a constant 1 (default value only); translations and rotations are time samples.
    A one-frame pose has one sample, which USD holds for all time.
    """
    anim = UsdSkel.Animation.Define(stage, path)
    anim.CreateJointsAttr(Vt.TokenArray(skeleton.paths))
    joints = len(skeleton.names)
    anim.CreateScalesAttr(Vt.Vec3hArray.FromNumpy(np.ones((joints, 3), dtype=np.float16)))
    t_attr = anim.CreateTranslationsAttr()
    r_attr = anim.CreateRotationsAttr()
    local_t = skeleton.rest_local_translations.astype(np.float32)
    for i in range(pose.frame_count):
        t = local_t.copy()
        t[0] = pose.root_translation[i]
        time = Usd.TimeCode(first_frame + i)
        t_attr.Set(Vt.Vec3fArray.FromNumpy(t), time)
        r_attr.Set(quatf_array(pose.local_rotations[i]), time)
    return anim


def bind_animation(skeleton_prim: Usd.Prim, animation_path) -> None:
    """``skel:animationSource`` on the Skeleton (UsdSkel.BindingAPI)."""
    binding = UsdSkel.BindingAPI.Apply(skeleton_prim)
    binding.CreateAnimationSourceRel().SetTargets([Sdf.Path(animation_path)])


def bind_mesh(
    mesh_prim: Usd.Prim, skeleton_path, joint_indices: np.ndarray, joint_weights: np.ndarray
) -> UsdSkel.BindingAPI:
    """Skin a mesh: ``skel:skeleton``, per-vertex joint indices/weights (elementSize
    :data:`INFLUENCES`, vertex interpolation) and an identity ``skel:geomBindTransform`` (the
    mesh points are authored in skeleton space at the bind pose)."""
    joint_indices = np.asarray(joint_indices, dtype=np.int32)
    joint_weights = np.asarray(joint_weights, dtype=np.float32)
    k = joint_indices.shape[1]
    binding = UsdSkel.BindingAPI.Apply(mesh_prim)
    binding.CreateSkeletonRel().SetTargets([Sdf.Path(skeleton_path)])
    binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray.FromNumpy(joint_indices.ravel()))
    binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray.FromNumpy(joint_weights.ravel()))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    return binding


def define_skel_root(stage: Usd.Stage, path) -> UsdSkel.Root:
    return UsdSkel.Root.Define(stage, path)


# ---------------------------------------------------------------------------- reading back
def skinned_points(
    stage: Usd.Stage,
    mesh_path,
    time=Usd.TimeCode.Default(),  # noqa: B008 (an immutable value)
    space: str = "skel",
) -> np.ndarray:
    """Points of a person's mesh as posed at ``time``: skinned meshes (the Body, props) posed by
    UsdSkel (``UsdSkel.Cache`` + ``SkinningQuery``), meshes without joint influences (garments:
    a time-sampled point cache) read at ``time``.

    ``space`` "skel": in the Skeleton's space (= the SkelRoot's local space for our layers);
    "world": times the Skeleton's local-to-world at ``time`` (unbound meshes: their own
    local-to-world).
    """
    mesh_prim = stage.GetPrimAtPath(str(mesh_path))
    points = UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get(time)
    root = UsdSkel.Root.Find(mesh_prim)
    cache = UsdSkel.Cache()
    if root:
        cache.Populate(root, Usd.PrimDefaultPredicate)
    query = cache.GetSkinningQuery(mesh_prim) if root else None
    skel = UsdSkel.BindingAPI(mesh_prim).GetInheritedSkeleton()
    if not (query and query.HasJointInfluences() and skel):
        return _unbound_points(mesh_prim, points, time, root, space)
    skel_query = cache.GetSkelQuery(skel)
    xforms = skel_query.ComputeSkinningTransforms(time)
    if not query.ComputeSkinnedPoints(xforms, points, time):
        raise RuntimeError(f"UsdSkel could not skin {mesh_path}")
    out = np.asarray(points, dtype=np.float64)
    if space == "world":
        m = np.asarray(UsdGeom.Xformable(skel.GetPrim()).ComputeLocalToWorldTransform(time))
        out = out @ m[:3, :3] + m[3, :3]
    return out


def _unbound_points(mesh_prim: Usd.Prim, points, time, root, space: str) -> np.ndarray:
    """A mesh UsdSkel does not skin: its points at ``time`` in world space, or in the space of
    its SkelRoot's Skeleton (else the SkelRoot's, else the mesh's own) for ``space`` "skel"."""
    out = np.asarray(points if points is not None else [], dtype=np.float64).reshape(-1, 3)
    m = np.asarray(UsdGeom.Xformable(mesh_prim).ComputeLocalToWorldTransform(time))
    if space != "world":
        frame = (
            next((p for p in Usd.PrimRange(root.GetPrim()) if p.IsA(UsdSkel.Skeleton)), None)
            if root
            else None
        )
        frame = frame or (root.GetPrim() if root else mesh_prim)
        m = m @ np.linalg.inv(np.asarray(UsdGeom.Xformable(frame).ComputeLocalToWorldTransform(time)))
    return out @ m[:3, :3] + m[3, :3]
