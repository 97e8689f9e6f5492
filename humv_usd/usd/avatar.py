"""Typed readers and writers of a person on the stage: /World/Humans/<id> (HumvAvatarAPI and
its metabolic-rate schedule), its UsdSkel Skeleton, the joint motion, the skinned Body mesh and
its garments (HumvClothingAPI and the air-gap primvar).

Downstream tools (clothing, thermal, ground truth) read the person through these functions
only, so a TD who replaces or edits the avatar layer (another stature, a body mesh from a DCC,
other skin weights) is honoured; the avatar and clothing tools write through them. Every
problem is one :class:`~humv_usd.errors.InputError` line naming the prim.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel, Vt

from humv_usd.errors import InputError, bad_value
from humv_usd.usd import schemas as S
from humv_usd.usd.paths import body_path, human_path, skeleton_path

# Label attributes of the avatar's Body (and garments, props): custom, not in the schemas
BODY_REGION_PRIMVAR = "primvars:humv:label:bodyRegion"  # int[], uniform
BODY_REGION_NAMES_ATTR = "humv:label:bodyRegionNames"  # token[], index = id
JOS3_SEGMENT_PRIMVAR = "primvars:humv:label:jos3Segment"  # int[], uniform
JOS3_SEGMENT_NAMES_ATTR = "humv:label:jos3SegmentNames"  # token[], index = value
COCO_KEYPOINTS_ATTR = "humv:label:cocoKeypoints"  # point3f[], time-sampled
COCO_KEYPOINT_NAMES_ATTR = "humv:label:cocoKeypointNames"  # token[]


@dataclass(frozen=True)
class AvatarParameters:
    """What HumvAvatarAPI says about a person (units as the schema: yr, m, kg)."""

    human_id: str
    sex: str  # "male" | "female"
    age_yr: float
    stature_m: float
    mass_kg: float
    build: float  # MakeHuman muscle macro value, 0..1
    fitness: str
    activity: str


@dataclass(frozen=True)
class SkeletonRest:
    """The avatar's UsdSkel Skeleton at its bind pose (skeleton space, metres)."""

    joints: list[str]  # UsdSkel joint paths ("Hips/LowerBack/...")
    bind_positions: np.ndarray  # (J, 3) joint origins at the bind pose
    bind_rotations: np.ndarray  # (J, 3, 3) their rotations (identity for world-aligned rigs)


@dataclass(frozen=True)
class BodyMesh:
    """The avatar's Body mesh at rest (its authored points) with its UsdSkel skinning."""

    path: str
    points: np.ndarray  # (V, 3) rest points [m], skeleton space
    face_counts: np.ndarray  # (F,)
    face_indices: np.ndarray  # (sum counts,)
    joint_indices: np.ndarray  # (V, k) int32 into SkeletonRest.joints
    joint_weights: np.ndarray  # (V, k) float32, rows sum to 1
    face_regions: np.ndarray | None  # (F,) body region id per face (bodyRegion primvar), if authored


def _avatar_prim(stage: Usd.Stage, human_id: str) -> Usd.Prim:
    path = human_path(human_id)
    prim = stage.GetPrimAtPath(path)
    if not prim:
        raise InputError(f"{path}: no avatar on the stage (the avatar layer of {human_id!r} is missing)")
    if not prim.HasAPI(S.AVATAR_API):
        raise InputError(f"{path}: has no {S.AVATAR_API} (sex, age, stature, mass of the person)")
    return prim


def read_avatar(stage: Usd.Stage, human_id: str) -> AvatarParameters:
    """The person's parameters from HumvAvatarAPI on ``/World/Humans/<human_id>``.

    sex, age, stature and mass must be authored (or inherited from a stronger layer); build,
    fitness and activity fall back to the schema's defaults.
    """
    prim = _avatar_prim(stage, human_id)

    def value(name: str, required: bool):
        attr = prim.GetAttribute(name)
        v = attr.Get() if attr else None
        if v is None and required:
            raise InputError(f"{prim.GetPath()}.{name}: not authored (the clothing tool needs it)")
        return v

    return AvatarParameters(
        human_id=human_id,
        sex=str(value(S.AVATAR_SEX, True)),
        age_yr=_as_written(value(S.AVATAR_AGE, True)),
        stature_m=_as_written(value(S.AVATAR_STATURE, True)),
        mass_kg=_as_written(value(S.AVATAR_MASS, True)),
        build=_as_written(value(S.AVATAR_BUILD, False) or 0.5),
        fitness=str(value(S.AVATAR_FITNESS, False) or "average"),
        activity=str(value(S.AVATAR_ACTIVITY, False) or "stand"),
    )


def _as_written(value) -> float:
    """A float attribute as the layer's text shows it: the shortest decimal that gives the same
    float32 (1.78 stays 1.78 instead of 1.7799999713897705), so a body rebuilt from the stage is
    the avatar tool's to the last bit."""
    return float(str(np.float32(value)))


