"""The render folder's manifest (``OUT/manifest.json``): settings, versions, per-sensor records,
error summaries and timings. Built from the records of every call (:mod:`humv_usd.pipeline.records`)."""

from __future__ import annotations

import datetime as _dt
import os
from collections import defaultdict

import numpy as np

import humv_usd
from humv_usd import images as writers
from humv_usd import mode
from humv_usd.constants import EMISSIVITY_WEIGHTING_TEMPERATURE_K
from humv_usd.geometry.camera import CAMERA_FILE
from humv_usd.physics.sensor import SensorModel
from humv_usd.pipeline import records as R
from humv_usd.render import bands, radiometry
from humv_usd.render import estimator as E
from humv_usd.render import quality as Q

MANIFEST_NAME = "manifest.json"


def versions(mi) -> dict:
    import drjit
    import OpenImageIO
    from pxr import Usd

    return {
        "humv_usd": humv_usd.__version__,
        "mitsuba": mi.__version__,
        "drjit": drjit.__version__,
        "usd": ".".join(str(v) for v in Usd.GetVersion()),
        "numpy": np.__version__,
        "OpenImageIO": OpenImageIO.VERSION_STRING,
    }


class ErrorAccumulator:
    """Pixel-weighted mean and max of the Monte Carlo error over several images."""

    def __init__(self):
        self.sums = defaultdict(float)
        self.counts = defaultdict(int)
        self.maxima: dict[str, float] = {}

    def add(self, stderr_l, stderr_k):
        for name, a in (("radiance_stderr", stderr_l), ("temperature_stderr", stderr_k)):
            a = a[np.isfinite(a)]
            if a.size:
                self.sums[name] += float(a.sum())
                self.counts[name] += a.size
                self.maxima[name] = max(self.maxima.get(name, 0.0), float(a.max()))

    def merge(self, other: ErrorAccumulator) -> None:
        """Add what ``other`` summed (the same totals as adding its images again)."""
        for name, total in other.sums.items():
            self.sums[name] += total
            self.counts[name] += other.counts[name]
        for name, top in other.maxima.items():
            self.maxima[name] = max(self.maxima.get(name, 0.0), top)

    def stats(self) -> dict:
        def mean(n):
            return self.sums[n] / self.counts[n] if self.counts[n] else None

        return {
            "radiance_stderr_mean": mean("radiance_stderr"),
            "radiance_stderr_max": self.maxima.get("radiance_stderr"),
            "temperature_stderr_mean_k": mean("temperature_stderr"),
            "temperature_stderr_max_k": self.maxima.get("temperature_stderr"),
        }


def estimator_key(estimator: str) -> str:
    """The infrared estimator and the parameters its pixels depend on (part of an image's
    record settings: images of another estimator are other images)."""
    if estimator != "fast":
        return estimator
    return (
        f"fast (splits {E.DEFAULT_SPLITS}, replicas {E.DEFAULT_REPLICAS}, roulette from depth "
        f"{E.RR_DEPTH}, filter radius {E.DEFAULT_FILTER_RADIUS} px, back sides as cavities, "
        f"smooth shading (crease {E.SMOOTH_CREASE_DEG:g} deg))"
    )


def spp_mode(spp_auto: bool) -> str:
    """How the samples per pixel were chosen (record settings): given, or the automatic rule."""
    if not spp_auto:
        return "fixed"
    return (
        f"automatic (to NETD/{Q.AUTO_NETD_FRACTION:g}, p99 <= {Q.AUTO_P99_K:g} K on the image and per region "
        f"of >= {Q.MIN_REGION_PIXELS} px, >= {Q.MIN_BATCHES} batches, <= {Q.AUTO_MAX_SPP} spp, "
        f"seed stride {Q.AUTO_SEED_STRIDE}, per-pixel direct positions <= {E.MAX_PIXEL_DIRECT_FACTOR})"
    )


