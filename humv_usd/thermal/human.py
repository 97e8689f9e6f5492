"""Skin and garment facet temperatures of one person over the scenario's frames (seed §2.2).

The chain, per person:

1. radiation environment (seed Eq. 2): a lat-long radiance map around the person from the
   sky (:mod:`humv_usd.thermal.sky`: the atmosphere layer's longwave table with cloud cover
   when the stage has one, else the analytic clear sky with the cloud mix) and the scene
   surfaces at their temperatures (:mod:`humv_usd.thermal.scene_radiance`, :mod:`humv_usd.thermal.qrad`);
2. absorbed radiation per facet (Eq. 3-4), ``fast`` method, on the bare body (for the mean radiant
   temperature of each JOS-3 segment, Eq. 1) and on the clothed body (for the garments' outer
   surfaces);
3. physiology (JOS-3 or Gagge's two-node model, :mod:`humv_usd.thermal.physiology`) driven by
   the avatar's metabolic-rate schedule, the weather, an effective radiant temperature per
   segment (first the segment MRT) and the garments' own insulation per segment
   (:func:`garment_clo`: air gap + fabric of the faces over the segment), with a spin-up;
4. skin per facet (``[thermal] skin_detail = "facet"``): each facet's balance over its
   segment's core-skin conductance (:func:`humv_usd.thermal.physiology.local_skin_temperature`),
   with its own absorbed radiation, convection and emission when bare, or the skin-side flux of
   the garment face over it; the segment's area-weighted mean is the physiology's skin;
5. garment facets: the energy balance of Eq. 5-9 over the skin facet underneath, with the
   per-face air gap: steady state at frame 0 (:func:`humv_usd.physics.garment.steady_state`),
   then implicit steps with the fabric's heat capacity along the frames
   (:func:`humv_usd.physics.garment.transient_step`);
6. two-way coupling: per segment the area-weighted skin-side flux (garment q_in or bare-skin
   loss) is compared with the physiology's own sensible loss; the segment's effective radiant
   temperature is set so that the physiology's dry exchange gives that flux
   (:func:`humv_usd.thermal.physiology.radiant_temperature_for_sensible_loss`) and 3-5 are
   repeated until they agree within :data:`COUPLING_TOLERANCE_W_M2` (the residual and the
   iterations go to the layer's metadata). With the two-node model (one skin node) the
   whole body's area-weighted flux is matched.

The sky (weather and sun of the environment layer, :mod:`humv_usd.usd.environment`) and the
scene surfaces (their temperatures from :mod:`humv_usd.thermal.surfaces`) are given per radiation sample by the
caller (:class:`Surroundings`). Not modelled: sunlight reflected from one body part onto
another (a ray blocked by the person brings its long-wave emission only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from pxr import Usd, UsdGeom

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.human import labels as L
from humv_usd.human.usdskel import skinned_points
from humv_usd.physics.convection import convective_coefficient, relative_air_speed
from humv_usd.physics.garment import (
    air_conductivity,
    areal_heat_capacity,
    grey_plates_exchange_factor,
    steady_state,
    transient_step,
)
from humv_usd.thermal import qrad as Q
from humv_usd.thermal import scene_radiance as SR
from humv_usd.thermal.physiology import (
    N_SEGMENTS,
    lagged_skin,
    local_skin_temperature,
    radiant_temperature_for_sensible_loss,
    simulate_physiology,
)
from humv_usd.thermal.sky import ClearSky
from humv_usd.usd.avatar import read_air_gap, read_body_regions, read_garment, read_metabolic_rate
from humv_usd.usd.materials import StageMaterial, band_emissivity, mesh_material

MODEL_NAMES = {"jos3": "jos3", "twoNode": "two_node"}

#: Largest vertex displacement [m] between radiation samples for which a person's ray
#: visibility is replayed instead of re-cast (a standing person sways about 2 cm). Measured on
#: humvvex's clothed avatar (31.7k facets, adaptive 32 rays) 1 s after frame 0 with 2.3 cm
#: sway: 2.1 % RMS error against a 256-ray run with replayed visibility vs 2.0 % with fresh
#: rays, at 0.2 s instead of 0.55 s (a few facets at changing contacts err by tens of %); the
#: replayed rays also keep the Monte Carlo noise still from frame to frame (no flicker).
VISIBILITY_REUSE_M = 0.025


#: Band [um] of the long-wave emissivity of the thermal balances (the bulk of the thermal
#: emission at 250-350 K).
LONGWAVE_BAND_UM = (8.0, 14.0)


def longwave_emissivity(material: StageMaterial) -> float:
    """Long-wave emissivity of a stage material: its band emissivity over
    :data:`LONGWAVE_BAND_UM` (:func:`humv_usd.usd.materials.band_emissivity`, the function the
    render uses for a sensor band, so both see one number for one band)."""
    return band_emissivity(material, LONGWAVE_BAND_UM)


@dataclass
class _Part:
    path: str
    counts: np.ndarray
    indices: np.ndarray
    triangles: np.ndarray  # (T, 3) indices into the part's points
    tri_face: np.ndarray  # (T,) authored face of each triangle
    region: np.ndarray  # (F,) body region id per face
    segment: np.ndarray  # (F,) JOS-3 segment per face
    material: StageMaterial  # bound on the stage (skin, or the garment's fabric)
    garment: str | None = None

    def absorptivity(self) -> np.ndarray:
        """(solar absorptivity, long-wave emissivity) of the part's bound material."""
        alpha = self.material.require("solar_absorptivity", self.path)
        return np.array([alpha, longwave_emissivity(self.material)])


