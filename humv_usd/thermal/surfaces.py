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
  Duffie & Beckman 2013, section 2.15-2.16);
* incident long wave  E_sky (1 + n_z)/2 + [eps_g sigma T_g^4 + (1 - eps_g) E_sky] (1 - n_z)/2,
  E_sky = eps_sky sigma T_air^4 with the Berdahl & Martin (1984) clear-sky emissivity and the
  cloud cover mixed in (Crawford & Duchon 1999); with an atmosphere layer, E_sky at each
  sample from frame 0 on is the hemispherical irradiance of the layer's longwave sky table at
  that time code (:func:`with_sky_table`), the sky the render and the people's radiance maps
  see; during the spin-up before frame 0 (no layer value there) the analytic sky scaled to
  frame 0's table;
* convection  h = 2.8 + 3.0 V (Watmuff et al. 1977).

Weather and sun (spin-up included) are read from the environment layer on the stage
(:func:`forcing_at`, :mod:`humv_usd.usd.environment`).

Constructions (every property from the bound material on the stage,
:mod:`humv_usd.usd.materials`): the ground is its material's layer over its substrate (the
material its ``humv:material:substrate`` points to, soil from the materials tool) down to 1 m,
with the bottom held at the mean air temperature of the spin-up day; objects are their material's layer with an
adiabatic back (insulated siding, a panel on a stand). Scene faces do not exchange radiation with
each other beyond the ground term, and people do not shade the scene.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.geometry.raycast import ray_caster
from humv_usd.physics import slab
from humv_usd.physics.convection import watmuff
from humv_usd.physics.sky import cloudy_sky_emissivity, effective_sky_temperature, hemispherical_irradiance
from humv_usd.scenario.times import SPIN_UP_STEP_S
from humv_usd.thermal.human import longwave_emissivity
from humv_usd.usd.environment import ENVIRONMENT_PATH, read_sun, read_weather, time_codes
from humv_usd.usd.layers import SCOPES
from humv_usd.usd.materials import THERMAL_ATTRIBUTES, StageMaterial, mesh_material, substrate
from humv_usd.usd.paths import GROUND, object_path

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

    @property
    def solar_absorptivity(self) -> float:
        return self.material.require("solar_absorptivity", self.path)

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
    """Every mesh of the composed stage outside /World/Humans, with its bound material
    (:func:`humv_usd.usd.materials.mesh_material`) and held value.

    A mesh the scenario does not hold (a slab, also one from a hand-made layer) needs the
    thermal properties of HumvMaterialAPI on its material, a slab ground thinner than
    :data:`GROUND_DEPTH_M` also its substrate; InputError naming the mesh otherwise."""
    held: dict[str, float | None] = {}
    if scenario["scene"]:
        held[str(GROUND)] = scenario["scene"]["ground"].get("temperature_k")
        for o in scenario["scene"]["object"]:
            held[str(object_path(o["id"]))] = o.get("temperature_k")
        for a in scenario["scene"].get("asset") or ():  # every mesh of the asset
            held[str(object_path(a["id"]))] = a.get("temperature_k")
    out = []
    for prim in upstream.Traverse():
        if not prim.IsA(UsdGeom.Mesh) or str(prim.GetPath()).startswith(str(SCOPES["humans"])):
            continue
        mesh = UsdGeom.Mesh(prim)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
        pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
        xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
        pts = pts @ xf[:3, :3] + xf[3, :3]
        tris, tri_face = fan_triangulate(counts, np.asarray(mesh.GetFaceVertexIndicesAttr().Get()))
        path = str(prim.GetPath())
        material = mesh_material(prim)
        h = _held(path, held)  # a mesh from a hand-made layer: a slab of its material
        is_ground = path == str(GROUND)
        under = None
        if h is None:
            for field in THERMAL_ATTRIBUTES:
                material.require(field, path)
            if is_ground and material.thickness < GROUND_DEPTH_M:
                under = substrate(material, upstream, path)
                for field in THERMAL_ATTRIBUTES:
                    under.require(field, path)
        out.append(SceneMesh(path, pts, tris, tri_face, len(counts), material, h, is_ground, under))
    return out


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


