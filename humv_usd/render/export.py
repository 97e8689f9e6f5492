"""USD stage -> per-frame scene description in plain numpy (no Mitsuba here).

Reads attributes by name (``prim.GetAttribute``), so it works whether or not the Humv API schemas
are applied or registered. Conventions are those of ``docs/architecture.md``: Z-up metre stages,
time codes are frames, cameras look down local -Z with +Y up, per-face data are ``uniform``
primvars (one value per authored face) and polygons are triangulated as fans.

What is read
------------
- every ``UsdGeom.Mesh`` with purpose default/render (instance proxies included), when visible
  at the frame: world points at the frame (``UsdGeom.XformCache``), fan triangles with a
  triangle -> authored-face map, one part per bound material (``GeomSubset`` material bindings
  included), ``primvars:humv:thermal:temperature`` at the frame, ``humv:label:instanceId`` of the
  mesh or its nearest ancestor;
- materials: ``humv:material:wavelengths`` [um] and ``humv:material:emissivity`` through
  :func:`humv_usd.usd.materials.read_material` (the reader the thermal tool uses too);
- ``/World/Atmosphere.humv:atmosphere:skyTemperature`` [K] at the frame;
- optional, per frame: ``/World/Atmosphere`` spectral tables
  (``humv:atmosphere:wavelengths``, ``skyZenithAngles``, ``skySpectralRadiance``,
  ``solarSpectralIrradiance``), ``/World/Environment.humv:environment:sunDirection`` and the
  per-sensor slant paths ``/World/Atmosphere/Paths/<sensor>`` (:meth:`StageExport.atmosphere_spectra`,
  :meth:`StageExport.sun_direction`, :meth:`StageExport.path_table`); materials'
  ``humv:material:reflectance`` (EO);
- every camera with ``humv:sensor:*`` attributes (HumvSensorAPI), as the one sensor model
  (:func:`humv_usd.usd.sensor.read_sensor` -> :class:`humv_usd.physics.sensor.SensorModel`), and
  its pose at the frame (:func:`humv_usd.usd.sensor.read_camera_pose`). A band starting below
  3 um (or the token ``EO``) is an EO sensor (``SensorModel.kind``), rendered by
  :mod:`humv_usd.render.eo`.

Skinned meshes (UsdSkel): a mesh under a ``SkelRoot`` bound to a ``Skeleton`` (``skel:skeleton``
with joint influences) is posed at each frame by UsdSkel itself (``UsdSkel.Cache`` ->
``SkinningQuery.ComputeSkinnedPoints`` with the skeleton's skinning transforms at the frame's
time code, i.e. its bound ``skel:animationSource``), giving points in skeleton space that the
Skeleton prim's local-to-world takes to world space. Blend shapes are not applied (warned).

Not handled (documented limits): point instancers, hole indices, aperture offsets (warned and
ignored), topology that changes over time, blend shapes.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom, UsdShade, UsdSkel

from humv_usd.errors import InputError, bad_value, summary
from humv_usd.geometry.camera import CameraPose
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.physics.sensor import SensorModel
from humv_usd.render.radiometry import PathTable
from humv_usd.usd import atmosphere as usd_atmosphere
from humv_usd.usd import environment as usd_environment
from humv_usd.usd import schemas as _s
from humv_usd.usd.atmosphere import AtmosphereSpectra
from humv_usd.usd.materials import StageMaterial, bound_material, read_material
from humv_usd.usd.sensor import read_camera_pose, read_sensor

# Attribute names: the contract of docs/architecture.md, read by name so that rendering does not
# depend on whether the schemas are registered or applied.
TEMPERATURE_ATTR = _s.TEMPERATURE_PRIMVAR
SKY_TEMPERATURE_ATTR = _s.ATMOSPHERE_SKY_TEMPERATURE
INSTANCE_ID_ATTR = _s.LABEL_INSTANCE_ID
SENSOR_API = _s.SENSOR_API
ENV_DNI_ATTR = _s.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE
SENSOR_PREFIX = "humv:sensor:"
ATMOSPHERE_PATH = "/World/Atmosphere"
ENVIRONMENT_PATH = "/World/Environment"
#: Per-sensor path tables live under this scope, one child per sensor.
ATMOSPHERE_PATHS = ATMOSPHERE_PATH + "/Paths"
# Environment / atmosphere attributes (the environment and atmosphere layers); absent -> not used
SUN_DIRECTION_ATTR = getattr(_s, "ENVIRONMENT_SUN_DIRECTION", "humv:environment:sunDirection")
ATM_MODEL_ATTR = _s.ATMOSPHERE_MODEL
ATM_WAVELENGTHS_ATTR = getattr(_s, "ATMOSPHERE_WAVELENGTHS", "humv:atmosphere:wavelengths")
ATM_SKY_ZENITH_ATTR = getattr(_s, "ATMOSPHERE_SKY_ZENITH_ANGLES", "humv:atmosphere:skyZenithAngles")
ATM_SKY_RADIANCE_ATTR = getattr(_s, "ATMOSPHERE_SKY_SPECTRAL_RADIANCE", "humv:atmosphere:skySpectralRadiance")
ATM_SOLAR_ATTR = getattr(
    _s, "ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE", "humv:atmosphere:solarSpectralIrradiance"
)
PATH_SENSOR_ATTR = getattr(_s, "ATMOSPHERE_PATH_SENSOR", "humv:atmospherePath:sensor")
PATH_RANGES_ATTR = getattr(_s, "ATMOSPHERE_PATH_RANGES", "humv:atmospherePath:ranges")
PATH_TRANSMITTANCE_ATTR = getattr(_s, "ATMOSPHERE_PATH_TRANSMITTANCE", "humv:atmospherePath:transmittance")
PATH_RADIANCE_ATTR = getattr(_s, "ATMOSPHERE_PATH_RADIANCE", "humv:atmospherePath:radiance")

#: Allowed temperatures [K] for surfaces and the sky.
TEMPERATURE_RANGE_K = (1.0, 5000.0)
#: Largest instance id (stored exactly in a float32 face attribute).
MAX_INSTANCE_ID = 2**24 - 1


def _get(attr, time):
    if not attr or not attr.IsValid():
        return None
    return attr.Get(time)


#: A material as the render reads it (:func:`humv_usd.usd.materials.read_material`).
Material = StageMaterial


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


@dataclass
class FrameState:
    """Everything that changes per frame, as numpy arrays keyed by mesh path / sensor name."""

    frame: int
    meshes: list[MeshInfo]  # visible meshes, in stage order
    points: dict[str, np.ndarray] = field(default_factory=dict)  # world points (P, 3) [m]
    flip: dict[str, bool] = field(default_factory=dict)  # reverse the winding (mirror or leftHanded)
    temperatures: dict[str, np.ndarray] = field(default_factory=dict)  # (F,) [K]
    cameras: dict[str, CameraPose] = field(default_factory=dict)
    sky_temperature_k: float = float("nan")

    @property
    def topology_key(self) -> tuple:
        """Changes exactly when the Mitsuba scene must be rebuilt."""
        return tuple((m.path, self.flip[m.path]) for m in self.meshes)


#: Distance of the back-side copy of a doubleSided mesh behind its front [m]: far above float32
#: resolution at scene scale (~2e-6 m at 20 m), far below garment air gaps (>= 2 mm).
BACK_SIDE_OFFSET_M = 1e-4


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh (counter-clockwise front)."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    face_n = np.cross(b - a, c - a)
    n = np.zeros_like(points)
    for k in range(3):
        np.add.at(n, triangles[:, k], face_n)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(length > 0, length, 1.0)


def stage_frames(stage: Usd.Stage) -> list[int]:
    """All integer frames from the stage's startTimeCode to endTimeCode (at least one)."""
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    first, last = math.ceil(start), math.floor(end)
    if last < first:
        return [int(round(start))]
    return list(range(int(first), int(last) + 1))