def _part(stage: Usd.Stage, path: str, garment: str | None) -> _Part:
    prim = stage.GetPrimAtPath(path)
    mesh = UsdGeom.Mesh(prim)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
    tris, tri_face = fan_triangulate(counts, indices)
    region = read_body_regions(prim)
    material = mesh_material(prim)
    return _Part(path, counts, indices, tris, tri_face, region, L.jos3_segments(region), material, garment)


def _trimesh(points_by_part: list[np.ndarray], parts: list[_Part]) -> trimesh.Trimesh:
    offset, faces = 0, []
    for pts, part in zip(points_by_part, parts):
        faces.append(part.triangles + offset)
        offset += len(pts)
    return trimesh.Trimesh(np.concatenate(points_by_part), np.concatenate(faces), process=False)


def _self_radiance(parts: list[_Part], skin_k: float, air_k: float) -> np.ndarray:
    """(2, triangles) leaving radiance of the person's own faces, for rays that the body or
    a garment blocks (arm against torso, skin under fabric): a first guess, skin at ``skin_k``
    and fabric half-way to the air, eps sigma T^4 / pi longwave, no shortwave. Without it a
    blocked ray would bring nothing (the seed's 1_ij = 0) and hidden facets would freeze."""
    lw = []
    for p in parts:
        eps = longwave_emissivity(p.material)
        t = skin_k if p.garment is None else 0.5 * (skin_k + air_k)
        lw.append(np.full(len(p.triangles), eps * STEFAN_BOLTZMANN * t**4 / np.pi))
    lw = np.concatenate(lw)
    return np.stack([np.zeros_like(lw), lw])


def scenario_sky(
    scenario,
    weather: dict | None = None,
    sun: tuple | None = None,
    ground_k: float | None = None,
    longwave: tuple | None = None,
    ground_albedo: float = 0.2,
) -> ClearSky:
    """The sky of the scenario's weather over its ground.

    ``weather``: one sample of the environment layer's weather
    (:func:`humv_usd.usd.environment.read_weather`) as a dict, as the thermal layer passes it
    (default the constant ``[atmosphere]`` values, for benches and tests without a stage;
    ``cloud_cover`` defaults to 0); ``sun``: (unit
    direction towards the sun, DNI, DHI) [W m^-2] or None (night / no sun); ``ground_k``: ground
    surface temperature (default the scenario's held ground temperature, else the air
    temperature); ``longwave``: (zenith angles [deg], longwave sky radiance [W m^-2 sr^-1])
    from the atmosphere layer (clouds included), else the analytic sky with the cloud mix;
    ``ground_albedo``: 1 - solar absorptivity of the ground's material on the stage
    (:func:`humv_usd.thermal.surfaces.ground_albedo`).
    """
    atm = weather if weather is not None else scenario["atmosphere"]
    if ground_k is None and scenario["scene"]:
        ground_k = scenario["scene"]["ground"].get("temperature_k")
    kw = {}
    if sun is not None:
        kw = dict(
            sun_direction=tuple(float(x) for x in sun[0]),
            direct_normal_irradiance=float(sun[1]),
            diffuse_horizontal_irradiance=float(sun[2]),
        )
    if longwave is not None:
        kw.update(
            longwave_zenith_deg=tuple(float(x) for x in longwave[0]),
            longwave_radiance=tuple(float(x) for x in longwave[1]),
        )
    return ClearSky(
        air_temperature_k=float(atm["air_temperature_k"]),
        relative_humidity=float(atm["relative_humidity"]),
        cloud_cover=float(atm.get("cloud_cover", 0.0) or 0.0),
        ground_temperature_k=None if ground_k is None else float(ground_k),
        ground_solar_reflectance=float(ground_albedo),
        **kw,
    )


