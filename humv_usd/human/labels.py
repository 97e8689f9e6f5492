"""Ground-truth labels on the avatar: body regions, JOS-3 segments and COCO keypoints.

Body regions (``primvars:humv:label:bodyRegion``, int, uniform: one id per body face). The ids
of :data:`BODY_REGIONS` cover the seed's Table 2 regions (its "Hat" is our ``head``, "Torso"
our ``abdomen`` + ``back`` + ``pelvis``: :data:`SEED_TABLE2_REGIONS`) plus neck, pelvis and
hands; 0 is reserved for "not the body" (background in region masks). A face's region is that
of its dominant skinning joint (largest summed weight over its vertices, MakeHuman's CC0
``cmu_mb`` weights), refined by geometric rules where one joint spans two regions, all in the
rest pose (skeleton space: +Z up, the body faces -Y, +X is the person's left):

* Head joint: ``face`` in front of the coronal plane through the ears' centres and below the
  brow line (mean height of MakeHuman's eyebrow vertices), the rest ``head`` (scalp,
  forehead, ears, back of the head); the ears themselves are always ``head``.
* Neck / Neck1: ``neck``.
* Trunk joints (Hips, L/RHipJoint, LowerBack, Spine, Spine1, L/RShoulder = clavicles):
  ``pelvis`` below the waist (the LowerBack joint's height, ~ iliac crest); above it ``back``
  behind the trunk's mid-depth at that height (the mid-axillary line) and in front ``chest``
  above the Spine1 joint (~ lower end of the rib cage) or ``abdomen`` below.
* Upper-leg joints: the buttock (behind the mid-depth, above the crotch) and everything above
  the hip joint's height go to ``pelvis``, the rest is the thigh (``leftUpperLeg``...).
* Limb joints: upper arm (Arm), lower arm (ForeArm), hand (Hand, thumb, fingers), upper leg
  (UpLeg), lower leg (Leg), foot (Foot, ToeBase).

JOS-3 segments (``primvars:humv:label:jos3Segment``, int, uniform) are the 0-based index into
JOS-3's 17 segments in its own order (:data:`JOS3_SEGMENTS`; Takahashi et al. 2021,
Energy & Buildings 231:110575; pythermalcomfort ``JOS3``), so a per-segment JOS-3 array
indexes directly by face: ``t_skin[jos3Segment]``. They follow from the regions
(:data:`REGION_TO_JOS3`): JOS-3 "Shoulder" is the upper arm, "Arm" the forearm, "Leg" the
lower leg, "Chest" the whole front of the trunk above the pelvis.

COCO keypoints: the 17 of COCO person keypoints (Lin et al. 2014) in COCO's order
(:data:`COCO_KEYPOINTS`). Shoulders, elbows, wrists, hips, knees and ankles are joint heads
(LeftArm, LeftForeArm, LeftHand, LeftUpLeg, LeftLeg, LeftFoot...); nose, eyes and ears are body
surface vertices chosen once on MakeHuman's base mesh (:func:`coco_surface_vertices`; the body
group's topology is the same for every fitted body): the nose tip (most anterior vertex of the
nose targets' region), the body vertex nearest the front of each eyeball (``helper-*-eye``)
and the body vertex nearest each ear's centre (``ears/*-ear-scale-incr`` target region).
"""

from __future__ import annotations

import gzip
from functools import lru_cache
from types import MappingProxyType

import numpy as np

from humv_usd.assets import makehuman_dir
from humv_usd.human.body import to_usd
from humv_usd.human.macro import obj_data, parse_target
from humv_usd.human.skeleton import Skeleton

