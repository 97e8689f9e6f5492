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

from humv_usd.catalog.garments import HAIR_GARMENTS
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.human import labels as L
from humv_usd.human.usdskel import skinned_points
from humv_usd.physics.convection import (
    convective_coefficient,
    natural_iso7730,
    relative_air_velocity,
    windward_ratio,
)
from humv_usd.physics.garment import (
    air_conductivity,
    areal_heat_capacity,
    grey_plates_exchange_factor,
    stack_steady_state,
    stack_transient_step,
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
from humv_usd.usd.sensor import stage_sensors

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
    one person; diagnostics: the q_rad method's relative RMS error (measured by replicates,
    bare body, first sample), the faces' temperature noise from it (per person and per mesh,
    :func:`_face_temperature_noise`), the mean absorbed short wave on the skin at the first
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
    # hair alone (no garment): the body keeps its own q_rad pass and the hair faces get theirs
    # (:data:`HAIR_ONLY_PASS`), instead of a second pass over the whole clothed person
    hair_only = HAIR_ONLY_PASS and bool(garments) and all(p.garment in CLOSE_HAIR for p in garments)
    own_pass = not garments or hair_only  # the body's pass takes the ray budget and the replicates
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
    normals = np.zeros((len(samples), len(body.counts), 3))  # body face normals per sample
    q_var = None  # the q_rad rays' variance per triangle [W^2 m^-4] (body, then garments; sample 0)
    for k, frame in enumerate(samples):
        t = Usd.TimeCode(frame)
        sky, scene = world.skies[k], world.scenes[k]
        air_k = float(air[frame])
        pts = [skinned_points(stage, p.path, t, space="world") for p in parts]
        if k == 0:
            pts0 = pts
            cover = _coverage(body, garments, pts0, stage)  # once: the balance below uses it too
            seen = _visible_faces(cover, garments, pts0, stage)
            # once, so that the visibility caches' keys (which hold it) stay valid
            importance = _ray_importance(parts, pts0, seen)
        centre = centres[k] = pts[0].mean(axis=0)
        env = SR.radiance_map(centre, sky, scene, resolution=settings["radiation_resolution"])
        bare = _trimesh(pts[:1], parts[:1])
        normals[k] = _face_normals(body, bare)
        self_bare = _self_radiance([body], skin_guess, air_k)
        stats: dict = {}
        # with garments the bare body's rays feed only the segments' mean radiant temperature
        # (area means over hundreds of facets: their noise averages out); the face
        # temperatures take the clothed call's, which gets the ray budget
        bare_qrad = qrad if own_pass or method == "brute" else dict(qrad, rays=BARE_MRT_RAYS)
        q = Q.absorbed_radiation(
            bare,
            env,
            absorb_body,
            replicate_facets=_replicate_facets(parts[:1], seen[:1], g["seed"]) if k == 0 and own_pass else 0,
            scene=scene,
            seed=g["seed"] + frame,
            mesh_radiance=self_bare,
            stats=stats,
            cache=cache_bare,
            cache_tolerance_m=VISIBILITY_REUSE_M,
            importance=importance[: len(body.triangles)] if own_pass else None,
            **bare_qrad,
        )
        areas = bare.area_faces
        if k == 0 and method != "brute" and own_pass:
            # Monte Carlo error of the ray methods, measured by independent replicates on
            # random facets (qrad.absorbed_radiation's stats)
            diagnostics["qradRmsRelErrorEstimate"] = stats["rms_rel_error_estimate"]
            q_var = _part_variance(stats, parts[:1])
        if k == 0:
            diagnostics["absorbedShortwaveMean_W_m2"] = float(np.average(q[0], weights=areas))
        mrt[k] = Q.mean_radiant_temperature(q, areas, body.segment[body.tri_face], n_segments=N_SEGMENTS)
        q_skin[k] = _face_mean(body, q.sum(axis=0), areas)
        if hair_only:
            q_hair = _hair_radiation(pts, parts, env, scene, bare, self_bare, skin_guess, air_k)
            stats_h: dict = {}
            qh = q_hair(
                seed=g["seed"] + frame,
                stats=stats_h if k == 0 and method != "brute" else None,
                replicate_facets=_replicate_facets(garments, seen[1:], g["seed"]) if k == 0 else 0,
                importance=importance[len(body.triangles) :],
                cache=cache_clothed,
                cache_tolerance_m=VISIBILITY_REUSE_M,
                **qrad,
            )
            if k == 0 and method != "brute":
                q_var = np.concatenate([q_var, _part_variance(stats_h, garments)])
                # the RMS over all the person's facets (body and hair) of the two passes' errors
                n_b, n_h = len(body.triangles), len(qh)
                diagnostics["qradRmsRelErrorEstimate"] = float(
                    np.sqrt(
                        (
                            n_b * diagnostics["qradRmsRelErrorEstimate"] ** 2
                            + n_h * stats_h["rms_rel_error_estimate"] ** 2
                        )
                        / (n_b + n_h)
                    )
                )
            start = 0
            for p in garments:
                qt, area = qh[start : start + len(p.triangles)], q_hair.area[start : start + len(p.triangles)]
                start += len(p.triangles)
                q_garment[p.path][k] = np.bincount(p.tri_face, qt * area, len(p.counts)) / np.maximum(
                    np.bincount(p.tri_face, area, len(p.counts)), 1e-12
                )
        elif garments:
            clothed = _trimesh(pts, parts)
            absorb = np.concatenate(
                [np.repeat(absorb_body[:, None], len(body.triangles), axis=1)]
                + [np.repeat(p.absorptivity()[:, None], len(p.triangles), axis=1) for p in garments],
                axis=1,
            )
            stats_c: dict = {}
            qc = Q.absorbed_radiation(
                clothed,
                env,
                absorb,
                scene=scene,
                seed=g["seed"] + frame,
                mesh_radiance=_self_radiance(parts, skin_guess, air_k),
                stats=stats_c if k == 0 and method != "brute" else None,
                replicate_facets=_replicate_facets(parts, seen, g["seed"]) if k == 0 else 0,
                # the rays go where the flux is used: bare skin and the outer garment layers
                # (skin under a garment and inner layers take the stacks' balance instead),
                # weighted by the faces' area and temperature response
                importance=importance,
                cache=cache_clothed,
                cache_tolerance_m=VISIBILITY_REUSE_M,
                **qrad,
            ).sum(axis=0)
            if k == 0 and method != "brute":
                q_var = _part_variance(stats_c, parts)  # the skin and garments among the garments
                diagnostics["qradRmsRelErrorEstimate"] = stats_c["rms_rel_error_estimate"]
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
    clothes = [_Garment(p, stage, frames) for p in garments]
    wardrobe = _Wardrobe(clothes, cover.under, pts0, settings, fps) if garments else None
    clo = garment_clo(body, area, cover, wardrobe)
    q_garment_all = np.concatenate([q_garment[p.path] for p in garments], axis=1) if garments else None
    # convection sees the air speed relative to the moving body (walking, running), not the wind
    air_velocity = relative_air_velocity(
        body_velocity(stage, body, samples, centres, frames, fps), wind, world.wind_direction_deg
    )
    wind = np.linalg.norm(air_velocity, axis=-1)
    diagnostics["relativeAirSpeedMean_m_s"] = float(np.mean(wind))
    convection = settings["convection_model"]
    # windward facets lose more by forced convection than the sides and the lee (per segment
    # the mean coefficient is the correlation's)
    windward = at_frames(
        np.stack(
            [
                _windward_ratio(normals[k], air_velocity[frame], body.segment, area)
                for k, frame in enumerate(samples)
            ]
        )
    )
    eps_skin = longwave_emissivity(body.material)
    transient = settings.get("garment_transient", "transient") == "transient"

    def fluxes(t_faces, slope=True):
        """Sensible loss of every skin facet [W m^-2] at skin ``t_faces`` (frames, F), its slope
        dq/dT and the garments' outer temperatures and largest residual."""
        sigma_eps = eps_skin * STEFAN_BOLTZMANN
        # forced convection, with ISO 7730's natural-convection floor 2.38 |T_sk - T_a|^0.25
        # for bare skin in calm air (a 33 degC facet in still 16 degC air: h = 4.8 W m^-2 K^-1)
        forced = convective_coefficient(wind[:, None], 0.0, model=convection) * windward
        h_skin = np.maximum(forced, natural_iso7730(t_faces - air[:, None]))
        q = h_skin * (t_faces - air[:, None]) + sigma_eps * t_faces**4 - q_skin
        g = h_skin + 4.0 * sigma_eps * t_faces**3
        if not garments:
            return q, g, {}, 0.0
        # sweat wicked into a garment worn on the skin: the segment's wettedness, at most its
        # latent loss (the physiology of the current coupling iteration)
        wet = limit = None
        if result.wettedness is not None:
            seg = body.segment[wardrobe.under]
            wet = np.clip(np.asarray(result.wettedness)[:, seg], 0.0, 1.0)
            limit = np.maximum(np.asarray(result.segment_latent_w_m2)[:, seg], 0.0)
        args = (air, q_garment_all, wind, rh, transient, wet, limit)
        # with the slope: the stacks at t_faces and t_faces + SLOPE_STEP_K in the same calls
        t_out, q_in, worst, *q_in2 = wardrobe.series(
            t_faces, *args, skin_step=SLOPE_STEP_K if slope else None
        )
        covered = cover.garment >= 0
        cover_face = wardrobe.offset[cover.garment[covered]] + cover.face[covered]
        q[:, covered] = q_in[:, cover_face]
        if slope:
            g[:, covered] = ((q_in2[0] - q_in) / SLOPE_STEP_K)[:, cover_face]
        return q, g, wardrobe.split(t_out), worst

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
            # JOS-3 gets the person's own body fat (Deurenberg et al. 1991 from BMI, age and sex:
            # the avatar's density model), not its 15 % reference man (thermal VERSION 10)
            **({} if two_node else {"body_fat_percent": None}),
        )
        skin = np.asarray(result.segment_skin_temperature_k)  # (frames, 17)
        if t_lin is None:
            t_lin = skin[:, body.segment]
            q_lin, g_lin, _, _ = fluxes(t_lin)
        t_face = skin[:, body.segment].copy()
        if settings.get("skin_detail", "facet") == "facet":  # all frames in one call
            t_face = local_skin_temperature(
                skin,
                result.segment_skin_conductance_w_m2_k,
                result.segment_latent_w_m2,
                body.segment,
                area,
                q_lin,
                g_lin,
                t_lin,
                segment_core_k=result.segment_core_temperature_k,
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
    if q_var is not None:
        noise = _face_temperature_noise(
            q_var,
            [body, *garments],
            pts0,
            np.asarray(result.segment_skin_conductance_w_m2_k)[0][body.segment] + g_lin[0],
            seen,
            wardrobe,
            garment_response=None
            if not garments
            else lambda: _garment_response(
                wardrobe, t_face[:1], air[:1], q_garment_all[:1], wind[:1], rh[:1], transient
            ),
        )
        diagnostics.update(noise)
    # the physiological bound (issue 25): the hottest skin facet against its segment's core
    core = np.asarray(result.segment_core_temperature_k)[:, body.segment]
    diagnostics["skinMax_K"] = float(t_face.max())
    diagnostics["skinMinusSegmentCoreMax_K"] = float((t_face - core).max())
    if garments:
        diagnostics["garmentMaxResidual_W_m2"] = float(garment_residual)
        # sweat evaporating from garments worn on the skin (issue 25: wet fabric)
        diagnostics["garmentEvaporationMax_W_m2"] = float(wardrobe.evaporation_max)
    out = {body.path: t_face, **garment_temps}
    return out, diagnostics


#: A wardrobe of hair alone (:data:`humv_usd.catalog.garments.HAIR_GARMENTS`, e.g. the default
#: ``hair_short`` of a person with no ``clothing`` key) takes :func:`_hair_radiation` instead of
#: the second q_rad pass over the whole clothed person (issue 29.2: that pass made hair cost
#: +2.2 of 8.6 CPU-s of a 31-frame JOS-3 walker's thermal layer).
HAIR_ONLY_PASS = True
#: The hair styles that stay on the head and neck, for which :func:`_hair_radiation` holds;
#: long hair alone takes the full clothed pass: it hangs 2-4 cm off the back, shoulders and face
#: and shades them (without its shadow 86 of 13,378 body faces of a JOS-3 walker moved by more
#: than 1 K, up to 6.7 K; hair_tied: 3 faces at the nape, up to 5.9 K; hair_short: none > 0.3 K)
CLOSE_HAIR = tuple(g for g in HAIR_GARMENTS if g != "hair_long")


def _hair_radiation(pts, parts, env, scene, bare, self_bare, skin_k: float, air_k: float):
    """q_rad of the hair faces alone (``parts[1:]``, all hair): a callable taking
    :func:`humv_usd.thermal.qrad.absorbed_radiation`'s ray settings and returning (triangles,)
    [W m^-2] summed over the bands, with ``.area`` the triangles' areas.

    The hair's rays see the body (``bare``, at its first-guess leaving radiance ``self_bare``)
    and the scene as occluders, the hair itself as the clothed pass does; the body's own pass
    (the caller's) ignores the hair. Neglected against the full clothed pass: the hair's shadow
    and long-wave exchange on the bare skin beside it (a fringe on the forehead, long hair on
    the neck); skin under the hair takes the hair stack's balance either way. Measured on a
    JOS-3 walker (``/work/notes/s8/people.md``)."""
    hair = _trimesh(pts[1:], parts[1:])
    garments = parts[1:]
    if scene is not None and len(scene.mesh.faces):
        occluders = SR.SceneSurfaces(
            trimesh.util.concatenate([scene.mesh, bare]),
            np.concatenate([np.asarray(scene.radiance, dtype=float), self_bare], axis=1),
        )
    else:
        occluders = SR.SceneSurfaces(bare, self_bare)
    absorb = np.concatenate(
        [np.repeat(p.absorptivity()[:, None], len(p.triangles), axis=1) for p in garments], axis=1
    )

    def run(**settings) -> np.ndarray:
        return Q.absorbed_radiation(
            hair,
            env,
            absorb,
            scene=occluders,
            mesh_radiance=_self_radiance(garments, skin_k, air_k),
            **settings,
        ).sum(axis=0)

    run.area = hair.area_faces
    return run


#: Rays per facet of a clothed person's bare-body q_rad, which feeds only the segments' mean
#: radiant temperature (the adaptive method's pilot: no second stage).
BARE_MRT_RAYS = 16

#: Typical response dT/dq [K m^2 W^-1] of a visible face's temperature to its absorbed flux,
#: only to spread the q_rad rays (:func:`_ray_importance`; the estimate and its stated error do
#: not depend on it): bare skin 1 / (dq/dT + the skin's conductance to the core), a garment's
#: outer face the stack's dT/dq (:func:`_garment_response`); medians over the demo person's
#: visible faces 0.022 and 0.035 (cap 0.039, shoes 0.033).
SKIN_RESPONSE_K_M2_W = 0.022
GARMENT_RESPONSE_K_M2_W = 0.035


def _ray_importance(parts, points, visible) -> np.ndarray:
    """(triangles,) weight of each triangle's q_rad variance in the person's face-temperature
    error (qrad.absorbed_radiation's ``importance``): a face f of area A_f made of triangles of
    areas a_t has the temperature variance r^2 sum_t (a_t / A_f)^2 Var(q_t), r its response
    (:data:`SKIN_RESPONSE_K_M2_W`, :data:`GARMENT_RESPONSE_K_M2_W`); its pixels in an image
    are ~ A_f, so the area-weighted error that the rays should minimise is
    sum_t r^2 a_t^2 / A_f Var(q_t). Hidden faces (``visible`` False) weigh 0. Scaled to a mean
    of 1 over the weighted triangles."""
    out = []
    for part, pts, seen in zip(parts, points, visible):
        a, b, c = (pts[part.triangles[:, i]] for i in range(3))
        tri = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
        face = np.bincount(part.tri_face, tri, len(part.counts))
        r = SKIN_RESPONSE_K_M2_W if part.garment is None else GARMENT_RESPONSE_K_M2_W
        w = r**2 * tri**2 / np.maximum(face[part.tri_face], 1e-300)
        out.append(np.where(seen[part.tri_face], w, 0.0))
    w = np.concatenate(out)
    mean = float(w[w > 0].mean()) if np.any(w > 0) else 1.0
    return w / mean


#: ``[thermal] radiation_rays`` when not given (:func:`auto_radiation_rays`): the rays of an
#: LWIR camera's person (NETD 50 mK), and the fewest the rule gives
AUTO_RAYS_BASE = 192
#: the thermal layer's noise per person pixel at :data:`AUTO_RAYS_BASE` rays [K], as the render
#: states it through its smooth shading (``geometry.shading.smooth_noise``): the demo person
#: 8.8-9.3 mK in lwir640 and mwir_insb (measured by two q_rad seeds: 7.3-7.6 mK; s8 qrad-noise)
AUTO_PIXEL_NOISE_K = 0.009
#: the share of the person's target (NETD/3) that the render's own error takes at the automatic
#: quality (demo: 11.9 / 16.7 mK lwir640, 3.9 / 6.7 mK mwir_insb; the boosts aim each pixel at the
#: target, the person's mean lands at ~0.6-0.7 of it), rounded up for the spread of the per-pixel
#: errors (the mean of the pixels' totals is above the total of the means): with 0.6 the demo's
#: mwir_insb got 547 rays and a person total of 6.663 mK against 6.667, with 0.7 687 rays and
#: 6.64 mK (its per-pixel thermal noise 4.93 and 4.88 mK: the stated figure is itself a
#: replicate estimate, +-10 %)
AUTO_RENDER_SHARE = 0.75
#: most rays per facet the rule asks for (the scenario key's upper bound)
AUTO_RAYS_MAX = 4096


def auto_radiation_rays(stage) -> tuple[int, float | None]:
    """q_rad rays per facet for a scenario that does not give ``[thermal] radiation_rays``, from
    the thermal cameras of ``stage`` (its sensors layer), and the NETD [K] that set them (None:
    no thermal camera).

    The person's total error per pixel is the render's and the thermal layer's in quadrature
    (:func:`humv_usd.render.quality.combine_error`), and its target is NETD/3 (issue 25.3). With
    the render taking :data:`AUTO_RENDER_SHARE` s of the target, the layer may add
    sqrt(1 - s^2) NETD/3; its noise falls as 1/sqrt(rays) (Monte Carlo), from
    :data:`AUTO_PIXEL_NOISE_K` at :data:`AUTO_RAYS_BASE` rays, so the most demanding camera (the
    smallest NETD) needs AUTO_RAYS_BASE (AUTO_PIXEL_NOISE_K / (sqrt(1 - s^2) NETD/3))^2 rays, and
    never fewer than AUTO_RAYS_BASE: 192 for LWIR cameras of NETD 50 mK (needing 128), 800 for a
    cooled MWIR camera of NETD 20 mK (the demo's mwir_insb: 547 rays gave a person total of
    6.663 mK against its 6.667, 687 rays 6.64 mK, 800 rays 6.14 mK). The noise per pixel is the
    demo's; another scene's differs, and the render states what it is (``total_error_mean_k``
    per region), so a miss shows."""
    netds = [
        float(s.netd_k)
        for s in stage_sensors(stage)
        if not s.skip_reason and s.kind != "EO" and not s.is_reflective and s.netd_k and s.netd_k > 0
    ]
    if not netds:
        return AUTO_RAYS_BASE, None
    netd = min(netds)
    allowed = np.sqrt(1.0 - AUTO_RENDER_SHARE**2) * netd / 3.0
    rays = AUTO_RAYS_BASE * (AUTO_PIXEL_NOISE_K / allowed) ** 2
    return int(min(max(np.ceil(rays), AUTO_RAYS_BASE), AUTO_RAYS_MAX)), netd


#: triangles per part (body, each garment) whose q_rad is estimated a second time with
#: independent rays, to measure the rays' real error (qrad's replicates)
REPLICATES_PER_PART = 256


def _visible_faces(cover: _Coverage, garments: list[_Part], points: list, stage: Usd.Stage) -> list:
    """Per part (body, then garments) the faces a camera can see, at the first radiation
    sample: bare skin (no garment face over it in ``cover``, :func:`_coverage`) and the
    outermost layer of each garment stack (:func:`_layer_links`)."""
    out = [cover.garment < 0]
    if garments:
        _, above = _layer_links([_Garment(p, stage, 1) for p in garments], points)
        out += [a[:, 0] < 0 for a in above]
    return out


def _replicate_facets(parts, visible, seed) -> np.ndarray:
    """Triangle indices (into the parts' concatenated triangles) drawn per part for qrad's
    replicate error estimate: up to REPLICATES_PER_PART of each part's visible faces
    (``visible``: per part, per face), so that small garments get their own measured error
    and hidden faces (skin under a shirt, a shirt under a jacket), whose rays stratify
    differently, do not set it."""
    rng = np.random.default_rng([int(seed), 25])
    out, start = [], 0
    for part, seen in zip(parts, visible):
        pool = np.flatnonzero(seen[part.tri_face])
        if len(pool) == 0:
            pool = np.arange(len(part.triangles))
        out.append(start + rng.choice(pool, size=min(len(pool), REPLICATES_PER_PART), replace=False))
        start += len(part.triangles)
    return np.sort(np.concatenate(out))


def _part_variance(stats: dict, parts) -> np.ndarray:
    """Per triangle q_rad variance [W^2 m^-4]: the per-ray sample variance scaled, part by part,
    by the ratio of the variance measured by the replicates to the per-ray one on that part's
    replicated triangles (stratification gains differ between the open body and a garment
    folded over it); the whole mesh's ratio where a part has no replicate."""
    if "replicate_facets" not in stats:
        return np.asarray(stats["variance"], dtype=float)
    per_ray = stats["per_ray_variance"]
    facets, measured = stats["replicate_facets"], stats["replicate_variance"]
    out = np.array(stats["variance"], dtype=float)
    start = 0
    for part in parts:
        stop = start + len(part.triangles)
        inside = (facets >= start) & (facets < stop)
        denominator = float(per_ray[facets[inside]].sum())
        if np.any(inside) and denominator > 0:
            out[start:stop] = per_ray[start:stop] * float(measured[inside].sum()) / denominator
        start = stop
    return out


#: absorbed-flux step [W m^-2] of the garments' finite-difference temperature response
RESPONSE_STEP_W_M2 = 1.0


def _garment_response(wardrobe, skin, air, q_abs, wind, rh, transient) -> np.ndarray:
    """(N,) d T_outer / d q_abs [K m^2 W^-1] of every garment face at the first frame (steady
    there), by a finite difference of the stacks' balance; 0 for a face under another layer
    (only the outermost layer of a stack absorbs its own flux)."""
    evaporation_max = wardrobe.evaporation_max  # series() records it: keep the real run's
    t0 = wardrobe.series(skin, air, q_abs, wind, rh, transient)[0][0]
    t1 = wardrobe.series(skin, air, q_abs + RESPONSE_STEP_W_M2, wind, rh, transient)[0][0]
    wardrobe.evaporation_max = evaporation_max
    return (t1 - t0) / RESPONSE_STEP_W_M2


#: key of :func:`_face_temperature_noise`'s per-face arrays in the diagnostics (the layer takes
#: them out of its report and writes them per mesh)
FACE_NOISE = "_faceTemperatureNoise_K"


def _face_temperature_noise(q_var, parts, points, skin_g, visible, wardrobe, garment_response=None) -> dict:
    """The faces' temperature noise from the q_rad rays' noise (issue 25: the render adds it to
    its stated error), at the first frame: per authored face the variance of its triangles'
    area-weighted mean flux, then sigma_T = sigma_q / (dq/dT + the skin's conductance to the
    core) on bare skin (``skin_g``: that sum per body face) and sigma_T = sigma_q |dT/dq| on a
    garment's outer faces (``garment_response``: a callable giving the stacks' response).
    Only the ``visible`` faces (per part) count: skin under a garment and a garment under
    another are not seen.

    Returns {faceTemperatureNoiseRms_K: area-weighted RMS over the visible faces of the
    person, faceTemperatureNoiseRmsByMesh_K: {mesh path: RMS over its visible faces},
    FACE_NOISE: {mesh path: (faces,) sigma_T of every face [K]}} (the last for the layer's
    per-face primvar, :func:`humv_usd.usd.thermal.write_face_temperature_noise`: the render
    propagates each face's own noise through its smooth shading)."""
    by_mesh: dict[str, float] = {}
    per_face: dict[str, np.ndarray] = {}
    sq, weights = [], []
    start = 0
    response = garment_response() if garment_response is not None else None
    for i, part in enumerate(parts):
        tri = trimesh.Trimesh(points[i], part.triangles, process=False).area_faces
        n_t = len(part.triangles)
        var_t = np.asarray(q_var[start : start + n_t], dtype=float)
        start += n_t
        n_f = len(part.counts)
        a_face = np.bincount(part.tri_face, tri, n_f)
        # a face of zero area (degenerate triangles) has no flux noise: 0/0 was NaN (and a warning)
        area2 = a_face**2
        var_face = np.divide(
            np.bincount(part.tri_face, tri**2 * var_t, n_f), area2, out=np.zeros(n_f), where=area2 > 0
        )
        if i == 0:
            sigma = np.sqrt(var_face) / np.maximum(skin_g, 1e-6)
        else:
            sigma = np.sqrt(var_face) * np.abs(response[wardrobe.offset[i - 1] : wardrobe.offset[i]])
        per_face[part.path] = sigma
        seen = visible[i]
        if not np.any(seen) or a_face[seen].sum() <= 0:
            continue
        by_mesh[part.path] = float(np.sqrt(np.average(sigma[seen] ** 2, weights=a_face[seen])))
        # a hidden face (skin under a garment, an inner layer) keeps its pilot rays and takes its
        # temperature from the stack's balance, not from its own flux: its figure here is not its
        # noise. The render blends it into its visible neighbours' corners: it gets the mesh's
        # visible RMS (demo body, smoothed over visible points: stated 28 mK with the hidden
        # faces' own figures against 14 mK measured by two seeds)
        per_face[part.path] = np.where(seen, sigma, by_mesh[part.path])
        sq.append(sigma[seen] ** 2)
        weights.append(a_face[seen])
    if not sq:
        return {}
    total = float(np.sqrt(np.average(np.concatenate(sq), weights=np.concatenate(weights))))
    return {
        "faceTemperatureNoiseRms_K": total,
        "faceTemperatureNoiseRmsByMesh_K": by_mesh,
        FACE_NOISE: per_face,
    }


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


def _face_normals(part: _Part, mesh: trimesh.Trimesh) -> np.ndarray:
    """(F, 3) unit normals of the authored faces of ``part`` (the first part of ``mesh``):
    area-weighted means of their triangles' normals."""
    n = len(part.counts)
    tri = len(part.triangles)
    weighted = mesh.face_normals[:tri] * mesh.area_faces[:tri, None]
    out = np.stack([np.bincount(part.tri_face, weighted[:, i], n) for i in range(3)], axis=1)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)


