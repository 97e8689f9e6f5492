"""Scene assets from 3D files (``[[scene.asset]]``): what is in a file, in plain numpy.

Formats (by suffix, :data:`humv_usd.scenario.spec.ASSET_FORMATS`):

* USD (usd, usda, usdc, usdz): opened only to list its meshes (name, path below the root prim,
  bound material's name), its ``metersPerUnit`` and ``upAxis``; the scene layer references the
  file (not copied) and corrects units and up axis with the asset's transform.
* glTF/GLB, PLY, STL: read with trimesh (node transforms applied, one mesh per geometry and
  node; trimesh splits glTF meshes by material); OBJ by a small reader here (one mesh per object
  and material, polygons kept); converted to Z-up metres here.
* FBX: read with Blender (``bpy``, imported only for an FBX file; its importer applies the file's
  unit scale and axes, so the meshes come out Z-up in metres); one mesh per object and material.

Every problem with a file is one :class:`~humv_usd.errors.InputError` line: the file and what is
wrong with it.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Gf, Tf, Usd, UsdGeom, UsdShade

from humv_usd.errors import InputError
from humv_usd.scenario.spec import ASSET_FORMATS, ASSET_UNITS
from humv_usd.usd.layers import usd_error_text

#: (metres per unit, up axis) a mesh format means when the scenario says "auto"
MESH_FORMAT_DEFAULTS = {".gltf": (1.0, "Y"), ".glb": (1.0, "Y"), ".fbx": (1.0, "Z")}
MESH_FORMAT_FALLBACK = (1.0, "Z")  # OBJ, PLY, STL: no unit or axis in the format


@dataclass
class SourceMesh:
    """One mesh of an asset file.

    ``path`` is the mesh's path below the asset's root (USD: the prim path relative to the root
    prim; other formats: the node name); ``material`` the source material's name ('' if none).
    Mesh formats carry ``points`` (Z-up metres, before the asset's scale and placement),
    ``face_counts`` and ``face_indices``; USD meshes carry none (they stay in the file). A USD
    mesh's GeomSubsets with material bindings are entries of their own (path ``<mesh>/<subset>``)
    so that each gets its mapped material.
    """

    name: str
    path: str
    material: str
    points: np.ndarray | None = None
    face_counts: np.ndarray | None = None
    face_indices: np.ndarray | None = None


@dataclass
class AssetFile:
    """What a file holds: meshes, and (USD) the root prim, its units/up axis and instance roots."""

    file: str
    kind: str  # "usd", "mesh" or "fbx"
    meshes: list[SourceMesh]
    meters_per_unit: float
    up_axis: str
    root_prim: str | None = None  # USD: the prim the scene layer references
    instances: tuple[str, ...] = ()  # USD: instanceable prims (relative), de-instanced by the layer


def fail(file: str, what: str) -> InputError:
    """One line: the file and what is wrong with it."""
    return InputError(f"{file}: {what}")


def read_asset(file: str, units: str = "auto", up_axis: str = "auto") -> AssetFile:
    """The meshes of an asset file (see the module doc), with the units and up axis it means
    (``units``/``up_axis`` of the scenario override "auto")."""
    suffix = Path(file).suffix.lower()
    kind = ASSET_FORMATS.get(suffix)
    if kind is None:
        raise fail(file, "unknown format (expected " + ", ".join(ASSET_FORMATS) + ")")
    if not Path(file).is_file():
        raise fail(file, "file not found")
    if kind == "usd":
        asset = _read_usd(file)
    else:
        reader = _read_fbx if kind == "fbx" else _read_obj if suffix == ".obj" else _read_trimesh
        meshes = reader(file)
        mpu, up = MESH_FORMAT_DEFAULTS.get(suffix, MESH_FORMAT_FALLBACK)
        asset = AssetFile(file, kind, meshes, mpu, up)
    if ASSET_UNITS[units] is not None:
        asset.meters_per_unit = ASSET_UNITS[units]
    if up_axis != "auto":
        asset.up_axis = up_axis
    if kind != "usd":
        for m in asset.meshes:  # mesh formats: baked to Z-up metres here
            m.points = to_z_up_metres(m.points, asset.meters_per_unit, asset.up_axis)
    return asset


def to_z_up_metres(points: np.ndarray, meters_per_unit: float, up_axis: str) -> np.ndarray:
    """Source points in Z-up metres: scaled, and Y-up turned by +90 deg about x
    ((x, y, z) -> (x, -z, y), as Blender's importers do)."""
    p = np.asarray(points, dtype=float) * meters_per_unit
    if up_axis == "Y":
        p = np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)
    return p


def source_correction(meters_per_unit: float, up_axis: str) -> Gf.Matrix4d:
    """The matrix (USD row vectors) that takes a referenced USD asset to Z-up metres."""
    m = Gf.Matrix4d().SetScale(Gf.Vec3d(meters_per_unit))
    if up_axis == "Y":
        m = m * Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 0, 0), 90.0))
    return m