@dataclass
class Surroundings:
    """What one person's thermal model needs from the world, per radiation sample and frame.

    samples: frame index of each radiation sample (ascending, starting at 0); skies, scenes:
    the ClearSky and the SceneSurfaces (or None) at each sample; air_k, rh, wind: weather per
    frame (frames,) [K, 0-1, m/s].
    """

    samples: list
    skies: list
    scenes: list
    air_k: np.ndarray
    rh: np.ndarray
    wind: np.ndarray
    #: (frames,) compass direction the wind blows from [deg]; None: the person's own motion
    #: is taken as across the wind (speeds add in quadrature)
    wind_direction_deg: np.ndarray | None = None


def human_temperatures(
    stage: Usd.Stage, human: dict, human_path: str, scenario, world: Surroundings, model: str, settings: dict
) -> tuple[dict[str, np.ndarray], dict]:
    """({mesh path: (frames, faces) temperature [K]}, diagnostics) for the body and garments of
    one person; diagnostics: the q_rad method's relative RMS error estimate (per-ray sample
    variance, bare body, first sample), the mean absorbed short wave on the skin at the first
    sample [W m^-2] and the garment balance's largest residual [W m^-2].

    ``stage``: the composed upstream stage (avatar and clothing layers); ``world``: sky, scene
    and weather per sample / frame (:class:`Surroundings`); ``model``: 'jos3' | 'twoNode';
    ``settings``: the scenario's ``[thermal]`` section.
    """
    g = scenario["general"]
    fps, frames = g["fps"], scenario.frame_count
    air, rh, wind = world.air_k, world.rh, world.wind
    body = _part(stage, f"{human_path}/Body", None)
    garments = []
    clothing = stage.GetPrimAtPath(f"{human_path}/Clothing")
    if clothing:
        for child in clothing.GetChildren():
            garments.append(_part(stage, str(child.GetPath()), read_garment(child)))
    parts = [body, *garments]
    diagnostics: dict = {}
    skin_guess = scenario["thermal"]["skin_temperature_k"]
    absorb_body = body.absorptivity()
    method = settings.get("radiation_method", "adaptive")
    qrad = dict(method=method, rays=settings["radiation_rays"])

    # radiation at sample frames (every radiation_step_s), held in between
    samples = list(world.samples)
    # visibility caches: a person who does not move between samples (standing) reuses the
    # rays of the first sample with the new sky and scene radiances
    cache_bare: dict = {}
    cache_clothed: dict = {}
    mrt = np.zeros((len(samples), N_SEGMENTS))
    q_garment = {p.path: np.zeros((len(samples), len(p.counts))) for p in garments}
    q_skin = np.zeros((len(samples), len(body.counts)))  # absorbed by bare skin [W m^-2]
    pts0: list = []
    centres = np.zeros((len(samples), 3))
    for k, frame in enumerate(samples):
        t = Usd.TimeCode(frame)
        sky, scene = world.skies[k], world.scenes[k]
        air_k = float(air[frame])
        pts = [skinned_points(stage, p.path, t, space="world") for p in parts]
        if k == 0:
            pts0 = pts
        centre = centres[k] = pts[0].mean(axis=0)
        env = SR.radiance_map(centre, sky, scene, resolution=settings["radiation_resolution"])
        bare = _trimesh(pts[:1], parts[:1])
        self_bare = _self_radiance([body], skin_guess, air_k)
        stats: dict = {}
        q = Q.absorbed_radiation(
            bare,
            env,
            absorb_body,
            scene=scene,
            seed=g["seed"] + frame,
            mesh_radiance=self_bare,
            stats=stats,
            cache=cache_bare,
            cache_tolerance_m=VISIBILITY_REUSE_M,
            **qrad,
        )
        areas = bare.area_faces
        if k == 0 and method != "brute":
            # Monte Carlo error of the ray methods from the per-ray sample variance (an upper
            # estimate: stratification makes the true error smaller)
            diagnostics["qradRmsRelErrorEstimate"] = stats["rms_rel_error_estimate"]
        if k == 0:
            diagnostics["absorbedShortwaveMean_W_m2"] = float(np.average(q[0], weights=areas))
        mrt[k] = Q.mean_radiant_temperature(q, areas, body.segment[body.tri_face], n_segments=N_SEGMENTS)
        q_skin[k] = _face_mean(body, q.sum(axis=0), areas)
        if garments:
            clothed = _trimesh(pts, parts)
            absorb = np.concatenate(
                [np.repeat(absorb_body[:, None], len(body.triangles), axis=1)]
                + [np.repeat(p.absorptivity()[:, None], len(p.triangles), axis=1) for p in garments],
                axis=1,
            )
            qc = Q.absorbed_radiation(
                clothed,
                env,
                absorb,
                scene=scene,
                seed=g["seed"] + frame,
                mesh_radiance=_self_radiance(parts, skin_guess, air_k),
                cache=cache_clothed,
                cache_tolerance_m=VISIBILITY_REUSE_M,
                **qrad,
            ).sum(axis=0)
            start = len(body.triangles)
            # bare skin among the garments: what it absorbs with the garments' shadows
            q_skin[k] = _face_mean(body, qc[:start], clothed.area_faces[:start])
            for p in garments:
                qt = qc[start : start + len(p.triangles)]
                start += len(p.triangles)
                # area-weighted mean over the triangles of each authored face
                area = clothed.area_faces[start - len(p.triangles) : start]
                q_garment[p.path][k] = np.bincount(p.tri_face, qt * area, len(p.counts)) / np.maximum(
                    np.bincount(p.tri_face, area, len(p.counts)), 1e-12
                )
    # radiation at every frame, linear between the samples (held after the last): no jumps at
    # the sample boundaries (issue 25: walkers' facets jumped up to 7 K once a second)
    at_frames = sample_interpolation(samples, frames)
    q_skin = at_frames(q_skin)
    q_garment = {path: at_frames(q) for path, q in q_garment.items()}

    # physiology over the frames, coupled both ways with the local skin and garment balances
    rate = read_metabolic_rate(stage.GetPrimAtPath(human_path), frames)
    times = np.arange(frames) / fps
    area = _face_area(body, pts0[0])
    cover = _coverage(body, garments, pts0, stage)
    clothes = [_Garment(p, stage, frames, settings, fps) for p in garments]
    clo = garment_clo(body, area, cover, clothes)
    # convection sees the air speed relative to the moving body (walking, running), not the wind
    wind = relative_air_speed(
        body_velocity(stage, body, samples, centres, frames, fps), wind, world.wind_direction_deg
    )
    diagnostics["relativeAirSpeedMean_m_s"] = float(np.mean(wind))
    convection = settings["convection_model"]
    eps_skin = longwave_emissivity(body.material)
    transient = settings.get("garment_transient", "transient") == "transient"

    def fluxes(t_faces, slope=True):
        """Sensible loss of every skin facet [W m^-2] at skin ``t_faces`` (frames, F), its slope
        dq/dT and the garments' outer temperatures and largest residual."""
        sigma_eps = eps_skin * STEFAN_BOLTZMANN
        # forced convection, with ISO 7730's natural-convection floor 2.38 |T_sk - T_a|^0.25
        # for bare skin in calm air (a 33 degC facet in still 16 degC air: h = 4.8 W m^-2 K^-1)
        h_skin = convective_coefficient(wind[:, None], t_faces - air[:, None], model=convection)
        q = h_skin * (t_faces - air[:, None]) + sigma_eps * t_faces**4 - q_skin
        g = h_skin + 4.0 * sigma_eps * t_faces**3
        temps, worst = {}, 0.0
        for gi, c in enumerate(clothes):
            skin_g = t_faces[:, cover.under[gi]]
            q_abs = q_garment[c.part.path]
            t_out, q_in, res = c.series(skin_g, air, q_abs, wind, transient)
            temps[c.part.path], worst = t_out, max(worst, res)
            sel = cover.garment == gi
            q[:, sel] = q_in[:, cover.face[sel]]
            if slope:
                q_in2 = c.series(skin_g + SLOPE_STEP_K, air, q_abs, wind, transient)[1]
                g[:, sel] = ((q_in2 - q_in) / SLOPE_STEP_K)[:, cover.face[sel]]
        return q, g, temps, worst

    seg_area = np.bincount(body.segment, area, N_SEGMENTS)
    two_node = MODEL_NAMES[model] == "two_node"
    mrt = at_frames(mrt)
    tr_eff = np.where(np.isnan(mrt), air[:, None], mrt)
    t_lin = None
    for iteration in range(1, COUPLING_MAX_ITERATIONS + 1):
        diagnostics["couplingIterations"] = iteration
        result = simulate_physiology(
            times,
            rate,
            air,
            tr_eff.mean(axis=1) if two_node else tr_eff,
            rh,
            np.maximum(wind, 0.1),
            _area_mean(clo, seg_area) if two_node else clo,
            model=MODEL_NAMES[model],
            height_m=human["stature_m"],
            mass_kg=human["mass_kg"],
            age_years=human["age_yr"],
            sex=human["sex"],
            fitness=human["fitness"],
            spin_up_s=settings["spin_up_s"],
        )
        skin = np.asarray(result.segment_skin_temperature_k)  # (frames, 17)
        if t_lin is None:
            t_lin = skin[:, body.segment]
            q_lin, g_lin, _, _ = fluxes(t_lin)
        t_face = skin[:, body.segment].copy()
        for f in range(frames if settings.get("skin_detail", "facet") == "facet" else 0):
            t_face[f] = local_skin_temperature(
                skin[f],
                result.segment_skin_conductance_w_m2_k[f],
                result.segment_latent_w_m2[f],
                body.segment,
                area,
                q_lin[f],
                g_lin[f],
                t_lin[f],
                segment_core_k=result.segment_core_temperature_k[f],
            )[0]
        if frames > 1 and settings.get("skin_detail", "facet") == "facet":
            t_face = lagged_skin(
                t_face,
                skin,
                result.segment_skin_capacity_j_m2_k,
                np.asarray(result.segment_skin_conductance_w_m2_k)[:, body.segment] + np.maximum(g_lin, 0.0),
                1.0 / fps,
                body.segment,
                area,
                result.segment_core_temperature_k,
            )
        # the slope of the first linearisation is kept (a chord iteration: the fluxes
        # themselves are exact at every iterate)
        q_face, _, garment_temps, garment_residual = fluxes(t_face, slope=False)
        q_seg = np.stack([np.bincount(body.segment, area * q_face[f], N_SEGMENTS) for f in range(frames)])
        q_seg = q_seg / np.maximum(seg_area, 1e-12)
        sensible = np.asarray(result.segment_sensible_w_m2)
        if two_node:  # one skin node: the body's area-weighted flux is what the model can match
            q_seg = np.repeat(_area_mean(q_seg, seg_area)[:, None], N_SEGMENTS, axis=1)
        present = seg_area > 0
        residual = np.abs(q_seg - sensible)[:, present].max()
        if residual <= COUPLING_TOLERANCE_W_M2:
            break
        tr_eff = radiant_temperature_for_sensible_loss(
            skin,
            q_seg,
            air[:, None],
            result.segment_hc_w_m2_k,
            result.segment_hr_w_m2_k,
            result.segment_dry_resistance_m2_k_w,
        )
        t_lin, q_lin = t_face, q_face
    diagnostics["couplingMaxResidual_W_m2"] = float(residual)
    # the physiological bound (issue 25): the hottest skin facet against its segment's core
    core = np.asarray(result.segment_core_temperature_k)[:, body.segment]
    diagnostics["skinMax_K"] = float(t_face.max())
    diagnostics["skinMinusSegmentCoreMax_K"] = float((t_face - core).max())
    if garments:
        diagnostics["garmentMaxResidual_W_m2"] = float(garment_residual)
    out = {body.path: t_face, **garment_temps}
    return out, diagnostics