def _windward_ratio(
    normals: np.ndarray, air_velocity: np.ndarray, segment: np.ndarray, area: np.ndarray
) -> np.ndarray:
    """(F,) local over segment-mean forced convection of each body face for a horizontal air
    velocity relative to the body (:func:`humv_usd.physics.convection.windward_ratio`),
    renormalised to an area-weighted mean of 1 over each segment."""
    speed = float(np.linalg.norm(air_velocity))
    if speed < 1e-9:
        return np.ones(len(normals))
    toward = -np.array([air_velocity[0], air_velocity[1], 0.0]) / speed  # where the air comes from
    r = windward_ratio(normals @ toward, speed)
    mean = np.bincount(segment, area * r, N_SEGMENTS) / np.maximum(
        np.bincount(segment, area, N_SEGMENTS), 1e-300
    )
    return r / np.where(mean > 0, mean, 1.0)[segment]


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
    """One garment's fabric and air gaps per frame (the gap to the skin, as the clothing layer
    writes it: for an outer garment it spans the layers under it)."""

    def __init__(self, part: _Part, stage: Usd.Stage, frames: int):
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


#: An outer garment face lies over an inner garment's face when the inner face's outer
#: surface (its gap + thickness) is within the outer face's gap + this tolerance [m] (the
#: clothing layer keeps the outer one at least the minimum gap beyond, at its vertices).
LAYER_TOLERANCE_M = 0.001
#: Residual tolerance of the garment stacks [W m^-2] (a tenth of the layer's reported bound, so
#: that the round-off floor of deep stacks stays inside it).
GARMENT_TOLERANCE_W_M2 = 1e-7
#: Most garment layers in one stack (hair, shirt, sweater, coat; deeper stacks are cut).
MAX_LAYERS = 4