def _skeleton(stage: Usd.Stage, human_id: str) -> UsdSkel.Skeleton:
    path = skeleton_path(human_id)
    prim = stage.GetPrimAtPath(path)
    if not prim or not prim.IsA(UsdSkel.Skeleton):
        raise InputError(f"{path}: no UsdSkel Skeleton (the avatar layer's rig)")
    return UsdSkel.Skeleton(prim)


def read_skeleton_rest(stage: Usd.Stage, human_id: str) -> SkeletonRest:
    """Joint paths and bind transforms of ``/World/Humans/<id>/Skeleton``."""
    skel = _skeleton(stage, human_id)
    joints = [str(j) for j in (skel.GetJointsAttr().Get() or [])]
    bind = skel.GetBindTransformsAttr().Get()
    if bind is None or len(bind) != len(joints):
        raise InputError(
            f"{skel.GetPath()}.bindTransforms: {0 if bind is None else len(bind)} transforms "
            f"for {len(joints)} joints"
        )
    m = np.asarray(bind, dtype=np.float64).reshape(-1, 4, 4)  # Gf: row vectors
    return SkeletonRest(joints, m[:, 3, :3].copy(), np.transpose(m[:, :3, :3], (0, 2, 1)).copy())


def read_joint_transforms(stage: Usd.Stage, human_id: str, frame_count: int, fps: float) -> np.ndarray:
    """(F, J, 4, 4) column-vector joint transforms in skeleton space per frame, of whatever
    animation the avatar's Skeleton is bound to (its rest pose without one); F = 1 when the
    pose does not change over the frames.

    Frame f is read at the stage time of f / ``fps`` seconds: a root layer without our
    timeCodesPerSecond (e.g. an anonymous one, 24 by default) rescales its sublayers' times.
    """
    skel = _skeleton(stage, human_id)
    joints = len(skel.GetJointsAttr().Get() or [])
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath(human_path(human_id))), Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(skel)
    out = np.empty((max(frame_count, 1), joints, 4, 4))
    scale = stage.GetTimeCodesPerSecond() / fps
    for f in range(len(out)):
        m = np.asarray(query.ComputeJointSkelTransforms(Usd.TimeCode(f * scale)), dtype=np.float64)
        out[f] = np.transpose(m, (0, 2, 1))  # Gf row-vector -> column-vector
    if np.allclose(out, out[:1], atol=1e-9):
        return out[:1]
    return out


def read_body_mesh(stage: Usd.Stage, human_id: str) -> BodyMesh:
    """``/World/Humans/<id>/Body``: authored rest points, faces and UsdSkel joint influences.

    The points must be in skeleton space (identity ``skel:geomBindTransform``, as the avatar
    tool writes them) and the influences per vertex (``vertex`` interpolation). The body region
    per face (``primvars:humv:label:bodyRegion``, uniform) comes along when authored.
    """
    path = body_path(human_id)
    prim = stage.GetPrimAtPath(path)
    if not prim or not prim.IsA(UsdGeom.Mesh):
        raise InputError(f"{path}: no Body mesh (the avatar layer's skinned body)")
    mesh = UsdGeom.Mesh(prim)
    points = np.asarray(mesh.GetPointsAttr().Get() or [], dtype=np.float64)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], dtype=np.int64)
    binding = UsdSkel.BindingAPI(prim)
    geom_bind = binding.GetGeomBindTransformAttr().Get()
    if geom_bind is not None and not np.allclose(np.asarray(geom_bind), np.eye(4), atol=1e-9):
        raise InputError(f"{path}.skel:geomBindTransform: expected identity (points in skeleton space)")
    idx_pv, w_pv = binding.GetJointIndicesPrimvar(), binding.GetJointWeightsPrimvar()
    if not (idx_pv and w_pv and idx_pv.HasAuthoredValue() and w_pv.HasAuthoredValue()):
        raise InputError(f"{path}: no skel:jointIndices / skel:jointWeights (the body is not skinned)")
    if idx_pv.GetInterpolation() != UsdGeom.Tokens.vertex:
        raise InputError(f"{path}.primvars:skel:jointIndices: interpolation must be vertex")
    k = idx_pv.GetElementSize()
    joint_indices = np.asarray(idx_pv.Get(), dtype=np.int32).reshape(-1, k)
    joint_weights = np.asarray(w_pv.Get(), dtype=np.float32).reshape(-1, k)
    if len(joint_indices) != len(points) or joint_weights.shape != joint_indices.shape:
        raise InputError(
            f"{path}: {len(joint_indices)} joint influences for {len(points)} points (need one per point)"
        )
    return BodyMesh(
        str(path), points, counts, indices, joint_indices, joint_weights, _face_ints(prim, len(counts))
    )