#: Largest |skin-side garment + bare-skin flux - physiology sensible loss| per segment [W m^-2]
#: at which the body-clothing coupling stops (issue 14: within 1 W m^-2).
COUPLING_TOLERANCE_W_M2 = 0.5
COUPLING_MAX_ITERATIONS = 20
#: Skin temperature step [K] of the finite-difference slope of the garments' skin-side flux.
SLOPE_STEP_K = 0.25
#: A body facet is under a garment when the nearest garment face centre is within that face's
#: air gap + fabric thickness + this margin [m] (the centres of a fitted garment's faces and the
#: body's are not aligned).
COVER_MARGIN_M = 0.015


def sample_interpolation(samples: list, frames: int):
    """A function taking (S, ...) values at the radiation sample frames to (frames, ...): linear
    in time between samples, held after the last."""
    s = np.asarray(samples, dtype=float)
    f = np.arange(frames, dtype=float)
    i0 = np.clip(np.searchsorted(s, f, side="right") - 1, 0, len(s) - 1)
    i1 = np.minimum(i0 + 1, len(s) - 1)
    w1 = np.where(i1 > i0, (f - s[i0]) / np.where(i1 > i0, s[i1] - s[i0], 1.0), 0.0)

    def at_frames(values: np.ndarray) -> np.ndarray:
        v = np.asarray(values, dtype=float)
        w = w1.reshape((-1,) + (1,) * (v.ndim - 1))
        return (1.0 - w) * v[i0] + w * v[i1]

    return at_frames


