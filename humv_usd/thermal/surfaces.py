"""Scene surface temperatures (ground, buildings, panels) over the scenario's time line.

Each scene mesh face is a 1-D slab (:mod:`humv_usd.physics.slab`) of its material, heated by
the sun and the diffuse sky, exchanging long wave with the sky and the ground and heat with the
air by convection, run through a diurnal spin-up that ends at frame 0 and then stepped over the
frames. A face whose scenario entry gives ``temperature_k`` is held at it (a controlled
blackbody panel, or a measured surface) and solves nothing.

Per face and time, with n the outward face normal, s the unit vector towards the sun and
f_lit the sunlit fraction of the face (shadow rays against the scene from points on the face):

* absorbed short wave  alpha_s [DNI max(n.s, 0) f_lit + DHI (1 + n_z)/2 + rho_g GHI (1 - n_z)/2]
  (isotropic diffuse sky and Lambertian ground of albedo rho_g, view factors (1 +- n_z)/2;
  Duffie & Beckman 2013, section 2.15-2.16), alpha_s the material spectrum's own under the
  ASTM G173 sun (:func:`humv_usd.usd.materials.read_material`);
* incident long wave  E_sky V(n) + [eps_g sigma T_g^4 + (1 - eps_g) E_sky] (1 - n_z)/2, with
  V(n) = E_sky(tilt) / E_sky(horizontal) of the sky's angular distribution
  (:func:`humv_usd.physics.sky.tilted_irradiance`: a wall sees the bright horizon sky, not an
  isotropic half), E_sky = eps_sky sigma T_air^4 with the Berdahl & Martin (1984) clear-sky
  emissivity and the cloud cover mixed in (Crawford & Duchon 1999); with an atmosphere layer,
  E_sky at each sample from frame 0 on is the hemispherical irradiance of the layer's longwave
  sky table at that time code and V its frame-0 table's (:func:`with_sky_table`), the sky the
  render and the people's radiance maps see; during the spin-up before frame 0 (no layer value
  there) the analytic sky scaled to frame 0's table;
* convection  h = 2.8 + 3.0 V (Watmuff et al. 1977).

Surroundings (issue 25; ``exchange=False`` turns them off): each face sees only part of the sky
(:mod:`humv_usd.thermal.views`: sky view factor and view factors to the other scene faces by
cosine-weighted rays from points over the face, with :mod:`humv_usd.geometry.raycast`). The sky
terms above are scaled by the seen share of the sky (the long wave weighted by the sky's
angular radiance: a canyon floor sees the darker zenith; the diffuse short wave isotropic), the
ground term by the share of downward rays that leave the modelled ground, and the face receives
the radiosity eps_k sigma T_k^4 + (1 - eps_k) L_k and the reflected short wave of every scene
face k it sees (F_ik). The temperatures T_k are iterated over the whole time series
(:func:`surface_temperatures`, fixed point, to :data:`EXCHANGE_TOLERANCE_K`).

Shadows: f_lit from shadow rays (4 points per triangle) against the scene meshes and the people
(:func:`people_occluders`: posed at each frame from frame 0 on; before it, in the frame-0 pose
for ``[[placement]] standing_before_s``, weighted by the share of each slab step they stood
there), so a person leaves a cool patch that grows with the time stood and fades after they
walk away. Tessellation adapts (:func:`refine_meshes`): faces where the recent direct sun
varies across the face (shadow edges, building bases, object footprints, a person's shadow)
are split into four down to :data:`MIN_CELL_M`; the thermal layer authors the new faces on the
mesh (:func:`write_refined_topology`), so no face straddles sun and shade.

Weather and sun (spin-up included) are read from the environment layer on the stage
(:func:`forcing_at`, :mod:`humv_usd.usd.environment`).

Constructions (every property from the bound material on the stage,
:mod:`humv_usd.usd.materials`; per face: a face in a GeomSubset with its own material binding
is a slab of that material, :func:`humv_usd.usd.materials.face_materials`, as the render reads it): the ground is its material's layer over its substrate (the
material its ``humv:material:substrate`` points to, soil from the materials tool) down to 1 m,
with the bottom held at the mean air temperature of the spin-up day; objects are their material's layer with an
adiabatic back (insulated siding, a panel on a stand), or, with ``interior_air_temperature_k``,
a back exchanging heat with the room air through ISO 6946's inside surface coefficient
(7.7 W m^-2 K^-1). People shade the scene but do not warm it (no long-wave or contact
exchange with it) and do not enter its view factors.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from humv_usd.catalog.materials import surface_water
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.geometry.camera import Camera
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.geometry.raycast import first_faces, ray_caster, unblocked, unblocked_local
from humv_usd.human.usdskel import skinned_points
from humv_usd.physics import clouds, evaporation, slab, snow, vegetation
from humv_usd.physics.convection import watmuff
from humv_usd.physics.sky import (
    cloudy_sky_emissivity,
    directional_sky_emissivity,
    effective_sky_temperature,
    hemispherical_irradiance,
    tilted_irradiance,
)
from humv_usd.physics.sun import OVERCAST_DNI_FACTOR, cloud_dni_factor
from humv_usd.scenario.times import SPIN_UP_STEP_S
from humv_usd.thermal.human import longwave_emissivity
from humv_usd.thermal.views import VIEW_RAYS, ZENITH_BINS_DEG, face_views, orthonormal_frames, ray_samples
from humv_usd.usd.environment import ENVIRONMENT_PATH, read_sun, read_weather, time_codes
from humv_usd.usd.heat import read_held_temperature
from humv_usd.usd.layers import SCOPES
from humv_usd.usd.materials import THERMAL_ATTRIBUTES, StageMaterial, face_materials, read_material, substrate
from humv_usd.usd.mesh import override_topology, scene_mesh_prims
from humv_usd.usd.paths import GROUND, human_path, object_path
from humv_usd.usd.sensor import read_camera_pose, stage_sensors
from humv_usd.usd.snow import SnowCover, read_snow_cover

log = logging.getLogger(__name__)

#: Depth of the ground construction (material layer + soil) [m]
GROUND_DEPTH_M = 1.0
#: Largest layer of the slab discretisation [m] (at least 4 layers per material)
MAX_LAYER_M = 0.01


@dataclass
class SceneMesh:
    """One scene mesh in world coordinates with its bound material and held temperature."""

    path: str
    points: np.ndarray  # (P, 3) [m], world
    triangles: np.ndarray  # (T, 3)
    tri_face: np.ndarray  # (T,) authored face of each triangle
    n_faces: int
    material: StageMaterial  # bound on the stage
    held_k: float | None  # scenario temperature_k: held at it; None: slab
    is_ground: bool
    substrate: StageMaterial | None = None  # under a slab ground thinner than GROUND_DEPTH_M
    interior_k: float | None = None  # room air behind a building's walls [K]; None: adiabatic back
    counts: np.ndarray | None = None  # (F,) authored vertices per face
    indices: np.ndarray | None = None  # authored face-vertex indices
    to_world: np.ndarray | None = None  # (4, 4) local-to-world (USD row vectors)
    refinable: bool = False  # plain polygon mesh (3/4-gons, no subsets, no primvars) we may re-tessellate
    parent_face: np.ndarray | None = None  # (F,) upstream face each face refines; None: not refined
    #: per-face materials (GeomSubset bindings): the materials and the index of each face's;
    #: None when every face has ``material``
    face_materials: tuple[StageMaterial, ...] = ()
    material_of_face: np.ndarray | None = None
    #: snow on a slab ground (issue 30.4, :mod:`humv_usd.usd.snow`) and the bare ground's
    #: material under it; ``material`` is then the snow's
    snow: SnowCover | None = None
    bare: StageMaterial | None = None

    @property
    def solar_absorptivity(self) -> float:
        return self.material.require("solar_absorptivity", self.path)

    def per_face(self, value) -> np.ndarray:
        """(F,) ``value(material)`` of each face's material (its GeomSubset's, else the mesh's)."""
        if self.material_of_face is None:
            return np.full(self.n_faces, value(self.material), dtype=float)
        return np.array([value(m) for m in self.face_materials], dtype=float)[self.material_of_face]

    def face_geometry(self):
        """(normals (F, 3), centroids (F, 3), areas (F,)) of the authored faces."""
        v = self.points[self.triangles]
        cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
        area_t = 0.5 * np.linalg.norm(cross, axis=1)
        area = np.bincount(self.tri_face, area_t, self.n_faces)
        nrm = np.stack([np.bincount(self.tri_face, cross[:, k], self.n_faces) for k in range(3)], axis=1)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-30)
        cen = (
            np.stack(
                [np.bincount(self.tri_face, v.mean(axis=1)[:, k] * area_t, self.n_faces) for k in range(3)],
                axis=1,
            )
            / np.maximum(area, 1e-30)[:, None]
        )
        return nrm, cen, area


def air_at_frame0(upstream: Usd.Stage, scenario) -> float:
    """Air temperature of frame 0 [K] for meshes nothing solves: the environment layer's, or
    the scenario's constant one when the stage has no environment layer (a fixed-model stage
    assembled without it)."""
    if upstream.GetPrimAtPath(ENVIRONMENT_PATH):
        return float(read_weather(upstream, [0.0]).air_temperature_k[0])
    return float((scenario["atmosphere"] or {}).get("air_temperature_k", 293.15))


