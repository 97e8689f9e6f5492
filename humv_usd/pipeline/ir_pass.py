"""The infrared pass of one sensor at one frame: radiometry, render in batches (automatic
quality), labels, sensor chain, files and the frame's record entry.

Called by :class:`humv_usd.pipeline.render` 's frame loop (``run``: its frame renderer, which
holds the frame's scene, the band caches, the sensor chains and the per-sensor records).
"""

from __future__ import annotations

import logging
import os
import time

import numpy as np

from humv_usd import images as writers
from humv_usd.geometry import shading
from humv_usd.geometry.camera import Camera
from humv_usd.groundtruth.labels import CLASS_ID
from humv_usd.physics import planck
from humv_usd.physics.sensor import SensorModel
from humv_usd.pipeline.manifest import ErrorAccumulator
from humv_usd.render import bands, lights, nightlight, radiometry
from humv_usd.render import estimator as E
from humv_usd.render import quality as Q
from humv_usd.render.frame import exr_metadata
from humv_usd.render.frame import path_table as read_path_table
from humv_usd.render.light import FrameLight
from humv_usd.render.renderer import band_renderer
from humv_usd.usd import thermal as usd_thermal
from humv_usd.usd.paths import human_path

log = logging.getLogger(__name__)

AUTO_SEED_STRIDE = Q.AUTO_SEED_STRIDE
AUTO_MAX_SPP = Q.AUTO_MAX_SPP
AUTO_NETD_FRACTION = Q.AUTO_NETD_FRACTION
AUTO_P99_K = Q.AUTO_P99_K
#: Grid [um] of the night light added to NIR/SWIR sensors (render.nightlight: 5 nm, 0.36-2.5 um).
_NIGHT_WL = np.arange(0.36, 2.5 + 1e-9, 0.005)


def _needs_more_samples(plan, sensor, noise: dict, batches: int, regions: dict | None = None) -> bool:
    """Automatic quality (no spp given, fast estimator): another batch while fewer than
    :data:`humv_usd.render.quality.MIN_BATCHES` were taken, or the mean error away from edges
    exceeds NETD / 3 or its 99th percentile exceeds AUTO_P99_K on the image (``noise``) or on a
    labelled region (``regions``, :func:`humv_usd.render.quality.region_stats`), and fewer than
    AUTO_MAX_SPP samples were spent."""
    if not plan.spp_auto or noise.get("mean_k") is None:
        return False
    if getattr(sensor, "is_reflective", False):  # NIR/SWIR: the error relative to the radiance
        return Q.needs_more(True, Q.verdict(noise, regions or {}, REFLECTIVE_PSEUDO_NETD), batches, plan.spp)
    netd = getattr(sensor, "netd_k", None)
    if not netd or netd <= 0:
        return False
    return Q.needs_more(True, Q.verdict(noise, regions or {}, netd), batches, plan.spp)


#: NIR/SWIR cameras (reflected light, radiance out) have no NETD: their automatic quality holds
#: the per-pixel error relative to the mean radiance away from edges to the EO camera's target
#: (mean <= :data:`humv_usd.render.quality.EO_TARGET_RELATIVE`) through the infrared rule with
#: this "NETD" in relative units (mean <= it / AUTO_NETD_FRACTION; p99 <= AUTO_P99_K, i.e. 10 %)
REFLECTIVE_PSEUDO_NETD = Q.RELATIVE_NETD
#: how the errors of a NIR/SWIR camera are expressed (the manifest's monte_carlo_error_k and
#: quality regions hold these dimensionless numbers for such a camera)
RELATIVE_UNIT = "relative to the mean radiance away from edges (no NETD: reflected light)"


def _netd_text(sensor) -> str:
    """The sensor's NETD for a sentence (float32 attributes print as 0.019999999552965164)."""
    netd = getattr(sensor, "netd_k", None)
    return "no NETD" if netd is None else f"{float(netd):.4g} K"


