"""The person the clothing tool dresses, read from the avatar layer on the upstream stage.

Everything about the person comes from the stage (:mod:`humv_usd.usd.avatar`): HumvAvatarAPI's
sex, age, stature, mass and build, the Skeleton's joints and bind pose, the Body mesh's rest
points, its UsdSkel skin weights and body-region labels (garment faces take the region under
them), and (in :mod:`humv_usd.clothing.layer`) the joint motion.

Garments are cut from MakeHuman's helper geometry (helper-tights, helper-skirt), which the avatar
layer does not carry. So the MakeHuman body is rebuilt from the parameters read from the stage
(:func:`humv_usd.human.body.build_body`, deterministic) and its body points are compared with the
stage's Body rest points:

* equal within :data:`MATCH_TOLERANCE_M` (the avatar tool's layer, or one re-authored for
  another person): the rebuilt body is used as is;
* same vertices and faces but another shape (the mesh sculpted in a DCC, or HumvAvatarAPI
  overridden by a stronger layer without a new mesh): the garments are fitted on the stage's
  body, which is what the render shows. The body vertices take the stage's points and every
  other MakeHuman vertex (helpers, joint cubes) moves with the body surface closest to it: by
  the barycentric blend of that triangle's vertex displacements (:func:`transfer_to_body`). A
  warning says by how much the bodies differed;
* another topology (a body from elsewhere): one :class:`~humv_usd.errors.InputError` naming
  the Body prim (helper geometry cannot be placed on an unknown mesh).

The skeleton's joints must be the CMU rig's (paths as the avatar tool writes them) with
world-aligned bind frames (pure translations); its bind positions are the stage's.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from pxr import Usd

from humv_usd.errors import InputError
from humv_usd.geometry.mesh import Surface, fan_triangulate
from humv_usd.human.body import Body, build_body
from humv_usd.human.proportions import check_sitting_height_ratio
from humv_usd.human.skeleton import Skeleton, skeleton_for
from humv_usd.usd.avatar import (
    AvatarParameters,
    BodyMesh,
    SkeletonRest,
    read_avatar,
    read_body_mesh,
    read_skeleton_rest,
)
from humv_usd.usd.paths import human_path, skeleton_path

log = logging.getLogger(__name__)

#: Largest distance [m] between the stage's Body points and the rebuilt MakeHuman body at
#: which the two count as the same body (the layer stores float32 points: ~1e-7 m).
MATCH_TOLERANCE_M = 1e-4


@dataclass(frozen=True)
class Person:
    """One person as the clothing tool needs it (skeleton space, rest pose)."""

    parameters: AvatarParameters
    body: Body  # MakeHuman vertices (helpers included) on the stage's body
    skeleton: Skeleton  # CMU rig at the stage's bind positions
    joint_indices: np.ndarray  # (V, 4) the stage Body's skinning
    joint_weights: np.ndarray  # (V, 4)
    face_regions: np.ndarray | None  # (F,) the Body's region labels, if authored
    body_deviation_m: float  # max distance of the stage's Body from the rebuilt body


def rebuild_body(
    parameters: AvatarParameters, proportions: float = 0.5, sitting_height_ratio: float | None = None
) -> Body:
    """The MakeHuman body of HumvAvatarAPI's parameters (as the avatar tool builds it), with
    MakeHuman's ``proportions`` macro (``human.proportions``; see :func:`fit_proportions`) and
    the requested ``human.sitting_height_ratio`` (:func:`fit_sitting_height_ratio`)."""
    p = parameters
    return build_body(p.sex, p.age_yr, p.stature_m, p.mass_kg, p.build, proportions, sitting_height_ratio)


#: customData of the avatar's SkelRoot that records its MakeHuman fit (avatar tool)
FIT_DATA = "humv:fit"


def fit_proportions(stage: Usd.Stage, human_id: str) -> float:
    """The proportions macro the avatar tool used: its fit record's ``macros.proportions``
    (customData ``humv:fit`` on the person's SkelRoot), 0.5 (none) when not recorded. HumvAvatarAPI
    has no proportions attribute; without this the body rebuilt from the parameters would differ
    from the stage's by ~1-2 cm and the garments would go through :func:`transfer_to_body`."""
    prim = stage.GetPrimAtPath(human_path(human_id))
    fit = prim.GetCustomDataByKey(FIT_DATA) if prim else None
    value = ((fit or {}).get("macros") or {}).get("proportions", 0.5)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return 0.5
    return value if 0.0 <= value <= 1.0 else 0.5


def fit_sitting_height_ratio(stage: Usd.Stage, human_id: str) -> float | None:
    """The sitting-height ratio the avatar tool was asked for (its fit record's
    ``sittingHeightRatioRequested``), None when not recorded (MakeHuman's own legs) or invalid."""
    prim = stage.GetPrimAtPath(human_path(human_id))
    fit = prim.GetCustomDataByKey(FIT_DATA) if prim else None
    value = (fit or {}).get("sittingHeightRatioRequested")
    try:
        return check_sitting_height_ratio(value) if value is not None else None
    except (TypeError, ValueError):
        return None


def transfer_to_body(template: Body, body_points: np.ndarray) -> Body:
    """``template`` with its body vertices at ``body_points`` (compact, as ``body_mesh()``) and
    every other vertex moved by the displacement of the template's body surface closest to it
    (barycentric blend of that triangle's three vertex displacements).

    Exact for any affine motion of the body shared by the vertex (a translation moves helpers by
    the same translation); derived measures (stature, volume, mass) stay the template's.
    """
    mesh = template.body_mesh()
    tris, _ = fan_triangulate(mesh.face_counts, mesh.face_indices)
    delta = np.asarray(body_points, dtype=np.float64) - mesh.points
    others = np.setdiff1d(np.arange(len(template.points)), mesh.vertex_ids)
    near = Surface(mesh.points, tris).closest(template.points[others])
    points = template.points.copy()
    points[others] += np.einsum("nk,nki->ni", near.bary, delta[tris[near.triangle]])
    points[mesh.vertex_ids] = body_points
    return dataclasses.replace(template, points=points)


def body_on_stage(template: Body, stage_mesh: BodyMesh) -> tuple[Body, float]:
    """(the body to fit garments on, max deviation [m] of the stage's Body from ``template``);
    see the module doc for the three cases."""
    mesh = template.body_mesh()
    same_topology = (
        len(stage_mesh.points) == len(mesh.points)
        and np.array_equal(stage_mesh.face_counts, mesh.face_counts)
        and np.array_equal(stage_mesh.face_indices, mesh.face_indices)
    )
    if not same_topology:
        raise InputError(
            f"{stage_mesh.path}: {len(stage_mesh.points)} points and {len(stage_mesh.face_counts)} faces, "
            f"not the MakeHuman body's {len(mesh.points)} and {len(mesh.face_counts)}: garments are cut "
            "from MakeHuman helper geometry and need the avatar tool's body topology (any shape)"
        )
    deviation = float(np.linalg.norm(stage_mesh.points - mesh.points, axis=1).max())
    if deviation <= MATCH_TOLERANCE_M:
        return template, deviation
    log.warning(
        "%s: differs from the MakeHuman body of its HumvAvatarAPI parameters by up to %.1f mm; "
        "garments are fitted on the stage's body (helper geometry moved with it)",
        stage_mesh.path,
        deviation * 1e3,
    )
    return transfer_to_body(template, stage_mesh.points), deviation


def skeleton_on_stage(body: Body, rest: SkeletonRest, where: str) -> Skeleton:
    """The CMU rig with the stage's bind positions (bone tails from ``body``'s joint cubes)."""
    rig = skeleton_for(body.points, body.groups)
    if rest.joints != rig.paths:
        raise InputError(
            f"{where}: joints differ from the CMU rig's ({len(rest.joints)} vs {len(rig.paths)}); "
            "the clothing tool needs the avatar tool's rig"
        )
    if not np.allclose(rest.bind_rotations, np.eye(3), atol=1e-5):
        raise InputError(f"{where}.bindTransforms: expected pure translations (world-aligned rest frames)")
    return dataclasses.replace(rig, rest_positions=np.asarray(rest.bind_positions, dtype=np.float64))


def read_person(stage: Usd.Stage, human_id: str) -> Person:
    """The person ``human_id`` from the avatar layer on ``stage`` (see the module doc)."""
    parameters = read_avatar(stage, human_id)
    stage_mesh = read_body_mesh(stage, human_id)
    rebuilt = rebuild_body(
        parameters, fit_proportions(stage, human_id), fit_sitting_height_ratio(stage, human_id)
    )
    body, deviation = body_on_stage(rebuilt, stage_mesh)
    rest = read_skeleton_rest(stage, human_id)
    skeleton = skeleton_on_stage(body, rest, str(skeleton_path(human_id)))
    if stage_mesh.joint_indices.shape[1] != 4 or stage_mesh.joint_indices.max() >= len(rest.joints):
        raise InputError(f"{stage_mesh.path}: expected 4 influences per point into the Skeleton's joints")
    return Person(
        parameters,
        body,
        skeleton,
        stage_mesh.joint_indices,
        stage_mesh.joint_weights,
        stage_mesh.face_regions,
        deviation,
    )