def sensor_record(plan, run, s: SensorModel, done: list[dict]) -> dict:
    """The manifest entry of one IR sensor (its frames from the records of all calls)."""
    rec = run.per_sensor[s.name]
    mine = [r for r in done if r["sensor"] == s.name]
    return {
        "name": s.name,
        "prim": s.path,
        "band": s.band,
        "wavelength_range_um": list(s.wavelength_range_um),
        "response": None
        if s.band_response is None
        else {"wavelengths_um": s.band_response[0], "values": s.band_response[1]},
        "resolution": list(s.resolution),
        "netd_k": s.netd_k,
        "netd_origin": s.netd_note,
        "subbands_um": [list(b) for b in plan.sub_of[s.name].bands],
        "subbands_requested": plan.n_of[s.name],
        "subbands_source": plan.n_source[s.name],
        "spp_per_subband": plan.spp_sub[s.name],
        "camera": os.path.join(s.name, CAMERA_FILE) if mine else None,
        "frames": [r["entry"] for r in mine],
        "timings_s": {**rec["timings"], "total": sum(rec["timings"].values())},
        "monte_carlo_error": R.merge_errors(mine),
        "monte_carlo_error_k": interior_summary([r["entry"].get("monte_carlo_error_k") or {} for r in mine]),
        "quality": Q.quality_summary([r["entry"] for r in mine]),
    }


def interior_summary(per_frame: list[dict]) -> dict:
    """Per-sensor error in K away from geometric edges (mean over frames of the per-frame means,
    worst per-frame 99th percentile) and on edges (pixel footprint: signal, reported apart)."""
    s = Q.frames_summary(per_frame, "mean_k", "p99_k", "edge_mean_k")
    unit = next((f["unit"] for f in per_frame if f.get("unit")), None)  # NIR/SWIR: relative
    return {
        "mean_k": s["mean"],
        "p99_max_k": s["p99_max"],
        "edge_mean_k": s["edge_mean"],
        **({"unit": unit} if unit else {}),
        "definition": f"per-pixel Monte Carlo standard error {'in K' if unit is None else unit}; mean and "
        "99th percentile over pixels away from geometric edges (8-neighbours on the same part within 2 % "
        "depth), edge pixels apart",
        "not_estimable": None if s["mean"] is not None else "spp < 2: one replica, no error estimate",
        "spp_used": s["spp_used"],
        "spp_rule": s["spp_rule"],
    }


def radiometry_record(plan) -> dict:
    """The manifest's radiometry: sub-bands, sky and sun models."""
    if plan.spectra0.solar_irradiance is not None:
        sun_source = "humv:atmosphere:solarSpectralIrradiance"
    elif plan.use_sun:
        sun_source = f"humv:environment:directNormalIrradiance with a {radiometry.SUN_FALLBACK_NOTE}"
    else:
        sun_source = None
    return {
        "subbands": plan.n_of,
        "subbands_option": plan.subbands_option,
        "subbands_default": radiometry.DEFAULT_SUBBANDS,
        "spp_per_subband": plan.spp_sub,
        "model": "per sub-band gray Lambertian render summed with the sensor response; "
        "L = sum_k tau_k(r) S_k + P_k(r) per pixel by range (see humv_usd.render.radiometry)",
        "sky": "envmap from the zenith table"
        if plan.use_sky_map
        else "uniform (blackbody at skyTemperature)",
        "sun_emitter": bool(plan.use_sun),
        "sun_source": sun_source,
        "atmosphere_model": plan.spectra0.model,
    }


def closure_record(run) -> dict:
    """The manifest's Kirchhoff closure: per material and sensor band the largest
    |eps + rho + tau - 1| at the table's nodes and the table taken as given there."""
    recs = list(run.closure_records.values())
    return {
        "rule": "eps + rho + tau = 1 (Kirchhoff); thermal bands take the emissivity as given (the render "
        "reflects 1 - eps - tau), reflective bands the reflectance (humv_usd.render.bands.authority)",
        "tolerance": bands.CLOSURE_TOLERANCE,
        "max_error": max((r["max_error"] for r in recs), default=None),
        "not_met": [r for r in recs if not r["ok"]],
        "checked": len(recs),
    }