def _spp_rule(plan, sensor) -> str:
    if getattr(sensor, "is_reflective", False):
        if not plan.spp_auto:
            return Q.rule_text(False, plan.spp, "")
        return (
            f"automatic: at least {Q.MIN_BATCHES} batches of {plan.spp} spp, more until the mean error "
            f"away from edges is <= {Q.EO_TARGET_RELATIVE:.0%} of the mean radiance there and its 99th "
            f"percentile <= {Q.AUTO_P99_K:.0%} of it, on the image and on every labelled region class, "
            f"or {Q.AUTO_MAX_SPP} spp"
        )
    return Q.rule_text(plan.spp_auto, plan.spp, _netd_text(sensor))


def preview_grey(bt: np.ndarray, levels: tuple[float, float]) -> np.ndarray:
    """The IR file's display channels: brightness temperature stretched between the PNG
    preview's ``levels`` (:func:`humv_usd.images.preview_levels`) to 0..1 (0 where not finite),
    so that viewers do not open it black."""
    lo, hi = levels
    grey = (bt - lo) / (hi - lo) if hi > lo else np.full(bt.shape, 0.5)
    return np.where(np.isfinite(grey), np.clip(grey, 0.0, 1.0), 0.0)


def thermal_noise(run, s: SensorModel, state, hits) -> np.ndarray | None:
    """The thermal layer's own noise [K] per pixel (H, W): the RMS face-temperature noise
    from the q_rad rays of the mesh the pixel-centre ray hits
    (:func:`humv_usd.usd.thermal.face_temperature_noise_by_mesh`: the body's bare skin, each
    garment's outer faces; a layer without it: the person's,
    :func:`humv_usd.usd.thermal.face_temperature_noise`), times the band's
    emissivity-weighted share (a face's radiance error is eps dL/dT sigma_T, read back in K
    through the pixel's dL/dT: about eps sigma_T); 0 elsewhere. None when the layer states no
    noise.

    More samples do not reduce it, so the stopping rule does not see it: each region's
    record states it and the total with the render's own error in quadrature
    (:func:`humv_usd.render.quality.add_thermal_noise`); the EXR's ``radiance_stderr``
    stays the render's Monte Carlo error. The layer measures its rays' error with independent
    replicates (:func:`humv_usd.thermal.qrad.absorbed_radiation`): on the demo person it is
    within 20 % of the seed-to-seed difference per mesh.

    Each face carries its own noise where the layer states it per face
    (:func:`humv_usd.usd.thermal.read_face_temperature_noise`; else its mesh's RMS). The fast
    estimator shades the faces smooth (corner blend and one-ring gain steps), which averages
    the errors of the faces around each corner, taken as independent (each face's rays are its
    own): the pixel gets the error of the shaded field at its hit point
    (:func:`humv_usd.geometry.shading.smooth_noise`); flat faces (the path estimator) their
    face's. Demo, two q_rad seeds, one render seed, person pixels away from edges (lwir640 /
    mwir_insb): the images differ by 7.6 / 7.3 mK RMS (difference / sqrt 2; mean 5.4 / 5.0 mK),
    stated 8.8-9.3 mK mean, about 1.3-1.4 times the measured mean sigma
    (``tests/test_thermal_noise_pixels.py``, extended); every pixel its mesh's flat-face RMS
    stated 22 mK, each face its mesh's RMS through the shading 12.4-12.9 mK."""
    if not hasattr(run, "_person_noise"):
        run._person_noise = usd_thermal.face_temperature_noise(run.plan.stage)
        run._mesh_noise = usd_thermal.face_temperature_noise_by_mesh(run.plan.stage)
        run._thermal_note = (
            {person: noise for person, noise in run._person_noise.items()} if run._person_noise else None
        )
    if not run._person_noise:
        return None
    parts = run.scene.parts
    if not hasattr(run, "_face_noise"):
        run._face_noise = {}
    per_part = np.zeros(len(parts) + 1)
    per_face = [None] * len(parts)
    for i, part in enumerate(parts):
        for person, noise in run._person_noise.items():
            if part.mesh_path.startswith(str(human_path(person)) + "/"):
                noise = run._mesh_noise.get(part.mesh_path, noise)
                eps = bands.band_emissivity(run.band_eps, part.material, s)
                per_part[i] = eps * noise
                if part.mesh_path not in run._face_noise:
                    run._face_noise[part.mesh_path] = usd_thermal.read_face_temperature_noise(
                        run.plan.stage.GetPrimAtPath(part.mesh_path)
                    )
                face = run._face_noise[part.mesh_path]
                per_face[i] = None if face is None else eps * face
    out = per_part[np.where(hits.part >= 0, hits.part, len(parts))]
    return _face_thermal_noise(
        run.scene, per_part, per_face, hits, out, run.plan.estimator == "fast" and E.SMOOTH_SHADING
    )


