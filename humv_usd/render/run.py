"""``render_stage``: render every infrared sensor of a composed stage, frame by frame."""
from __future__ import annotations

import datetime as _dt
import os
import tempfile
import time
from collections import defaultdict

import numpy as np

from humv_usd.errors import InputError, bad_value
from humv_usd.physics import planck
from humv_usd.render import mode, writers
from humv_usd.render.export import Sensor, StageExport, stage_frames
from humv_usd.usd.layers import open_stage
from humv_usd.render.ir import IRScene, SensorSetup, monte_carlo_stderr

#: Temperature of the blackbody that weights the band emissivity [K].
EMISSIVITY_WEIGHTING_TEMPERATURE_K = 300.0
MANIFEST_NAME = "manifest.json"
TIMING_KEYS = ("load_export", "render", "labels", "write")


def _versions(mi) -> dict:
    import drjit
    import OpenImageIO
    from pxr import Usd

    import humv_usd

    return {
        "humv_usd": humv_usd.__version__,
        "mitsuba": mi.__version__,
        "drjit": drjit.__version__,
        "usd": ".".join(str(v) for v in Usd.GetVersion()),
        "numpy": np.__version__,
        "OpenImageIO": OpenImageIO.VERSION_STRING,
    }


def _check_settings(spp, seed, max_depth):
    if isinstance(spp, bool) or not isinstance(spp, (int, np.integer)) or not 1 <= spp <= 2**20:
        raise InputError(bad_value("spp", spp, "expected an integer in 1..1048576"))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**32:
        raise InputError(bad_value("seed", seed, "expected an integer in 0..4294967295"))
    if isinstance(max_depth, bool) or not isinstance(max_depth, (int, np.integer)) or not (max_depth == -1 or max_depth >= 1):
        raise InputError(bad_value("max_depth", max_depth, "expected -1 (unbounded, Russian roulette) or an integer >= 1"))


def _select_frames(stage, frames) -> list[int]:
    available = stage_frames(stage)
    if frames is None:
        return available
    if isinstance(frames, (int, np.integer)) and not isinstance(frames, bool):
        frames = [frames]
    out: list[int] = []
    for f in frames:
        if isinstance(f, bool) or not isinstance(f, (int, np.integer)):
            raise InputError(bad_value("frames", f, "expected integer frames"))
        if not available[0] <= f <= available[-1]:
            raise InputError(bad_value("frames", int(f), f"expected frames in the stage's time range "
                                                         f"{available[0]}..{available[-1]} (startTimeCode..endTimeCode)"))
        if int(f) not in out:
            out.append(int(f))
    if not out:
        raise InputError(bad_value("frames", list(frames), "expected at least one frame"))
    return out


def _select_sensors(all_sensors: list[Sensor], wanted) -> list[Sensor]:
    if wanted is None:
        return list(all_sensors)
    if isinstance(wanted, str):
        wanted = [wanted]
    by_key = {}
    for s in all_sensors:
        by_key[s.name] = s
        by_key[s.path] = s
    out = []
    for w in wanted:
        if w not in by_key:
            names = ", ".join(s.name for s in all_sensors) or "none"
            raise InputError(bad_value("sensors", w, f"expected a sensor name or prim path; the stage has: {names}"))
        if by_key[w] not in out:
            out.append(by_key[w])
    return out


class _Accumulator:
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

    def stats(self) -> dict:
        def mean(n):
            return self.sums[n] / self.counts[n] if self.counts[n] else None

        return {
            "radiance_stderr_mean": mean("radiance_stderr"),
            "radiance_stderr_max": self.maxima.get("radiance_stderr"),
            "temperature_stderr_mean_k": mean("temperature_stderr"),
            "temperature_stderr_max_k": self.maxima.get("temperature_stderr"),
        }


def _error_stats(stderr_l: np.ndarray, stderr_k: np.ndarray) -> dict:
    acc = _Accumulator()
    acc.add(stderr_l, stderr_k)
    return acc.stats()