def scene_meshes(upstream: Usd.Stage, scenario) -> list[SceneMesh]:
    """Every mesh of the composed stage outside /World/Humans, with its bound material(s)
    (:func:`humv_usd.usd.materials.face_materials`: per face with material GeomSubsets) and
    held value.

    A mesh the scenario does not hold (a slab, also one from a hand-made layer) needs the
    thermal properties of HumvMaterialAPI on its material, a slab ground thinner than
    :data:`GROUND_DEPTH_M` also its substrate; InputError naming the mesh otherwise."""
    held: dict[str, float | None] = {}
    interior: dict[str, float | None] = {}
    if scenario["scene"]:
        held[str(GROUND)] = scenario["scene"]["ground"].get("temperature_k")
        for o in scenario["scene"]["object"]:
            held[str(object_path(o["id"]))] = o.get("temperature_k")
            interior[str(object_path(o["id"]))] = o.get("interior_air_temperature_k")
        for a in scenario["scene"].get("asset") or ():  # every mesh of the asset
            held[str(object_path(a["id"]))] = a.get("temperature_k")
    out = []
    for prim in scene_mesh_prims(upstream):  # the render's rule: what is drawn is solved
        if str(prim.GetPath()).startswith(str(SCOPES["humans"])):
            continue
        mesh = UsdGeom.Mesh(prim)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
        pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
        xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
        pts = pts @ xf[:3, :3] + xf[3, :3]
        tris, tri_face = fan_triangulate(counts, np.asarray(mesh.GetFaceVertexIndicesAttr().Get()))
        path = str(prim.GetPath())
        materials, of_face = face_materials(prim, len(counts))
        # the mesh's material: that of most of its faces (all of them without material subsets)
        material = materials[int(np.argmax(np.bincount(of_face, minlength=len(materials))))]
        h = _held(path, held)  # a mesh from a hand-made layer: a slab of its material
        if h is None:  # a warm-clutter part with a heat source (humv_usd.scene.objects)
            h = read_held_temperature(prim)
        # the ground and its terrain zones (humv_usd.scene.ground: customData humv:groundZone)
        is_ground = path == str(GROUND) or bool(prim.GetCustomDataByKey("humv:groundZone"))
        under = None
        if h is None:
            for field in THERMAL_ATTRIBUTES:
                for m in materials:
                    m.require(field, path)
            if is_ground and material.thickness < GROUND_DEPTH_M:
                under = substrate(material, upstream, path)
                for field in THERMAL_ATTRIBUTES:
                    under.require(field, path)
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
        out.append(
            SceneMesh(
                path,
                pts,
                tris,
                tri_face,
                len(counts),
                material,
                h,
                is_ground,
                under,
                interior.get(path),
                counts,
                indices,
                xf,
                h is None and _refinable(prim, counts),
            )
        )
        if len(materials) > 1:  # set by name: keep these two fields last in SceneMesh
            out[-1].face_materials, out[-1].material_of_face = tuple(materials), of_face
        cover = read_snow_cover(prim) if h is None else None
        if cover is not None:  # snow over the ground's (a roof's) own material (physics.snow)
            bare = read_material(upstream.GetPrimAtPath(cover.bare_material), path)
            for field in THERMAL_ATTRIBUTES:
                bare.require(field, path)
            out[-1].snow, out[-1].bare = cover, bare
    return out


def _refinable(prim: Usd.Prim, counts: np.ndarray) -> bool:
    """Whether the thermal layer may re-tessellate a mesh: its own prim (not an instance
    proxy), triangles and quads only, no GeomSubsets and no primvars (their per-face or
    per-vertex values would not follow the new faces)."""
    if prim.IsInstanceProxy() or len(counts) == 0 or not np.all((counts == 3) | (counts == 4)):
        return False
    if prim.GetCustomDataByKey("humv:refine") is False:  # e.g. plants (humv_usd.scene.vegetation)
        return False
    if UsdGeom.Subset.GetAllGeomSubsets(UsdGeom.Imageable(prim)):
        return False
    return not UsdGeom.PrimvarsAPI(prim).GetPrimvarsWithValues()


def _held(path: str, held: dict[str, float | None]) -> float | None:
    """The held temperature of the mesh at ``path`` or of its nearest listed ancestor (an asset)."""
    p = Sdf.Path(path)
    while p != Sdf.Path.absoluteRootPath:
        if str(p) in held:
            return held[str(p)]
        p = p.GetParentPath()
    return None


def ground_albedo(meshes: list[SceneMesh], default: float = 0.2) -> float:
    """Short-wave albedo of the ground, 1 - solar absorptivity of its material on the stage;
    ``default`` when the stage has no ground."""
    for m in meshes:
        if m.is_ground:
            return 1.0 - m.solar_absorptivity
    return default


@dataclass
class Occluders:
    """Meshes that shade the scene without being solved by the slabs (the people): per
    forcing sample the index of the mesh present then (-1: none)."""

    meshes: list  # [(points (P, 3) world [m], triangles (T, 3))]
    at_time: np.ndarray  # (M,) int
    #: (M,) share of the step ending at each sample during which they stood there [0-1]
    presence: np.ndarray | None = None

    @staticmethod
    def none(n_times: int) -> Occluders:
        return Occluders([], np.full(n_times, -1, dtype=np.int64), np.zeros(n_times))


def _posed_points(stage: Usd.Stage, prim: Usd.Prim, frame: float) -> np.ndarray:
    """World points of a mesh at a frame: UsdSkel-posed when it is skinned, else its
    local-to-world transform at that time."""
    if UsdSkel.BindingAPI(prim).GetInheritedSkeleton():
        return skinned_points(stage, prim.GetPath(), Usd.TimeCode(frame), space="world")
    t = Usd.TimeCode(frame)
    pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(t), dtype=float)
    xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))
    return pts @ xf[:3, :3] + xf[3, :3]


def _person_mesh(stage: Usd.Stage, human_id: str, frame: float):
    """(points, triangles) of every mesh of a person (body, garments, props) at a frame."""
    root = stage.GetPrimAtPath(str(human_path(human_id)))
    pts, tris, offset = [], [], 0
    for prim in scene_mesh_prims(stage, root) if root else []:
        mesh = UsdGeom.Mesh(prim)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
        t, _ = fan_triangulate(counts, np.asarray(mesh.GetFaceVertexIndicesAttr().Get()))
        p = _posed_points(stage, prim, frame)
        pts.append(p)
        tris.append(t + offset)
        offset += len(p)
    if not pts:
        return None
    return np.concatenate(pts), np.concatenate(tris)


def presence_share(times_s, arrive_s: float = -np.inf, leave_s: float = np.inf) -> np.ndarray:
    """(M,) share [0-1] of the slab step ending at each of ``times_s`` (it starts at the
    previous sample; the first one is a spin-up step long) that lies within [arrive, leave]."""
    t = np.asarray(times_s, dtype=float)
    prev = np.r_[t[0] - SPIN_UP_STEP_S, t[:-1]] if t.size else t
    inside = np.minimum(t, leave_s) - np.maximum(prev, arrive_s)
    return np.clip(inside / np.maximum(t - prev, 1e-9), 0.0, 1.0)


def standing_occluder(
    points, triangles, times_s, arrive_s: float = -np.inf, leave_s: float = np.inf
) -> Occluders:
    """A fixed shadow caster (world ``points``, ``triangles``) present from ``arrive_s`` to
    ``leave_s`` [s after frame 0]."""
    share = presence_share(times_s, arrive_s, leave_s)
    at = np.where(share > 0.0, 0, -1).astype(np.int64)
    return Occluders([(np.asarray(points, float), np.asarray(triangles, np.int64))], at, share)


def people_occluders(stage: Usd.Stage, scenario, times_s) -> Occluders:
    """The people as shadow casters on the scene at the forcing times ``times_s`` [s after
    frame 0].

    From frame 0 on every person casts a shadow in their pose of that frame; before frame 0 a
    person whose ``[[placement]] standing_before_s`` is S stands in their frame-0 pose from -S
    on (the cool patch under them grows with S), and is absent before. The slab step ending at
    a sample covers the time since the previous one; the share of it a person stood there
    (:attr:`Occluders.presence`) weights their shadow, so S = 0 leaves the ground as it was
    at frame 0.
    """
    times = np.asarray(times_s, dtype=float)
    humans = [h["id"] for h in scenario["human"] or []]
    if not humans:
        return Occluders.none(len(times))
    fps = float(scenario["general"]["fps"])
    stood = {p["human"]: float(p.get("standing_before_s") or 0.0) for p in scenario["placement"] or []}
    keys: dict = {}
    meshes, at = [], np.full(len(times), -1, dtype=np.int64)
    presence = np.zeros(len(times))
    shares = {h: presence_share(times, -stood.get(h, 0.0)) for h in humans}
    for i, t in enumerate(times):
        frame = float(max(0, round(t * fps)))
        present = tuple(h for h in humans if shares[h][i] > 0.0)
        if not present:
            continue
        presence[i] = max(shares[h][i] for h in present)
        key = (frame, present)
        if key not in keys:
            parts = [m for m in (_person_mesh(stage, h, frame) for h in present) if m is not None]
            if not parts:
                keys[key] = -1
            else:
                offsets = np.cumsum([0] + [len(p) for p, _ in parts])
                meshes.append(
                    (
                        np.concatenate([p for p, _ in parts]),
                        np.concatenate([t + o for (_, t), o in zip(parts, offsets)]),
                    )
                )
                keys[key] = len(meshes) - 1
        at[i] = keys[key]
    return Occluders(meshes, at, presence)