def _face_thermal_noise(scene, per_part, per_face, hits, flat, smooth):
    """:func:`thermal_noise` at the pixels of parts with noise from each face's own noise
    (``per_face``: (faces,) per part or None for the part's ``per_part``), through the fast
    estimator's smooth shading of the faces' temperatures when ``smooth``. Only the parts with
    noise take faces of their own (the blend never mixes parts); every other triangle shares
    one face of no noise."""
    on = (hits.part >= 0) & (flat > 0)
    if not on.any() or (not smooth and all(f is None for f in per_face)):
        return flat
    parts = scene.parts
    noisy = [i for i in range(len(parts)) if per_part[i] > 0]
    n_tri = np.array([len(p.triangles) for p in parts], dtype=np.int64)
    tri0 = np.concatenate([[0], np.cumsum(n_tri)[:-1]])
    face_of = np.zeros(int(n_tri.sum()), dtype=np.int64)  # face 0: no noise
    sigma = [np.zeros(1)]
    first = 1
    for i in noisy:
        tf = np.asarray(parts[i].triangle_face, dtype=np.int64)
        n_face = max(int(tf.max()) + 1 if len(tf) else 0, 0 if per_face[i] is None else len(per_face[i]))
        face_of[tri0[i] : tri0[i] + n_tri[i]] = first + tf
        f = (
            np.full(n_face, per_part[i])
            if per_face[i] is None
            else np.pad(per_face[i], (0, n_face - len(per_face[i])))
        )
        sigma.append(f)
        first += n_face
    face_sigma = np.concatenate(sigma)
    p, t = hits.part[on], hits.triangle[on]
    out = flat.copy()
    if not smooth:
        out[on] = face_sigma[face_of[tri0[p] + t]]
        return out
    local0 = np.zeros(len(parts) + 1, dtype=np.int64)
    tri = []
    for i in noisy:
        tri.append(np.asarray(scene.vertices(parts[i]), float)[scene.face_corners(parts[i])])
        local0[i] = sum(len(x) for x in tri[:-1])
    bary = np.clip(
        shading.barycentric(np.concatenate(tri), np.asarray(hits.position)[on], index=local0[p] + t), 0.0, 1.0
    )
    out[on] = shading.smooth_noise(
        scene.corner_blend(), face_of, face_sigma, tri0[p] + t, bary, E.DARK_GAIN_STEPS
    )
    return out


def _tick(run, timings: dict, key: str, t: float) -> float:
    dt = time.perf_counter() - t
    timings[key] += dt
    run.totals[key] += dt
    return time.perf_counter()


