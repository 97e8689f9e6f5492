"""Author meshes with our conventions: rightHanded (counter-clockwise seen from outside)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.usd import schemas as S


def define_mesh(
    stage: Usd.Stage,
    path: Sdf.Path | str,
    points: np.ndarray,
    face_counts: np.ndarray,
    face_indices: np.ndarray,
    material: Sdf.Path | None = None,
) -> UsdGeom.Mesh:
    """Define a polygon mesh (no subdivision) with extent and an optional material binding."""
    mesh = UsdGeom.Mesh.Define(stage, path)
    points = np.asarray(points, dtype=np.float32)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.asarray(face_counts, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(face_indices, np.int32)))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreateDoubleSidedAttr(False)
    lo, hi = points.min(axis=0), points.max(axis=0)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    if material is not None:
        bind_material(mesh.GetPrim(), material)
    return mesh


def bind_material(prim: Usd.Prim, material: Sdf.Path) -> None:
    """Direct material binding to a path that may live in another layer (materials.usda)."""
    UsdShade.MaterialBindingAPI.Apply(prim)
    prim.CreateRelationship(UsdShade.Tokens.materialBinding, custom=False).SetTargets([material])


def label(prim: Usd.Prim, instance_id: int, label_class: str) -> None:
    """HumvLabelAPI on ``prim``: the object's instance id and class token."""
    prim.ApplyAPI(S.LABEL_API)
    prim.GetAttribute(S.LABEL_INSTANCE_ID).Set(int(instance_id))
    prim.GetAttribute(S.LABEL_CLASS).Set(label_class)


def write_class(prim: Usd.Prim, label_class: str) -> None:
    """The class token alone (``humv:label:class``, custom; no HumvLabelAPI): a part that takes
    its instance id from an ancestor but has a class of its own (a carried prop)."""
    prim.CreateAttribute(S.LABEL_CLASS, Sdf.ValueTypeNames.Token, custom=True).Set(label_class)


def triangle_areas(points: np.ndarray, face_counts, face_indices) -> np.ndarray:
    """Area of each polygon [m^2] (fan triangulation; exact for planar convex faces)."""
    tris, face = fan_triangulate(face_counts, face_indices)
    a, b, c = (points[tris[:, k]] for k in range(3))
    tri_area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return np.bincount(face, weights=tri_area, minlength=len(face_counts))


def signed_volume(points: np.ndarray, face_counts, face_indices) -> float:
    """Signed enclosed volume [m^3] (divergence theorem); > 0 for outward CCW faces."""
    tris, _ = fan_triangulate(face_counts, face_indices)
    a, b, c = (points[tris[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0


def bound_corners(stage, root) -> np.ndarray:
    """World-space corners [m] of the axis-aligned bounding box of every mesh under ``root``
    (default time code), (8 x meshes, 3); empty when the stage has no prim there."""
    prim = stage.GetPrimAtPath(str(root)) if stage is not None else None
    if not (prim and prim.IsValid()):
        return np.zeros((0, 3))
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    corners = []
    for p in Usd.PrimRange(prim):
        if not p.IsA(UsdGeom.Mesh):
            continue
        box = cache.ComputeWorldBound(p).ComputeAlignedRange()
        if box.IsEmpty():
            continue
        corners += [np.asarray(box.GetCorner(i), dtype=float) for i in range(8)]
    return np.asarray(corners, dtype=float).reshape(-1, 3)


def override_topology(prim: Usd.Prim, points: np.ndarray, face_counts, face_indices) -> None:
    """Author new polygons on a mesh (an ``over`` in a stronger layer: the thermal layer's
    re-tessellated scene surfaces), points in the mesh's local space, with its extent."""
    mesh = UsdGeom.Mesh(prim)
    points = np.asarray(points, dtype=np.float32)
    mesh.CreatePointsAttr().Set(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(np.asarray(face_counts, np.int32)))
    mesh.CreateFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(np.asarray(face_indices, np.int32)))
    lo, hi = points.min(axis=0), points.max(axis=0)
    mesh.CreateExtentAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))


#: customData of an asset's referencing prim: the referenced file's units and up axis, which
#: the asset's transform corrects (``humv-usd check`` accepts a non-Z-up / non-metre file there)
ASSET_SOURCE = "humv:assetSource"


def write_asset_source(prim: Usd.Prim, file: str, meters_per_unit: float, up_axis: str) -> None:
    """Record on the prim that references ``file`` the units and up axis its transform corrects
    (and the file's name only: the reference holds its path, relative to the written layer, so
    the output can move; an absolute path here would go stale)."""
    prim.SetCustomDataByKey(
        ASSET_SOURCE,
        {"file": Path(file).name, "metersPerUnit": float(meters_per_unit), "upAxis": str(up_axis)},
    )


def read_asset_source(prim: Usd.Prim) -> dict | None:
    """What :func:`write_asset_source` recorded on ``prim`` or its nearest ancestor, else None."""
    p = prim
    while p and p.IsValid() and not p.IsPseudoRoot():
        value = p.GetCustomDataByKey(ASSET_SOURCE)
        if value:
            return dict(value)
        p = p.GetParent()
    return None


#: The one traversal rule for scene geometry, shared by the render
#: (:class:`humv_usd.render.scene_export.SceneMeshes`), the thermal tool
#: (:func:`humv_usd.thermal.surfaces.scene_meshes` and the layer it writes) and the editor's view:
#: active, loaded, defined, non-abstract prims, through instance proxies.
TRAVERSAL = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
#: Mesh purposes that are drawn, and so solved: ``guide`` and ``proxy`` meshes are neither.
DRAWN_PURPOSES = (UsdGeom.Tokens.default_, UsdGeom.Tokens.render)


def is_drawn_mesh(prim: Usd.Prim) -> bool:
    """Whether ``prim`` is a ``UsdGeom.Mesh`` the render draws (purpose default or render)."""
    return prim.IsA(UsdGeom.Mesh) and UsdGeom.Imageable(prim).ComputePurpose() in DRAWN_PURPOSES


def scene_mesh_prims(stage: Usd.Stage, root: Usd.Prim | None = None) -> list[Usd.Prim]:
    """Every drawn mesh of ``stage`` (or of the subtree at ``root``) in traversal order, by
    :data:`TRAVERSAL` and :func:`is_drawn_mesh`: what the render draws is what the thermal tool
    solves."""
    prims = stage.Traverse(TRAVERSAL) if root is None else Usd.PrimRange(root, TRAVERSAL)
    return [p for p in prims if is_drawn_mesh(p)]