def body_velocity(
    stage: Usd.Stage, body: _Part, samples: list, centres: np.ndarray, frames: int, fps: float
) -> np.ndarray:
    """(frames, 3) velocity of the body over the ground [m/s]: the displacement of the skinned
    body's centroid between radiation samples (one frame apart when there is one sample and
    more frames), linearly interpolated to every frame; zero for a one-frame scenario."""
    if frames < 2:
        return np.zeros((frames, 3))
    times, points = list(samples), list(centres)
    if len(times) < 2:
        times.append(1)
        points.append(skinned_points(stage, body.path, Usd.TimeCode(1), space="world").mean(axis=0))
    t = np.asarray(times, dtype=float) / fps
    c = np.asarray(points)
    v = np.diff(c, axis=0) / np.diff(t)[:, None]
    mid = 0.5 * (t[1:] + t[:-1])
    f = np.arange(frames) / fps
    return np.stack([np.interp(f, mid, v[:, i]) for i in range(3)], axis=1)


def _face_mean(part: _Part, per_triangle: np.ndarray, tri_area: np.ndarray) -> np.ndarray:
    """Area-weighted mean over the triangles of each authored face of ``part``."""
    n = len(part.counts)
    return np.bincount(part.tri_face, per_triangle * tri_area, n) / np.maximum(
        np.bincount(part.tri_face, tri_area, n), 1e-12
    )