def _face_ints(prim: Usd.Prim, faces: int) -> np.ndarray | None:
    """The body-region primvar (one int per face), or None when missing or of another size."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(BODY_REGION_PRIMVAR.removeprefix("primvars:"))
    values = primvar.Get() if primvar and primvar.GetInterpolation() == UsdGeom.Tokens.uniform else None
    if values is None or len(values) != faces:
        return None
    return np.asarray(values, dtype=np.int32)


# ---------------------------------------------------------------------------- writers


def write_avatar(prim: Usd.Prim, person: AvatarParameters, body_surface_area_m2: float) -> None:
    """Apply HumvAvatarAPI to the person's SkelRoot ``prim`` and author its parameters (sex, age
    [yr], stature [m], mass [kg], build (muscle macro 0..1), fitness, activity) and the body
    surface area [m2]."""
    prim.ApplyAPI(S.AVATAR_API)
    for attr, value in (
        (S.AVATAR_SEX, person.sex),
        (S.AVATAR_AGE, person.age_yr),
        (S.AVATAR_STATURE, person.stature_m),
        (S.AVATAR_MASS, person.mass_kg),
        (S.AVATAR_BUILD, person.build),
        (S.AVATAR_FITNESS, person.fitness),
        (S.AVATAR_ACTIVITY, person.activity),
        (S.AVATAR_BODY_SURFACE_AREA, body_surface_area_m2),
    ):
        prim.GetAttribute(attr).Set(value)


def write_metabolic_rate(prim: Usd.Prim, rate_w) -> None:
    """The metabolic-rate schedule [W] per frame on the person's ``prim``: one default value
    when it does not change over the frames, else a time sample per frame (time code = frame).
    The prim has HumvAvatarAPI (:func:`write_avatar`)."""
    if not prim.HasAPI(S.AVATAR_API):
        raise InputError(
            f"{prim.GetPath()}: has no {S.AVATAR_API} (write the avatar before its metabolic rate)"
        )
    rate = np.asarray(rate_w, dtype=float)
    attr = prim.GetAttribute(S.AVATAR_METABOLIC_RATE)
    if len(rate) == 1 or np.allclose(rate, rate[0]):
        attr.Set(float(rate[0]))
    else:
        for frame, value in enumerate(rate):
            attr.Set(float(value), frame)


def write_garment(prim: Usd.Prim, garment: str, ease_m: float, minimum_gap_m: float) -> None:
    """Apply HumvClothingAPI to a garment mesh: its catalogue name, ease [m] and minimum air gap
    [m] over the skin."""
    prim.ApplyAPI(S.CLOTHING_API)
    prim.GetAttribute(S.CLOTHING_GARMENT).Set(garment)
    prim.GetAttribute(S.CLOTHING_EASE).Set(float(ease_m))
    prim.GetAttribute(S.CLOTHING_MINIMUM_GAP).Set(float(minimum_gap_m))


def write_air_gap(prim: Usd.Prim, air_gap_m, time_sampled: bool) -> None:
    """The air gap [m] between each garment vertex and the skin (vertex primvar
    ``primvars:humv:clothing:airGap``): ``air_gap_m`` (F, V), a time sample per frame when
    ``time_sampled``, else row 0 as the default value."""
    gaps = np.asarray(air_gap_m)
    primvar = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
        S.AIR_GAP_PRIMVAR.removeprefix("primvars:"), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
    )
    if not time_sampled:
        primvar.Set(Vt.FloatArray.FromNumpy(gaps[0].astype(np.float32)))
        return
    for frame, values in enumerate(gaps):
        primvar.Set(Vt.FloatArray.FromNumpy(values.astype(np.float32)), Usd.TimeCode(frame))


def _face_label(prim: Usd.Prim, primvar_name: str, values, names_attr: str, names, doc: str, tag: bool):
    """One uniform int primvar per face with its documentation and the token table of its ids
    (``tag``: the table also as the primvar's ``humv:names`` custom data)."""
    pv = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
        primvar_name.removeprefix("primvars:"), Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.uniform
    )
    pv.Set(Vt.IntArray.FromNumpy(np.asarray(values, dtype=np.int32)))
    pv.GetAttr().SetDocumentation(doc)
    if tag:
        pv.GetAttr().SetCustomDataByKey("humv:names", Vt.StringArray(list(names)))
    prim.CreateAttribute(names_attr, Sdf.ValueTypeNames.TokenArray, custom=True).Set(
        Vt.TokenArray(list(names))
    )


