"""Thermal tool → layers/thermal.usda: per-face temperature [K] on every mesh of the stage.

People (``[thermal] model``):

* ``fixed``: skin at the scenario's uniform skin temperature, garments at the air temperature
  (a closed form that tests compare renders and labels against; not a physical signature);
* ``jos3`` / ``twoNode``: per person, radiation environment (sky + sun + scene surfaces) →
  segment MRT → physiology → skin per facet (``skin_detail``), and the garment energy balance
  for garment facets, coupled both ways until per segment the skin-side flux equals the
  physiology's sensible loss, per frame (:mod:`humv_usd.thermal.human`).

Scene surfaces (ground, objects, any other mesh outside /World/Humans), in every model: held at
the scenario's ``temperature_k`` when it is given, else a 1-D slab of the material with sun,
sky, wind and a diurnal spin-up ending at frame 0 (:mod:`humv_usd.thermal.surfaces`); with
``[atmosphere] cloud_size_m`` moving cloud shadows take the sun off the faces under them; after
rain, faces still wet at frame 0 are bound to wet variants of their materials, which this layer
defines (:mod:`humv_usd.thermal.wet`).
Weather and sun are read from the upstream stage's environment layer
(:mod:`humv_usd.usd.environment`, at each frame / radiation sample / spin-up step's time code).
The long-wave sky is read from the upstream stage's /World/Atmosphere (``skyLongwaveRadiance``
against zenith, LOWTRAN7 or analytic, cloud cover included; :func:`humv_usd.usd.atmosphere.longwave_sky`)
at each radiation sample's time code, exactly as the render reads it: the people's radiance maps
use the table itself and the slabs its hemispherical irradiance, so MRT, q_rad and the scene see
the render's sky at every frame, also when an hourly ``weather_csv`` time-samples it. Where the
layer has no value the analytic Berdahl & Martin sky with the Crawford & Duchon cloud mix stands
in: without an atmosphere layer, and in the slab spin-up before frame 0 (scaled there to frame
0's table, :func:`humv_usd.thermal.surfaces.with_sky_table`).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom
from threadpoolctl import threadpool_limits

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import CLOCK
from humv_usd.scenario.times import spin_up_times
from humv_usd.thermal import scene_radiance as SR
from humv_usd.thermal.human import (
    FACE_NOISE,
    Surroundings,
    auto_radiation_rays,
    human_temperatures,
    scenario_sky,
)
from humv_usd.thermal.snow import author_snow_cover
from humv_usd.thermal.surfaces import (
    air_at_frame0,
    camera_footprints,
    forcing_at,
    ground_albedo,
    longwave_emissivity,
    people_beam_gate,
    people_occluders,
    refine_meshes,
    scene_meshes,
    surface_temperatures,
    with_cloud_shadows,
    with_sky_table,
    with_water,
    write_refined_topology,
)
from humv_usd.thermal.wet import author_wet_surfaces
from humv_usd.usd.atmosphere import longwave_sky, model_name
from humv_usd.usd.environment import read_weather
from humv_usd.usd.layers import finish, new_layer_stage
from humv_usd.usd.paths import body_path, human_path
from humv_usd.usd.spill import SampleSpill
from humv_usd.usd.thermal import spill_temperatures, write_face_temperature_noise, write_surface_temperature

NAME = "thermal"
#: the weather comes from the environment layer (UPSTREAM), not from [atmosphere]
READS = (
    *CLOCK,
    "human",
    "scene",
    "thermal",
    "placement.*.standing_before_s",
    "atmosphere.rain_mm_h",
    "atmosphere.rain_end_h",
    "atmosphere.rain_duration_h",
    "atmosphere.cloud_size_m",
    "atmosphere.wind_direction_deg",
    "placement.*.position_m",
)
#: sensors: the ground's shadow edges are refined to the closest camera's pixel footprint
UPSTREAM = ("environment", "atmosphere", "materials", "scene", "avatar_*", "clothing_*", "sensors")
#: 4: faces in material GeomSubsets are slabs of their material; 5: scene surfaces see their
#: surroundings (sky view, exchange), shadow edges to the cameras' pixel footprint
#: 6: evapotranspiration of vegetation and soil, rain on the surfaces and their drying (issue 30);
#: 7: terrain zones as ground, leaves' convection, plants not refined, ground sky view vs objects only;
#: 8: people's ray offset no longer grows with a ground to the horizon (qrad.OFFSET_SCENE_SIZE_CAP_M)
#: 9: faces wet after rain bound to wet variants of their materials (thermal.wet)
#: 10: JOS-3 runs with the person's own body fat (Deurenberg 1991), not 15 %
#: 11: moving cloud shadows on the scene surfaces ([atmosphere] cloud_size_m); 12: and on the people
#: 13: snow on the ground melts (physics.snow); faces bare at frame 0 bound to the ground's material
#: 14: the people's face-temperature noise measured by replicates, per mesh (report only); and
#: snow on the flat roofs of box objects (98492fa); 15: shallow snow bound by depth level
#: (<material>__snow<mm>, thermal.snow); 16: and on roofs
#: 17: the garment stacks' solver stops stiff stacks at round-off (e308df6, 08d73d8): a few faces of
#: stiff stacks move by < 1e-6 K (Table 1 v0066: 4 of 540,062 values by one float32 ulp)
#: 18: the garment stacks solved by Newton on all layer temperatures at once (every node
#: balance to the tolerance; garmentMaxResidual_W_m2 0.073 -> 8e-8 on Table 1 v0066, whose
#: temperatures move by <= 3e-5 K: 3 of 540,062 values by one float32 ulp); 19: the coupling's
#: radiant temperatures by Anderson mixing (3bbd00e; withdrawn in 21);
#: 20: q_rad's rays spread to minimise the area-weighted face-temperature error
#: (human._ray_importance), a clothed person's bare-body (MRT) call at 16 rays, 192 rays by default
#: 21: the coupling's plain chord iteration again (no Anderson mixing: stopped by the flux residual
#: after an accelerated step, the demo person's facets were 0.23 K from the fixed point, 0.04 K before)
#: 22: q_rad's rays that miss every face see the sky, not the scene as the map's centre sees it
#: (the demo's cap -0.14 K, shoes -0.04 K, skin and T-shirt -0.02 K on average)
#: 23: a wardrobe of hair alone takes its own q_rad pass (human._hair_radiation) instead of a
#: second pass over the clothed person (other rays: a walker's faces move by |d| p99 0.1-0.2 K)
#: 24: the people's meshes carry their faces' q_rad noise (primvars:humv:thermal:temperatureNoise,
#: per face [K]; usd.thermal.FACE_NOISE_PRIMVAR), which the render propagates per pixel
#: 25: a hidden face's noise is its mesh's visible RMS (the render blends it into visible corners)
#: 26: long hair alone takes the full clothed q_rad pass again (human.CLOSE_HAIR: its shadow on the
#: back and face matters); short or tied hair and beards keep the hair-only pass (23)
#: 27: ``[thermal] radiation_rays`` left out follows the thermal cameras (human.auto_radiation_rays:
#: 192 for LWIR cameras of NETD 50 mK, 800 with a cooled MWIR camera of 20 mK, e.g. the demo)
VERSION = "27"
#: compose hands this tool a :class:`~humv_usd.usd.spill.SampleSpill` (per-frame samples to disk;
#: the layer's text is unchanged, so no VERSION bump)
SPILLS = True


#: BLAS threads while the layer builds: its linear algebra is small (JOS-3 inverts an 85 x 85
#: matrix per minute of simulated time); OpenBLAS's threads cost 20x the CPU of one thread on
#: such matrices, and far more wall time on a busy machine (they spin waiting for a core)
BLAS_THREADS = 1


def build(scenario: Scenario, upstream: Usd.Stage, spill: SampleSpill | None = None) -> Sdf.Layer:
    """Read the meshes of the composed ``upstream`` stage; write one temperature per face.

    ``spill`` (compose passes one): each mesh's per-frame temperatures go to it as soon as they
    are solved (a person at a time, a scene mesh a chunk of frames at a time), so the layer and
    the tool hold no whole clip; the layer then has placeholders that ``spill.export`` replaces
    by the samples (:mod:`humv_usd.usd.spill`; the same text as without a spill)."""
    with threadpool_limits(BLAS_THREADS, user_api="blas"):
        return _build(scenario, upstream, spill)


def _build(scenario: Scenario, upstream: Usd.Stage, spill: SampleSpill | None = None) -> Sdf.Layer:
    g = scenario["general"]
    th = scenario["thermal"]
    model = th["model"]
    rays_rule = "given"
    if th.get("radiation_rays") is None:  # not given: from the thermal cameras' NETD
        rays, netd = auto_radiation_rays(upstream)
        th = {**th, "radiation_rays": rays}
        rays_rule = "automatic " + (
            "(no thermal camera)" if netd is None else f"(the thermal cameras' smallest NETD: {netd:g} K)"
        )
    frames, fps = scenario.frame_count, g["fps"]
    stage = new_layer_stage(fps, frames, f"HumV-USD thermal layer: per-face temperatures ({model} model)")
    stage.RemovePrim("/World")  # this layer only adds opinions: overs, no defs
    people = model != "fixed" and bool(scenario["human"])
    step = max(1, int(round(th["radiation_step_s"] * fps)))
    samples = list(range(0, frames, step))
    sample_t = np.asarray(samples, dtype=float) / fps
    nearest = np.searchsorted(np.asarray(samples), np.arange(frames), side="right") - 1

    meshes = scene_meshes(upstream, scenario)
    slabs = any(m.held_k is None for m in meshes)
    report: dict = {"model": model}
    surf: dict[str, np.ndarray] = {}
    sdiag: dict = {}
    forcing = None
    if slabs or people:
        spin = th["surface_spin_up_s"] if slabs else 0.0
        spin_t = spin_up_times(scenario) if slabs else np.zeros(0)
        all_t = np.concatenate([spin_t, sample_t])
        tables = sky_tables(upstream, samples)
        forcing = with_water(with_sky_table(forcing_at(upstream, all_t), tables, len(spin_t)), scenario)
        forcing = with_cloud_shadows(forcing, scenario)
        report["sky"] = _sky_report(forcing, tables, len(spin_t), upstream)
        shade = people_occluders(upstream, scenario, all_t)
        # [thermal] surface_cell_m > 0: that smallest cell, no camera footprint (the editor's preview)
        cell = float(th.get("surface_cell_m") or 0.0)
        fine = {"min_cell_m": cell} if cell > 0 else {"cameras": camera_footprints(upstream, samples)}
        meshes, refined = refine_meshes(meshes, forcing, shade, **fine)
        surf, sdiag = surface_temperatures(scenario, meshes, sample_t, spin, forcing, shade)
        report["surfaces"] = {
            "model": "slab" if slabs else "held",
            "spinUp_s": spin,
            "slabMaxResidual_W_m2": round(sdiag["slabMaxResidual_W_m2"], 9),
            "tessellation": refined,
            **{
                k: round(sdiag[k], 6)
                for k in ("exchangePasses", "exchangeLastChange_K", "viewRays")
                if k in sdiag
            },
        }
        ground_k = sdiag["groundMeanTemperature_k"]
    solved: dict[str, np.ndarray] = {}
    face_noise: dict[str, np.ndarray] = {}  # per-face q_rad noise [K] of the people's meshes
    for m in meshes:
        if m.path not in surf:
            solved[m.path] = np.full((1, m.n_faces), float(m.held_k))
        elif spill is not None:  # frames expanded from the samples a chunk at a time, to disk
            solved[m.path] = spill_temperatures(spill, surf[m.path], nearest)
        else:
            solved[m.path] = surf[m.path][nearest]
    if people:
        w = read_weather(upstream, np.arange(frames, dtype=float))
        n_spin = len(forcing.times_s) - len(samples)
        skies, scenes = [], []
        mesh, eps_tri, tri_offsets = _scene_trimesh(meshes)
        beam = people_beam_gate(forcing, scenario)  # cloud shadows where the people are
        for k in range(len(samples)):
            i = n_spin + k
            sun = (
                (forcing.sun_direction[i], forcing.dni_w_m2[i] * beam[i], forcing.dhi_w_m2[i])
                if forcing.sun_up[i]
                else None
            )
            weather = {
                "air_temperature_k": forcing.air_temperature_k[i],
                "relative_humidity": forcing.relative_humidity[i],
                "cloud_cover": forcing.cloud_cover[i],
            }
            sky = scenario_sky(
                scenario,
                weather,
                sun,
                float(ground_k[k]) if scenario["scene"] else None,
                longwave=None if tables is None else tables[k],
                ground_albedo=ground_albedo(meshes),
            )
            skies.append(sky)
            if mesh is None:
                scenes.append(None)
                continue
            t_tri = np.concatenate([surf[m.path][k][m.tri_face] for m in meshes])
            scenes.append(
                SR.SceneSurfaces(
                    mesh,
                    SR.scene_surface_radiance(
                        mesh, t_tri, eps_tri, sky, solar_reflectance=_solar_reflectance(meshes)
                    ),
                )
            )
        world = Surroundings(
            samples,
            skies,
            scenes,
            w.air_temperature_k,
            w.relative_humidity,
            w.wind_speed_m_s,
            w.wind_direction_deg,
        )
        report.update(
            {
                "qradMethod": th["radiation_method"],
                "qradRays": th["radiation_rays"],
                "qradRaysRule": rays_rule,
                "mapResolution": th["radiation_resolution"],
                "garmentBalance": th["garment_transient"],
            }
        )
        for h in scenario["human"]:
            temps_h, diag = human_temperatures(
                upstream, h, str(human_path(h["id"])), scenario, world, model, th
            )
            if spill is not None:  # to disk now: the layer holds one person's arrays at a time
                temps_h = {p: spill_temperatures(spill, v) for p, v in temps_h.items()}
            solved.update(temps_h)
            del temps_h
            face_noise.update(diag.pop(FACE_NOISE, {}))
            report[h["id"]] = _rounded(diag)
    wet = sdiag.get("wetFraction") if slabs else None
    if wet:  # issue 30.4: faces wet after rain render with a wet variant of their material
        report["wetSurfaces"] = author_wet_surfaces(
            stage, upstream, meshes, {p: w[0] for p, w in wet.items()}
        )
    snow_water = sdiag.get("snowWater") if slabs else None
    if snow_water:  # issue 30.4: faces melted bare by frame 0 show the ground's own material
        report["snowCover"] = author_snow_cover(
            stage, upstream, meshes, {p: w[0] for p, w in snow_water.items()}
        )
    # error estimates (deterministic for fixed seeds) travel with the layer; run times go
    # to compose's report, so an unchanged scenario still rewrites nothing
    stage.GetRootLayer().customLayerData = {"humv:thermal": report}
    fixed = _fixed_people(scenario)
    air0 = air_at_frame0(upstream, scenario)
    kinds = {m.path: ("fixed" if m.held_k is not None else "slab") for m in meshes}
    refined_meshes = {m.path: m for m in meshes if m.parent_face is not None}
    for prim in upstream.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        path = prim.GetPath()
        faces = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [])
        over = stage.OverridePrim(path)
        if str(path) in refined_meshes:
            write_refined_topology(over, refined_meshes[str(path)])
        series = solved.get(str(path))
        if series is None:
            write_surface_temperature(over, "fixed", np.full(faces, fixed.get(path, air0), dtype=np.float32))
            continue
        if str(path) in kinds:
            kind = kinds[str(path)]
        else:
            kind = model if str(path).endswith("/Body") else "balance"
        write_surface_temperature(over, kind, series, spill)
        if str(path) in face_noise:
            write_face_temperature_noise(over, face_noise[str(path)])
    return finish(stage)


def sky_tables(upstream: Usd.Stage, frames) -> list | None:
    """The atmosphere layer's long-wave sky table at each frame of ``frames`` (the radiation
    samples), as the render reads it, or None without an atmosphere layer / table."""
    tables = [longwave_sky(upstream, float(f)) for f in frames]
    return None if any(t is None for t in tables) else tables


def _sky_report(forcing, tables, i0, upstream) -> dict:
    """Where the long-wave sky came from and its irradiance at frame 0 (for the layer)."""
    if tables is None:
        source = "analytic: Berdahl & Martin (1984) + Crawford & Duchon (1999) clouds"
    else:
        source = f"atmosphere layer skyLongwaveRadiance ({model_name(upstream)}) at each radiation sample"
    return {
        "source": source,
        "cloudCover": round(float(forcing.cloud_cover[i0]), 6),
        "longwaveIrradiance_W_m2": round(float(forcing.sky_longwave[i0]), 4),
        "emissivity": round(
            float(forcing.sky_longwave[i0] / (STEFAN_BOLTZMANN * forcing.air_temperature_k[i0] ** 4)), 6
        ),
    }


def _rounded(values: dict) -> dict:
    """A report dict with its numbers rounded to 9 digits (nested dicts too)."""
    return {k: _rounded(v) if isinstance(v, dict) else round(v, 9) for k, v in values.items()}


def _fixed_people(scenario: Scenario) -> dict[Sdf.Path, float]:
    """Skin of every person at the scenario's uniform skin temperature (fixed model)."""
    th = scenario["thermal"]
    return {body_path(h["id"]): th["skin_temperature_k"] for h in scenario["human"]}


def _scene_trimesh(meshes):
    """(trimesh of every scene mesh, long-wave emissivity per triangle, triangle offsets)."""
    import trimesh

    if not meshes:
        return None, None, None
    points, faces, eps, offsets, offset, tri = [], [], [], [], 0, 0
    for m in meshes:
        points.append(m.points)
        faces.append(m.triangles + offset)
        offset += len(m.points)
        offsets.append(tri)
        tri += len(m.triangles)
        eps.append(m.per_face(longwave_emissivity)[m.tri_face])
    mesh = trimesh.Trimesh(np.concatenate(points), np.concatenate(faces), process=False)
    return mesh, np.concatenate(eps), offsets


def _solar_reflectance(meshes):
    """Broadband short-wave reflectance 1 - solar absorptivity per triangle (bound materials)."""
    return np.concatenate(
        [m.per_face(lambda x, m=m: 1.0 - x.require("solar_absorptivity", m.path))[m.tri_face] for m in meshes]
    )