class _Shadows:
    """Shadow rays against the scene meshes plus, per time, the occluders present then."""

    def __init__(self, meshes: list[SceneMesh], occluders: Occluders):
        self.points = np.concatenate([m.points for m in meshes]) if meshes else np.zeros((0, 3))
        offsets = np.cumsum([0] + [len(m.points) for m in meshes])
        self.triangles = (
            np.concatenate([m.triangles + o for m, o in zip(meshes, offsets)])
            if meshes
            else np.zeros((0, 3), np.int64)
        )
        self.occluders = occluders
        ext = np.ptp(self.points, axis=0) if len(self.points) else np.ones(3)
        # offset of the shadow rays' origins: relative to the scene's size, but not to a ground
        # that reaches the horizon (kilometres away: only the modelled rectangle's size counts)
        self.eps = 2e-5 * min(float(np.linalg.norm(ext)), EPS_SCENE_SIZE_CAP_M) + 1e-4
        self._casters: dict = {}
        self._origins: tuple = ()  # (caster key, points, normals, float32 local origins)

    def caster(self, k: int):
        if k not in self._casters:
            if k < 0:
                self._casters[k] = ray_caster(self.points, self.triangles)
            else:
                p, t = self.occluders.meshes[k]
                self._casters[k] = ray_caster(
                    np.concatenate([self.points, p]), np.concatenate([self.triangles, t + len(self.points)])
                )
        return self._casters[k]

    def _local_origins(self, k: int, points, normals) -> np.ndarray:
        """The offset ray origins of ``points`` in caster ``k``'s float32 frame, converted once
        for the many sun directions cast from the same points (the arrays are held, so the
        identity check cannot see a recycled id)."""
        held = self._origins
        if not held or held[0] != k or held[1] is not points or held[2] is not normals:
            self._origins = held = (k, points, normals, self.caster(k).local(points + self.eps * normals))
        return held[3]

    def lit(self, points, normals, sun, time_index: int) -> np.ndarray:
        """(n,) sunlit share of each point (offset along its normal) over the step ending at a
        time: 0 or 1, or in between where an occluder stood there for part of the step."""
        facing = normals @ sun > 0.0
        out = np.zeros(len(points))
        if facing.any():
            n = int(facing.sum())
            d = np.broadcast_to(np.asarray(sun, dtype=np.float32), (n, 3))
            k = int(self.occluders.at_time[time_index]) if len(self.occluders.at_time) else -1
            o = self._local_origins(-1, points, normals)[facing]
            free = unblocked_local(self.caster(-1), o, d).astype(float)
            if k >= 0:
                w = float(self.occluders.presence[time_index])
                o = self.caster(k).local(points[facing] + self.eps * normals[facing])
                free = (1.0 - w) * free + w * unblocked_local(self.caster(k), o, d)
            out[facing] = free
        return out


def _sunlit_fraction(meshes, sun_dirs, up, occluders: Occluders | None = None):
    """(times, faces of all meshes) sunlit fraction from 4 points per triangle."""
    occluders = occluders or Occluders.none(len(sun_dirs))
    shadows = _Shadows(meshes, occluders)
    v = shadows.points[shadows.triangles]
    cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    tri_area = 0.5 * np.linalg.norm(cross, axis=1)
    tri_n = cross / np.maximum(2.0 * tri_area, 1e-30)[:, None]
    bary = np.array(
        [[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]
    )
    pts = np.einsum("kj,tjc->tkc", bary, v).reshape(-1, 3)
    nrm = np.repeat(tri_n, 4, axis=0)
    face_of_tri = np.concatenate(
        [m.tri_face + sum(x.n_faces for x in meshes[:i]) for i, m in enumerate(meshes)]
    )
    n_faces = sum(m.n_faces for m in meshes)
    face_area = np.bincount(face_of_tri, tri_area, n_faces)
    out = np.zeros((len(sun_dirs), n_faces))
    for i, (s, is_up) in enumerate(zip(sun_dirs, up)):
        if not is_up:
            continue
        frac_t = shadows.lit(pts, nrm, s, i).reshape(-1, 4).mean(axis=1)
        out[i] = np.bincount(face_of_tri, frac_t * tri_area, n_faces) / np.maximum(face_area, 1e-30)
    return out


#: scene size above which the ray offsets stop growing [m] (a ground to the horizon, issue 30)
EPS_SCENE_SIZE_CAP_M = 150.0


# --- adaptive tessellation ---------------------------------------------------------------------
#: smallest cell the refinement makes [m] (edge length; 7.5 m ground cells / 2^6)
MIN_CELL_M = 0.12
#: a cell is split while its absorbed direct sun, weighted over the recent past, varies by more
#: than this across it [W m^-2] (about 0.5-1 K of surface temperature)
REFINE_THRESHOLD_W_M2 = 20.0
#: memory of the weighting: a sample t s before frame 0 counts exp(t / memory) (the surface layer
#: of concrete or soil forgets its forcing over about an hour; samples from frame 0 on count 1)
REFINE_MEMORY_S = 3600.0
#: a cell is split (down to ``min_cell_m``) while its sky view factor differs by more than this
#: between its centre and corners: the long wave and reflected sun of the walls it sees change
#: across it (near a sunlit wall about 7 K per unit of sky view, so about 0.3 K)
VIEW_SPREAD = 0.04
#: refinement stops (warning) when a mesh would exceed this many faces
MAX_REFINED_FACES = 60000

#: finest cell a camera's pixel footprint may ask for [m] (bounds the faces where a camera is close)
MIN_FOOTPRINT_CELL_M = 0.005
#: a moving camera's poses are kept at most this many per camera for the footprints (beyond
#: that they are thinned evenly and the closest-pose bound below no longer holds)
FOOTPRINT_FRAMES = 48
#: a moving camera's next pose is kept once it has moved this fraction of its height above the
#: ground (z = 0) or turned by FOOTPRINT_TURN_DEG: a cell's closest pose over the clip is then
#: at most about sqrt(1 + 0.25^2) = 3 % farther than the kept one nearest to it
FOOTPRINT_MOVE = 0.5
FOOTPRINT_TURN_DEG = 5.0


def _footprint_poses(poses: list) -> list:
    """The poses of one camera over the clip the footprints use: the first, then each that has
    moved :data:`FOOTPRINT_MOVE` x its height or turned :data:`FOOTPRINT_TURN_DEG` since the last
    kept one (a vehicle or drone passing close to the ground keeps its closest poses); at most
    :data:`FOOTPRINT_FRAMES`, thinned evenly beyond that."""
    kept = [poses[0]]
    for pose in poses[1:]:
        last = kept[-1]
        moved = float(np.linalg.norm(pose.origin - last.origin))
        turned = float(np.degrees(np.arccos(min(1.0, float(np.dot(pose.forward, last.forward))))))
        if moved > FOOTPRINT_MOVE * max(abs(float(pose.origin[2])), 0.1) or turned > FOOTPRINT_TURN_DEG:
            kept.append(pose)
    if len(kept) > FOOTPRINT_FRAMES:
        pick = np.unique(np.linspace(0, len(kept) - 1, FOOTPRINT_FRAMES).round().astype(int))
        kept = [kept[i] for i in pick]
    return kept


def camera_footprints(stage: Usd.Stage, frames=(0,)) -> list[Camera]:
    """The infrared sensor cameras of ``stage`` (:func:`humv_usd.usd.sensor.stage_sensors`, the
    sensors layer; an EO image does not show the temperatures) as pinhole :class:`humv_usd.geometry.camera.Camera` s, one per camera and pose over
    ``frames`` (a moving camera counts where it is, :func:`_footprint_poses`: the finest
    footprint of a cell is that of the camera's closest pose over the clip).
    Cameras the render skips (not perspective) are left out."""
    frames = np.atleast_1d(np.asarray(frames, dtype=float))
    out = []
    for sensor in stage_sensors(stage):
        if sensor.skip_reason or sensor.kind == "EO":  # EO images do not show the temperatures
            continue
        prim = stage.GetPrimAtPath(sensor.path)
        w, h = (int(v) for v in sensor.resolution)
        still = not UsdGeom.Xformable(prim).TransformMightBeTimeVarying()
        poses = [read_camera_pose(prim, Usd.TimeCode(float(f))) for f in (frames[:1] if still else frames)]
        out += [Camera.from_pose(p, w, h) for p in _footprint_poses(poses)]
    return out


def pixel_footprint(camera: Camera, points) -> np.ndarray:
    """(n,) size [m] one pixel of ``camera`` spans at each point, depth x 2 tan(fov_x/2) / W
    (pixel pitch / focal length x depth along the optical axis; pinhole, square pixels); inf
    for points outside the image (one pixel of margin) or behind the camera."""
    uv, z = camera.project(np.asarray(points, dtype=float))
    with np.errstate(invalid="ignore"):
        inside = (
            (z > 0.0)
            & (uv[:, 0] >= -1.0)
            & (uv[:, 0] <= camera.width + 1.0)
            & (uv[:, 1] >= -1.0)
            & (uv[:, 1] <= camera.height + 1.0)
        )
    return np.where(inside, z * 2.0 * camera.tan_x / camera.width, np.inf)


def _footprint_cells(cells, cameras: list[Camera], shadows: _Shadows) -> np.ndarray:
    """(C,) the finest pixel footprint [m] of the cameras that see each cell (its corners and
    centre inside the image and not hidden behind the scene), inf where none does."""
    out = np.full(len(cells), np.inf)
    if not cameras or not len(cells):
        return out
    pts = np.concatenate([cells, cells.mean(axis=1, keepdims=True)], axis=1)  # (C, k + 1, 3)
    nrm = np.repeat(_cell_normals(cells), pts.shape[1], axis=0)
    flat = pts.reshape(-1, 3)
    caster = shadows.caster(-1)
    for cam in cameras:
        fp = pixel_footprint(cam, flat)
        look = np.isfinite(fp)
        if not look.any():
            continue
        o = flat[look] + shadows.eps * nrm[look]
        to_cam = cam.origin - o
        dist = np.linalg.norm(to_cam, axis=1)
        facing = np.einsum("ij,ij->i", to_cam, nrm[look]) > 0.0
        seen = facing & (caster.hit_distance(o, to_cam / np.maximum(dist, 1e-12)[:, None]) >= dist)
        fp_seen = np.full(len(flat), np.inf)
        fp_seen[np.flatnonzero(look)[seen]] = fp[look][seen]
        out = np.minimum(out, fp_seen.reshape(pts.shape[:2]).min(axis=1))
    return out


_QUAD_UV = np.array([((i + 0.5) / 4, (j + 0.5) / 4) for j in range(4) for i in range(4)])


def _tri_bary():
    """Barycentric centroids of the 16 triangles of a triangle split twice into four."""
    tris = [np.eye(3)]
    for _ in range(2):
        nxt = []
        for a, b, c in tris:
            ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
            nxt += [np.array(t) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))]
        tris = nxt
    return np.array([t.mean(axis=0) for t in tris])


_TRI_BARY = _tri_bary()