# ---------------------------------------------------------------------------- id tables
#: Body region ids (1-based; 0 = not the body) and names (USD tokens).
BODY_REGIONS: tuple[tuple[int, str], ...] = (
    (1, "head"),
    (2, "face"),
    (3, "neck"),
    (4, "chest"),
    (5, "abdomen"),
    (6, "back"),
    (7, "pelvis"),
    (8, "leftUpperArm"),
    (9, "leftLowerArm"),
    (10, "leftHand"),
    (11, "rightUpperArm"),
    (12, "rightLowerArm"),
    (13, "rightHand"),
    (14, "leftUpperLeg"),
    (15, "leftLowerLeg"),
    (16, "leftFoot"),
    (17, "rightUpperLeg"),
    (18, "rightLowerLeg"),
    (19, "rightFoot"),
)
REGION_ID = {name: rid for rid, name in BODY_REGIONS}
#: names indexed by id (index 0 = "background"), as written to ``humv:label:bodyRegionNames``.
BODY_REGION_NAMES: tuple[str, ...] = ("background",) + tuple(n for _, n in BODY_REGIONS)

#: JOS-3's 17 segments in JOS-3's order (index = ``jos3Segment`` value).
JOS3_SEGMENTS: tuple[str, ...] = (
    "Head",
    "Neck",
    "Chest",
    "Back",
    "Pelvis",
    "LShoulder",
    "LArm",
    "LHand",
    "RShoulder",
    "RArm",
    "RHand",
    "LThigh",
    "LLeg",
    "LFoot",
    "RThigh",
    "RLeg",
    "RFoot",
)
#: The same segments as pythermalcomfort names them (``JOS3BodyParts`` fields).
JOS3_PYTHERMALCOMFORT: tuple[str, ...] = (
    "head",
    "neck",
    "chest",
    "back",
    "pelvis",
    "left_shoulder",
    "left_arm",
    "left_hand",
    "right_shoulder",
    "right_arm",
    "right_hand",
    "left_thigh",
    "left_leg",
    "left_foot",
    "right_thigh",
    "right_leg",
    "right_foot",
)

REGION_TO_JOS3 = {
    "head": "Head",
    "face": "Head",
    "neck": "Neck",
    "chest": "Chest",
    "abdomen": "Chest",
    "back": "Back",
    "pelvis": "Pelvis",
    "leftUpperArm": "LShoulder",
    "leftLowerArm": "LArm",
    "leftHand": "LHand",
    "rightUpperArm": "RShoulder",
    "rightLowerArm": "RArm",
    "rightHand": "RHand",
    "leftUpperLeg": "LThigh",
    "leftLowerLeg": "LLeg",
    "leftFoot": "LFoot",
    "rightUpperLeg": "RThigh",
    "rightLowerLeg": "RLeg",
    "rightFoot": "RFoot",
}

#: The seed's Table 2 regions (HumV paper, Sec. 4) as unions of ours.
SEED_TABLE2_REGIONS = {
    "Full body": tuple(n for _, n in BODY_REGIONS),
    "Hat": ("head",),
    "Chest": ("chest",),
    "Torso": ("abdomen", "back", "pelvis"),
    "Left upper arm": ("leftUpperArm",),
    "Left lower arm": ("leftLowerArm",),
    "Right upper arm": ("rightUpperArm",),
    "Right lower arm": ("rightLowerArm",),
    "Left upper leg": ("leftUpperLeg",),
    "Left lower leg": ("leftLowerLeg",),
    "Left foot": ("leftFoot",),
    "Right upper leg": ("rightUpperLeg",),
    "Right lower leg": ("rightLowerLeg",),
    "Right foot": ("rightFoot",),
    "Face": ("face",),
}