def _sunlit_fraction(meshes, sun_dirs, up):
    """(times, faces of all meshes) sunlit fraction from 4 points per triangle."""
    import trimesh

    offset = 0
    faces, points = [], []
    for m in meshes:
        faces.append(m.triangles + offset)
        points.append(m.points)
        offset += len(m.points)
    combined = trimesh.Trimesh(np.concatenate(points), np.concatenate(faces), process=False)
    caster = ray_caster(combined.vertices, combined.faces)
    tri_n = np.asarray(combined.face_normals)
    v = np.asarray(combined.triangles)
    bary = np.array(
        [[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]
    )
    eps = 2e-5 * float(np.linalg.norm(combined.extents)) + 1e-4
    pts = (np.einsum("kj,tjc->tkc", bary, v) + eps * tri_n[:, None]).reshape(-1, 3)
    tri_area = np.asarray(combined.area_faces)
    face_of_tri = np.concatenate(
        [m.tri_face + sum(x.n_faces for x in meshes[:i]) for i, m in enumerate(meshes)]
    )
    n_faces = sum(m.n_faces for m in meshes)
    face_area = np.bincount(face_of_tri, tri_area, n_faces)
    out = np.zeros((len(sun_dirs), n_faces))
    for i, (s, is_up) in enumerate(zip(sun_dirs, up)):
        if not is_up:
            continue
        facing = np.repeat(tri_n @ s > 0.0, 4)
        lit = np.zeros(len(pts), dtype=bool)
        if facing.any():
            o = pts[facing]
            lit[facing] = ~caster.intersects_any(o, np.broadcast_to(s, o.shape).copy())
        frac_t = lit.reshape(-1, 4).mean(axis=1)
        out[i] = np.bincount(face_of_tri, frac_t * tri_area, n_faces) / np.maximum(face_area, 1e-30)
    return out


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
    return dataclasses.replace(forcing, sky_longwave_factor=factor)


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
    )


def _face_forcing(mesh: SceneMesh, normals, lit, f: SurfaceForcing, ground_k, ground_eps, ground_albedo):
    """(absorbed solar, incident long wave, air, h), each (M, F)."""
    nz = normals[:, 2][None, :]
    up, down = 0.5 * (1.0 + nz), 0.5 * (1.0 - nz)
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
    lw = e_sky * up + ground_lw * down
    shape = e_sw.shape
    air = np.broadcast_to(f.air_temperature_k[:, None], shape)
    h = np.broadcast_to(watmuff(f.wind_speed_m_s)[:, None], shape)
    return mesh.solar_absorptivity * e_sw, lw, air, h


def _solve_mesh(mesh, normals, lit, f, ground_k, ground_eps, ground_albedo, deep_k):
    """(M, F) surface temperatures of one mesh's slab faces, and the max residual."""
    a_s, lw, air, h = _face_forcing(mesh, normals, lit, f, ground_k, ground_eps, ground_albedo)
    # faces with the same forcing history (most of an unshaded ground) are solved once
    stacked = np.concatenate([a_s, lw, air, h], axis=0).T  # (F, 4M)
    uniq, inverse = np.unique(np.round(stacked, 9), axis=0, return_inverse=True)
    inverse = np.asarray(inverse).ravel()
    m = len(f.times_s)
    cols = [uniq[:, k * m : (k + 1) * m].T for k in range(4)]  # (M, U) each
    dz, k, rc = _construction(mesh)
    t_surf, res = slab.simulate_many(
        f.times_s,
        *cols,
        dz,
        k,
        rc,
        emissivity=longwave_emissivity(mesh.material),
        bottom="fixed" if mesh.is_ground else "adiabatic",
        deep_temperature_k=deep_k,
    )
    return t_surf[:, inverse], res


def surface_temperatures(
    scenario, meshes: list[SceneMesh], times_s, spin_up_s=86400.0, forcing: SurfaceForcing | None = None
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

    Returns
    -------
    tuple
        ({mesh path: (n, faces) temperature [K]}, diagnostics: max |surface residual| of the
        slabs [W m^-2], the ground's mean temperature (n,) [K] and what each mesh got
        ('held' or 'slab')).
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
    lit_all = _sunlit_fraction(meshes, f.sun_direction, f.sun_up) if meshes else None
    starts = np.cumsum([0] + [m.n_faces for m in meshes])
    deep = (
        float(np.mean(f.air_temperature_k[all_t <= 0.0]))
        if np.any(all_t <= 0.0)
        else float(f.air_temperature_k[0])
    )
    out, kinds, max_res = {}, {}, 0.0
    ground_k = f.air_temperature_k.copy()
    ground_eps, ground_albedo = 0.95, 0.2
    order = sorted(range(len(meshes)), key=lambda i: not meshes[i].is_ground)
    for i in order:
        m = meshes[i]
        normals, _, area = geo[i]
        if m.held_k is not None:
            t_all = np.full((len(all_t), m.n_faces), float(m.held_k))
            kinds[m.path] = "held"
        else:
            lit = lit_all[:, starts[i] : starts[i + 1]]
            t_all, res = _solve_mesh(m, normals, lit, f, ground_k, ground_eps, ground_albedo, deep)
            max_res = max(max_res, res)
            kinds[m.path] = "slab"
        if m.is_ground:
            ground_k = (t_all * area).sum(axis=1) / max(area.sum(), 1e-30)
            ground_eps = longwave_emissivity(m.material)
            ground_albedo = 1.0 - m.solar_absorptivity
        out[m.path] = t_all[idx]
    return out, {
        "slabMaxResidual_W_m2": max_res,
        "groundMeanTemperature_k": ground_k[idx],
        "surfaceModels": kinds,
    }
