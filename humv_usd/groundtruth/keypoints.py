"""COCO-17 person keypoints: read from the stage, projected, with visibility from the depth buffer.

The avatar layer authors ``humv:label:cocoKeypoints`` (point3f[17], time-sampled, COCO order) on
each person's SkelRoot, in the SkelRoot's space; here they go to world space with the SkelRoot's
local-to-world at the frame and are projected with the sensor's pinhole model.

Visibility (COCO: v = 0 not labelled, 1 labelled but occluded, 2 visible):

- v = 0 when the keypoint is behind the camera or projects outside the image (x = y = 0 then, as
  COCO writes unlabelled points), or the stage has no keypoints for the frame;
- v = 2 when the first surface on the camera ray through the keypoint itself (an exact ray cast
  in the render's scene: the depth buffer sampled at the keypoint's sub-pixel position) belongs
  to the same person (instance id), lies on one of the body regions around that keypoint
  (:data:`KEYPOINT_REGIONS`: e.g. the left knee's are the left upper and lower leg; garments
  carry the region of the body under them), and is no more than :data:`KEYPOINT_TOLERANCE_M`
  in front of the keypoint's depth (joint keypoints lie inside the limb, so the visible skin is
  in front of them by up to the limb's half-thickness plus clothing; nose, eyes and ears are
  surface points);
- v = 2 also for a surface point (nose, eyes, ears) whose ray misses the person and hits only
  what lies beyond it (on the silhouette, e.g. the nose tip in profile, the grazing ray can
  miss the mesh; nothing is in front of it);
- v = 1 otherwise (another object, another body part, or the person's own far side is in front).
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.human import labels as AL
from humv_usd.usd.avatar import has_keypoints, read_keypoints

_L, _R = "left", "right"


def _side(side: str, *parts: str) -> tuple[str, ...]:
    return tuple(side + p for p in parts)


#: Body regions (names of humv_usd.human.labels.BODY_REGIONS) on which a keypoint counts as seen.
KEYPOINT_REGIONS: dict[str, tuple[str, ...]] = {
    "nose": ("face",),
    "left_eye": ("face",),
    "right_eye": ("face",),
    "left_ear": ("head", "face"),
    "right_ear": ("head", "face"),
    **{f"{s}_shoulder": ("chest", "back", "neck") + _side(s, "UpperArm") for s in (_L, _R)},
    **{f"{s}_elbow": _side(s, "UpperArm", "LowerArm") for s in (_L, _R)},
    **{f"{s}_wrist": _side(s, "LowerArm", "Hand") for s in (_L, _R)},
    **{f"{s}_hip": ("pelvis", "abdomen") + _side(s, "UpperLeg") for s in (_L, _R)},
    **{f"{s}_knee": _side(s, "UpperLeg", "LowerLeg") for s in (_L, _R)},
    **{f"{s}_ankle": _side(s, "LowerLeg", "Foot") for s in (_L, _R)},
}
#: How far [m] the depth buffer may lie in front of a keypoint for it to count as visible: about
#: the largest joint-centre-to-skin depth (plus clothing) of each joint; 3 cm for surface points.
KEYPOINT_TOLERANCE_M: dict[str, float] = {
    "nose": 0.03,
    "left_eye": 0.03,
    "right_eye": 0.03,
    "left_ear": 0.03,
    "right_ear": 0.03,
    "left_shoulder": 0.12,
    "right_shoulder": 0.12,
    "left_elbow": 0.08,
    "right_elbow": 0.08,
    "left_wrist": 0.06,
    "right_wrist": 0.06,
    "left_hip": 0.18,
    "right_hip": 0.18,
    "left_knee": 0.10,
    "right_knee": 0.10,
    "left_ankle": 0.08,
    "right_ankle": 0.08,
}
#: COCO's skeleton (1-based keypoint index pairs), as in person_keypoints_*.json.
COCO_SKELETON = [
    [16, 14],
    [14, 12],
    [17, 15],
    [15, 13],
    [12, 13],
    [6, 12],
    [7, 13],
    [6, 7],
    [6, 8],
    [7, 9],
    [8, 10],
    [9, 11],
    [2, 3],
    [1, 2],
    [1, 3],
    [2, 4],
    [3, 5],
    [4, 6],
    [5, 7],
]

_ALLOWED = [np.array([AL.REGION_ID[r] for r in KEYPOINT_REGIONS[k]]) for k in AL.COCO_KEYPOINTS]
_TOL = np.array([KEYPOINT_TOLERANCE_M[k] for k in AL.COCO_KEYPOINTS])
_SURFACE = np.array([AL.COCO_KEYPOINTS.index(k) for k in AL.COCO_SURFACE])


def find_keypoint_prims(stage: Usd.Stage) -> list[Usd.Prim]:
    """Prims carrying ``humv:label:cocoKeypoints`` (the persons' SkelRoots)."""
    pred = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    return [p for p in stage.Traverse(pred) if has_keypoints(p)]


def world_keypoints(prim: Usd.Prim, frame: int, cache: UsdGeom.XformCache) -> np.ndarray | None:
    """(17, 3) world keypoints [m] of a person at ``frame`` (None if not 17 finite points)."""
    pts = read_keypoints(prim, frame)
    if pts is None:
        return None
    if pts.shape[0] != len(AL.COCO_KEYPOINTS) or not np.all(np.isfinite(pts)):
        return None
    m = np.array(cache.GetLocalToWorldTransform(prim), dtype=float)  # row-vector convention
    mpu = float(UsdGeom.GetStageMetersPerUnit(prim.GetStage()))
    return (pts @ m[:3, :3] + m[3, :3]) * mpu


def keypoint_visibility(camera, keypoints_world: np.ndarray, instance_id: int, first_hit) -> dict:
    """Project the 17 keypoints and judge visibility (module doc).

    ``first_hit(directions (N, 3))`` returns, for rays from the camera centre, the depth along
    the optical axis [m] (inf on a miss), instance id and body region id of the first surface:
    the depth buffer sampled exactly at the keypoint (the render's ray cast, not the pixel centre).
    Returns ``{"keypoints": [x1, y1, v1, ...] (COCO), "uv": (17, 2), "depth_m": (17,),
    "visibility": (17,), "depth_buffer_m": (17,)}``; ``uv`` are continuous pixel coordinates
    (NaN behind the camera).
    """
    uv, z = camera.project(keypoints_world)
    h, w = camera.height, camera.width
    inside = np.isfinite(uv).all(axis=1) & (z > 0)
    inside &= (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    d = np.asarray(keypoints_world, dtype=float) - camera.origin
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    buf = np.full(len(z), np.nan)
    v = np.zeros(len(z), dtype=int)
    if inside.any():
        depth, inst, region = first_hit(d[inside])
        buf[inside] = depth
        idx = np.flatnonzero(inside)
        on_region = np.array([region[j] in _ALLOWED[k] for j, k in enumerate(idx)])
        seen = (np.asarray(inst) == instance_id) & on_region & (np.asarray(depth) >= z[inside] - _TOL[inside])
        # a surface keypoint on the silhouette (the nose tip in profile): its grazing ray can
        # miss the person and hit only what lies beyond; nothing hides it
        grazing = np.isin(idx, _SURFACE) & (np.asarray(inst) != instance_id)
        seen |= grazing & (np.asarray(depth) > z[inside] + _TOL[inside])
        v[inside] = np.where(seen, 2, 1)
    flat = []
    for k in range(len(v)):
        flat += [float(uv[k, 0]), float(uv[k, 1]), int(v[k])] if v[k] else [0.0, 0.0, 0]
    return {"keypoints": flat, "uv": uv, "depth_m": z, "visibility": v, "depth_buffer_m": buf}