#: COCO person keypoints, COCO's order.
COCO_KEYPOINTS: tuple[str, ...] = (
    "nose",
    "left_eye",
    "right_eye",
    "left_ear",
    "right_ear",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
#: Joints whose heads are the limb keypoints.
COCO_JOINTS = {
    "left_shoulder": "LeftArm",
    "right_shoulder": "RightArm",
    "left_elbow": "LeftForeArm",
    "right_elbow": "RightForeArm",
    "left_wrist": "LeftHand",
    "right_wrist": "RightHand",
    "left_hip": "LeftUpLeg",
    "right_hip": "RightUpLeg",
    "left_knee": "LeftLeg",
    "right_knee": "RightLeg",
    "left_ankle": "LeftFoot",
    "right_ankle": "RightFoot",
}
COCO_SURFACE = ("nose", "left_eye", "right_eye", "left_ear", "right_ear")

# joint name -> coarse class for the dominant-joint rule
_TRUNK = {"Hips", "LHipJoint", "RHipJoint", "LowerBack", "Spine", "Spine1", "LeftShoulder", "RightShoulder"}
_LIMB = {
    "LeftArm": "leftUpperArm",
    "LeftForeArm": "leftLowerArm",
    "LeftHand": "leftHand",
    "LThumb": "leftHand",
    "LeftFingerBase": "leftHand",
    "LeftHandFinger1": "leftHand",
    "RightArm": "rightUpperArm",
    "RightForeArm": "rightLowerArm",
    "RightHand": "rightHand",
    "RThumb": "rightHand",
    "RightFingerBase": "rightHand",
    "RightHandFinger1": "rightHand",
    "LeftUpLeg": "leftUpperLeg",
    "LeftLeg": "leftLowerLeg",
    "LeftFoot": "leftFoot",
    "LeftToeBase": "leftFoot",
    "RightUpLeg": "rightUpperLeg",
    "RightLeg": "rightLowerLeg",
    "RightFoot": "rightFoot",
    "RightToeBase": "rightFoot",
    "Neck": "neck",
    "Neck1": "neck",
}
_SLICE_M = 0.02  # height of the slices for the trunk's mid-depth [m]


# ---------------------------------------------------------------------------- landmarks
def _target_vertices(name: str, strength: float = 0.5) -> np.ndarray:
    """Full-list vertex ids a MakeHuman target moves by >= ``strength`` x its largest offset."""
    raw = gzip.decompress((makehuman_dir() / "targets" / f"{name}.target.gz").read_bytes())
    idx, delta = parse_target(raw)
    mag = np.linalg.norm(delta, axis=1)
    return np.sort(idx[mag >= strength * mag.max()])


@lru_cache(maxsize=1)
def _landmarks() -> dict[str, np.ndarray]:
    """Landmark vertex sets (full base.obj ids) from MakeHuman's feature targets."""
    return {
        "ear_left": _target_vertices("ears/l-ear-scale-incr", 0.1),
        "ear_right": _target_vertices("ears/r-ear-scale-incr", 0.1),
        "eyebrows": _target_vertices("eyebrows/eyebrows-trans-up"),
        "nose": _target_vertices("nose/nose-trans-forward"),
    }


def _compact(vertex_ids: np.ndarray, full_ids: np.ndarray) -> np.ndarray:
    """Positions in ``vertex_ids`` (sorted full ids of a MeshPart) of those ``full_ids`` in it."""
    pos = np.searchsorted(vertex_ids, full_ids)
    pos = np.clip(pos, 0, len(vertex_ids) - 1)
    return pos[vertex_ids[pos] == full_ids]


@lru_cache(maxsize=1)
def coco_surface_vertices() -> MappingProxyType:
    """Body-mesh vertices (indices into ``Body.body_mesh().points``) of nose, eyes and ears.

    Chosen once on MakeHuman's base mesh, in our frame (front = -Y, left = +X).
    """
    points_mh, groups = obj_data()
    p = to_usd(points_mh)
    body_ids = np.unique(groups["body"])
    body_p = p[body_ids]
    lm = _landmarks()

    def nearest(target: np.ndarray) -> int:
        return int(np.argmin(np.linalg.norm(body_p - target, axis=1)))

    out: dict[str, int] = {}
    nose = _compact(body_ids, lm["nose"])
    out["nose"] = int(nose[np.argmin(body_p[nose, 1])])  # most anterior
    for side in ("left", "right"):
        eye = p[np.unique(groups[f"helper-{side[0]}-eye"])]
        out[f"{side}_eye"] = nearest(eye[np.argmin(eye[:, 1])])  # front of the eyeball
        out[f"{side}_ear"] = nearest(p[lm[f"ear_{side}"]].mean(axis=0))
    return MappingProxyType({name: out[name] for name in COCO_SURFACE})


# ---------------------------------------------------------------------------- regions
def face_joint_weights(face_counts, face_indices, joint_indices, joint_weights, joints: int) -> np.ndarray:
    """(F, J) summed skinning weight of each joint over each face's vertices."""
    counts = np.asarray(face_counts, dtype=np.int64)
    idx = np.asarray(face_indices, dtype=np.int64)
    face_of = np.repeat(np.arange(counts.size), counts)
    k = joint_indices.shape[1]
    out = np.zeros((counts.size, joints))
    np.add.at(out, (np.repeat(face_of, k), joint_indices[idx].ravel()), joint_weights[idx].ravel())
    return out


def _face_centres(points, face_counts, face_indices) -> np.ndarray:
    counts = np.asarray(face_counts, dtype=np.int64)
    face_of = np.repeat(np.arange(counts.size), counts)
    sums = np.zeros((counts.size, 3))
    np.add.at(sums, face_of, points[np.asarray(face_indices)])
    return sums / counts[:, None]


def _mid_depth(points: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Mid-depth y of a cross-section (mean of its front- and back-most y) at heights ``z``,
    from ``points`` in slices of :data:`_SLICE_M`, interpolated between slice centres."""
    lo = points[:, 2].min()
    slot = np.floor((points[:, 2] - lo) / _SLICE_M).astype(np.int64)
    n = slot.max() + 1
    ymin = np.full(n, np.inf)
    ymax = np.full(n, -np.inf)
    np.minimum.at(ymin, slot, points[:, 1])
    np.maximum.at(ymax, slot, points[:, 1])
    ok = np.isfinite(ymin)
    centres = lo + (np.arange(n) + 0.5) * _SLICE_M
    return np.interp(z, centres[ok], 0.5 * (ymin[ok] + ymax[ok]))


def body_regions(
    mesh, skeleton: Skeleton, joint_indices: np.ndarray, joint_weights: np.ndarray
) -> np.ndarray:
    """Region id (:data:`BODY_REGIONS`) of every face of the rest-pose body mesh.

    ``mesh`` is :meth:`humv_usd.human.body.Body.body_mesh` (points in skeleton space at rest,
    ``vertex_ids`` into base.obj); ``joint_indices``/``joint_weights`` its skinning
    (:func:`humv_usd.human.skeleton.skin_weights`). Rules: see the module docstring.
    """
    points = np.asarray(mesh.points, dtype=np.float64)
    names = skeleton.names
    per_joint = face_joint_weights(
        mesh.face_counts, mesh.face_indices, joint_indices, joint_weights, len(names)
    )
    dominant = per_joint.argmax(axis=1)
    centre = _face_centres(points, mesh.face_counts, mesh.face_indices)
    x, y, z = centre.T
    region = np.zeros(len(dominant), dtype=np.int32)
    joint_of = np.asarray(names, dtype=object)[dominant]

    for joint, name in _LIMB.items():
        region[joint_of == joint] = REGION_ID[name]

    rest = skeleton.rest_positions
    z_waist = rest[skeleton.index("LowerBack"), 2]
    # ~ xiphoid: halfway between the Spine and Spine1 joints (~0.70 x stature)
    z_chest = 0.5 * (rest[skeleton.index("Spine"), 2] + rest[skeleton.index("Spine1"), 2])
    z_hip = 0.5 * (rest[skeleton.index("LeftUpLeg"), 2] + rest[skeleton.index("RightUpLeg"), 2])
    # crotch: the lowest body point on the midline above the knees
    mid = (np.abs(points[:, 0]) < 0.01) & (points[:, 2] > rest[skeleton.index("LeftLeg"), 2])
    z_crotch = points[mid, 2].min()

    trunk = np.isin(joint_of, sorted(_TRUNK))
    up_leg = np.isin(joint_of, ["LeftUpLeg", "RightUpLeg"])
    # the trunk's mid-depth per height, from trunk and thigh vertices near the midline
    fv = np.asarray(mesh.face_indices)
    face_of = np.repeat(np.arange(len(dominant)), np.asarray(mesh.face_counts))
    core = np.unique(fv[np.isin(face_of, np.flatnonzero(trunk | up_leg))])
    core = core[np.abs(points[core, 0]) < rest[skeleton.index("LeftUpLeg"), 0]]
    y_mid = _mid_depth(points[core], z)
    behind = y > y_mid

    region[trunk & (z < z_waist)] = REGION_ID["pelvis"]
    upper = trunk & (z >= z_waist)
    region[upper & behind] = REGION_ID["back"]
    region[upper & ~behind & (z >= z_chest)] = REGION_ID["chest"]
    region[upper & ~behind & (z < z_chest)] = REGION_ID["abdomen"]
    region[up_leg & ((z >= z_hip) | (behind & (z >= z_crotch)))] = REGION_ID["pelvis"]

    head = joint_of == "Head"
    lm = _landmarks()
    vid = np.asarray(mesh.vertex_ids)
    brow_z = points[_compact(vid, lm["eyebrows"]), 2].mean()
    ears = np.concatenate([_compact(vid, lm["ear_left"]), _compact(vid, lm["ear_right"])])
    ear_y = points[ears, 1].mean()
    on_ear = np.zeros(len(points), dtype=bool)
    on_ear[ears] = True
    counts = np.asarray(mesh.face_counts)
    ear_face = np.bincount(face_of, weights=on_ear[fv], minlength=len(dominant)) * 2 >= counts
    is_face = head & (z < brow_z) & (y < ear_y) & ~ear_face
    region[head] = REGION_ID["head"]
    region[is_face] = REGION_ID["face"]

    if np.any(region == 0):  # a joint the tables do not know (another rig)
        raise ValueError(f"faces without a region (joints {sorted(set(joint_of[region == 0]))})")
    return region


def jos3_segments(regions: np.ndarray) -> np.ndarray:
    """JOS-3 segment index (0..16, :data:`JOS3_SEGMENTS`) of each face from its region id."""
    table = np.full(len(BODY_REGION_NAMES), -1, dtype=np.int32)
    for rid, name in BODY_REGIONS:
        table[rid] = JOS3_SEGMENTS.index(REGION_TO_JOS3[name])
    out = table[np.asarray(regions)]
    if np.any(out < 0):
        raise ValueError("region id 0 (background) has no JOS-3 segment")
    return out


def region_area_fractions(areas: np.ndarray, regions: np.ndarray) -> dict[str, float]:
    """Share of the total area of each region (by name)."""
    total = float(np.sum(areas))
    sums = np.bincount(np.asarray(regions), weights=areas, minlength=len(BODY_REGION_NAMES))
    return {name: float(sums[rid]) / total for rid, name in BODY_REGIONS}


# ---------------------------------------------------------------------------- keypoints
def coco_keypoints(
    skeleton: Skeleton,
    world_transforms: np.ndarray,
    body_points_posed: np.ndarray,
    vertex_ids: dict[str, int] | None = None,
) -> np.ndarray:
    """The 17 COCO keypoints (:data:`COCO_KEYPOINTS` order) [m] for one or more frames.

    world_transforms: (..., J, 4, 4) joint transforms (column-vector, e.g. from
    :func:`humv_usd.human.skeleton.forward_kinematics`); body_points_posed: (..., V, 3) the
    posed body mesh points in the same space; vertex_ids: the surface vertices of nose, eyes
    and ears (indices into those points), default :func:`coco_surface_vertices`.
    Returns (..., 17, 3).
    """
    world = np.asarray(world_transforms, dtype=np.float64)
    pts = np.asarray(body_points_posed, dtype=np.float64)
    ids = coco_surface_vertices() if vertex_ids is None else vertex_ids
    out = np.empty(world.shape[:-3] + (len(COCO_KEYPOINTS), 3))
    for k, name in enumerate(COCO_KEYPOINTS):
        if name in COCO_JOINTS:
            out[..., k, :] = world[..., skeleton.index(COCO_JOINTS[name]), :3, 3]
        else:
            out[..., k, :] = pts[..., ids[name], :]
    return out