def render_stage(stage_path, out_dir, frames=None, spp=16, sensors=None, seed=0, max_depth=-1) -> dict:
    """Render the infrared sensors of a composed HumV-USD stage.

    For every camera with HumvSensorAPI attributes whose band starts at or above 3 um, and every
    requested frame, renders band radiance with Mitsuba 3 (mono variant, see
    :mod:`humv_usd.render.mode`) and writes ``OUT/<sensor>/<frame:04d>.exr`` (float32 channels
    ``radiance`` [W m^-2 sr^-1], ``brightness_temperature`` [K], ``radiance_stderr``
    [W m^-2 sr^-1], ``depth`` [m], ``instance_id`` [integer stored as float32]), an 8-bit
    grayscale preview ``OUT/<sensor>/<frame:04d>.png`` (brightness temperature stretched between
    its 1st and 99th percentile) and ``OUT/manifest.json``. EO sensors are listed as skipped.

    Parameters
    ----------
    stage_path : path-like
        Composed stage (``stage.usda``).
    out_dir : path-like
        Output directory (created).
    frames : list of int, optional
        Frames (time codes) to render; default every integer frame from startTimeCode to
        endTimeCode. A frame outside that range is an InputError.
    spp : int, default 16
        Samples per pixel.
    sensors : list of str, optional
        Sensor names (camera prim names) or prim paths; default all.
    seed : int, default 0
        Sampler seed; frame ``f`` uses ``seed + f``.
    max_depth : int, default -1
        Path depth; -1 is unbounded (unbiased, Russian roulette).

    Returns
    -------
    dict
        The manifest (also written to ``OUT/manifest.json``).

    Raises
    ------
    InputError
        Bad arguments or a stage that lacks what rendering needs (the message names the prim,
        attribute, value and allowed range).

    Notes
    -----
    Radiometry: opaque gray-band Lambertian surfaces. A part of a mesh bound to a material with
    spectral emissivity :math:`\\varepsilon(\\lambda)` gets the band emissivity
    :math:`\\varepsilon_b = \\int \\varepsilon R B(\\lambda, 300 K) d\\lambda / \\int R B(\\lambda, 300 K) d\\lambda`
    (R the sensor response, or 1 over the band), emits :math:`\\varepsilon_b L_b(T_{face})` from
    its front side and reflects with :math:`1 - \\varepsilon_b` (Kirchhoff). The same
    :math:`\\varepsilon_b` on both sides keeps an isothermal scene exactly at :math:`L_b(T)`;
    for a non-gray material at a temperature far from 300 K the band average is approximate,
    and spectral sub-bands (a later issue) reduce that error. The sky is a uniform environment
    at :math:`L_b(T_{sky})`, no atmospheric path radiance or transmission yet. Faces are
    one-sided (their back neither emits nor reflects). Next-event estimation samples the sky only
    (see :data:`humv_usd.render.ir.AREA_EMITTER_SAMPLING_WEIGHT`).

    Monte Carlo error: ``radiance_stderr`` is the standard error of each pixel's mean from the
    ``moment`` integrator, :math:`\\sqrt{(m_2 - m_1^2)/(n-1)}`, floored at the float32
    resolution of the moments (:func:`humv_usd.render.ir.monte_carlo_stderr`); the manifest also
    gives it in K (divided by :math:`dL_b/dT` at the pixel's brightness temperature).

    Timings: ``load_export`` covers opening the stage, reading USD per frame, building the
    Mitsuba scene (once per set of visible meshes) and per-sensor parameter updates; ``render``
    the Monte Carlo render plus the brightness temperature and error images; ``labels`` the ray
    cast; ``write`` the EXR/PNG files.
    """
    t_start = time.perf_counter()
    _check_settings(spp, seed, max_depth)
    out_dir = os.path.abspath(os.fspath(out_dir))
    totals = dict.fromkeys(TIMING_KEYS, 0.0)

    t = time.perf_counter()
    stage = open_stage(stage_path)
    exporter = StageExport(stage)
    if not exporter.sensors:
        raise InputError(f"{stage_path}: no sensor to render: the stage has no camera with "
                         "HumvSensorAPI attributes (add a [[sensor]] to the scenario)")
    frame_list = _select_frames(stage, frames)
    selected = _select_sensors(exporter.sensors, sensors)
    rendered = [s for s in selected if s.rendered]
    skipped = [{"name": s.name, "prim": s.path, "band": s.band, "reason": s.skip_reason}
               for s in selected if not s.rendered]
    mi = mode.mitsuba()
    totals["load_export"] += time.perf_counter() - t

    sensor_ids = {s.name: f"sensor_{i}" for i, s in enumerate(rendered)}
    per_sensor = {s.name: {"timings": dict.fromkeys(TIMING_KEYS, 0.0), "frames": [], "errors": _Accumulator()}
                  for s in rendered}
    overall = _Accumulator()
    band_eps: dict[tuple[str, str], float] = {}
    scene: IRScene | None = None
    scene_key = None
    scene_builds = 0

    for frame in frame_list if rendered else []:
        t = time.perf_counter()
        state = exporter.frame_state(frame, rendered)
        parts = [(part, state.points[m.path][part.vertex_ids], state.flip[m.path])
                 for m in state.meshes for part in m.parts]
        if scene is None or state.topology_key != scene_key:
            setups = [SensorSetup(sensor_ids[s.name], s.resolution[0], s.resolution[1], state.cameras[s.name])
                      for s in rendered]
            with tempfile.TemporaryDirectory(prefix="humv_render_") as tmp:
                scene = IRScene(parts, setups, spp=spp, max_depth=max_depth, workdir=tmp)
            scene_key = state.topology_key
            scene_builds += 1
        else:
            for part, vertices, _ in parts:
                scene.set_vertices(part, vertices)
        for s in rendered:
            scene.set_camera(sensor_ids[s.name], state.cameras[s.name])
        scene.update()
        totals["load_export"] += time.perf_counter() - t

        for s in rendered:
            timings = per_sensor[s.name]["timings"]
            band, response = s.wavelength_range_um, s.response
            t = time.perf_counter()
            for m in state.meshes:
                face_l = planck.band_radiance(state.temperatures[m.path], band, response)
                for part in m.parts:
                    eps = _band_emissivity(band_eps, part.material, s)
                    scene.set_surface(part, eps * face_l[part.triangle_face], 1.0 - eps)
            scene.set_sky(planck.band_radiance(state.sky_temperature_k, band, response))
            scene.update()
            dt = time.perf_counter() - t
            timings["load_export"] += dt
            totals["load_export"] += dt

            t = time.perf_counter()
            m1, m2 = scene.render(sensor_ids[s.name], spp=spp, seed=seed + frame)
            stderr_l = monte_carlo_stderr(m1, m2, spp)
            bt, dl_dt = planck.brightness_temperature_sensitivity(m1, band, response)
            with np.errstate(invalid="ignore", divide="ignore"):
                stderr_k = np.where(dl_dt > 0, stderr_l / dl_dt, np.nan)
            dt = time.perf_counter() - t
            timings["render"] += dt
            totals["render"] += dt

            t = time.perf_counter()
            depth, instance = scene.labels(sensor_ids[s.name])
            dt = time.perf_counter() - t
            timings["labels"] += dt
            totals["labels"] += dt

            t = time.perf_counter()
            rel = os.path.join(s.name, f"{frame:04d}")
            writers.write_exr(os.path.join(out_dir, rel + ".exr"), {
                "radiance": m1,
                "brightness_temperature": bt,
                "radiance_stderr": stderr_l,
                "depth": depth,
                "instance_id": instance.astype(np.float32),
            }, metadata={"humv:sensor": s.path, "humv:frame": str(frame),
                         "humv:band_um": f"{band[0]:g}-{band[1]:g}", "humv:spp": str(spp)})
            levels = writers.write_preview_png(os.path.join(out_dir, rel + ".png"), bt)
            dt = time.perf_counter() - t
            timings["write"] += dt
            totals["write"] += dt

            per_sensor[s.name]["errors"].add(stderr_l, stderr_k)
            overall.add(stderr_l, stderr_k)
            finite_bt = bt[np.isfinite(bt)]
            per_sensor[s.name]["frames"].append({
                "frame": frame,
                "exr": rel + ".exr",
                "png": rel + ".png",
                "preview_levels_k": list(levels),
                "radiance_mean": float(np.mean(m1)),
                "brightness_temperature_mean_k": float(finite_bt.mean()) if finite_bt.size else None,
                "sky_temperature_k": state.sky_temperature_k,
                "monte_carlo_error": _error_stats(stderr_l, stderr_k),
            })

    totals["total"] = time.perf_counter() - t_start
    manifest = {
        "stage": os.path.abspath(os.fspath(stage_path)),
        "output_dir": out_dir,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "versions": _versions(mi),
        "mitsuba_variant": mode.variant(),
        "mitsuba_variant_reason": mode.variant_reason(),
        "settings": {
            "spp": int(spp), "frames": frame_list, "seed": int(seed), "seed_per_frame": "seed + frame",
            "max_depth": int(max_depth), "integrator": "moment(path)", "film": "hdrfilm luminance, box filter",
            "sampler": "independent", "emissivity_weighting_temperature_k": EMISSIVITY_WEIGHTING_TEMPERATURE_K,
            "stderr": "sqrt(max(m2 - m1^2, 4 * 2^-24 * m2) / (spp - 1)) per pixel from the moment "
                      "integrator (the floor is the float32 resolution of the moments; NaN for spp = 1); in K: "
                      "divided by dL_band/dT at the pixel's brightness temperature",
        },
        "channels": {name: {"unit": unit, "dtype": "float32"} for name, unit in writers.EXR_CHANNELS.items()},
        "preview": {"format": "PNG, 8-bit grayscale", "quantity": "brightness_temperature",
                    "stretch": "linear between the 1st and 99th percentile of each image "
                               "(levels per frame in preview_levels_k); non-finite pixels black"},
        "sensors": [{
            "name": s.name, "prim": s.path, "band": s.band,
            "wavelength_range_um": list(s.wavelength_range_um),
            "response": None if s.response is None else {"wavelengths_um": s.response[0], "values": s.response[1]},
            "resolution": list(s.resolution),
            "frames": per_sensor[s.name]["frames"],
            "timings_s": {**per_sensor[s.name]["timings"],
                          "total": sum(per_sensor[s.name]["timings"].values())},
            "monte_carlo_error": per_sensor[s.name]["errors"].stats(),
        } for s in rendered],
        "skipped_sensors": skipped,
        "scene_builds": scene_builds,
        "timings_s": totals,
        "monte_carlo_error": overall.stats(),
    }
    writers.write_json(os.path.join(out_dir, MANIFEST_NAME), manifest)
    return writers._jsonable(manifest)


def _band_emissivity(cache: dict, material, sensor: Sensor) -> float:
    key = (material.path, sensor.name)
    if key not in cache:
        band = sensor.wavelength_range_um
        wl = material.wavelengths_um
        if wl.size > 1 and (wl[-1] < band[0] or wl[0] > band[1]):
            raise InputError(bad_value(
                f"{material.path}.humv:material:wavelengths", f"{wl[0]:g}-{wl[-1]:g} um",
                f"expected a table that reaches into the band {band[0]:g}-{band[1]:g} um of sensor {sensor.path}"))
        cache[key] = planck.band_emissivity(wl, material.emissivity, band, sensor.response,
                                            temperature_k=EMISSIVITY_WEIGHTING_TEMPERATURE_K)
    return cache[key]