def estimator_settings(plan) -> dict:
    """What the infrared estimator was and how its error is estimated (manifest ``settings``)."""
    if plan.estimator == "fast":
        return {
            "estimator": "fast",
            "estimator_note": plan.estimator_note,
            "integrator": "humv_usd.render.estimator.render_band_fast: sub-bands on one path, emission "
            "evaluated, sun by next-event estimation, sky + ground control variate, "
            f"{E.DEFAULT_SPLITS} stratified reflection directions per camera sample, Russian roulette "
            f"from depth {E.RR_DEPTH}, reflected radiance averaged over a "
            f"{2 * E.DEFAULT_FILTER_RADIUS + 1}^2 px window on the same surface",
            "shading": "smooth: each face's surface terms (emission at its layer temperature, "
            "reflected G and sun) blended at shared vertices over faces within "
            f"{E.SMOOTH_CREASE_DEG:g} deg of each other (area-weighted) and interpolated at the hit "
            "(Gouraud); the path tracer shades one value per flat face",
            "film": "box filter (each sample in its pixel), path per sample at its first hit's range",
            "sampler": "Cranley-Patterson rotated Fibonacci lattices per pixel (pixel position, "
            f"first reflection direction), independent replicas: the smallest divisor >= {E.DEFAULT_REPLICAS} of spp",
            "spp_meaning": "camera samples per pixel, shared by all sub-bands",
            "emissivity_weighting_temperature_k": EMISSIVITY_WEIGHTING_TEMPERATURE_K,
            "stderr": "standard error of the pixel mean from the spread of the replica means "
            "(randomised quasi-Monte Carlo), c4-corrected, filtered part propagated as sum w^2 var; "
            "NaN (not estimable) when spp < 2; in K: divided by dL_band/dT at the pixel's brightness "
            "temperature",
        }
    return {
        "estimator": "path",
        "estimator_note": plan.estimator_note,
        "integrator": "moment(path)",
        "film": "hdrfilm luminance, box filter",
        "sampler": "independent",
        "spp_meaning": "samples per pixel split over the sub-bands (see spp_per_subband)",
        "emissivity_weighting_temperature_k": EMISSIVITY_WEIGHTING_TEMPERATURE_K,
        "stderr": "sqrt(max(m2 - m1^2, 4 * 2^-24 * m2) / (spp - 1)) per pixel from the moment "
        "integrator (the floor is the float32 resolution of the moments; NaN for spp = 1); in K: "
        "divided by dL_band/dT at the pixel's brightness temperature",
    }


def build(plan, run, ground_truth, totals: dict, done: list[dict]) -> dict:
    """The render folder's manifest (``OUT/manifest.json``): this call's settings and timings,
    the frames of all calls (from the records)."""
    eo_frames = {s.name: [r["entry"] for r in done if r["sensor"] == s.name] for s in plan.eo_run.sensors}
    return {
        "stage": os.path.abspath(plan.stage_path),
        "output_dir": plan.out_dir,
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "versions": versions(plan.mi),
        "mitsuba_variant": mode.variant(),
        "mitsuba_variant_reason": mode.variant_reason(),
        "settings": {
            "spp": int(plan.spp),
            "frames": sorted({r["frame"] for r in done}),
            "seed": int(plan.seed),
            "seed_per_frame": "seed + frame",
            "max_depth": int(plan.max_depth),
            "spp_auto": bool(plan.spp_auto),
            "spp_auto_rule": "fast estimator without a given spp: "
            + Q.rule_text(True, plan.spp, "the sensor's NETD")
            + " (per sensor and frame: monte_carlo_error_k.spp_used, quality; humv_usd.render.quality)"
            if plan.spp_auto
            else None,
            **estimator_settings(plan),
        },
        "channels": {
            **{
                name: writers.channel_info(name, unit, half=("R", "G", "B"))
                for name, unit in writers.EXR_CHANNELS.items()
            },
            **plan.truth.channel_units(),
        },
        "ground_truth": ground_truth,
        "preview": {
            "format": "PNG, 8-bit grayscale",
            "quantity": "brightness_temperature",
            "stretch": "linear between the 1st and 99th percentile of each image "
            "(levels per frame in preview_levels_k); non-finite pixels black",
        },
        "sensors": [sensor_record(plan, run, s, done) for s in plan.rendered],
        "eo_sensors": plan.eo_run.manifest(eo_frames),
        "skipped_sensors": plan.skipped + plan.eo_run.skipped,
        "radiometry": radiometry_record(plan),
        "kirchhoff_closure": closure_record(run),
        "sensor_chain": run.chains.status(),
        "scene_builds": run.scene_builds,
        "timings_s": totals,
        "monte_carlo_error": R.merge_errors([r for r in done if r["kind"] == "ir"]),
        "rendered_this_call": run.frames_rendered,
    }