def check_temperatures(values, where: str, expected: int | None = None) -> np.ndarray:
    """Validate an array of temperatures [K] (finite, in TEMPERATURE_RANGE_K, right length)."""
    lo, hi = TEMPERATURE_RANGE_K
    a = np.asarray(values, dtype=float).ravel()
    allowed = f"expected {'' if expected is None else f'{expected} '}finite temperatures in {lo:g}-{hi:g} K"
    if expected is not None and a.size != expected:
        raise InputError(bad_value(where, f"<{a.size} values>", allowed + " (one per authored face)"))
    bad = ~np.isfinite(a) | (a < lo) | (a > hi)
    if np.any(bad):
        idx = np.flatnonzero(bad)
        raise InputError(
            bad_value(where, f"{a[idx[0]]!r} at index {idx[0]} ({idx.size} bad of {a.size})", allowed)
        )
    return a


class StageExport:
    """A composed stage read for rendering. Construct, then call :meth:`frame_state` per frame."""

    def __init__(self, stage: Usd.Stage):
        self.stage = stage
        self.meters_per_unit = float(UsdGeom.GetStageMetersPerUnit(stage))
        self._mesh_prims = self._find_meshes()
        self._skinned = self._find_skinned()
        self._mesh_cache: dict[str, MeshInfo] = {}
        self._materials: dict[str, Material] = {}
        self._part_count = 0
        self.sensors = self._find_sensors()

    # --- discovery ---------------------------------------------------------------------------
    def _traverse(self):
        return self.stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))

    def _find_meshes(self) -> list[Usd.Prim]:
        out = []
        for prim in self._traverse():
            if not prim.IsA(UsdGeom.Mesh):
                continue
            purpose = UsdGeom.Imageable(prim).ComputePurpose()
            if purpose in (UsdGeom.Tokens.default_, UsdGeom.Tokens.render):
                out.append(prim)
        return out

    def _find_skinned(self) -> dict[str, tuple]:
        """mesh path -> (SkinningQuery, SkelQuery, Skeleton prim) for meshes UsdSkel skins."""
        roots = [p for p in self._traverse() if p.IsA(UsdSkel.Root)]
        if not roots:
            return {}
        self._skel_cache = UsdSkel.Cache()
        predicate = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
        for root in roots:
            self._skel_cache.Populate(UsdSkel.Root(root), predicate)
        out = {}
        for prim in self._mesh_prims:
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

    def _points(self, prim: Usd.Prim, path: str, time, cache: UsdGeom.XformCache):
        """(local points, local-to-world row-vector matrix) of a mesh at ``time``; skinned meshes
        are posed by UsdSkel and come in skeleton space with the Skeleton's local-to-world."""
        pts = _get(UsdGeom.Mesh(prim).GetPointsAttr(), time)
        skinned = self._skinned.get(path)
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

    def _find_sensors(self) -> list[SensorModel]:
        sensors: list[SensorModel] = []
        names: dict[str, str] = {}
        for prim in self._traverse():
            if not prim.IsA(UsdGeom.Camera):
                continue
            has_api = SENSOR_API in prim.GetAppliedSchemas()
            authored = any(
                a.GetName().startswith(SENSOR_PREFIX) and a.HasAuthoredValue() for a in prim.GetAttributes()
            )
            if not (has_api or authored):
                continue
            sensor = read_sensor(prim)
            if sensor.name in names:
                raise InputError(
                    bad_value(
                        str(prim.GetPath()),
                        sensor.name,
                        f"sensor names (camera prim names) must be unique; {names[sensor.name]} has it too",
                    )
                )
            names[sensor.name] = str(prim.GetPath())
            sensors.append(sensor)
        return sensors

    # --- per mesh (static) ---------------------------------------------------------------------
    def _material(self, material: UsdShade.Material, mesh_path: str, time) -> Material:
        mpath = str(material.GetPath())
        if mpath not in self._materials:
            self._materials[mpath] = read_material(material, mesh_path, time)
        return self._materials[mpath]

    def _bound_material(self, prim: Usd.Prim, mesh_path: str, time) -> Material:
        return self._material(bound_material(prim), mesh_path, time)

    @staticmethod
    def _instance_id(prim: Usd.Prim) -> int:
        p = prim
        while p and p.IsValid() and not p.IsPseudoRoot():
            attr = p.GetAttribute(INSTANCE_ID_ATTR)
            if attr and attr.HasAuthoredValue():
                value = attr.Get()
                if value is None or not (0 <= int(value) <= MAX_INSTANCE_ID) or int(value) != value:
                    raise InputError(
                        bad_value(
                            f"{p.GetPath()}.{INSTANCE_ID_ATTR}",
                            value,
                            f"expected an integer in 0..{MAX_INSTANCE_ID}",
                        )
                    )
                return int(value)
            p = p.GetParent()
        return 0

    def _mesh_info(self, prim: Usd.Prim, time) -> MeshInfo:
        path = str(prim.GetPath())
        if path in self._mesh_cache:
            return self._mesh_cache[path]
        mesh = UsdGeom.Mesh(prim)
        counts = _get(mesh.GetFaceVertexCountsAttr(), time)
        indices = _get(mesh.GetFaceVertexIndicesAttr(), time)
        points = _get(mesh.GetPointsAttr(), time)
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
        triangles, triangle_face = fan_triangulate(counts, indices)
        front_triangles = triangles
        double_sided = bool(mesh.GetDoubleSidedAttr().Get())
        if double_sided:
            # the back side: same faces, reversed winding, on the offset copy of the points
            triangles = np.concatenate([triangles, triangles[:, ::-1] + npoints])
            triangle_face = np.concatenate([triangle_face, triangle_face])
        nfaces = counts.size
        # one part per material: GeomSubsets with their own binding first, the rest on the mesh's
        material_of_face = np.full(nfaces, -1, dtype=np.int64)
        materials: list[Material] = []
        order: dict[str, int] = {}
        binding = UsdShade.MaterialBindingAPI(prim)
        for subset in binding.GetMaterialBindSubsets():
            sub_indices = _get(subset.GetIndicesAttr(), time)
            if sub_indices is None or len(sub_indices) == 0:
                continue
            sub_indices = np.asarray(sub_indices, dtype=np.int64)
            if sub_indices.min() < 0 or sub_indices.max() >= nfaces:
                raise InputError(
                    bad_value(
                        f"{subset.GetPath()}.indices",
                        summary(sub_indices),
                        f"expected face indices in 0..{nfaces - 1}",
                    )
                )
            mat = self._bound_material(subset.GetPrim(), path, time)
            if mat.path not in order:
                order[mat.path] = len(materials)
                materials.append(mat)
            free = sub_indices[material_of_face[sub_indices] < 0]
            material_of_face[free] = order[mat.path]
        if np.any(material_of_face < 0):
            mat = self._bound_material(prim, path, time)
            if mat.path not in order:
                order[mat.path] = len(materials)
                materials.append(mat)
            material_of_face[material_of_face < 0] = order[mat.path]
        instance_id = self._instance_id(prim)
        parts = []
        for m_index, mat in enumerate(materials):
            sel = material_of_face[triangle_face] == m_index
            if not np.any(sel):
                continue
            tris = triangles[sel]
            vertex_ids, local = np.unique(tris.ravel(), return_inverse=True)
            parts.append(
                Part(
                    key=f"part_{self._part_count:05d}",
                    mesh_path=path,
                    material=mat,
                    instance_id=instance_id,
                    vertex_ids=vertex_ids,
                    triangles=local.reshape(-1, 3).astype(np.int64),
                    triangle_face=triangle_face[sel],
                )
            )
            self._part_count += 1
        orientation = mesh.GetOrientationAttr().Get()
        info = MeshInfo(
            path=path,
            point_count=npoints,
            face_count=nfaces,
            left_handed=(orientation == UsdGeom.Tokens.leftHanded),
            parts=parts,
            double_sided=double_sided,
            front_triangles=front_triangles if double_sided else None,
        )
        self._mesh_cache[path] = info
        return info

    # --- per frame ---------------------------------------------------------------------------
    def sky_temperature(self, time) -> float:
        value = usd_atmosphere.sky_temperature(self.stage, time)
        return float(check_temperatures([value], f"{ATMOSPHERE_PATH}.{SKY_TEMPERATURE_ATTR}")[0])

    # --- environment and atmosphere (humv_usd.usd readers; every part optional) ---------------
    def _float_array(self, prim, name, time, where_expected, positive=False, ascending=False):
        return usd_atmosphere.float_array(prim, name, time, where_expected, positive, ascending)

    def atmosphere_spectra(self, time) -> AtmosphereSpectra:
        """Sky spectral radiance against zenith, solar spectral irradiance and the model token
        of ``/World/Atmosphere`` at ``time`` (None for what is not authored)."""
        return usd_atmosphere.atmosphere_spectra(self.stage, time)

    def sun_direction(self, time) -> np.ndarray | None:
        """Unit vector toward the sun (stage coordinates) at ``time``, or None if not authored."""
        return usd_environment.sun_direction(self.stage, time)

    def direct_normal_irradiance(self, time) -> float | None:
        """Broadband direct normal irradiance ``humv:environment:directNormalIrradiance`` [W m-2]
        at ``time``, or None if not authored."""
        return usd_environment.direct_normal_irradiance(self.stage, time)

    def path_table(self, sensor: SensorModel, time):
        """The sensor's slant-path table (``radiometry.PathTable``) at ``time``, or None
        (:func:`humv_usd.usd.atmosphere.path_table`)."""
        t = usd_atmosphere.path_table(self.stage, sensor.path, sensor.name, time)
        if t is None:
            return None
        return PathTable(t.prim, t.ranges_m, t.wavelengths_um, t.transmittance, t.radiance)

    def camera_pose(self, sensor: SensorModel, time) -> CameraPose:
        """The sensor's camera at ``time`` (:func:`humv_usd.usd.sensor.read_camera_pose`)."""
        return read_camera_pose(self.stage.GetPrimAtPath(sensor.path), time)

    def face_temperatures(self, prim: Usd.Prim, info: MeshInfo, time) -> np.ndarray:
        where = f"{info.path}.{TEMPERATURE_ATTR}"
        attr = prim.GetAttribute(TEMPERATURE_ATTR)
        if not attr or not attr.HasValue():
            raise InputError(
                bad_value(
                    where,
                    None,
                    f"a rendered mesh needs one temperature per authored face "
                    f"({info.face_count} faces, uniform primvar, K, HumvThermalAPI)",
                )
            )
        primvar = UsdGeom.Primvar(attr)
        interpolation = primvar.GetInterpolation() if primvar else UsdGeom.Tokens.uniform
        if interpolation not in (UsdGeom.Tokens.uniform, UsdGeom.Tokens.constant):
            raise InputError(
                bad_value(
                    f"{where} interpolation",
                    str(interpolation),
                    "expected uniform (one value per authored face) or constant",
                )
            )
        values = primvar.ComputeFlattened(time) if primvar else attr.Get(time)
        if values is None:
            raise InputError(bad_value(where, None, f"no value at frame {time.GetValue():g}"))
        values = np.asarray(values, dtype=float).ravel()
        if primvar and primvar.GetInterpolation() == UsdGeom.Tokens.constant and values.size == 1:
            values = np.full(info.face_count, values[0])
        return check_temperatures(values, where, expected=info.face_count)

    def frame_state(self, frame: int, sensors: list[SensorModel]) -> FrameState:
        """Read everything needed to render ``frame`` for ``sensors``.

        Temperatures (faces, sky) are required only when an infrared sensor is among
        ``sensors``; for EO sensors alone (a stage without a thermal or atmosphere layer) an
        unauthored face temperature is NaN (it only feeds the surface_temperature label) and the
        sky temperature is NaN.
        """
        time = Usd.TimeCode(frame)
        cache = UsdGeom.XformCache(time)
        state = FrameState(frame=frame, meshes=[])
        infrared = any(s.kind != "EO" for s in sensors)
        state.sky_temperature_k = self.sky_temperature(time) if infrared else float("nan")
        for prim in self._mesh_prims:
            if UsdGeom.Imageable(prim).ComputeVisibility(time) == UsdGeom.Tokens.invisible:
                continue
            info = self._mesh_info(prim, time)
            pts, m = self._points(prim, info.path, time, cache)  # m: row-vector convention
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
                    bad_value(
                        f"{info.path}.points", "<non-finite>", f"expected finite points at frame {frame}"
                    )
                )
            flip = bool(info.left_handed) != bool(np.linalg.det(m[:3, :3]) < 0)
            if info.double_sided:
                # behind the rendered front: against the normal, which a flip turns around
                normals = vertex_normals(world, info.front_triangles) * (-1.0 if flip else 1.0)
                world = np.concatenate([world, world - BACK_SIDE_OFFSET_M * normals])
            state.meshes.append(info)
            state.points[info.path] = world
            state.flip[info.path] = flip
            attr = prim.GetAttribute(TEMPERATURE_ATTR)
            if infrared or (attr and attr.HasValue()):
                state.temperatures[info.path] = self.face_temperatures(prim, info, time)
            else:
                state.temperatures[info.path] = np.full(info.face_count, np.nan)
        for sensor in sensors:
            state.cameras[sensor.name] = self.camera_pose(sensor, time)
        return state