def placement(asset: dict) -> Gf.Matrix4d:
    """The scenario's scale then placement (``transform``, or ``heading_deg`` and ``position_m``)."""
    scale = Gf.Matrix4d().SetScale(Gf.Vec3d(asset["scale"]))
    if asset.get("transform"):
        return scale * Gf.Matrix4d(*[float(v) for row in asset["transform"] for v in row])
    rot = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(0, 0, 1), float(asset.get("heading_deg") or 0.0)))
    move = Gf.Matrix4d().SetTranslate(Gf.Vec3d(*(asset.get("position_m") or (0.0, 0.0, 0.0))))
    return scale * rot * move


def first_match(mapping, mesh: SourceMesh, default):
    """The value of the first ``[pattern, value]`` whose glob matches the mesh's name, its path
    in the asset or its source material's name (case-sensitive fnmatch); else ``default``."""
    for pattern, value in mapping or ():
        if any(fnmatch.fnmatchcase(s, pattern) for s in (mesh.name, mesh.path, mesh.material) if s):
            return value
    return default


def prim_name(text: str, taken: set[str]) -> str:
    """A valid, unique prim name for ``text``."""
    base = Tf.MakeValidIdentifier(text or "mesh")
    name, k = base, 1
    while name in taken:
        k += 1
        name = f"{base}_{k}"
    taken.add(name)
    return name


# ----------------------------------------------------------------------------------------- USD
def _read_usd(file: str) -> AssetFile:
    try:
        stage = Usd.Stage.Open(file, Usd.Stage.LoadAll)
    except Exception as exc:  # noqa: BLE001 (pxr raises Tf.ErrorException)
        raise fail(file, f"does not open as USD ({usd_error_text(exc)[:200]})") from None
    if stage is None:
        raise fail(file, "does not open as USD")
    root = stage.GetDefaultPrim()
    if not root:
        roots = list(stage.GetPseudoRoot().GetChildren())
        if not roots:
            raise fail(file, "holds no prims")
        root = roots[0]
    meshes, instances = [], []
    predicate = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    for prim in Usd.PrimRange(root, predicate):
        rel = prim.GetPath().MakeRelativePath(root.GetPath())
        if prim.IsInstance() and prim != root:  # the root is de-instanced by the referencing prim
            instances.append(str(rel))
        if not prim.IsA(UsdGeom.Mesh):
            continue
        binding = UsdShade.MaterialBindingAPI(prim)
        material, _ = binding.ComputeBoundMaterial()
        source = material.GetPrim().GetName() if material else ""
        meshes.append(SourceMesh(prim.GetName(), str(rel), source))
        for subset in binding.GetMaterialBindSubsets():  # per-face materials (a DCC's export)
            material, _ = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()
            name = material.GetPrim().GetName() if material else ""
            meshes.append(SourceMesh(subset.GetPrim().GetName(), f"{rel}/{subset.GetPrim().GetName()}", name))
    if not meshes:
        raise fail(file, f"no UsdGeom.Mesh under its root prim {root.GetPath()}")
    up = str(UsdGeom.GetStageUpAxis(stage))
    return AssetFile(
        file,
        "usd",
        meshes,
        float(UsdGeom.GetStageMetersPerUnit(stage)),
        up,
        root_prim=str(root.GetPath()),
        instances=tuple(instances),
    )