def render_sensor(run, s: SensorModel, state, frame, light: FrameLight) -> None:
    """One IR sensor at one frame: radiometry, render, labels, sensor chain, files, record."""
    plan, scene = run.plan, run.scene
    timings = run.per_sensor[s.name]["timings"]
    band, response = s.wavelength_range_um, s.band_response
    sensor_id = plan.sensor_ids[s.name]
    before = dict(timings)
    cpu0 = time.process_time()
    t = time.perf_counter()
    sub = plan.sub_of[s.name]
    frame_rad = radiometry.frame_radiometry(
        sub,
        state.sky_temperature_k,
        light.spectra,
        light.sun_direction,
        read_path_table(plan.stage, s, light.time_code),
        dni_w_m2=light.dni_w_m2,
    )
    if s.is_reflective and (night := nightlight.frame_night_light(light, _NIGHT_WL)):
        nightlight.add_to_subbands(frame_rad, night, sub, _NIGHT_WL)  # twilight, moon, airglow
    if s.is_reflective and light.lamps:  # street lamps, headlights, lit windows (render.lights)
        frame_rad.lamps = lights.lamp_table(
            list(light.lamps), _NIGHT_WL * 1000.0, lambda per_nm: sub.integrate(_NIGHT_WL, per_nm * 1000.0)
        )
        frame_rad.ran["lamps"] = lights.describe(list(light.lamps)) + (
            "" if plan.estimator == "fast" else " (not rendered: only the fast estimator has lamps)"
        )
    if light.clouds is not None and frame_rad.sun_irradiance is not None and light.sun_direction is not None:
        if light.sun_direction[2] > 0.0:  # broken clouds' shadows on the sun (render.light)
            frame_rad.clouds = light.clouds
            frame_rad.ran["cloud_shadows"] = light.clouds.describe() + (
                "" if plan.estimator == "fast" else " (not rendered: only the fast estimator has them)"
            )
    t = _tick(run, timings, "load_export", t)

    renderer = band_renderer(plan.estimator)
    hits = scene.hits(sensor_id)
    edges = E.geometric_edges(hits) if plan.estimator == "fast" else None
    regions, region_names = Q.region_map(hits.part, [p.label_class for p in scene.parts])
    netd = getattr(s, "netd_k", None)
    # the thermal layer's own noise [K] per pixel (NIR/SWIR: reflected light, not the layer's)
    thermal_k = None if s.is_reflective else thermal_noise(run, s, state, hits)
    fast_auto = plan.estimator == "fast" and plan.spp_auto

    first_served = Q.first_boost(regions, region_names)  # people: a boost budget of their own
    boost_where = first_served

    def direct_target(radiance, variance):
        """Per-pixel variance target of the estimator's boosts (automatic quality): the people's
        pixels and those of the failing regions; in the first batch, of the regions that would
        miss their targets unboosted (``variance``: the batch's own, before boosts)."""
        _, dl_dt = planck.brightness_temperature_tabulated(radiance[0], band, response)
        where = boost_where
        if pooled.count == 0:
            with np.errstate(invalid="ignore", divide="ignore"):
                err_k = np.where(dl_dt > 0, np.sqrt(np.nansum(variance, axis=0)) / dl_dt, np.nan)
            where = where | Q.likely_to_miss(err_k, edges, regions, region_names, netd)
        return Q.pixel_target_var(netd, dl_dt, where, batches_done=pooled.count)

    pooled = Q.Batches()
    back_face = None
    replicas = E.replica_count(plan.spp_sub[s.name]) if plan.estimator == "fast" else None
    estimator_s = 0.0  # the estimator's share of "render" (the rest: conversions, edges, stats)
    frame_tables: dict = {}  # the estimator's tables, shared by this frame's batches
    estimator_cpu = 0.0  # process CPU (all threads, the background writer's too) in the estimator
    while True:
        t_est, c_est = time.perf_counter(), time.process_time()
        extra = {}
        if plan.estimator == "fast":
            extra["info"] = info = {}
            extra["reuse"] = frame_tables  # the per-triangle tables, built in the first batch
            if s.is_reflective:  # NIR/SWIR: the sun term is the signal (its smooth shading kept unbiased)
                extra["sun_mean_steps"] = E.REFLECTIVE_SUN_MEAN_STEPS
                extra["sun_gain_steps"] = E.REFLECTIVE_SUN_GAIN_STEPS
                extra["dark_gain_steps"] = E.REFLECTIVE_DARK_GAIN_STEPS
            if fast_auto and Q.targets(netd) is not None:
                extra["direct_target"] = direct_target
                extra["boost_first"] = first_served
        batch = renderer.render(
            scene,
            sensor_id,
            state,
            sub,
            lambda material: bands.subband_emissivity(run.sub_eps, material, s, sub),
            frame_rad,
            spp=plan.spp_sub[s.name],
            seed=(plan.seed + frame + AUTO_SEED_STRIDE * pooled.count) % 2**32,
            transmittance_of=lambda material: bands.subband_transmittance(run.sub_eps, material, s, sub),
            **extra,
        )
        estimator_s += time.perf_counter() - t_est
        estimator_cpu += time.process_time() - c_est
        pooled.add(batch[0], batch[1], replicas or plan.spp_sub[s.name])
        if plan.estimator == "fast":
            fraction = info["back_face_fraction"]
            back_face = fraction if back_face is None else back_face + fraction
        m1 = pooled.mean()
        # one batch: its estimator's error as it stands; more: replicas and batches pooled
        stderr_l = batch[1] if pooled.count == 1 else pooled.stderr()
        bt, dl_dt = planck.brightness_temperature_tabulated(m1, band, response)  # < 1e-4 K of exact
        with np.errstate(invalid="ignore", divide="ignore"):
            stderr_k = np.where(dl_dt > 0, stderr_l / dl_dt, np.nan)
        if edges is None:
            edges = E.geometric_edges(hits)
        if s.is_reflective:  # no temperature: the error relative to the mean radiance (as EO's)
            inner = ~edges & np.isfinite(m1)
            mean_l = float(np.mean(m1[inner])) if inner.any() else float(np.nanmean(m1))
            stderr_k = stderr_l / mean_l if mean_l > 0 else np.full(m1.shape, np.nan)
        away_from_edges = E.noise_stats(stderr_k, edges)
        per_region = Q.region_stats(
            stderr_k,
            edges,
            regions,
            region_names,
            None if back_face is None else back_face / pooled.count,
        )
        if not _needs_more_samples(plan, s, away_from_edges, pooled.count, per_region):
            break
        boost_where = Q.next_boost(regions, region_names, Q.verdict(away_from_edges, per_region, netd))
    if thermal_k is not None:  # the thermal layer's noise: not the render's to reduce; stated apart
        Q.add_thermal_noise(per_region, stderr_k, thermal_k, edges, regions, region_names)
    judge_netd = REFLECTIVE_PSEUDO_NETD if s.is_reflective else netd
    judged = Q.verdict(away_from_edges, per_region, judge_netd if plan.spp_auto else None)
    for name, rec in per_region.items():
        rec["met"] = judged["regions"].get(name)
    spp_used = plan.spp_sub[s.name] * pooled.count
    away_from_edges["spp_used"] = spp_used
    away_from_edges["spp_rule"] = _spp_rule(plan, s)
    away_from_edges["quality_met"] = judged["met"]
    if s.is_reflective:
        away_from_edges["unit"] = RELATIVE_UNIT
    quality = {
        "met": judged["met"],
        "image_met": judged["regions"].get("image"),
        "targets_k": Q.targets(judge_netd) if plan.spp_auto else None,
        **({"unit": RELATIVE_UNIT} if s.is_reflective else {}),
        "regions": per_region,
        "batches": pooled.count,
        "replicas_per_pixel": pooled.count * (replicas or 1),
        "error_dof": pooled.dof if replicas else None,
        "thermal_noise_k": None if thermal_k is None else run._thermal_note,
        "at_cap": bool(plan.spp_auto and judged["met"] is False),
    }
    t = _tick(run, timings, "render", t)
    t = _tick(run, timings, "labels", t)  # the pixel-centre cast is the labels' (cached)

    rel = os.path.join(s.name, f"{frame:04d}")
    c_labels = time.process_time()
    labels = plan.truth.annotate(
        scene,
        sensor_id,
        s,
        state,
        lambda part: bands.band_emissivity(run.band_eps, part.material, s),
        plan.out_dir,
        rel,
        write=run.write,
    )
    labels_cpu = time.process_time() - c_labels
    t = _tick(run, timings, "labels", t)

    # sensor chain: the single call site for IR (depth and instances: the motion blur's velocity)
    movers = run.chains.movers(labels.channels.get("class_id"), labels.instance)
    chained = run.chains.apply(s, m1, frame, depth=labels.depth, instance=movers)
    camera = Camera.from_pose(state.cameras[s.name], m1.shape[1], m1.shape[0])
    run.per_sensor[s.name]["cameras"].append((frame, camera))
    # NIR/SWIR (reflected light): the output is radiance; a brightness temperature means nothing
    shown = m1 if s.is_reflective else bt
    if s.is_reflective:
        bt = np.full(bt.shape, np.nan)
    class_id = labels.channels.get("class_id")
    people = None if class_id is None else np.asarray(class_id).astype(int) == CLASS_ID["person"]
    levels = writers.preview_levels(shown, keep=people)  # people stay readable in the PNG
    grey = preview_grey(shown, levels)
    channels = {
        "R": grey,
        "G": grey,
        "B": grey,
        "radiance": m1,
        "brightness_temperature": bt,
        "radiance_stderr": stderr_l,
        "depth": labels.depth,
        "instance_id": labels.instance.astype(np.float32),
        **labels.channels,
        **({} if chained is None else {"counts": chained.counts.astype(np.float32)}),
    }
    if s.is_reflective:
        del channels["brightness_temperature"]
    run.write(
        rel + ".exr",
        writers.write_exr,
        os.path.join(plan.out_dir, rel + ".exr"),
        channels,
        metadata=exr_metadata(
            s,
            frame,
            plan.spp * pooled.count,  # automatic quality: the samples spent
            camera,
            band_um=f"{band[0]:g}-{band[1]:g}",
            quality_met=judged["met"],
            subbands=len(sub),
            preview=f"R=G=B: {'radiance' if s.is_reflective else 'brightness temperature'} "
            "stretched as the PNG (0 at the 1st, 1 at the 99th percentile); display only",
        ),
        half=("R", "G", "B"),
    )
    plan.truth.image_written(rel, channels)
    run.write(
        rel + ".png", writers.write_preview_png, os.path.join(plan.out_dir, rel + ".png"), shown, levels
    )
    chain_record = run.chains.write(chained, plan.out_dir, rel, write=run.write)
    _tick(run, timings, "write", t)  # in the foreground: queueing (the writer's time is write_background)

    log.info(
        "frame %d %s: render %.2f s, labels %.2f s, error %s K away from edges",
        frame,
        s.name,
        timings["render"] - before["render"],  # this frame's, not the running total
        timings["labels"] - before["labels"],
        "n/a" if away_from_edges["mean_k"] is None else f"{away_from_edges['mean_k']:.4f}",
    )
    if quality["at_cap"]:
        log.warning(
            "frame %d %s: stopped at %d spp without meeting the quality target on %s",
            frame,
            s.name,
            spp_used,
            ", ".join(k for k, v in judged["regions"].items() if v is False),
        )
    frame_errors = ErrorAccumulator()  # summed once per image, merged into the totals
    # NIR/SWIR: reflected light has no brightness temperature, so no temperature error either
    frame_errors.add(stderr_l, np.full(stderr_k.shape, np.nan) if s.is_reflective else stderr_k)
    run.per_sensor[s.name]["errors"].merge(frame_errors)
    run.overall.merge(frame_errors)
    run.per_sensor[s.name]["frame_errors"] = {
        "sums": dict(frame_errors.sums),
        "counts": dict(frame_errors.counts),
        "maxima": frame_errors.maxima,
    }
    finite_bt = bt[np.isfinite(bt)]
    run.per_sensor[s.name]["frames"].append(
        {
            "frame": frame,
            "exr": rel + ".exr",
            "png": rel + ".png",
            "preview_levels_k": list(levels),
            "radiance_mean": float(np.mean(m1)),
            "brightness_temperature_mean_k": float(finite_bt.mean()) if finite_bt.size else None,
            "sky_temperature_k": state.sky_temperature_k,
            "monte_carlo_error": frame_errors.stats(),
            "monte_carlo_error_k": away_from_edges,
            "quality": quality,
            "radiometry": frame_rad.ran,
            "sensor_chain": chain_record,
            "timings_s": {
                **{k: timings[k] - before[k] for k in timings},
                "estimator": estimator_s,
                "estimator_cpu": estimator_cpu,
                "labels_cpu": labels_cpu,
                "cpu": time.process_time() - cpu0,
            },
        }
    )
