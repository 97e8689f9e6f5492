"""The meshes of a composed stage as the render needs them, in plain numpy (no Mitsuba here).

Conventions are those of ``docs/architecture.md``: Z-up metre stages, time codes are frames,
per-face data are ``uniform`` primvars (one value per authored face) and polygons are
triangulated as fans (:func:`humv_usd.geometry.mesh.fan_triangulate`).

What is read
------------
- every ``UsdGeom.Mesh`` with purpose default/render (instance proxies included):
  :func:`humv_usd.usd.mesh.scene_mesh_prims`, the rule the thermal tool solves by too;
- per mesh, once (topology must not change over time): fan triangles with a triangle ->
  authored-face map, one :class:`Part` per bound material (``GeomSubset`` material bindings
  first, the rest on the mesh's own binding; materials through
  :func:`humv_usd.usd.materials.read_material`, the reader the thermal tool uses too),
  ``humv:label:instanceId`` of the mesh or its nearest ancestor
  (:func:`humv_usd.usd.labels.instance_id`), ``orientation`` and
  ``doubleSided``;
- per mesh and frame: world points [m] (``UsdGeom.XformCache``) and whether the winding flips
  (a mirroring transform or a leftHanded mesh). A doubleSided mesh (garments, open shells) gets
  a back side: a copy of its points :data:`BACK_SIDE_OFFSET_M` behind the front, with reversed
  winding.

Skinned meshes (UsdSkel): a mesh under a ``SkelRoot`` bound to a ``Skeleton`` (``skel:skeleton``
with joint influences) is posed at each frame by UsdSkel itself (``UsdSkel.Cache`` ->
``SkinningQuery.ComputeSkinnedPoints`` with the skeleton's skinning transforms at the frame's
time code, i.e. its bound ``skel:animationSource``), giving points in skeleton space that the
Skeleton prim's local-to-world takes to world space. Blend shapes are not applied (warned).

Not handled (documented limits): point instancers, hole indices, topology that changes over
time, blend shapes.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom, UsdShade, UsdSkel

from humv_usd.errors import InputError, bad_value, summary
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.usd.labels import instance_id, nearest_class, nearest_instance_id
from humv_usd.usd.layers import attribute_value
from humv_usd.usd.materials import StageMaterial, bound_material, face_materials, read_material
from humv_usd.usd.mesh import TRAVERSAL, scene_mesh_prims

#: A material as the render reads it (:func:`humv_usd.usd.materials.read_material`).
Material = StageMaterial

#: Distance of the back-side copy of a doubleSided mesh behind its front [m]: far above float32
#: resolution at scene scale (~2e-6 m at 20 m), far below garment air gaps (>= 2 mm).
BACK_SIDE_OFFSET_M = 1e-4


@dataclass
class Part:
    """The faces of one mesh bound to one material, triangulated.

    ``vertex_ids`` index the mesh's points; ``triangles`` index ``vertex_ids`` (authored winding:
    counter-clockwise is the front for a right-handed mesh); ``triangle_face`` is the authored
    face of each triangle.
    """

    key: str
    mesh_path: str
    material: Material
    instance_id: int
    vertex_ids: np.ndarray
    triangles: np.ndarray
    triangle_face: np.ndarray
    #: label class token of the object the mesh belongs to (``humv:label:class`` at the prim that
    #: carries its instance id, as the ground truth's class; None: no instance id, background):
    #: the automatic quality's regions (:mod:`humv_usd.render.quality`)
    label_class: str | None = None


@dataclass
class MeshInfo:
    path: str
    point_count: int
    face_count: int
    left_handed: bool
    parts: list[Part]
    # doubleSided meshes (e.g. garments, open shells): the back side is a copy of the surface
    # with reversed winding, offset by BACK_SIDE_OFFSET_M behind the front; its points are
    # appended after the authored ones (indices point_count..2*point_count-1)
    double_sided: bool = False
    front_triangles: np.ndarray | None = None


def face_corners(triangles: np.ndarray, flipped: bool) -> np.ndarray:
    """(t, 3) vertex indices of triangles in the winding the scene draws them: ``flipped``
    (USD ``orientation = "leftHanded"``, a mirrored transform) reverses it (corners 0, 2, 1).
    The one rule for the Mitsuba mesh (:func:`humv_usd.render.elements.mesh`), its geometric
    normals and the corner order of a hit's barycentric coordinates (``si.uv``) that the fast
    estimator's smooth shading weights."""
    return triangles[:, [0, 2, 1]] if flipped else triangles


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh (counter-clockwise front)."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    face_n = np.cross(b - a, c - a)
    n = np.zeros_like(points)
    for k in range(3):
        np.add.at(n, triangles[:, k], face_n)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def _traverse(stage: Usd.Stage):
    return stage.Traverse(TRAVERSAL)