def _split(cells: np.ndarray) -> np.ndarray:
    """Four children of each cell (C, 3|4, 3) -> (4C, 3|4, 3), winding kept."""
    if cells.shape[1] == 4:
        a, b, c, d = (cells[:, i] for i in range(4))
        ab, bc, cd, da, m = (a + b) / 2, (b + c) / 2, (c + d) / 2, (d + a) / 2, cells.mean(axis=1)
        kids = [(a, ab, m, da), (ab, b, bc, m), (m, bc, c, cd), (da, m, cd, d)]
    else:
        a, b, c = (cells[:, i] for i in range(3))
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        kids = [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
    return np.stack([np.stack(k, axis=1) for k in kids], axis=1).reshape(-1, cells.shape[1], 3)


def _samples(cells: np.ndarray) -> np.ndarray:
    """(C, 16, 3) sample points spread over each cell."""
    if cells.shape[1] == 4:
        u, v = _QUAD_UV[:, 0][None, :, None], _QUAD_UV[:, 1][None, :, None]
        a, b, c, d = (cells[:, i][:, None] for i in range(4))
        return (1 - u) * (1 - v) * a + u * (1 - v) * b + u * v * c + (1 - u) * v * d
    return np.einsum("sk,ckx->csx", _TRI_BARY, cells)


def _cell_normals(cells: np.ndarray) -> np.ndarray:
    if cells.shape[1] == 4:
        n = np.cross(cells[:, 2] - cells[:, 0], cells[:, 3] - cells[:, 1])
    else:
        n = np.cross(cells[:, 1] - cells[:, 0], cells[:, 2] - cells[:, 0])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def _cell_size(cells: np.ndarray) -> np.ndarray:
    edges = cells - np.roll(cells, -1, axis=1)
    return np.linalg.norm(edges, axis=2).max(axis=1)


def _recent_weights(f: SurfaceForcing, memory_s: float) -> np.ndarray:
    """(M,) weights of the forcing samples in the refinement's sun dose (sum 1, zero when the
    sun is down or the sample is many memories old)."""
    w = np.exp(np.minimum(f.times_s, 0.0) / memory_s)
    w[w < 0.01] = 0.0
    w /= w.sum()
    return np.where(f.sun_up & (f.dni_w_m2 > 0.0), w, 0.0)


def _dose(cells, shadows: _Shadows, f: SurfaceForcing, weights) -> np.ndarray:
    """(C, 16) weighted mean direct irradiance [W m^-2] at each cell's sample points."""
    pts = _samples(cells)
    nrm = _cell_normals(cells)
    flat_p = pts.reshape(-1, 3)
    flat_n = np.repeat(nrm, pts.shape[1], axis=0)
    dose = np.zeros(len(flat_p))
    for i in np.flatnonzero(weights):
        s = f.sun_direction[i]
        cos = np.maximum(flat_n @ s, 0.0)
        dose += weights[i] * f.dni_w_m2[i] * cos * shadows.lit(flat_p, flat_n, s, i)
    return dose.reshape(pts.shape[:2])


def _sky_view_spread(cells, shadows: _Shadows | None, rays: int = 64) -> np.ndarray:
    """(C,) largest difference of the sky view factor between a cell's centre and its corners
    (pulled 2 % towards the centre): ``rays`` rays per point, cosine-weighted
    (:func:`humv_usd.thermal.views.ray_samples`, the same directions at every point)."""
    if shadows is None or not len(shadows.triangles):  # nothing to see but the sky
        return np.zeros(len(cells))
    centre = cells.mean(axis=1, keepdims=True)
    pts = np.concatenate([centre, centre + 0.98 * (cells - centre)], axis=1)  # (C, k + 1, 3)
    nrm = _cell_normals(cells)
    _, local = ray_samples(rays)
    t_axis, b_axis = orthonormal_frames(nrm)
    d = (
        local[None, :, 0:1] * t_axis[:, None, :]
        + local[None, :, 1:2] * b_axis[:, None, :]
        + local[None, :, 2:3] * nrm[:, None, :]
    )  # (C, R, 3)
    k = pts.shape[1]
    shape = (len(cells), k, rays, 3)
    o = np.broadcast_to((pts + shadows.eps * nrm[:, None, :])[:, :, None, :], shape)
    dirs = np.broadcast_to(d[:, None, :, :], shape)
    free = unblocked(shadows.caster(-1), o.reshape(-1, 3), dirs.reshape(-1, 3)) & (
        dirs.reshape(-1, 3)[:, 2] > 0.0
    )
    svf = free.reshape(len(cells), k, rays).mean(axis=2)
    return np.ptp(svf, axis=1)


def _straddles_a_footprint(cells, shadows: _Shadows) -> np.ndarray:
    """(C,) whether a cell lies partly inside a closed mesh standing on it (a building's
    footprint): of 16 points over it, some see the back of a face straight above them and some
    do not. A wall's foot on its shaded side is not found by the sun's dose (shade on both
    sides), but the sky view (:mod:`humv_usd.thermal.views`) changes there."""
    pts = _samples(cells)
    nrm = np.repeat(_cell_normals(cells), pts.shape[1], axis=0)
    o = pts.reshape(-1, 3) + shadows.eps * nrm
    hit = first_faces(shadows.caster(-1), o, nrm)
    inside = np.zeros(len(o), dtype=bool)
    h = hit >= 0
    if h.any():
        tri = shadows.points[shadows.triangles[hit[h]]]
        inside[h] = (
            np.einsum("ij,ij->i", np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), nrm[h]) > 0.0
        )
    inside = inside.reshape(pts.shape[:2])
    return inside.any(axis=1) & ~inside.all(axis=1)


def _under_occluders(cells, occluders: Occluders, f: SurfaceForcing, weights) -> np.ndarray:
    """(C,) whether an occluder's shadow (its bounding box projected along the sun onto each
    cell's plane) overlaps the cell at a weighted time: a person is smaller than a coarse
    cell's sample spacing, so their shadow is found by projection, not by sampling."""
    out = np.zeros(len(cells), dtype=bool)
    if not occluders.meshes:
        return out
    corners = []
    for p, _ in occluders.meshes:
        lo, hi = p.min(axis=0), p.max(axis=0)
        corners.append(
            np.array(
                [
                    [(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]]
                    for i in (0, 1)
                    for j in (0, 1)
                    for k in (0, 1)
                ]
            )
        )
    nrm, p0 = _cell_normals(cells), cells[:, 0]
    c_lo, c_hi = cells.min(axis=1) - 1e-3, cells.max(axis=1) + 1e-3
    for i in np.flatnonzero(weights):
        k = int(occluders.at_time[i])
        if k < 0:
            continue
        sun = f.sun_direction[i]
        sn = nrm @ sun
        ok = sn > 1e-6
        d = np.einsum("cjx,cx->cj", corners[k][None, :, :] - p0[:, None, :], nrm)  # heights above the plane
        proj = corners[k][None, :, :] - (d / np.where(ok, sn, 1.0)[:, None])[:, :, None] * sun
        lo, hi = proj.min(axis=1), proj.max(axis=1)
        out |= ok & np.all((lo <= c_hi) & (hi >= c_lo), axis=1)
    return out


def _assemble(mesh: SceneMesh, cells_by_kind: list[tuple[np.ndarray, np.ndarray]]) -> SceneMesh:
    """A SceneMesh of the final cells ([(cells (C, n, 3), parent face (C,))]), sorted by parent."""
    polys, parents = [], []
    for cells, parent in cells_by_kind:
        polys += list(cells)
        parents += list(parent)
    order = np.argsort(np.asarray(parents), kind="stable")
    polys = [polys[i] for i in order]
    parent = np.asarray(parents, dtype=np.int64)[order]
    counts = np.array([len(p) for p in polys], dtype=np.int64)
    flat = np.concatenate(polys)
    uniq, inverse = np.unique(np.round(flat, 6), axis=0, return_inverse=True)
    inverse = np.asarray(inverse).ravel()
    # vertex positions: the mean of the merged ones (they differ by < 1e-6 m)
    pts = np.zeros((len(uniq), 3))
    np.add.at(pts, inverse, flat)
    pts /= np.bincount(inverse, minlength=len(uniq))[:, None]
    tris, tri_face = fan_triangulate(counts, inverse)
    return dataclasses.replace(
        mesh,
        points=pts,
        triangles=tris,
        tri_face=tri_face,
        n_faces=len(counts),
        counts=counts,
        indices=inverse.astype(np.int64),
        parent_face=parent,
    )