def write_body_labels(prim: Usd.Prim, regions, region_names, segments, segment_names) -> None:
    """The Body's labels per face: body region id (index into ``region_names``; 0 = not the
    body) and JOS-3 segment (0-based index into ``segment_names``), uniform int primvars with
    their name tables."""
    _face_label(
        prim,
        BODY_REGION_PRIMVAR,
        regions,
        BODY_REGION_NAMES_ATTR,
        region_names,
        "body region id per face (names in humv:label:bodyRegionNames, index = id; 0 = not the body)",
        tag=True,
    )
    _face_label(
        prim,
        JOS3_SEGMENT_PRIMVAR,
        segments,
        JOS3_SEGMENT_NAMES_ATTR,
        segment_names,
        "JOS-3 segment per face: 0-based index into JOS-3's 17 segments (names in humv:label:jos3SegmentNames)",
        tag=True,
    )


def write_garment_regions(prim: Usd.Prim, regions, region_names) -> None:
    """The body region under each garment face (ids as the Body's), uniform int primvar with
    the name table."""
    _face_label(
        prim,
        BODY_REGION_PRIMVAR,
        regions,
        BODY_REGION_NAMES_ATTR,
        region_names,
        "body region under each garment face (ids as the Body's humv:label:bodyRegionNames)",
        tag=False,
    )


def write_keypoints(prim: Usd.Prim, keypoints_m, names) -> None:
    """COCO keypoints of the person (its SkelRoot ``prim``): ``keypoints_m`` (F, K, 3) in
    skeleton space [m], a time sample per frame, and their names (K,)."""
    attr = prim.CreateAttribute(COCO_KEYPOINTS_ATTR, Sdf.ValueTypeNames.Point3fArray, custom=True)
    for frame, points in enumerate(keypoints_m):
        attr.Set(Vt.Vec3fArray.FromNumpy(np.asarray(points, dtype=np.float32)), frame)
    prim.CreateAttribute(COCO_KEYPOINT_NAMES_ATTR, Sdf.ValueTypeNames.TokenArray, custom=True).Set(
        Vt.TokenArray(list(names))
    )


def has_keypoints(prim: Usd.Prim) -> bool:
    """The prim carries COCO keypoints (``humv:label:cocoKeypoints`` with a value)."""
    attr = prim.GetAttribute(COCO_KEYPOINTS_ATTR)
    return bool(attr.IsValid() and attr.HasValue())


def read_keypoints(prim: Usd.Prim, frame: int) -> np.ndarray | None:
    """(K, 3) COCO keypoints [scene units, the prim's space] at ``frame``; None when absent."""
    value = prim.GetAttribute(COCO_KEYPOINTS_ATTR).Get(Usd.TimeCode(frame))
    return None if value is None else np.asarray(value, dtype=float).reshape(-1, 3)


# ---------------------------------------------------------------------------- more readers


def read_metabolic_rate(prim: Usd.Prim, frames: int, default_w: float = 100.0) -> np.ndarray:
    """(frames,) metabolic rate [W] of the person ``prim`` (its SkelRoot, HumvAvatarAPI) at each
    frame (time code = frame); ``default_w`` where nothing (or zero) is authored."""
    attr = prim.GetAttribute(S.AVATAR_METABOLIC_RATE) if prim else None
    values = [attr.Get(Usd.TimeCode(f)) if attr else None for f in range(frames)]
    return np.array([v or default_w for v in values], dtype=float)


def read_garment(prim: Usd.Prim) -> str | None:
    """The catalogue garment token of a garment mesh (``humv:clothing:garment``), None when the
    prim has none."""
    attr = prim.GetAttribute(S.CLOTHING_GARMENT)
    value = attr.Get() if attr else None
    return None if value is None else str(value)


def is_garment(prim: Usd.Prim) -> bool:
    """The mesh is a garment: HumvClothingAPI applied or a garment token authored."""
    attr = prim.GetAttribute(S.CLOTHING_GARMENT)
    return S.CLOTHING_API in prim.GetAppliedSchemas() or bool(attr and attr.HasAuthoredValue())


def read_air_gap(prim: Usd.Prim, frame: int) -> np.ndarray:
    """(V,) air gap [m] per garment vertex at ``frame`` (primvars:humv:clothing:airGap)."""
    attr = prim.GetAttribute(S.AIR_GAP_PRIMVAR)
    value = attr.Get(Usd.TimeCode(frame)) if attr else None
    if value is None:
        raise InputError(
            bad_value(f"{prim.GetPath()}.{S.AIR_GAP_PRIMVAR}", None, "expected one gap [m] per vertex")
        )
    return np.asarray(value, dtype=float)


def read_body_regions(prim: Usd.Prim) -> np.ndarray:
    """(F,) body region id per face of a body or garment mesh (primvars:humv:label:bodyRegion)."""
    attr = prim.GetAttribute(BODY_REGION_PRIMVAR)
    value = attr.Get() if attr else None
    if value is None:
        raise InputError(
            bad_value(f"{prim.GetPath()}.{BODY_REGION_PRIMVAR}", None, "expected a body region id per face")
        )
    return np.asarray(value, dtype=np.int64)
