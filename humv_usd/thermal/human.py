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
   the avatar's metabolic-rate schedule, the weather, the segment MRTs and the clothing
   insulation of each segment, with a spin-up; skin temperature per segment → skin facets;
4. garment facets: the energy balance of Eq. 5-9 over the skin temperature of the segment
   underneath, with the per-face air gap: steady state at frame 0
   (:func:`humv_usd.physics.garment.steady_state`), then implicit steps with the fabric's heat
   capacity along the frames (:func:`humv_usd.physics.garment.transient_step`).

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
from humv_usd.physics.convection import convective_coefficient
from humv_usd.physics.garment import areal_heat_capacity, steady_state, transient_step
from humv_usd.thermal import qrad as Q
from humv_usd.thermal import scene_radiance as SR
from humv_usd.thermal.physiology import N_SEGMENTS, simulate_physiology
from humv_usd.thermal.sky import ClearSky
from humv_usd.usd.avatar import read_air_gap, read_body_regions, read_garment, read_metabolic_rate
from humv_usd.usd.materials import StageMaterial, band_emissivity, mesh_material

#: Local insulation [clo] a garment adds to each JOS-3 segment it covers. Order-of-magnitude
#: values for single layers (ISO 9920:2007 Annex A local insulation of light shirts/trousers
#: 0.2-0.4 clo, jackets 0.4-0.6 clo); a garment not listed adds 0.3 clo.
LOCAL_CLO = {
    "cap": 0.2,
    "leggings": 0.2,
    "shorts": 0.25,
    "tshirt_white": 0.3,
    "tshirt_black": 0.3,
    "longsleeve": 0.3,
    "trousers": 0.3,
    "uniform_trousers": 0.35,
    "jacket": 0.55,
    "robe": 0.45,
    "vest": 0.4,
}

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


def segment_clo(garment_parts: list[_Part]) -> np.ndarray:
    """(17,) clothing insulation per JOS-3 segment from the garments covering it."""
    clo = np.zeros(N_SEGMENTS)
    for part in garment_parts:
        covered = np.zeros(N_SEGMENTS, dtype=bool)
        covered[np.unique(part.segment)] = True
        clo[covered] += LOCAL_CLO.get(part.garment, 0.3)
    return clo


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
    for k, frame in enumerate(samples):
        t = Usd.TimeCode(frame)
        sky, scene = world.skies[k], world.scenes[k]
        air_k = float(air[frame])
        pts = [skinned_points(stage, p.path, t, space="world") for p in parts]
        centre = pts[0].mean(axis=0)
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
            for p in garments:
                qt = qc[start : start + len(p.triangles)]
                start += len(p.triangles)
                # area-weighted mean over the triangles of each authored face
                area = clothed.area_faces[start - len(p.triangles) : start]
                q_garment[p.path][k] = np.bincount(p.tri_face, qt * area, len(p.counts)) / np.maximum(
                    np.bincount(p.tri_face, area, len(p.counts)), 1e-12
                )
    nearest = np.searchsorted(np.asarray(samples), np.arange(frames), side="right") - 1
    mrt_frames = np.where(np.isnan(mrt[nearest]), air[:, None], mrt[nearest])

    # physiology over the frames
    rate = read_metabolic_rate(stage.GetPrimAtPath(human_path), frames)
    times = np.arange(frames) / fps
    result = simulate_physiology(
        times,
        rate,
        air,
        mrt_frames,
        rh,
        np.maximum(wind, 0.1),
        segment_clo(garments),
        model=MODEL_NAMES[model],
        height_m=human["stature_m"],
        mass_kg=human["mass_kg"],
        age_years=human["age_yr"],
        sex=human["sex"],
        fitness=human["fitness"],
        spin_up_s=settings["spin_up_s"],
    )
    skin = np.asarray(result.segment_skin_temperature_k)  # (frames, 17)
    out = {body.path: skin[:, body.segment]}

    transient = settings.get("garment_transient", "transient") == "transient"
    for p in garments:
        # the fabric is the material bound to the garment mesh (the clothing layer binds the
        # catalogue fabric; a stronger layer may bind or override another)
        fabric = {
            k: p.material.require(k, p.path)
            for k in ("conductivity", "density", "specific_heat", "thickness")
        }
        eps_f = longwave_emissivity(p.material)
        heat_capacity = areal_heat_capacity(fabric["density"], fabric["specific_heat"], fabric["thickness"])
        garment_prim = stage.GetPrimAtPath(p.path)
        starts = np.concatenate([[0], np.cumsum(p.counts)[:-1]])
        temps = np.zeros((frames, len(p.counts)))
        for f in range(frames):
            gap_v = read_air_gap(garment_prim, f)
            gap = np.add.reduceat(gap_v[p.indices], starts) / p.counts
            h = convective_coefficient(wind[f], model=settings["convection_model"])
            args = (skin[f, p.segment], air[f], q_garment[p.path][nearest[f]], h, gap, fabric["thickness"])
            kw = dict(fabric_conductivity=fabric["conductivity"], fabric_emissivity=eps_f)
            if f == 0 or not transient:
                balance = steady_state(*args, **kw)
            else:
                balance = transient_step(temps[f - 1], 1.0 / fps, heat_capacity, *args, **kw)
            temps[f] = balance.outer_temperature_k
            diagnostics["garmentMaxResidual_W_m2"] = max(
                diagnostics.get("garmentMaxResidual_W_m2", 0.0), float(np.abs(balance.residual).max())
            )
        out[p.path] = temps
    return out, diagnostics