def refine_meshes(
    meshes: list[SceneMesh],
    forcing: SurfaceForcing,
    occluders: Occluders | None = None,
    min_cell_m: float = MIN_CELL_M,
    threshold_w_m2: float = REFINE_THRESHOLD_W_M2,
    memory_s: float = REFINE_MEMORY_S,
    max_faces: int = MAX_REFINED_FACES,
    cameras: list[Camera] | None = None,
    view_spread: float = VIEW_SPREAD,
) -> tuple[list[SceneMesh], dict]:
    """Split the slab faces that straddle a shadow or a footprint until no face does.

    A face (triangle or quad of a :attr:`SceneMesh.refinable` slab mesh) is split into four
    (edge midpoints) while it is larger than ``min_cell_m`` and its absorbed direct sun,
    alpha_s sum_i w_i DNI_i max(n.s_i, 0) lit_i with the weights of the recent past
    (exp(t / memory) before frame 0, 1 from frame 0 on, normalised), differs by more than
    ``threshold_w_m2`` between 16 points spread over it. Shadow rays see the scene and the
    occluders (people) present at each time, so a building's base, an object's footprint
    (always shaded), the moving shadow edges of the last hours and a person's own shadow all
    get small faces, and open ground keeps its large ones. Faces stay planar and keep the
    winding of the face they split; a split face's neighbours keep their edges (T-junctions on
    a plane, no gap).

    A cell is also split while its sky view factor varies by more than ``view_spread`` over
    it (:func:`_sky_view_spread`; the ground near a wall: the exchange with the wall changes
    across it; ``np.inf`` turns this off).

    Where a camera (``cameras``, :func:`camera_footprints`) sees a cell, the finest size is
    its pixel footprint there (:func:`pixel_footprint`, not below
    :data:`MIN_FOOTPRINT_CELL_M`) when that is finer than ``min_cell_m``, so a shadow edge in
    the image lies within one pixel of where it falls; elsewhere ``min_cell_m``. The face
    count is bounded by ``max_faces`` per mesh: before each level's cells are made, the count
    they would give is checked, and past the bound only the cells coarsest against their
    finest size are split (a warning says so).

    Returns the meshes (refined ones with :attr:`SceneMesh.parent_face`) and per refined mesh
    path its face count before and after and the smallest cell made [m].
    """
    occluders = occluders or Occluders.none(len(forcing.times_s))
    weights = _recent_weights(forcing, memory_s)
    if not weights.any() or not any(m.refinable for m in meshes):
        return meshes, {}
    shadows = _Shadows(meshes, occluders)
    # the ground's sky view changes near the objects standing on it; its own relief (terrain,
    # issue 30) is left out: a ditch's grass walls are near the floor's temperature, and
    # resolving every hollow to MIN_CELL_M would cost tens of thousands of faces
    objects = [x for x in meshes if not x.is_ground]
    view_casters = {False: shadows, True: _Shadows(objects, occluders) if objects else None}
    out, report = [], {}
    for m in meshes:
        if not m.refinable:
            out.append(m)
            continue
        alpha = m.solar_absorptivity
        final, active = [], []
        for n in (3, 4):
            faces = np.flatnonzero(m.counts == n)
            if len(faces) == 0:
                continue
            starts = np.concatenate([[0], np.cumsum(m.counts)[:-1]])
            idx = m.indices[starts[faces][:, None] + np.arange(n)[None, :]]
            active.append((m.points[idx], faces))
        total, capped, finest = m.n_faces, False, np.inf
        while active:
            nxt = []
            for cells, parent in active:
                size = _cell_size(cells)
                target = np.full(len(cells), float(min_cell_m))
                if cameras:
                    near = size > MIN_FOOTPRINT_CELL_M * (1.0 + 1e-9)
                    fp = _footprint_cells(cells[near], cameras, shadows)
                    target[near] = np.minimum(min_cell_m, np.maximum(fp, MIN_FOOTPRINT_CELL_M))
                big = size > target * (1.0 + 1e-9)
                split = np.zeros(len(cells), dtype=bool)
                if big.any():
                    d = _dose(cells[big], shadows, forcing, weights)
                    split[big] = alpha * np.ptp(d, axis=1) > threshold_w_m2
                    # footprints and people's bounding boxes: down to min_cell_m (the sun's
                    # dose finds the edges of a person's shadow below that)
                    coarse = big & (size > min_cell_m * (1.0 + 1e-9))
                    if coarse.any():
                        split[coarse] |= _under_occluders(cells[coarse], occluders, forcing, weights)
                        split[coarse] |= _straddles_a_footprint(cells[coarse], shadows)
                        split[coarse] |= (
                            _sky_view_spread(cells[coarse], view_casters[m.is_ground]) > view_spread
                        )
                if split.any() and total + 3 * int(split.sum()) > max_faces:
                    # the bound, checked before the children exist: split the cells coarsest
                    # against their finest size first, as many as it allows
                    budget = max((max_faces - total) // 3, 0)
                    idx = np.flatnonzero(split)
                    keep = idx[np.argsort(-(size[idx] / target[idx]), kind="stable")[:budget]]
                    split[:] = False
                    split[keep] = True
                    capped = True
                final.append((cells[~split], parent[~split]))
                if (~split).any():
                    finest = min(finest, float(size[~split].min()))
                if split.any():
                    total += 3 * int(split.sum())
                    nxt.append((_split(cells[split]), np.repeat(parent[split], 4)))
            active = nxt
        if capped:
            log.warning("%s: tessellation stopped at %d faces (max_faces)", m.path, total)
        if total == m.n_faces:
            out.append(m)
            continue
        refined = _assemble(m, final)
        report[m.path] = {
            "faces": int(m.n_faces),
            "refinedFaces": int(refined.n_faces),
            "smallestCell_m": round(finest, 6),
        }
        out.append(refined)
    return out, report


def _construction(mesh: SceneMesh):
    """(layer thicknesses, conductivity, rho c per layer) of a face's slab: the mesh's material
    over, for the ground, its substrate down to GROUND_DEPTH_M."""
    mat = mesh.material
    n = int(np.clip(np.ceil(mat.thickness / MAX_LAYER_M), 4, 40))
    dz = [np.full(n, mat.thickness / n)]
    k = [np.full(n, mat.conductivity)]
    rc = [np.full(n, mat.density * mat.specific_heat)]
    if mesh.is_ground and mat.thickness < GROUND_DEPTH_M:
        soil = mesh.substrate
        rest = GROUND_DEPTH_M - mat.thickness
        # 8 soil layers growing geometrically (x 8 over the column): the diurnal wave is
        # damped within ~0.15 m, deeper layers only need to carry the mean
        grow = np.geomspace(1.0, 8.0, 8)
        dz.append(rest * grow / grow.sum())
        k.append(np.full(8, soil.conductivity))
        rc.append(np.full(8, soil.density * soil.specific_heat))
    return np.concatenate(dz), np.concatenate(k), np.concatenate(rc)


@dataclass
class SurfaceForcing:
    """Weather and sun at the slab's sample times (seconds after frame 0).

    ``cloud_cover`` (M,) [0-1] or None (clear); ``sky_longwave_factor`` (scalar or (M,))
    multiplies the analytic sky long wave (1: Berdahl & Martin with the cloud mix;
    :func:`with_sky_table` sets it so that the slab sees the atmosphere layer's sky).
    """

    times_s: np.ndarray
    air_temperature_k: np.ndarray
    relative_humidity: np.ndarray
    wind_speed_m_s: np.ndarray
    sun_direction: np.ndarray  # (M, 3)
    sun_up: np.ndarray
    dni_w_m2: np.ndarray
    dhi_w_m2: np.ndarray
    ghi_w_m2: np.ndarray
    cloud_cover: np.ndarray | None = None
    sky_longwave_factor: float | np.ndarray = 1.0
    #: the sky's angular distribution, (zenith [deg] (Z,), radiance (Z,)): frame 0's table of
    #: the atmosphere layer (:func:`with_sky_table`); None: the Martin & Berdahl (1984) law of
    #: the analytic sky at the first sample
    sky_shape: tuple | None = None
    #: air pressure (M,) [Pa]; None: 101325
    pressure_pa: np.ndarray | None = None
    #: rain rate over the step ending at each sample (M,) [kg m^-2 s^-1]; None: no rain
    rain_kg_m2_s: np.ndarray | None = None
    #: relative available soil water under vegetation and bare soil [0-1] (1: field capacity)
    soil_moisture: float = 1.0
    #: broken cloud: ``beam_gate(x, y)`` (P,) [m] -> (M, P) factor on the direct beam at each
    #: sample (0 under a cloud's shadow; :func:`with_cloud_shadows`); None: uniform cover
    beam_gate: object = None

    def sky_distribution(self) -> tuple[np.ndarray, np.ndarray]:
        """The sky's angular distribution (zenith [deg] (Z,), radiance (Z,), any scale):
        :attr:`sky_shape`, else the Martin & Berdahl (1984) law of the analytic sky at the
        first sample."""
        if self.sky_shape is not None:
            return self.sky_shape
        _, eps = effective_sky_temperature(self.air_temperature_k[0], self.relative_humidity[0])
        if self.cloud_cover is not None:
            eps = cloudy_sky_emissivity(eps, self.cloud_cover[0])
        zen = np.linspace(0.0, 89.0, 90)
        return zen, directional_sky_emissivity(zen, float(eps))

    def sky_view(self, normals) -> np.ndarray:
        """(F,) irradiance from the sky on each face over the horizontal sky irradiance:
        :func:`humv_usd.physics.sky.tilted_irradiance` of the sky's angular distribution
        (not isotropic: a wall sees the bright horizon sky), 1 facing up, 0 facing down."""
        shape = self.sky_distribution()
        tilt = np.degrees(np.arccos(np.clip(np.asarray(normals)[:, 2], -1.0, 1.0)))
        uniq, inverse = np.unique(np.round(tilt, 2), return_inverse=True)
        e = tilted_irradiance(*shape, np.r_[0.0, uniq])
        return (e[1:] / e[0])[np.asarray(inverse).ravel()]

    @property
    def sky_longwave(self) -> np.ndarray:
        """Downwelling sky long wave [W m^-2]: factor x eps sigma T_air^4, eps the Berdahl &
        Martin (1984) clear-sky emissivity with the Crawford & Duchon (1999) cloud mix."""
        _, eps = effective_sky_temperature(self.air_temperature_k, self.relative_humidity)
        if self.cloud_cover is not None:
            eps = cloudy_sky_emissivity(eps, self.cloud_cover)
        return self.sky_longwave_factor * eps * STEFAN_BOLTZMANN * self.air_temperature_k**4


def with_sky_table(forcing: SurfaceForcing, table, frame0: int) -> SurfaceForcing:
    """The forcing with its sky long wave taken from the atmosphere layer's sky table(s).

    Parameters
    ----------
    forcing : SurfaceForcing
    table : (zenith_deg (Z,), radiance (Z,)), a list of them, or None
        The layer's ``skyLongwaveRadiance`` (:func:`humv_usd.usd.atmosphere.longwave_sky`) at
        the time code of each sample from frame 0 on (one table: the same for all of them);
        None returns ``forcing`` unchanged.
    frame0 : int
        Index of frame 0 in ``forcing.times_s``.

    Returns
    -------
    SurfaceForcing
        From frame 0 on, E_sky of sample i is the :func:`humv_usd.physics.sky.hemispherical_irradiance`
        of its table: the slab sees the sky the render and the people's radiance maps see at
        that time code. Before frame 0 (the spin-up) the layer has no sky: there the analytic
        sky (Berdahl & Martin with the cloud mix, following the spin-up weather) is scaled by
        E_table / E_analytic of frame 0.
    """
    if table is None:
        return forcing
    n = len(forcing.times_s)
    tables = list(table) if isinstance(table, list) else [table] * (n - frame0)
    if len(tables) != n - frame0:
        raise ValueError(f"expected {n - frame0} sky tables (one per sample from frame 0), got {len(tables)}")
    analytic = dataclasses.replace(forcing, sky_longwave_factor=1.0).sky_longwave
    factor = np.empty(n)
    factor[frame0:] = [hemispherical_irradiance(*t) / float(e) for t, e in zip(tables, analytic[frame0:])]
    factor[:frame0] = factor[frame0]
    return dataclasses.replace(forcing, sky_longwave_factor=factor, sky_shape=tuple(tables[0]))


def with_water(forcing: SurfaceForcing, scenario) -> SurfaceForcing:
    """The forcing with the scenario's rain (``[atmosphere] rain_mm_h``, ``rain_end_h``,
    ``rain_duration_h``: :func:`humv_usd.physics.evaporation.rain_schedule`) and soil moisture
    (``[scene.ground] soil_moisture``)."""
    atm = scenario["atmosphere"] or {}
    ground = (scenario["scene"] or {}).get("ground") or {}
    rate = float(atm.get("rain_mm_h") or 0.0)
    rain = None
    if rate > 0.0:
        rain = evaporation.rain_schedule(
            forcing.times_s,
            rate,
            3600.0 * float(atm.get("rain_end_h") or 0.0),
            3600.0 * float(atm.get("rain_duration_h", 2.0)),
        )
    moisture = ground.get("soil_moisture")
    return dataclasses.replace(
        forcing,
        rain_kg_m2_s=rain,
        soil_moisture=forcing.soil_moisture if moisture is None else float(moisture),
    )


def with_cloud_shadows(forcing: SurfaceForcing, scenario) -> SurfaceForcing:
    """The forcing with moving cloud shadows (``[atmosphere] cloud_size_m`` > 0, issue 30.4):
    :mod:`humv_usd.physics.clouds` fields of the scenario's ``general.seed``, thresholded to the
    forcing's cloud cover and carried by the cloud-level wind from ``wind_direction_deg``.
    Under a cloud the direct beam is 0; between clouds it is the clear-sky beam, the layer's
    DNI over Kasten & Czeplak's DNI / DNI_clear (:func:`humv_usd.physics.sun.cloud_dni_factor`).
    Unchanged without clouds or with ``cloud_size_m`` 0."""
    atm = scenario["atmosphere"] or {}
    size = float(atm.get("cloud_size_m") or 0.0)
    cover = forcing.cloud_cover
    if size <= 0.0 or cover is None or not np.any(np.asarray(cover) > 0.0):
        return forcing
    field = clouds.cloud_field(int(scenario["general"].get("seed") or 0), size)
    toward = (float(atm.get("wind_direction_deg") or 0.0) + 180.0) % 360.0
    shift = clouds.cloud_displacement(
        forcing.times_s, clouds.cloud_level_wind(forcing.wind_speed_m_s), toward
    )
    factor = np.broadcast_to(cloud_dni_factor(cover), forcing.times_s.shape)
    overcast = factor < OVERCAST_DNI_FACTOR
    clear = 1.0 / np.maximum(factor, OVERCAST_DNI_FACTOR)

    def gate(x, y):
        sun = clouds.cloud_shadow(field, x, y, shift, cover)
        return np.where(overcast[:, None], 1.0, sun * clear[:, None])

    return dataclasses.replace(forcing, beam_gate=gate)


def people_beam_gate(forcing: SurfaceForcing, scenario) -> np.ndarray:
    """(M,) factor on the direct beam that reaches the people at each sample: the cloud
    shadow (:func:`with_cloud_shadows`) at the centroid of their ``[[placement]]`` positions
    (a clip's walk is metres, a cloud hundreds of metres); ones without cloud shadows."""
    n = len(forcing.times_s)
    spots = [p["position_m"][:2] for p in (scenario["placement"] or ()) if p.get("position_m") is not None]
    if forcing.beam_gate is None or not spots:
        return np.ones(n)
    x, y = np.mean(np.asarray(spots, dtype=float), axis=0)
    return np.asarray(forcing.beam_gate(np.array([x]), np.array([y])), dtype=float)[:, 0]


def forcing_at(stage, times_s) -> SurfaceForcing:
    """Weather and sun of the stage's environment layer (:mod:`humv_usd.usd.environment`) at
    ``times_s`` seconds after frame 0; the spin-up times (< 0) are the layer's negative time
    codes (see :mod:`humv_usd.environment.layer`)."""
    t = np.asarray(times_s, dtype=float)
    codes = time_codes(stage, t)
    w = read_weather(stage, codes)
    sun = read_sun(stage, codes)
    return SurfaceForcing(
        t,
        w.air_temperature_k,
        w.relative_humidity,
        w.wind_speed_m_s,
        sun.direction,
        sun.up,
        sun.dni_w_m2,
        sun.dhi_w_m2,
        sun.ghi_w_m2,
        w.cloud_cover,
        pressure_pa=w.pressure_pa,
    )


@dataclass
class _Seen:
    """What the faces of one solve see besides the open sky (:mod:`humv_usd.thermal.views`):
    per face the seen share of the sky's long wave (radiance-weighted) and diffuse short wave
    (isotropic) and of the ground beyond the model, each over its open value, and per sample
    the short and long wave that reach the face from the scene faces it sees [W m^-2]."""

    sky_lw: np.ndarray  # (F,)
    sky_sw: np.ndarray  # (F,)
    ground: np.ndarray  # (F,)
    enclosed: np.ndarray  # (F,) share inside a closed mesh (a black body at the air temperature)
    scene_sw: np.ndarray  # (M, F)
    scene_lw: np.ndarray  # (M, F)

    def take(self, sel) -> _Seen:
        def cols(a):  # (M, F) or a scalar (nothing from the scene)
            return a[:, sel] if np.ndim(a) == 2 else a

        return _Seen(
            self.sky_lw[sel],
            self.sky_sw[sel],
            self.ground[sel],
            self.enclosed[sel],
            cols(self.scene_sw),
            cols(self.scene_lw),
        )


def _face_forcing(
    mesh: SceneMesh,
    normals,
    lit,
    f: SurfaceForcing,
    ground_k,
    ground_eps,
    ground_albedo,
    seen: _Seen | None = None,
):
    """(absorbed solar, incident long wave, air, h, incident short wave), each (M, F)."""
    nz = normals[:, 2][None, :]
    sky_view = f.sky_view(normals)[None, :]
    up, down = 0.5 * (1.0 + nz), 0.5 * (1.0 - nz)
    if seen is not None:
        sky_view = sky_view * seen.sky_lw[None, :]
        up = up * seen.sky_sw[None, :]
        down = down * seen.ground[None, :]
    cos = np.maximum(f.sun_direction @ normals.T, 0.0) * f.sun_up[:, None]
    e_sw = (
        f.dni_w_m2[:, None] * cos * lit
        + f.dhi_w_m2[:, None] * up
        + ground_albedo * f.ghi_w_m2[:, None] * down
    )
    e_sky = f.sky_longwave[:, None]
    ground_lw = (
        ground_eps * STEFAN_BOLTZMANN * np.asarray(ground_k)[:, None] ** 4 + (1.0 - ground_eps) * e_sky
    )
    lw = e_sky * sky_view + ground_lw * down
    if seen is not None:
        e_sw = e_sw + seen.scene_sw
        enclosure = seen.enclosed[None, :] * STEFAN_BOLTZMANN * f.air_temperature_k[:, None] ** 4
        lw = lw + seen.scene_lw + enclosure
    shape = e_sw.shape
    air = np.broadcast_to(f.air_temperature_k[:, None], shape)
    h = np.broadcast_to(watmuff(f.wind_speed_m_s)[:, None], shape)
    alpha = (
        0.0
        if mesh.held_k is not None
        else mesh.per_face(lambda m: m.require("solar_absorptivity", mesh.path))
    )
    return alpha * e_sw, lw, air, h, e_sw


def _solve_faces(mesh: SceneMesh, normals, lit, f, *args):
    """:func:`_solve_mesh` per material of a mesh with per-face materials: a face in a material
    GeomSubset is a slab of that material (construction, solar absorptivity, emissivity).
    Returns ((M, F) surface temperature, max residual, (M, F) incident long wave)."""
    if mesh.material_of_face is None:
        return _solve_mesh(mesh, normals, lit, f, *args)
    m = len(f.times_s)
    out, lw, res = np.empty((m, mesh.n_faces)), np.empty((m, mesh.n_faces)), 0.0
    wet = swe = None
    seen = args[-1]
    for k, material in enumerate(mesh.face_materials):
        sel = mesh.material_of_face == k
        if not sel.any():
            continue
        # the faces of a roof's snow subset are snow over the mesh's material (scene.ground.cover_roof)
        snowy = mesh.snow is not None and material.path != mesh.snow.bare_material
        one = dataclasses.replace(
            mesh,
            material=material,
            face_materials=(),
            material_of_face=None,
            n_faces=int(sel.sum()),
            snow=mesh.snow if snowy else None,
        )
        t, r, e, w, water = _solve_mesh(
            one, normals[sel], lit[:, sel], f, *args[:-1], None if seen is None else seen.take(sel)
        )
        out[:, sel], lw[:, sel], res = t, e, max(res, r)
        if water is not None:  # NaN: a face not under snow
            swe = np.full((m, mesh.n_faces), np.nan) if swe is None else swe
            swe[:, sel] = water
        if w is not None:
            wet = np.zeros((m, mesh.n_faces)) if wet is None else wet
            wet[:, sel] = w
    return out, res, lw, wet, swe


def _solve_mesh(mesh, normals, lit, f, ground_k, ground_eps, ground_albedo, deep_k, seen=None):
    """(M, F) surface temperatures of one mesh's slab faces, the max residual, the (M, F)
    incident long wave, the (M, F) wet fraction (None: no water on it) and the (M, F) snow
    water equivalent [kg m^-2] (None: no snow on it)."""
    a_s, lw, air, h, e_sw = _face_forcing(mesh, normals, lit, f, ground_k, ground_eps, ground_albedo, seen)
    leaf = surface_water(mesh.material.name).leaf_dimension_m
    if leaf is not None:  # foliage: both sides of its leaves exchange heat (physics.vegetation)
        pressure = 101325.0 if f.pressure_pa is None else np.asarray(f.pressure_pa)[:, None]
        h = np.broadcast_to(
            vegetation.leaf_heat_transfer_coefficient(
                f.wind_speed_m_s[:, None], leaf, 2, pressure, f.air_temperature_k[:, None]
            ),
            h.shape,
        )
    latent = _latent_forcing(mesh, f, e_sw)
    columns = [a_s, lw, air, h] + ([latent.pop("surface_resistance_s_m")] if latent else [])
    # faces with the same forcing history (most of an unshaded ground) are solved once
    stacked = np.ascontiguousarray(np.concatenate(columns, axis=0).T)  # (F, 4M or 5M)
    np.round(stacked, 9, out=stacked)  # in place: the largest array of the solve
    # rows compared as raw bytes (one void item per row): much faster than np.unique(axis=0)
    rows = stacked.view(np.dtype((np.void, stacked.dtype.itemsize * stacked.shape[1]))).ravel()
    _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    uniq = stacked[first]
    inverse = np.asarray(inverse).ravel()
    m = len(f.times_s)
    cols = [uniq[:, k * m : (k + 1) * m].T for k in range(len(columns))]  # (M, U) each
    if latent:
        latent["surface_resistance_s_m"] = cols.pop()
    if mesh.snow is not None:  # snow over the bare ground, melting (issue 30.4)
        t_surf, res, swe = _solve_snow(mesh, f.times_s, cols[0], *cols[1:4], deep_k)
        return t_surf[:, inverse], res, lw, None, swe[:, inverse]
    dz, k, rc = _construction(mesh)
    wet = latent.get("rain_kg_m2_s") is not None and np.any(latent["rain_kg_m2_s"] > 0.0)
    solved = slab.simulate_many(
        f.times_s,
        *cols,
        dz,
        k,
        rc,
        emissivity=longwave_emissivity(mesh.material),
        bottom="fixed" if mesh.is_ground else ("adiabatic" if mesh.interior_k is None else "interior"),
        deep_temperature_k=deep_k if mesh.interior_k is None else mesh.interior_k,
        melt_temperature_k=surface_water(mesh.material.name).melts_at_k,
        return_wet_fraction=bool(wet),
        **latent,
    )
    t_surf, res = solved[:2]
    return t_surf[:, inverse], res, lw, (solved[2][:, inverse] if wet else None), None


def _solve_snow(mesh: SceneMesh, times_s, absorbed, lw, air, h, deep_k):
    """:func:`humv_usd.physics.snow.simulate_cover` of a snow-covered ground's (or roof's)
    faces: the snow layer over the bare material's construction, its back as the mesh's (the
    ground's bottom held, a heated building's room air, else adiabatic); ``absorbed`` the
    snow's absorbed short wave (the bare surface's scales by the ratio of their
    absorptivities). Rain and evaporation are not modelled on snow."""
    bare = dataclasses.replace(mesh, material=mesh.bare, snow=None, bare=None)
    dz, k, rc = _construction(bare)
    ratio = mesh.bare.require("solar_absorptivity", mesh.path) / mesh.solar_absorptivity
    return snow.simulate_cover(
        times_s,
        absorbed,
        absorbed * ratio,
        lw,
        air,
        h,
        mesh.snow.depth_m,
        mesh.snow.density_kg_m3,
        dz,
        k,
        rc,
        emissivity_snow=longwave_emissivity(mesh.material),
        emissivity_bare=longwave_emissivity(mesh.bare),
        bottom="fixed" if mesh.is_ground else ("adiabatic" if mesh.interior_k is None else "interior"),
        deep_temperature_k=deep_k if mesh.interior_k is None else mesh.interior_k,
    )


def _latent_forcing(mesh: SceneMesh, f: SurfaceForcing, e_sw) -> dict:
    """:func:`humv_usd.physics.slab.simulate_many`'s evaporation arguments for a mesh's faces
    (issue 30): vegetation and bare soil transpire through the surface resistance of
    :func:`humv_usd.physics.evaporation.surface_resistance` (light on the face, the forcing's
    soil moisture; the material's :func:`humv_usd.catalog.materials.surface_water`), and any
    surface holds the rain of ``f.rain_kg_m2_s`` up to its capacity and dries; {} for a dry
    surface without rain (no latent flux, the model before issue 30)."""
    water = surface_water(mesh.material.name)
    raining = f.rain_kg_m2_s is not None and bool(np.any(f.rain_kg_m2_s > 0.0))
    if water.minimum_resistance_s_m is None and not raining:
        return {}
    if water.minimum_resistance_s_m is None:
        rs = np.full(e_sw.shape, np.inf)
    elif water.minimum_resistance_s_m == 0.0:  # free water (a puddle): no stomata, no soil
        rs = np.zeros(e_sw.shape)
    else:
        rs = evaporation.surface_resistance(
            water.minimum_resistance_s_m, e_sw, f.soil_moisture, water.leaf_area_index
        )
    pressure = np.full(len(f.times_s), 101325.0) if f.pressure_pa is None else np.asarray(f.pressure_pa)
    vapour = f.relative_humidity * evaporation.saturation_vapour_pressure(f.air_temperature_k)
    return {
        "surface_resistance_s_m": rs,
        "vapour_pressure_pa": vapour[:, None],
        "pressure_pa": pressure[:, None],
        "rain_kg_m2_s": 0.0 if f.rain_kg_m2_s is None else np.asarray(f.rain_kg_m2_s)[:, None],
        "water_capacity_kg_m2": water.water_capacity_kg_m2,
    }


#: the exchange between scene faces is iterated until no surface temperature changes by more
#: than this between passes [K] ...
EXCHANGE_TOLERANCE_K = 0.05
#: ... or for this many passes (a warning says where it stopped)
EXCHANGE_MAX_PASSES = 8
#: lower bound of a surface's conductance to its surroundings, h + 4 eps sigma T^3 [W m^-2 K^-1]
#: (Watmuff's h >= 2.8 in calm air, 4 eps sigma T^3 >= 3.5 for eps >= 0.8 above 240 K)
MIN_SURFACE_CONDUCTANCE = 6.0
#: short-wave inter-reflections between scene faces followed (bounces after the first)
SHORTWAVE_BOUNCES = 3


def _solar_reflectance(material: StageMaterial) -> float:
    """Broadband short-wave reflectance 1 - alpha_s of an opaque material; 0 (black) where a
    held face's material gives no absorptivity."""
    alpha = material.solar_absorptivity
    return 0.0 if alpha is None else 1.0 - float(alpha)


def _views(meshes: list[SceneMesh], rays: int):
    """:func:`humv_usd.thermal.views.face_views` of all scene meshes together (faces numbered
    mesh by mesh); ``rays`` per triangle of a face wider than half :data:`MIN_CELL_M` (sqrt of
    its area), a quarter of them for the camera-footprint cells of a shadow edge (their neighbours
    share the same ray pattern from nearly the same points, so their estimates move together)."""
    offsets = np.cumsum([0] + [len(m.points) for m in meshes])
    face0 = np.cumsum([0] + [m.n_faces for m in meshes])
    tri_face = np.concatenate([m.tri_face + o for m, o in zip(meshes, face0)])
    area = np.concatenate([m.face_geometry()[2] for m in meshes])
    per_tri = np.where(np.sqrt(area) >= 0.5 * MIN_CELL_M, rays, max(rays // 4, 1))[tri_face]
    return face_views(
        np.concatenate([m.points for m in meshes]),
        np.concatenate([m.triangles + o for m, o in zip(meshes, offsets)]),
        tri_face,
        int(face0[-1]),
        per_tri,
    )


def surface_temperatures(
    scenario,
    meshes: list[SceneMesh],
    times_s,
    spin_up_s=86400.0,
    forcing: SurfaceForcing | None = None,
    occluders: Occluders | None = None,
    exchange: bool = True,
    view_rays: int = VIEW_RAYS,
):  # scenario: unused, kept for callers' signature
    """Per-face temperatures of the scene meshes at ``times_s`` (seconds after frame 0, >= 0).

    Parameters
    ----------
    scenario : Scenario
    meshes : list of SceneMesh
        From :func:`scene_meshes`.
    times_s : array (n,)
        Increasing output times [s], the first normally 0.
    spin_up_s : float
        Length of the diurnal spin-up that ends at time 0 [s] (10-minute steps); the slab
        starts in equilibrium with the spin-up's mean forcing.
    forcing : SurfaceForcing
        Weather and sun at the spin-up and output times (:func:`forcing_at` of the stage).
    occluders : Occluders, optional
        Shadow casters that are not solved (the people, :func:`people_occluders`).
    exchange : bool, default True
        Each face sees its surroundings (:mod:`humv_usd.thermal.views`): the sky only where
        it is open (long wave weighted by the sky's angular radiance, diffuse short wave
        isotropic), the scene faces it sees with their leaving long wave and reflected short
        wave, the ground beyond the model where downward rays escape. False: every face sees
        the open sky and the ground as if nothing stood around it (the model before issue 25).
    view_rays : int
        Rays per triangle for the view factors.

    Returns
    -------
    tuple
        ({mesh path: (n, faces) temperature [K]}, diagnostics: max |surface residual| of the
        slabs [W m^-2], the ground's mean temperature (n,) [K], what each mesh got
        ('held' or 'slab'), and with ``exchange`` the passes of the exchange iteration, its
        last change [K], the rays cast and the area-weighted mean sky view factor per mesh;
        after rain ``wetFraction``: {mesh path: (n, faces) wet share [0-1]}; under snow
        ``snowWater``: {mesh path: (n, faces) snow water equivalent [kg m^-2], 0 melted out,
        NaN on faces that never had snow (a roof's walls)}).

    Notes
    -----
    Long-wave exchange: face i receives E_sky V(n_i) S_i + sum_k F_ik J_k + G_i, with S_i the
    seen share of the sky's radiance (1 in the open), F_ik the view factors, J_k = eps_k sigma
    T_k^4 + (1 - eps_k) L_k the radiosity of face k (L_k its incident long wave) and G_i the
    ground beyond the model. The T_k are those of the previous pass (fixed-point iteration of
    the whole time series, Jacobi; first pass: every face at the air temperature and
    L = E_sky); only faces that see other faces are solved again. Short wave: E_i = E0_i +
    sum_k F_ik rho_k E_k (rho = 1 - alpha_s), iterated :data:`SHORTWAVE_BOUNCES` times from E0
    (direct sun, seen diffuse sky, ground beyond). Radiosity method: Modest (2013), Radiative
    Heat Transfer, 3rd ed., ch. 5; urban canyon energy balance with sky view factors: Oke
    (1988), Johnson & Watson (1984).
    """
    times = np.asarray(times_s, dtype=float)
    spin = np.arange(-float(spin_up_s), 0.0, SPIN_UP_STEP_S) if spin_up_s > 0 else np.zeros(0)
    all_t = np.concatenate([spin, times[times > (spin[-1] if len(spin) else -np.inf)]])
    if len(all_t) == 0 or all_t[-1] < times[-1]:
        all_t = np.concatenate([all_t, times])
    if forcing is None:
        raise ValueError("surface_temperatures needs the forcing (forcing_at of the composed stage)")
    f = forcing
    if len(f.times_s) != len(all_t) or not np.allclose(f.times_s, all_t):
        raise ValueError("forcing times must be the spin-up steps followed by times_s")
    idx = np.searchsorted(all_t, times)
    geo = [m.face_geometry() for m in meshes]
    lit_all = _sunlit_fraction(meshes, f.sun_direction, f.sun_up, occluders) if meshes else None
    if f.beam_gate is not None and meshes:  # moving cloud shadows at each face's centroid
        centres = np.concatenate([g[1] for g in geo])
        lit_all = lit_all * f.beam_gate(centres[:, 0], centres[:, 1])
    starts = np.cumsum([0] + [m.n_faces for m in meshes])
    deep = (
        float(np.mean(f.air_temperature_k[all_t <= 0.0]))
        if np.any(all_t <= 0.0)
        else float(f.air_temperature_k[0])
    )
    n_t, n_all = len(all_t), int(starts[-1])
    views = _views(meshes, view_rays) if exchange and meshes else None
    ground_eps, ground_alb = 0.95, ground_albedo(meshes)
    ground_k = f.air_temperature_k.copy()
    for m in meshes:
        if m.is_ground:
            ground_eps = longwave_emissivity(m.material)
    seen_all = None
    if views is not None:
        zen, rad = f.sky_distribution()
        centres = 0.5 * (ZENITH_BINS_DEG[1:] + ZENITH_BINS_DEG[:-1])
        sky_lw = views.sky_ratio(np.interp(centres, zen, rad))
        seen_all = _Seen(
            sky_lw,
            views.sky_ratio(),
            views.ground_ratio,
            views.enclosed,
            0.0,
            0.0,
        )
        eps_face = np.concatenate([m.per_face(longwave_emissivity) for m in meshes])
        rho_face = np.concatenate([m.per_face(_solar_reflectance) for m in meshes])
        # short wave: first arrival (sun, seen sky, ground beyond), then inter-reflections
        e0 = np.empty((n_t, n_all))
        for i, m in enumerate(meshes):
            sl = slice(starts[i], starts[i + 1])
            s0 = seen_all.take(sl)
            e0[:, sl] = _face_forcing(m, geo[i][0], lit_all[:, sl], f, ground_k, ground_eps, ground_alb, s0)[
                4
            ]
        e_sw = e0
        for _ in range(SHORTWAVE_BOUNCES):
            e_sw = e0 + (views.to_faces @ (rho_face[:, None] * e_sw.T)).T
        scene_sw = e_sw - e0
        del e0, e_sw
    t_now = np.broadcast_to(f.air_temperature_k[:, None], (n_t, n_all)).copy()
    l_in = np.broadcast_to(f.sky_longwave[:, None], (n_t, n_all)).copy()
    used_lw = np.zeros((n_t, n_all))
    resolve_w_m2 = EXCHANGE_TOLERANCE_K * MIN_SURFACE_CONDUCTANCE
    kinds, max_res, passes, change = {}, 0.0, 0, 0.0
    wet_now = None  # (n_t, n_all) wet fraction of the faces that hold rain water
    swe_now = None  # (n_t, n_all) snow water equivalent [kg m^-2] of snow-covered faces
    order = sorted(range(len(meshes)), key=lambda i: not meshes[i].is_ground)
    coupled = views.coupled if views is not None else np.zeros(n_all, dtype=bool)
    ground_sum: dict[int, np.ndarray] = {}
    ground_area: dict[int, float] = {}
    for p in range(EXCHANGE_MAX_PASSES if views is not None else 1):
        passes = p + 1
        previous = t_now.copy()
        if views is not None:
            radiosity = eps_face * STEFAN_BOLTZMANN * t_now**4 + (1.0 - eps_face) * l_in
            scene_lw = (views.to_faces @ radiosity.T).T
            # a face is solved again only where what it sees changed enough to move it by the
            # tolerance: dT <= dL / (h + 4 eps sigma T^3) <= dL / MIN_SURFACE_CONDUCTANCE
            moved = coupled & (np.abs(scene_lw - used_lw).max(axis=0) > resolve_w_m2)
        for i in order:
            m = meshes[i]
            sl = slice(starts[i], starts[i + 1])
            normals, _, area = geo[i]
            sel = np.ones(m.n_faces, dtype=bool) if p == 0 else moved[sl]
            seen = None
            if views is not None:
                seen = dataclasses.replace(seen_all, scene_sw=scene_sw, scene_lw=scene_lw).take(
                    np.arange(starts[i], starts[i + 1])[sel]
                )
            if m.held_k is not None:
                t_now[:, sl] = float(m.held_k)
                kinds[m.path] = "held"
                if views is not None and sel.any():
                    lw = _face_forcing(
                        m, normals[sel], lit_all[:, sl][:, sel], f, ground_k, ground_eps, ground_alb, seen
                    )[1]
                    l_in[:, np.arange(starts[i], starts[i + 1])[sel]] = lw
            elif sel.any():
                sub = dataclasses.replace(
                    m,
                    n_faces=int(sel.sum()),
                    material_of_face=None if m.material_of_face is None else m.material_of_face[sel],
                )
                t_sel, res, lw, wet_sel, swe_sel = _solve_faces(
                    sub, normals[sel], lit_all[:, sl][:, sel], f, ground_k, ground_eps, ground_alb, deep, seen
                )
                cols = np.arange(starts[i], starts[i + 1])[sel]
                t_now[:, cols], l_in[:, cols] = t_sel, lw
                if wet_sel is not None:
                    wet_now = np.zeros((n_t, n_all)) if wet_now is None else wet_now
                    wet_now[:, cols] = wet_sel
                if swe_sel is not None:
                    swe_now = np.full((n_t, n_all), np.nan) if swe_now is None else swe_now
                    swe_now[:, cols] = swe_sel
                if views is not None:
                    used_lw[:, cols] = scene_lw[:, cols]
                max_res = max(max_res, res)
                kinds[m.path] = "slab"
            if m.is_ground:  # area-weighted over the ground and its zones
                ground_sum[i] = (t_now[:, sl] * area).sum(axis=1)
                ground_area[i] = area.sum()
                ground_k = sum(ground_sum.values()) / max(sum(ground_area.values()), 1e-30)
        change = float(np.max(np.abs(t_now - previous))) if p > 0 else np.inf
        if views is None or not coupled.any() or change < EXCHANGE_TOLERANCE_K or (p > 0 and not moved.any()):
            break
    else:
        log.warning("scene long-wave exchange: %d passes, last change %.3f K", passes, change)
    out = {m.path: t_now[:, starts[i] : starts[i + 1]][idx] for i, m in enumerate(meshes)}
    diag = {
        "slabMaxResidual_W_m2": max_res,
        "groundMeanTemperature_k": ground_k[idx],
        "surfaceModels": kinds,
    }
    if wet_now is not None:
        diag["wetFraction"] = {
            m.path: wet_now[:, starts[i] : starts[i + 1]][idx] for i, m in enumerate(meshes)
        }
    if swe_now is not None:
        diag["snowWater"] = {
            m.path: swe_now[:, starts[i] : starts[i + 1]][idx]
            for i, m in enumerate(meshes)
            if m.snow is not None
        }
    if views is not None:
        svf = views.sky_view_factor
        diag.update(
            {
                "exchangePasses": passes,
                "exchangeLastChange_K": float(change) if np.isfinite(change) else 0.0,
                "viewRays": views.rays,
                "meanSkyViewFactor": {
                    m.path: float(np.average(svf[starts[i] : starts[i + 1]], weights=geo[i][2] + 1e-300))
                    for i, m in enumerate(meshes)
                },
            }
        )
    return out, diag


def write_refined_topology(prim: Usd.Prim, mesh: SceneMesh) -> None:
    """Author a refined mesh's faces on its ``over`` in the thermal layer (local space), so
    the render and the ground truth see the faces the temperatures belong to."""
    inv = np.linalg.inv(mesh.to_world)
    local = mesh.points @ inv[:3, :3] + inv[3, :3]
    override_topology(prim, local, mesh.counts, mesh.indices)