def _layer_links(clothes: list[_Garment], points: list) -> tuple[list, list]:
    """(below, above): per garment (F_g, 2) int arrays of the (garment, face) directly under /
    over each face, -1 where none; from the face centres at the first radiation sample and the
    gaps at frame 0. A face of ``b`` is under a face of ``a`` when it is the nearest ``b`` face,
    its outer surface is inside ``a``'s gap (+ LAYER_TOLERANCE_M) and the centres are no
    farther apart than the gap between them + COVER_MARGIN_M; among several such garments the
    one nearest (the highest under, the lowest over) is taken."""
    from scipy.spatial import cKDTree

    centres = [_face_centres(c.part, points[i + 1]) for i, c in enumerate(clothes)]
    trees = [cKDTree(c) for c in centres]
    top = [c.gap[0] + c.fabric["thickness"] for c in clothes]  # outer surface over the skin
    below = [np.full((len(c), 2), -1) for c in centres]
    above = [np.full((len(c), 2), -1) for c in centres]
    best_below = [np.full(len(c), -np.inf) for c in centres]
    best_above = [np.full(len(c), np.inf) for c in centres]
    for a, ca in enumerate(clothes):
        for b, cb in enumerate(clothes):
            if a == b:
                continue
            # b under a, seen from a's faces
            d, j = trees[b].query(centres[a])
            ok = (top[b][j] <= ca.gap[0] + LAYER_TOLERANCE_M) & (
                d <= ca.gap[0] - cb.gap[0][j] + COVER_MARGIN_M
            )
            take = ok & (top[b][j] > best_below[a])
            below[a][take] = np.stack([np.full(take.sum(), b), j[take]], axis=1)
            best_below[a][take] = top[b][j[take]]
            # a over b, seen from b's faces
            d, i = trees[a].query(centres[b])
            ok = (top[b] <= ca.gap[0][i] + LAYER_TOLERANCE_M) & (
                d <= ca.gap[0][i] - cb.gap[0] + COVER_MARGIN_M
            )
            take = ok & (ca.gap[0][i] < best_above[b])
            above[b][take] = np.stack([np.full(take.sum(), a), i[take]], axis=1)
            best_above[b][take] = ca.gap[0][i[take]]
    return below, above