class SceneMeshes:
    """The rendered meshes of a stage: found once; each mesh's topology, parts and materials
    read once (cached); its world points read per frame (:meth:`world_points`)."""

    def __init__(self, stage: Usd.Stage):
        self.stage = stage
        self.meters_per_unit = float(UsdGeom.GetStageMetersPerUnit(stage))
        self.prims = scene_mesh_prims(stage)  # the thermal tool solves the same meshes
        self.skinned = self._find_skinned()
        self._mesh_cache: dict[str, MeshInfo] = {}
        self._materials: dict[str, Material] = {}
        self._part_count = 0

    # --- skinning ----------------------------------------------------------------------------
    def _find_skinned(self) -> dict[str, tuple]:
        """mesh path -> (SkinningQuery, SkelQuery, Skeleton prim) for meshes UsdSkel skins."""
        roots = [p for p in _traverse(self.stage) if p.IsA(UsdSkel.Root)]
        if not roots:
            return {}
        self._skel_cache = UsdSkel.Cache()
        for root in roots:
            self._skel_cache.Populate(UsdSkel.Root(root), TRAVERSAL)
        out = {}
        for prim in self.prims:
            query = self._skel_cache.GetSkinningQuery(prim)
            if not query or not query.HasJointInfluences():
                continue
            skel = UsdSkel.BindingAPI(prim).GetInheritedSkeleton()
            skel_query = self._skel_cache.GetSkelQuery(skel) if skel else None
            if not skel_query:
                continue
            if query.HasBlendShapes():
                warnings.warn(
                    f"{prim.GetPath()}: blend shapes are not applied by the renderer",
                    RuntimeWarning,
                    stacklevel=2,
                )
            out[str(prim.GetPath())] = (query, skel_query, skel.GetPrim())
        return out

    def points(self, prim: Usd.Prim, path: str, time, cache: UsdGeom.XformCache):
        """(local points, local-to-world row-vector matrix) of a mesh at ``time``; skinned meshes
        are posed by UsdSkel and come in skeleton space with the Skeleton's local-to-world."""
        pts = attribute_value(UsdGeom.Mesh(prim).GetPointsAttr(), time)
        skinned = self.skinned.get(path)
        if skinned is None or pts is None:
            pts = np.asarray(pts if pts is not None else np.zeros((0, 3)), dtype=float).reshape(-1, 3)
            return pts, np.array(cache.GetLocalToWorldTransform(prim), dtype=float)
        query, skel_query, skel_prim = skinned
        try:
            xforms = skel_query.ComputeSkinningTransforms(time)
            ok = bool(xforms) and query.ComputeSkinnedPoints(xforms, pts, time)
        except Exception:  # pxr raises Tf.ErrorException on malformed skinning data
            ok = False
        if not ok:
            raise InputError(
                bad_value(
                    f"{path}.primvars:skel:jointIndices",
                    "<cannot skin>",
                    f"expected valid UsdSkel joint influences and a posable skeleton "
                    f"{skel_prim.GetPath()} at frame {time.GetValue():g}",
                )
            )
        return (
            np.asarray(pts, dtype=float).reshape(-1, 3),
            np.array(cache.GetLocalToWorldTransform(skel_prim), dtype=float),
        )

    # --- per frame ---------------------------------------------------------------------------
    def world_points(
        self, prim: Usd.Prim, info: MeshInfo, frame: int, cache: UsdGeom.XformCache
    ) -> tuple[np.ndarray, bool]:
        """(world points [m], flip) of a mesh at ``frame``: flip reverses the winding (a
        mirroring transform or a leftHanded mesh); a doubleSided mesh's back-side copy is
        appended (behind the rendered front: against its normal, which a flip turns around)."""
        pts, m = self.points(prim, info.path, Usd.TimeCode(frame), cache)  # m: row-vector convention
        if pts.shape[0] != info.point_count:
            raise InputError(
                bad_value(
                    f"{info.path}.points",
                    f"<{pts.shape[0]} points at frame {frame}>",
                    f"expected {info.point_count} points (topology must not change over time)",
                )
            )
        world = (pts @ m[:3, :3] + m[3, :3]) * self.meters_per_unit
        if not np.all(np.isfinite(world)):
            raise InputError(
                bad_value(f"{info.path}.points", "<non-finite>", f"expected finite points at frame {frame}")
            )
        flip = bool(info.left_handed) != bool(np.linalg.det(m[:3, :3]) < 0)
        if info.double_sided:
            normals = vertex_normals(world, info.front_triangles) * (-1.0 if flip else 1.0)
            world = np.concatenate([world, world - BACK_SIDE_OFFSET_M * normals])
        return world, flip

    # --- per mesh (static) ---------------------------------------------------------------------
    def bound_material(self, prim: Usd.Prim, mesh_path: str, time) -> Material:
        """The material bound to ``prim`` (a mesh or a GeomSubset), read once per material."""
        material: UsdShade.Material = bound_material(prim)
        mpath = str(material.GetPath())
        if mpath not in self._materials:
            self._materials[mpath] = read_material(material, mesh_path, time)
        return self._materials[mpath]

    def mesh_info(self, prim: Usd.Prim, time) -> MeshInfo:
        """Topology, parts and materials of a mesh (read at its first rendered frame, cached)."""
        path = str(prim.GetPath())
        if path not in self._mesh_cache:
            self._mesh_cache[path] = self._read_mesh(prim, path, time)
        return self._mesh_cache[path]

    def _read_mesh(self, prim: Usd.Prim, path: str, time) -> MeshInfo:
        mesh = UsdGeom.Mesh(prim)
        counts, indices, npoints = self._topology(mesh, path, time)
        triangles, triangle_face = fan_triangulate(counts, indices)
        front_triangles = triangles
        double_sided = bool(mesh.GetDoubleSidedAttr().Get())
        if double_sided:
            # the back side: same faces, reversed winding, on the offset copy of the points
            triangles = np.concatenate([triangles, triangles[:, ::-1] + npoints])
            triangle_face = np.concatenate([triangle_face, triangle_face])
        materials, material_of_face = self._face_materials(prim, path, counts.size, time)
        mesh_id = instance_id(prim)
        id_prim, _ = nearest_instance_id(prim)
        label_class = None if id_prim is None else (nearest_class(id_prim)[1] or "other")
        parts = []
        for m_index, mat in enumerate(materials):
            sel = material_of_face[triangle_face] == m_index
            if not np.any(sel):
                continue
            vertex_ids, local = np.unique(triangles[sel].ravel(), return_inverse=True)
            parts.append(
                Part(
                    key=f"part_{self._part_count:05d}",
                    mesh_path=path,
                    material=mat,
                    instance_id=mesh_id,
                    vertex_ids=vertex_ids,
                    triangles=local.reshape(-1, 3).astype(np.int64),
                    triangle_face=triangle_face[sel],
                    label_class=label_class,
                )
            )
            self._part_count += 1
        return MeshInfo(
            path=path,
            point_count=npoints,
            face_count=counts.size,
            left_handed=(mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded),
            parts=parts,
            double_sided=double_sided,
            front_triangles=front_triangles if double_sided else None,
        )

    @staticmethod
    def _topology(mesh: UsdGeom.Mesh, path: str, time) -> tuple[np.ndarray, np.ndarray, int]:
        """(faceVertexCounts, faceVertexIndices, point count), checked."""
        counts = attribute_value(mesh.GetFaceVertexCountsAttr(), time)
        indices = attribute_value(mesh.GetFaceVertexIndicesAttr(), time)
        points = attribute_value(mesh.GetPointsAttr(), time)
        counts = np.asarray(counts if counts is not None else [], dtype=np.int64)
        indices = np.asarray(indices if indices is not None else [], dtype=np.int64)
        npoints = 0 if points is None else len(points)
        if np.any(counts < 3) or counts.sum() != indices.size:
            raise InputError(
                bad_value(
                    f"{path}.faceVertexCounts",
                    summary(counts),
                    f"expected counts >= 3 summing to len(faceVertexIndices) = {indices.size}",
                )
            )
        if indices.size and (indices.min() < 0 or indices.max() >= npoints):
            raise InputError(
                bad_value(
                    f"{path}.faceVertexIndices",
                    f"<range {indices.min()}..{indices.max()}>",
                    f"expected indices in 0..{npoints - 1}",
                )
            )
        return counts, indices, npoints

    def _face_materials(self, prim: Usd.Prim, path: str, nfaces: int, time):
        """(materials, material index of each authored face): GeomSubsets with their own
        binding first (a face in two subsets keeps the first), the rest on the mesh's
        (:func:`humv_usd.usd.materials.face_materials`, which the thermal tool reads too)."""
        return face_materials(prim, nfaces, lambda p: self.bound_material(p, path, time), time)