def _face_area(part: _Part, points: np.ndarray) -> np.ndarray:
    """(F,) area [m^2] of each authored face at ``points``."""
    a, b, c = (points[part.triangles[:, i]] for i in range(3))
    tri = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return np.bincount(part.tri_face, tri, len(part.counts))


def _face_centres(part: _Part, points: np.ndarray) -> np.ndarray:
    starts = np.concatenate([[0], np.cumsum(part.counts)[:-1]])
    return np.add.reduceat(points[part.indices], starts, axis=0) / part.counts[:, None]


def _area_mean(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted mean over the last axis."""
    return (values * weights).sum(axis=-1) / weights.sum()


@dataclass
class _Coverage:
    garment: np.ndarray  # (F_body,) index into garments covering each body face, -1 bare
    face: np.ndarray  # (F_body,) the covering garment face
    under: list  # per garment: (F_g,) the body face under each garment face


def _coverage(body: _Part, garments: list[_Part], points: list, stage: Usd.Stage) -> _Coverage:
    """Which garment face covers each body face, and which body face lies under each garment
    face, from the face centres at the first radiation sample (nearest neighbours; a body face
    is covered when the garment face is within its air gap + thickness + COVER_MARGIN_M)."""
    from scipy.spatial import cKDTree

    centres = _face_centres(body, points[0])
    tree = cKDTree(centres)
    n = len(body.counts)
    garment, face, best = np.full(n, -1), np.zeros(n, dtype=np.int64), np.full(n, np.inf)
    under = []
    for gi, p in enumerate(garments):
        gc = _face_centres(p, points[gi + 1])
        under.append(tree.query(gc)[1])
        starts = np.concatenate([[0], np.cumsum(p.counts)[:-1]])
        gap = np.add.reduceat(read_air_gap(stage.GetPrimAtPath(p.path), 0)[p.indices], starts) / p.counts
        reach = gap + p.material.require("thickness", p.path) + COVER_MARGIN_M
        d, j = cKDTree(gc).query(centres)
        take = (d <= reach[j]) & (d < best)
        garment[take], face[take], best[take] = gi, j[take], d[take]
    return _Coverage(garment, face, under)


class _Garment:
    """One garment's fabric, air gaps per frame and its balance over a skin temperature series."""

    def __init__(self, part: _Part, stage: Usd.Stage, frames: int, settings: dict, fps: float):
        self.part = part
        self.fabric = {
            k: part.material.require(k, part.path)
            for k in ("conductivity", "density", "specific_heat", "thickness")
        }
        self.eps = longwave_emissivity(part.material)
        self.heat_capacity = areal_heat_capacity(
            self.fabric["density"], self.fabric["specific_heat"], self.fabric["thickness"]
        )
        prim = stage.GetPrimAtPath(part.path)
        starts = np.concatenate([[0], np.cumsum(part.counts)[:-1]])
        self.gap = np.stack(
            [
                np.add.reduceat(read_air_gap(prim, f)[part.indices], starts) / part.counts
                for f in range(frames)
            ]
        )
        self.convection = settings["convection_model"]
        self.dt = 1.0 / float(fps)

    def series(self, skin, air, q_abs, wind, transient: bool):
        """(outer temperature, skin-side flux q_in, largest |residual|) per frame and face for
        the skin temperature ``skin`` (frames, F_g): steady state at frame 0, then implicit steps
        with the fabric's heat capacity (or steady at every frame)."""
        frames = len(skin)
        t_out, q_in, worst = np.zeros_like(skin), np.zeros_like(skin), 0.0
        kw = dict(fabric_conductivity=self.fabric["conductivity"], fabric_emissivity=self.eps)
        for f in range(frames):
            h = convective_coefficient(wind[f], model=self.convection)
            args = (skin[f], air[f], q_abs[f], h, self.gap[f], self.fabric["thickness"])
            if f == 0 or not transient:
                b = steady_state(*args, **kw)
            else:
                b = transient_step(t_out[f - 1], self.dt, self.heat_capacity, *args, **kw)
            t_out[f], q_in[f] = b.outer_temperature_k, b.q_in
            worst = max(worst, float(np.abs(b.residual).max()))
        return t_out, q_in, worst


def garment_clo(body: _Part, area: np.ndarray, cover: _Coverage, clothes: list) -> np.ndarray:
    """(17,) intrinsic clothing insulation per JOS-3 segment [clo] from the garments themselves:
    per covered body face the air gap's and the fabric's resistance in series,
    R = 1 / (k_air / d + 4 F sigma T^3) + l / k_f (still air, grey-plate radiation at 306 K, F
    for skin 0.98 and the fabric's emissivity), averaged over the segment's area with bare faces
    at 0 (the area-weighted local insulation of ISO 9920:2007 Annex A), 1 clo = 0.155 m^2 K W^-1."""
    resistance = np.zeros(len(body.counts))
    for gi, c in enumerate(clothes):
        sel = cover.garment == gi
        d = np.maximum(c.gap[0][cover.face[sel]], 1e-4)
        f_rad = grey_plates_exchange_factor(0.98, c.eps)
        h_gap = air_conductivity(306.0) / d + 4.0 * f_rad * STEFAN_BOLTZMANN * 306.0**3
        resistance[sel] = 1.0 / h_gap + c.fabric["thickness"] / c.fabric["conductivity"]
    seg_area = np.bincount(body.segment, area, N_SEGMENTS)
    return np.bincount(body.segment, area * resistance, N_SEGMENTS) / np.maximum(seg_area, 1e-12) / 0.155