class _Wardrobe:
    """All garment faces of one person as stacks of layers in series over the skin
    (:func:`humv_usd.physics.garment.stack_transient_step`): each garment face solves the stack
    it belongs to (the faces directly under it down to the skin, the faces over it up to the
    outermost), with each layer's air gap to the layer under it; faces are grouped by stack
    depth and solved together, frame by frame."""

    def __init__(self, clothes: list[_Garment], under: list, points: list, settings: dict, fps: float):
        self.clothes = clothes
        self.offset = np.concatenate([[0], np.cumsum([len(c.gap[0]) for c in clothes])])
        n = int(self.offset[-1])
        self.gap = np.concatenate([c.gap for c in clothes], axis=1)  # (frames, N) to the skin
        per = lambda f: np.concatenate([np.full(len(c.gap[0]), f(c)) for c in clothes])  # noqa: E731
        self.thickness = per(lambda c: c.fabric["thickness"])
        self.conductivity = per(lambda c: c.fabric["conductivity"])
        self.eps = per(lambda c: c.eps)
        self.capacity = per(lambda c: c.heat_capacity)
        self.under = np.concatenate(under)
        below, above = _layer_links(clothes, points)
        glob = lambda links: np.concatenate(  # noqa: E731
            [np.where(lk[:, 0] >= 0, self.offset[np.maximum(lk[:, 0], 0)] + lk[:, 1], -1) for lk in links]
        )
        down, up = glob(below), glob(above)
        chains = []
        for face in range(n):
            chain = [face]
            while down[chain[0]] >= 0 and len(chain) < MAX_LAYERS and down[chain[0]] not in chain:
                chain.insert(0, int(down[chain[0]]))
            while up[chain[-1]] >= 0 and len(chain) < MAX_LAYERS and up[chain[-1]] not in chain:
                chain.append(int(up[chain[-1]]))
            chains.append(chain)
        #: per depth: (member faces (m,), layer faces (depth, m), position of the member (m,))
        self.groups = []
        for depth in sorted({len(c) for c in chains}):
            members = np.array([i for i, c in enumerate(chains) if len(c) == depth], dtype=np.int64)
            layers = np.array([chains[i] for i in members], dtype=np.int64).T
            position = np.array([chains[i].index(i) for i in members], dtype=np.int64)
            self.groups.append((members, layers, position))
        self.depth = np.zeros(n, dtype=np.int64)
        for members, layers, _ in self.groups:
            self.depth[members] = len(layers)
        self.convection = settings["convection_model"]
        self.dt = 1.0 / float(fps)

    def layer_gaps(self, frame: int, layers: np.ndarray) -> np.ndarray:
        """(depth, m) air gap of each layer to the outer surface of the layer under it (the
        innermost: to the skin), >= 0."""
        g = self.gap[frame][layers]
        inner_top = np.concatenate([np.zeros((1, g.shape[1])), g[:-1] + self.thickness[layers[:-1]]])
        return np.maximum(g - inner_top, 0.0)

    def series(self, skin, air, q_abs, wind, rh, transient: bool, wet=None, evap_limit=None, skin_step=None):
        """(outer temperature, skin-side sensible flux, largest |residual|) per frame and
        garment face (frames, N) for the skin temperatures ``skin`` (frames, F_body): steady at
        frame 0, then implicit steps with every layer's heat capacity (or steady every frame).
        ``q_abs`` (frames, N): absorbed by each face's outer surface (only the outermost layer
        of a stack uses its own); ``wet``, ``evap_limit`` (frames, N): wetted fraction and
        largest evaporation [W m^-2] of a face worn directly on the skin with nothing over it
        (the sweat's latent heat at the fabric is the physiology's own latent loss, so it is
        taken off the skin-side flux the physiology is matched to).

        ``skin_step`` [K]: also the skin-side flux at ``skin + skin_step`` (a fourth item,
        (frames, N)), solved in the same stack calls as the first (each facet twice along the
        facet axis: every facet's arithmetic is a facet's own, so both equal two separate
        calls, in half the calls)."""
        frames = len(skin)
        n = int(self.offset[-1])
        t_out, q_side, worst = np.zeros((frames, n)), np.zeros((frames, n)), 0.0
        q_step = np.zeros((frames, n)) if skin_step is not None else None
        self.evaporation_max = 0.0
        prev = [None] * len(self.groups)
        two = (lambda v: np.concatenate([v, v], axis=-1)) if skin_step is not None else (lambda v: v)  # noqa: E731
        for f in range(frames):
            h = convective_coefficient(wind[f], model=self.convection)
            for k, (members, layers, position) in enumerate(self.groups):
                inner, outer = layers[0], layers[-1]
                t_skin = skin[f][self.under[inner]]
                if skin_step is not None:
                    t_skin = np.concatenate([t_skin, (skin[f] + skin_step)[self.under[inner]]])
                kw = dict(
                    skin_temperature_k=t_skin,
                    air_temperature_k=air[f],
                    absorbed_radiation=two(q_abs[f][outer]),
                    h_forced=h,
                    air_gaps_m=two(self.layer_gaps(f, layers)),
                    thicknesses_m=two(self.thickness[layers]),
                    conductivities=two(self.conductivity[layers]),
                    emissivities=two(self.eps[layers]),
                    relative_humidity=float(np.clip(rh[f], 0.0, 1.0)),
                    tol=GARMENT_TOLERANCE_W_M2,
                )
                if wet is not None and len(layers) == 1:
                    kw.update(wetted_fraction=two(wet[f][outer]), evaporation_limit=two(evap_limit[f][outer]))
                if f == 0 or not transient:
                    b = stack_steady_state(**kw)
                else:
                    b = stack_transient_step(prev[k], self.dt, two(self.capacity[layers]), **kw)
                prev[k] = b.outer_temperature_k
                m = len(members)
                cols = np.arange(m)
                t_out[f, members] = b.outer_temperature_k[position, cols]
                q = b.q_in - np.maximum(b.q_evap, 0.0)
                q_side[f, members] = q[:m]
                if skin_step is not None:
                    q_step[f, members] = q[m:]
                if m:
                    # as a separate call at skin + skin_step would leave it (the last run's)
                    self.evaporation_max = max(self.evaporation_max, float(b.q_evap[-m:].max()))
                worst = max(worst, float(np.abs(b.residual[:m]).max()) if m else 0.0)
        if skin_step is not None:
            return t_out, q_side, worst, q_step
        return t_out, q_side, worst

    def split(self, values: np.ndarray) -> dict:
        """(frames, N) -> {garment path: (frames, F_g)}."""
        return {
            c.part.path: values[:, self.offset[i] : self.offset[i + 1]] for i, c in enumerate(self.clothes)
        }

    def stack_resistance(self, faces: np.ndarray) -> np.ndarray:
        """(len(faces),) intrinsic insulation [m^2 K W^-1] of the stack each garment face
        belongs to at frame 0: per layer its air gap (still air + grey-plate radiation at
        306 K) and its fabric in series."""
        total = np.zeros(int(self.offset[-1]))
        for members, layers, _ in self.groups:
            d = np.maximum(self.layer_gaps(0, layers), 1e-4)
            eps_in = np.concatenate([np.full((1, layers.shape[1]), 0.98), self.eps[layers[:-1]]])
            f_rad = grey_plates_exchange_factor(eps_in, self.eps[layers])
            h_gap = air_conductivity(306.0) / d + 4.0 * f_rad * STEFAN_BOLTZMANN * 306.0**3
            total[members] = np.sum(1.0 / h_gap + self.thickness[layers] / self.conductivity[layers], axis=0)
        return total[faces]


def garment_clo(body: _Part, area: np.ndarray, cover: _Coverage, wardrobe: _Wardrobe | None) -> np.ndarray:
    """(17,) intrinsic clothing insulation per JOS-3 segment [clo] from the garments themselves:
    per covered body face the stack of layers over it, each layer's air gap and fabric in
    series, R = sum_i 1 / (k_air / d_i + 4 F_i sigma T^3) + l_i / k_i (still air, grey-plate
    radiation at 306 K between the facing surfaces' emissivities), averaged over the segment's
    area with bare faces at 0 (the area-weighted local insulation of ISO 9920:2007 Annex A),
    1 clo = 0.155 m^2 K W^-1."""
    resistance = np.zeros(len(body.counts))
    covered = cover.garment >= 0
    if covered.any():
        faces = wardrobe.offset[cover.garment[covered]] + cover.face[covered]
        resistance[covered] = wardrobe.stack_resistance(faces)
    seg_area = np.bincount(body.segment, area, N_SEGMENTS)
    return np.bincount(body.segment, area * resistance, N_SEGMENTS) / np.maximum(seg_area, 1e-12) / 0.155