# ----------------------------------------------------------------------------------------- OBJ
def _read_obj(file: str) -> list[SourceMesh]:
    """Wavefront OBJ: one mesh per object (``o``, else group ``g``) and material (``usemtl``),
    polygons kept as they are (trimesh 4.5 loses the object names when it splits a file)."""
    try:
        text = Path(file).read_text(encoding="utf-8", errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise fail(file, f"cannot be read as OBJ text ({exc})") from None
    vertices: list[list[float]] = []
    groups: dict[tuple[str, str], list[list[int]]] = {}
    name, material = Path(file).stem, ""
    for n, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "v":
                if len(parts) < 4:
                    raise ValueError("a vertex needs x, y and z")
                vertices.append([float(v) for v in parts[1:4]])
            elif parts[0] in ("o", "g") and len(parts) > 1:
                name = " ".join(parts[1:]) if parts[0] == "o" or name == Path(file).stem else name
            elif parts[0] == "usemtl":
                material = " ".join(parts[1:])
            elif parts[0] == "f":
                face = [int(v.split("/")[0]) for v in parts[1:]]
                face = [i - 1 if i > 0 else len(vertices) + i for i in face]
                if len(face) < 3 or min(face) < 0 or max(face) >= len(vertices):
                    raise ValueError("a face needs 3 or more valid vertex indices")
                groups.setdefault((name, material), []).append(face)
        except ValueError as exc:  # the reason, cut: a corrupt line can be megabytes long
            raise fail(file, f"line {n}: {' '.join(str(exc).split())[:160]}") from None
    points = np.asarray(vertices, dtype=float).reshape(-1, 3)
    meshes = []
    for (obj, mat), faces in groups.items():
        idx = np.concatenate([np.asarray(f) for f in faces])
        used, remap = np.unique(idx, return_inverse=True)
        counts = np.array([len(f) for f in faces])
        meshes.append(SourceMesh(obj, obj, mat, points[used], counts, remap.ravel()))
    return _checked(file, meshes)


# ------------------------------------------------------------------------------ glTF, PLY, STL
def _read_trimesh(file: str) -> list[SourceMesh]:
    import trimesh

    try:
        scene = trimesh.load(file, force="scene")
    except Exception as exc:  # noqa: BLE001 (trimesh raises many kinds)
        raise fail(
            file, f"cannot be read ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})"
        ) from None
    meshes: list[SourceMesh] = []
    for node in scene.graph.nodes_geometry:
        matrix, geom_name = scene.graph[node]
        geom = scene.geometry.get(geom_name)
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        points = trimesh.transform_points(np.asarray(geom.vertices, dtype=float), matrix)
        material = getattr(getattr(geom.visual, "material", None), "name", None) or ""
        faces = np.asarray(geom.faces, dtype=np.int64)
        meshes.append(
            SourceMesh(
                str(geom_name), str(node), str(material), points, np.full(len(faces), 3), faces.ravel()
            )
        )
    return _checked(file, meshes)


#: largest coordinate a USD point (float) holds
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _checked(file: str, meshes: list[SourceMesh]) -> list[SourceMesh]:
    if not meshes:
        raise fail(file, "holds no triangle mesh")
    for m in meshes:
        if not np.all(np.isfinite(m.points)):
            raise fail(file, f"mesh {m.path!r} has non-finite vertex coordinates")
        big = float(np.abs(m.points).max()) if m.points.size else 0.0
        if big > FLOAT32_MAX:  # USD stores points as float: they would become inf (issue 26)
            raise fail(
                file,
                f"mesh {m.path!r} has a vertex coordinate of {big:.3g}: allowed range "
                f"-{FLOAT32_MAX:.3g}..{FLOAT32_MAX:.3g} (USD's float points)",
            )
    extent = np.ptp(np.concatenate([m.points for m in meshes]), axis=0)
    if not math.isfinite(float(extent.max())) or extent.max() <= 0.0:
        raise fail(file, "all vertices coincide")
    return meshes


# ----------------------------------------------------------------------------------------- FBX
def _read_fbx(file: str) -> list[SourceMesh]:
    """FBX through Blender's importer (bpy imported here only: compose never loads Blender
    otherwise). One mesh per object and material slot, world coordinates (Z-up metres)."""
    try:
        import bpy
    except ImportError:
        raise fail(
            file, "FBX needs Blender's Python module (pip install bpy); or convert it to glTF/USD"
        ) from None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        result = bpy.ops.import_scene.fbx(filepath=str(file))
    except RuntimeError as exc:
        raise fail(file, f"Blender cannot import it ({' '.join(str(exc).split())[:200]})") from None
    if "FINISHED" not in result:
        raise fail(file, "Blender cannot import it")
    meshes: list[SourceMesh] = []
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH":
            continue
        evaluated = obj.evaluated_get(depsgraph)
        data = evaluated.to_mesh()
        matrix = np.array(obj.matrix_world)
        co = np.empty(len(data.vertices) * 3)
        data.vertices.foreach_get("co", co)
        points = co.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]
        counts = np.empty(len(data.polygons), dtype=np.int64)
        data.polygons.foreach_get("loop_total", counts)
        loops = np.empty(len(data.loops), dtype=np.int64)
        data.loops.foreach_get("vertex_index", loops)
        mat_index = np.empty(len(data.polygons), dtype=np.int64)
        data.polygons.foreach_get("material_index", mat_index)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        names = [s.material.name if s.material else "" for s in obj.material_slots] or [""]
        for k in np.unique(mat_index):
            faces = np.flatnonzero(mat_index == k)
            idx = np.concatenate([loops[starts[f] : starts[f] + counts[f]] for f in faces])
            used, remap = np.unique(idx, return_inverse=True)
            name = (
                obj.name if len(np.unique(mat_index)) == 1 else f"{obj.name}_{names[min(k, len(names) - 1)]}"
            )
            meshes.append(
                SourceMesh(name, obj.name, names[min(k, len(names) - 1)], points[used], counts[faces], remap)
            )
        evaluated.to_mesh_clear()
    return _checked(file, meshes)
