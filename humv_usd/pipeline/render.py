"""``render_stage``: render every infrared sensor of a composed stage, frame by frame."""

from __future__ import annotations

import datetime as _dt
import hashlib
import logging
import os
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd

import humv_usd
from humv_usd import images as writers
from humv_usd import mode
from humv_usd.constants import EMISSIVITY_WEIGHTING_TEMPERATURE_K
from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import check_output_dir, folder_lock, jsonable, remove_stale_temps, write_json
from humv_usd.geometry.camera import CAMERA_FILE, Camera, camera_file
from humv_usd.groundtruth import GroundTruth  # here: groundtruth imports render.writers
from humv_usd.physics import planck
from humv_usd.physics import sensor as chain
from humv_usd.physics.sensor import SensorModel
from humv_usd.pipeline import records as R
from humv_usd.pipeline.budget import render_budget, require_fits
from humv_usd.pipeline.preflight import check_stage_for_render
from humv_usd.pipeline.writer import BackgroundWriter
from humv_usd.render import eo as eo_render
from humv_usd.render import estimator as E
from humv_usd.render import quality as Q
from humv_usd.render import radiometry
from humv_usd.render.estimator import render_band_fast
from humv_usd.render.export import StageExport
from humv_usd.render.frame import path_table as read_path_table
from humv_usd.render.frame import stage_frames
from humv_usd.render.ir import (  # noqa: F401
    MIN_SUBBAND_SPP,
    IRScene,
    SensorSetup,
    monte_carlo_stderr,
    render_band,
    subband_spp,
)
from humv_usd.usd import environment as usd_environment
from humv_usd.usd import thermal as usd_thermal
from humv_usd.usd.atmosphere import AtmosphereSpectra, atmosphere_spectra
from humv_usd.usd.layers import open_stage
from humv_usd.usd.materials import band_emissivity, subband_emissivity, subband_transmittance
from humv_usd.usd.paths import human_path
from humv_usd.usd.sensor import check_subbands, read_sensor_model

log = logging.getLogger(__name__)

MANIFEST_NAME = "manifest.json"
#: frames between flushes of Dr.Jit's kernel cache (:func:`humv_usd.mode.release_kernel_cache`):
#: keeps the memory of a long render flat at the cost of compiling kernels again
KERNEL_CACHE_FRAMES = 10
#: Frames whose files may still be being written (by :class:`BackgroundWriter`) while the next
#: frame renders; 1 bounds the memory to about two frames of images.
WRITE_FRAMES_AHEAD = 1
#: Infrared estimators: "fast" (:func:`humv_usd.render.estimator.render_band_fast`: sub-bands on
#: one path, emission evaluated, sky control variate, stratified, RQMC error) and "path" (the
#: plain Mitsuba path tracer per sub-band, :func:`humv_usd.render.ir.render_band`: the reference,
#: and what the scalar fallback variant runs).
ESTIMATORS = ("fast", "path")
DEFAULT_ESTIMATOR = "fast"
#: Samples per pixel when the caller gives none, per estimator.
DEFAULT_SPP = {"fast": E.DEFAULT_SPP, "path": 16}
#: Samples per pixel of the visible (EO) path tracer (`--estimator path`) when the caller gives
#: none; the fast EO estimator then picks them (humv_usd.render.eo_fast: automatic quality).
EO_DEFAULT_SPP = 16
TIMING_KEYS = ("load_export", "render", "labels", "write")


def _versions(mi) -> dict:
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


def _check_settings(spp, seed, max_depth):
    if isinstance(spp, bool) or not isinstance(spp, (int, np.integer)) or not 1 <= spp <= 2**20:
        raise InputError(bad_value("spp", spp, "expected an integer in 1..1048576"))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**32:
        raise InputError(bad_value("seed", seed, "expected an integer in 0..4294967295"))
    if (
        isinstance(max_depth, bool)
        or not isinstance(max_depth, (int, np.integer))
        or not (max_depth == -1 or max_depth >= 1)
    ):
        raise InputError(
            bad_value("max_depth", max_depth, "expected -1 (unbounded, Russian roulette) or an integer >= 1")
        )


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
            raise InputError(
                bad_value(
                    "frames",
                    int(f),
                    f"expected frames in the stage's time range "
                    f"{available[0]}..{available[-1]} (startTimeCode..endTimeCode)",
                )
            )
        if int(f) not in out:
            out.append(int(f))
    if not out:
        raise InputError(bad_value("frames", list(frames), "expected at least one frame"))
    return out


def _select_sensors(all_sensors: list[SensorModel], wanted) -> list[SensorModel]:
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
            raise InputError(
                bad_value("sensors", w, f"expected a sensor name or prim path; the stage has: {names}")
            )
        if by_key[w] not in out:
            out.append(by_key[w])
    return out


# The automatic quality's rules, batching and error summaries: humv_usd.render.quality (one module)
AUTO_SEED_STRIDE = Q.AUTO_SEED_STRIDE
AUTO_MAX_SPP = Q.AUTO_MAX_SPP
AUTO_NETD_FRACTION = Q.AUTO_NETD_FRACTION
AUTO_P99_K = Q.AUTO_P99_K


def _needs_more_samples(plan, sensor, noise: dict, batches: int, regions: dict | None = None) -> bool:
    """Automatic quality (no spp given, fast estimator): another batch while fewer than
    :data:`humv_usd.render.quality.MIN_BATCHES` were taken, or the mean error away from edges
    exceeds NETD / 3 or its 99th percentile exceeds AUTO_P99_K on the image (``noise``) or on a
    labelled region (``regions``, :func:`humv_usd.render.quality.region_stats`), and fewer than
    AUTO_MAX_SPP samples were spent."""
    if not plan.spp_auto or noise.get("mean_k") is None:
        return False
    netd = getattr(sensor, "netd_k", None)
    if not netd or netd <= 0:
        return False
    return Q.needs_more(True, Q.verdict(noise, regions or {}, netd), batches, plan.spp)


def _netd_text(sensor) -> str:
    """The sensor's NETD for a sentence (float32 attributes print as 0.019999999552965164)."""
    netd = getattr(sensor, "netd_k", None)
    return "no NETD" if netd is None else f"{float(netd):.4g} K"


def _spp_rule(plan, sensor) -> str:
    return Q.rule_text(plan.spp_auto, plan.spp, _netd_text(sensor))


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

    def merge(self, other: _Accumulator) -> None:
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


def render_stage(
    stage_path,
    out_dir,
    frames=None,
    spp=None,
    sensors=None,
    seed=0,
    max_depth=-1,
    annotators=None,
    subbands=None,
    estimator=DEFAULT_ESTIMATOR,
    progress=None,
    force=False,
    wait=False,
    yes=False,
) -> dict:
    r"""Render the infrared sensors of a composed HumV-USD stage.

    For every camera with HumvSensorAPI attributes whose band starts at or above 3 um, and every
    requested frame, renders band radiance with Mitsuba 3 (mono variant, see
    :mod:`humv_usd.mode`) and writes ``OUT/<sensor>/<frame:04d>.exr`` (float32 channels
    ``radiance`` [W m^-2 sr^-1], ``brightness_temperature`` [K], ``radiance_stderr``
    [W m^-2 sr^-1], ``depth`` [m], ``instance_id`` [integer stored as float32]), an 8-bit
    grayscale preview ``OUT/<sensor>/<frame:04d>.png`` (brightness temperature stretched between
    its 1st and 99th percentile) and ``OUT/manifest.json``. EO sensors render with the fast EO
    estimator (:mod:`humv_usd.render.eo_fast`; ``estimator="path"``: Mitsuba's spectral path
    tracer, :mod:`humv_usd.render.eo`).

    Parameters
    ----------
    stage_path : path-like
        Composed stage (``stage.usda``).
    out_dir : path-like
        Output directory (created).
    frames : list of int, optional
        Frames (time codes) to render; default every integer frame from startTimeCode to
        endTimeCode. A frame outside that range is an InputError.
    spp : int, optional
        Samples per pixel: for the fast estimator, camera samples per pixel shared by all
        sub-bands (default :data:`humv_usd.render.estimator.DEFAULT_SPP`); for the path tracer,
        samples split over the sub-bands (default 16).
    estimator : {"fast", "path"}
        Infrared estimator (:data:`ESTIMATORS`).
    progress : callable(done, total, text), optional
        Called after each sensor of each frame is written (a progress display).
    sensors : list of str, optional
        SensorModel names (camera prim names) or prim paths; default all.
    seed : int, default 0
        Sampler seed; frame ``f`` uses ``seed + f``.
    max_depth : int, default -1
        Path depth; -1 is unbounded (unbiased, Russian roulette).
    subbands : int, optional
        Sub-bands per infrared band (1-64) for every IR sensor; default each sensor's
        ``humv:sensor:subbands`` (scenario key ``subbands``), else
        :data:`humv_usd.render.radiometry.DEFAULT_SUBBANDS`. ``spp`` is split over them
        (:func:`humv_usd.render.ir.subband_spp`).
    force : bool, default False
        Render the requested frames again even when they are done, and re-render the frames in
        the folder that were made with other settings (instead of refusing).
    wait : bool, default False
        Wait while another process writes ``out_dir`` (default: InputError naming it).
    yes : bool, default False
        Render even when the estimated memory or disk (:mod:`humv_usd.pipeline.budget`)
        exceeds this machine's (default: InputError with the estimate).
    annotators : list of str, optional
        Ground-truth annotators (:data:`humv_usd.groundtruth.ANNOTATORS`); default the stage's
        (scenario ``[annotations]``) or the default set. See :mod:`humv_usd.groundtruth`.

    Returns
    -------
    dict
        The manifest (also written to ``OUT/manifest.json``).

    Resuming: every finished image has a record (:mod:`humv_usd.pipeline.records`); a call
    renders only the requested frames whose images are not done with the same settings (stage
    content, spp and whether it is automatic, seed, depth, annotators, sub-bands, the infrared
    estimator and its parameters: :func:`humv_usd.pipeline.records.settings`), refuses
    (InputError, one line) when the folder holds images of the selected sensors made with other
    settings unless ``force``, and rebuilds the manifest, coco.json, regions.json and the camera
    files from all records of the selected sensors, so frames from separate calls (or a run
    killed and started again) accumulate into the result of one uninterrupted run. The folder
    is locked while the render runs (:func:`humv_usd.fileio.folder_lock`).

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
    for a non-gray material at a temperature far from 300 K the band average is approximate.
    The band is therefore split into ``subbands`` sub-bands (default
    :data:`humv_usd.render.radiometry.DEFAULT_SUBBANDS`), each rendered with its own emissivity,
    sky and sun and summed after the atmospheric path per pixel by range,
    :math:`L = \sum_k \tau_k(r) S_k + P_k(r)` (:func:`humv_usd.render.ir.render_band`,
    :mod:`humv_usd.render.radiometry`). The sky is an envmap from the atmosphere's spectral sky
    table, else a uniform blackbody at :math:`T_{sky}`; the sun a directional emitter when the
    stage has its direction and spectral irradiance and it is above the horizon. Faces are
    one-sided (their back neither emits nor reflects). Next-event estimation samples the sky and
    sun only (see :data:`humv_usd.render.ir.AREA_EMITTER_SAMPLING_WEIGHT`). EO sensors render in
    visible sub-bands with the fast estimator (:mod:`humv_usd.render.eo_fast`; without a given
    spp, batches until the error of Y is <= 1 % of the mean Y), or with ``estimator="path"`` in
    Mitsuba's spectral variant (:mod:`humv_usd.render.eo`). After the render, the sensor chain
    (:mod:`humv_usd.physics.sensor`) writes raw counts and an 8-bit image per IR/EO frame.

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
    eo_spp = EO_DEFAULT_SPP if spp is None else spp
    spp_auto = spp is None and estimator == "fast"
    if spp is None:
        spp = DEFAULT_SPP.get(estimator, DEFAULT_SPP["path"])
    _check_settings(spp, seed, max_depth)
    check_stage_for_render(stage_path, frames_given=frames is not None)  # what check flags as errors
    if estimator not in ESTIMATORS:
        raise InputError(bad_value("estimator", estimator, f"expected one of {', '.join(ESTIMATORS)}"))
    out_dir = os.path.abspath(check_output_dir(out_dir))
    with folder_lock(out_dir, "humv-usd render", wait=wait):
        args = (stage_path, out_dir, frames, spp, sensors, seed, max_depth, annotators, subbands)
        return _render_locked(t_start, args, (estimator, eo_spp, spp_auto), force, yes, progress)


def _render_locked(t_start, args, how, force, yes=False, progress=None) -> dict:
    """``args`` and ``how`` (estimator, EO spp, automatic spp) as :func:`_plan` takes them."""
    out_dir = args[1]
    totals = dict.fromkeys(TIMING_KEYS, 0.0)
    t = time.perf_counter()
    plan = _plan(*args, *how)
    totals["load_export"] += time.perf_counter() - t
    budget = render_budget(  # every knob: pixels, spp, sub-bands, estimator, sensors, frames
        [s.resolution for s in plan.rendered],
        len(plan.frames),
        plan.spp,
        estimator=plan.estimator,
        subbands=max(plan.n_of.values(), default=1),
        eo_resolutions=[s.resolution for s in plan.eo_run.sensors],
        eo_spp=plan.eo_run.spp,
    )
    require_fits(budget, out_dir, yes)  # before anything is written
    todo = _frames_to_render(plan, force)

    run = _FrameRenderer(plan, totals)
    frames_to_render = todo if (plan.rendered or plan.eo_run.sensors) else []
    run.progress = progress  # counts the images rendered in this call only
    run.units_total = len(frames_to_render) * (len(plan.rendered) + len(plan.eo_run.sensors))
    t_writes = time.perf_counter()
    with BackgroundWriter(frames_ahead=WRITE_FRAMES_AHEAD) as writer:  # frame N is written while N+1 renders
        run.writer = writer
        for frame in frames_to_render:
            run.render_frame(frame)
            run.record_frame(frame)  # queued after the frame's files: a record follows complete files
            t = time.perf_counter()
            writer.end_frame()
            totals["write"] += time.perf_counter() - t  # waiting for the writer (it was slower)
            mode.frame_rendered(KERNEL_CACHE_FRAMES)  # every KERNEL_CACHE_FRAMES of this process
        t = time.perf_counter()
    totals["write"] += time.perf_counter() - t  # waiting for the last frame's files
    totals["write_background"] = writer.seconds  # the writer thread's time, overlapped with renders
    totals["write_background_cpu"] = writer.cpu_seconds
    run.writer = None
    log.debug("frames and their writes took %.2f s", time.perf_counter() - t_writes)
    done = _records_of_this_render(plan)
    _write_cameras(out_dir, done)

    t = time.perf_counter()
    taken = [r["truth"] for r in done if r.get("truth")]
    ground_truth = plan.truth.finish(out_dir, totals["render"], taken=taken)
    totals["labels"] += time.perf_counter() - t
    totals["total"] = time.perf_counter() - t_start
    manifest = _manifest(plan, run, ground_truth, totals, done)
    write_json(os.path.join(out_dir, MANIFEST_NAME), manifest)
    return jsonable(manifest)


# ------------------------------------------------------------------------------- resuming
def stage_digest(stage: Usd.Stage) -> str:
    """SHA-256 (16 hex digits) of the content of every layer file of the stage's layer stack:
    an image rendered from another stage content is another image."""
    h = hashlib.sha256()
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        path = layer.realPath
        h.update((path and os.path.basename(path) or layer.identifier).encode())
        h.update(
            R.file_sha256(path).encode() if path and os.path.isfile(path) else layer.ExportToString().encode()
        )
    return h.hexdigest()[:16]


def _selected(plan: _Plan) -> list[SensorModel]:
    return list(plan.rendered) + list(plan.eo_run.sensors)


def _frames_to_render(plan: _Plan, force: bool) -> list[int]:
    """The requested frames not done with this call's settings (all with ``force``), plus with
    ``force`` the frames of images made with other settings; refuse those without ``force``.
    Removes what a killed render left: temp files and the files of images without a record."""
    out_dir = plan.out_dir
    names = [s.name for s in _selected(plan)]
    for folder in [out_dir, *(os.path.join(out_dir, n) for n in names)]:
        remove_stale_temps(folder)
    for n in names:
        remove_stale_temps(os.path.join(out_dir, R.RECORDS_DIR, n))
    if os.path.isdir(os.path.join(out_dir, R.RECORDS_DIR)):
        for sensor, frame in R.unrecorded_images(out_dir, names):
            log.info("removing the partial image %s/%04d of an interrupted render", sensor, frame)
            R.remove_image(out_dir, sensor, frame)
    os.makedirs(os.path.join(out_dir, R.RECORDS_DIR), exist_ok=True)
    records = R.read_records(out_dir)
    other = sorted(
        (key, rec)
        for key, rec in records.items()
        if key[0] in plan.wanted and rec.get("settings") != plan.wanted[key[0]]
    )
    if other and not force:
        (sensor, frame), rec = other[0]
        more = f" (and {len(other) - 1} more images)" if len(other) > 1 else ""
        raise InputError(
            f"{out_dir}: {sensor}/{frame:04d}{more} was rendered with other settings "
            f"({R.difference(rec.get('settings') or {}, plan.wanted[sensor])}); render into another "
            "folder, or pass --force to render them again with these settings"
        )
    todo = set(plan.frames) if force else set()
    todo |= {frame for (_, frame), _ in other}
    for f in plan.frames:
        if any(not R.is_done(out_dir, records.get((n, f)), plan.wanted[n]) for n in names):
            todo.add(f)
    if force:
        for sensor, frame in sorted({k for k, _ in other}):
            R.remove_image(out_dir, sensor, frame)
    log.info("rendering %d of %d requested frames", len(set(plan.frames) & todo), len(plan.frames))
    return sorted(todo)


def _records_of_this_render(plan: _Plan) -> list[dict]:
    """The records of the selected sensors with this call's settings, in the order one
    uninterrupted render writes them."""
    order = {s.name: i for i, s in enumerate(_selected(plan))}
    records = [
        rec
        for (sensor, _), rec in R.read_records(plan.out_dir).items()
        if sensor in plan.wanted and rec.get("settings") == plan.wanted[sensor]
    ]
    return sorted(records, key=R.image_order(order))


def _write_cameras(out_dir: str, done: list[dict]) -> None:
    """``<sensor>/camera.json`` of every sensor rendered (intrinsics, per-frame pose)."""
    by_sensor: dict[str, list[dict]] = defaultdict(list)
    for rec in done:
        by_sensor[rec["sensor"]].append(rec)
    for name, recs in by_sensor.items():
        cameras = R.merge_cameras(recs)
        if cameras is not None:
            write_json(os.path.join(out_dir, name, CAMERA_FILE), cameras)


# ------------------------------------------------------------------------------- the plan
@dataclass
class _Plan:
    """What :func:`render_stage` renders, decided once from the stage and its options."""

    stage_path: str
    out_dir: str
    stage: Usd.Stage
    exporter: StageExport
    truth: GroundTruth
    mi: object  # the mitsuba module (its variant is set)
    frames: list[int]
    rendered: list[SensorModel]  # infrared sensors
    skipped: list[dict]
    eo_run: eo_render.EORender
    spp: int
    seed: int
    max_depth: int
    subbands_option: int | None
    n_of: dict[str, int]  # sub-bands per IR sensor
    n_source: dict[str, str]  # where that count comes from
    sub_of: dict[str, radiometry.SubBands]
    spp_sub: dict[str, int]
    spectra0: AtmosphereSpectra  # the atmosphere at the first frame
    use_sky_map: bool
    use_sun: bool
    sensor_ids: dict[str, str] = field(default_factory=dict)
    wanted: dict[str, dict] = field(default_factory=dict)  # per sensor: the settings of its images
    estimator: str = DEFAULT_ESTIMATOR
    estimator_note: str = ""
    spp_auto: bool = False


def _plan(
    stage_path,
    out_dir,
    frames,
    spp,
    sensors,
    seed,
    max_depth,
    annotators,
    subbands,
    estimator=DEFAULT_ESTIMATOR,
    eo_spp=None,
    spp_auto=False,
) -> _Plan:
    """Open the stage, select frames and sensors, and set up the radiometry (sub-bands per IR
    sensor; sky map and sun from the environment at the first frame) and the EO run."""
    stage = open_stage(stage_path)
    exporter = StageExport(stage)
    truth = GroundTruth(stage, annotators)
    if not exporter.sensors:
        raise InputError(
            f"{stage_path}: no sensor to render: the stage has no camera with "
            "HumvSensorAPI attributes (add a [[sensor]] to the scenario)"
        )
    frame_list = _select_frames(stage, frames)
    selected = _select_sensors(exporter.sensors, sensors)
    eo_sensors = [s for s in selected if s.rendered and s.kind == "EO"]
    rendered = [s for s in selected if s.rendered and s.kind != "EO"]  # infrared
    skipped = [
        {"name": s.name, "prim": s.path, "band": s.band, "reason": s.skip_reason}
        for s in selected
        if not s.rendered
    ]
    mi = mode.mitsuba()
    est, note = estimator, f"requested: {estimator}"
    if estimator == "fast" and not mode.is_vectorized():
        est, note = (
            "path",
            f"fast estimator needs a vectorised variant; {mode.variant()} runs the path tracer",
        )
    elif estimator == "fast" and max_depth != -1:
        est, note = "path", f"max_depth {max_depth} asks for a truncated path: the path tracer honours it"
    if est != estimator:
        log.warning("infrared estimator: %s", note)
    # sub-bands per sensor: the render option, else the sensor's humv:sensor:subbands, else the default
    override = None if subbands is None else check_subbands(subbands)
    n_of = {s.name: override or s.subbands or radiometry.DEFAULT_SUBBANDS for s in rendered}
    n_source = {
        s.name: (
            "render option subbands"
            if override
            else "humv:sensor:subbands"
            if s.subbands
            else "default (humv_usd.render.radiometry.DEFAULT_SUBBANDS)"
        )
        for s in rendered
    }
    sub_of = {
        s.name: radiometry.SubBands(s.wavelength_range_um, s.band_response, n_of[s.name]) for s in rendered
    }
    first_time = Usd.TimeCode(frame_list[0])
    spectra0 = atmosphere_spectra(stage, first_time)
    sun0 = usd_environment.sun_direction(stage, first_time)
    use_sky_map = any(
        spectra0.sky_radiance is not None
        and radiometry.covers(spectra0.wavelengths_um, s.wavelength_range_um)
        for s in rendered
    )
    dni0 = usd_environment.direct_normal_irradiance(stage, first_time)
    # the sun: the solar table, else a blackbody scaled to the broadband DNI (radiometry.blackbody_sun)
    use_sun = sun0 is not None and (spectra0.solar_irradiance is not None or dni0 is not None)
    eo_run = eo_render.EORender(
        stage,
        eo_sensors,
        spp=spp if eo_spp is None else eo_spp,
        max_depth=max_depth,
        seed=seed,
        out_dir=out_dir,
        truth=truth,
        estimator=estimator,  # the fast EO estimator falls back to the path tracer as the IR one
        spp_auto=spp_auto,
    )
    spp_auto = bool(spp_auto) and est == "fast"
    digest = stage_digest(stage)
    ir_how = {"estimator": _estimator_key(est), "spp_mode": _spp_mode(spp_auto)}
    wanted = {
        s.name: R.settings(digest, spp, seed, max_depth, truth.annotators, n_of[s.name], **ir_how)
        for s in rendered
    }
    eo_key, eo_mode = eo_run.settings_key
    for s in eo_run.sensors:
        wanted[s.name] = R.settings(
            digest, eo_run.spp, seed, max_depth, truth.annotators, estimator=eo_key, spp_mode=eo_mode
        )
    return _Plan(
        wanted=wanted,
        stage_path=os.fspath(stage_path),
        out_dir=out_dir,
        stage=stage,
        exporter=exporter,
        truth=truth,
        mi=mi,
        frames=frame_list,
        rendered=rendered,
        skipped=skipped,
        eo_run=eo_run,
        spp=spp,
        seed=seed,
        max_depth=max_depth,
        subbands_option=override,
        n_of=n_of,
        n_source=n_source,
        sub_of=sub_of,
        spp_sub={name: spp if est == "fast" else subband_spp(spp, len(sub)) for name, sub in sub_of.items()},
        spectra0=spectra0,
        use_sky_map=use_sky_map,
        use_sun=use_sun,
        sensor_ids={s.name: f"sensor_{i}" for i, s in enumerate(rendered)},
        estimator=est,
        estimator_note=note,
        spp_auto=spp_auto,
    )


def _estimator_key(estimator: str) -> str:
    """The infrared estimator and the parameters its pixels depend on (part of an image's
    record settings: images of another estimator are other images)."""
    if estimator != "fast":
        return estimator
    return (
        f"fast (splits {E.DEFAULT_SPLITS}, replicas {E.DEFAULT_REPLICAS}, roulette from depth "
        f"{E.RR_DEPTH}, filter radius {E.DEFAULT_FILTER_RADIUS} px, back sides as cavities)"
    )


def _spp_mode(spp_auto: bool) -> str:
    """How the samples per pixel were chosen (record settings): given, or the automatic rule."""
    if not spp_auto:
        return "fixed"
    return (
        f"automatic (to NETD/{AUTO_NETD_FRACTION:g}, p99 <= {AUTO_P99_K:g} K on the image and per region "
        f"of >= {Q.MIN_REGION_PIXELS} px, >= {Q.MIN_BATCHES} batches, <= {AUTO_MAX_SPP} spp, "
        f"seed stride {AUTO_SEED_STRIDE}, per-pixel direct positions <= {E.MAX_PIXEL_DIRECT_FACTOR})"
    )


# ------------------------------------------------------------------------------- per frame
class _FrameRenderer:
    """Renders the plan frame by frame: keeps the IR scene (rebuilt when the visible meshes
    change), the emissivity caches, the sensor chains and the per-sensor records."""

    def __init__(self, plan: _Plan, totals: dict):
        self.plan, self.totals = plan, totals
        self.per_sensor = {
            s.name: {
                "timings": dict.fromkeys(TIMING_KEYS, 0.0),
                "frames": [],
                "errors": _Accumulator(),
                "cameras": [],
            }
            for s in plan.rendered
        }
        self.overall = _Accumulator()
        self.chains = _SensorChains(plan.stage, plan.seed, [s.path for s in plan.exporter.sensors])
        self.band_eps: dict[tuple[str, str], float] = {}
        self.sub_eps: dict[tuple[str, str], np.ndarray] = {}
        self.scene: IRScene | None = None
        self.scene_key = None
        self.scene_builds = 0
        self.frames_rendered: list[int] = []
        self.progress = None
        self.units_done = 0
        self.units_total = 0
        self.writer: BackgroundWriter | None = None  # set by the render loop; None: write now

    def write(self, what: str, fn, *args, **kwargs) -> None:
        """Write a file of the current frame: on the background writer when there is one (in
        order, errors raised at the next frame), else now."""
        if self.writer is None:
            fn(*args, **kwargs)
        else:
            self.writer.submit(what, fn, *args, **kwargs)

    def record_frame(self, frame: int) -> None:
        """Write the record of every image of ``frame`` (after all its files) and drop what this
        object kept of it, so that memory does not grow with frames."""
        plan = self.plan
        items = [
            (name, "ir", rec["frames"], rec["cameras"], rec.pop("frame_errors", None))
            for name, rec in self.per_sensor.items()
        ]
        items += [
            (name, "eo", rec["frames"], rec["cameras"], None) for name, rec in plan.eo_run.records.items()
        ]
        for name, kind, entries, cameras, errors in items:
            if not entries or entries[-1]["frame"] != frame:
                continue
            entry, (_, camera) = entries.pop(), cameras.pop()
            truth = plan.truth.take_image(os.path.splitext(entry["exr"])[0]) if plan.truth else None
            self.write(
                f"the record of {name}/{frame:04d}",
                R.write_record,
                plan.out_dir,
                name,
                frame,
                {
                    "settings": plan.wanted[name],
                    "kind": kind,
                    "entry": entry,
                    "camera": camera_file(name, [(frame, camera)]),
                    "error_sums": errors,
                    "truth": truth,
                },
            )

    def render_frame(self, frame: int) -> None:
        self.frames_rendered.append(int(frame))
        plan, exporter = self.plan, self.plan.exporter
        t = time.perf_counter()
        state = exporter.frame_state(frame, plan.rendered + plan.eo_run.sensors)
        if plan.rendered:  # the infrared scene (EO sensors have their own, in eo_run)
            self._update_scene(state)
        frame_time = Usd.TimeCode(frame)
        spectra = atmosphere_spectra(plan.stage, frame_time)
        sun_direction = usd_environment.sun_direction(plan.stage, frame_time)
        self.totals["load_export"] += time.perf_counter() - t
        for s in plan.rendered:
            self._render_sensor(s, state, frame, frame_time, spectra, sun_direction)
            self._advance(1, f"frame {frame} {s.name}")
        if plan.eo_run.sensors:  # visible sensors: spectral render of the same frame (render.eo)
            t = time.perf_counter()
            plan.eo_run.frame(state, frame, self.chains, write=self.write)
            self.totals["eo"] = self.totals.get("eo", 0.0) + time.perf_counter() - t
            self._advance(len(plan.eo_run.sensors), f"frame {frame} EO")

    def _advance(self, units: int, text: str) -> None:
        self.units_done += units
        if self.progress is not None:
            self.progress(self.units_done, self.units_total, text)

    def _update_scene(self, state) -> None:
        """Build the IR scene (first frame, or new visible meshes) or move its vertices; set
        the cameras."""
        plan = self.plan
        parts = [
            (part, state.points[m.path][part.vertex_ids], state.flip[m.path])
            for m in state.meshes
            for part in m.parts
        ]
        if self.scene is None or state.topology_key != self.scene_key:
            setups = [
                SensorSetup(plan.sensor_ids[s.name], s.resolution[0], s.resolution[1], state.cameras[s.name])
                for s in plan.rendered
            ]
            with tempfile.TemporaryDirectory(prefix="humv_render_") as tmp:
                self.scene = IRScene(
                    parts,
                    setups,
                    spp=plan.spp,
                    max_depth=plan.max_depth,
                    workdir=tmp,
                    sky_map=plan.use_sky_map,
                    sun=plan.use_sun,
                )
            self.scene_key = state.topology_key
            self.scene_builds += 1
        else:
            for part, vertices, _ in parts:
                self.scene.set_vertices(part, vertices)
        for s in plan.rendered:
            self.scene.set_camera(plan.sensor_ids[s.name], state.cameras[s.name])
        self.scene.update()

    def _thermal_noise(self, s: SensorModel, state, hits) -> np.ndarray | None:
        """The thermal layer's own noise [K] per pixel (H, W): each person's RMS face-temperature
        noise from its q_rad rays (:func:`humv_usd.usd.thermal.face_temperature_noise`), times
        the band's emissivity-weighted share (a face's radiance error is eps dL/dT sigma_T, read
        back in K through the pixel's dL/dT: about eps sigma_T), on the pixels whose pixel-centre
        hit is that person's; 0 elsewhere. None when the layer states no noise.

        More samples do not reduce it, so the stopping rule does not see it: each region's
        record states it and the total with the render's own error in quadrature
        (:func:`humv_usd.render.quality.add_thermal_noise`); the EXR's ``radiance_stderr``
        stays the render's Monte Carlo error (the layer's estimate is an upper bound: it
        ignores the rays' stratification)."""
        if not hasattr(self, "_person_noise"):
            self._person_noise = usd_thermal.face_temperature_noise(self.plan.stage)
            self._thermal_note = (
                {person: noise for person, noise in self._person_noise.items()}
                if self._person_noise
                else None
            )
        if not self._person_noise:
            return None
        parts = self.scene.parts
        per_part = np.zeros(len(parts) + 1)
        for i, part in enumerate(parts):
            for person, noise in self._person_noise.items():
                if part.mesh_path.startswith(str(human_path(person)) + "/"):
                    per_part[i] = _band_emissivity(self.band_eps, part.material, s) * noise
        return per_part[np.where(hits.part >= 0, hits.part, len(parts))]

    def _tick(self, timings: dict, key: str, t: float) -> float:
        dt = time.perf_counter() - t
        timings[key] += dt
        self.totals[key] += dt
        return time.perf_counter()

    def _render_sensor(self, s: SensorModel, state, frame, frame_time, spectra, sun_direction) -> None:
        """One IR sensor at one frame: radiometry, render, labels, sensor chain, files, record."""
        plan, scene = self.plan, self.scene
        timings = self.per_sensor[s.name]["timings"]
        band, response = s.wavelength_range_um, s.band_response
        sensor_id = plan.sensor_ids[s.name]
        before = dict(timings)
        cpu0 = time.process_time()
        t = time.perf_counter()
        sub = plan.sub_of[s.name]
        frame_rad = radiometry.frame_radiometry(
            sub,
            state.sky_temperature_k,
            spectra,
            sun_direction,
            read_path_table(plan.stage, s, frame_time),
            dni_w_m2=usd_environment.direct_normal_irradiance(plan.stage, frame_time),
        )
        t = self._tick(timings, "load_export", t)

        band_renderer = render_band_fast if plan.estimator == "fast" else render_band
        hits = scene.hits(sensor_id)
        edges = E.geometric_edges(hits) if plan.estimator == "fast" else None
        regions, region_names = Q.region_map(hits.part, [p.label_class for p in scene.parts])
        netd = getattr(s, "netd_k", None)
        thermal_k = self._thermal_noise(s, state, hits)  # the thermal layer's own noise [K] per pixel
        fast_auto = plan.estimator == "fast" and plan.spp_auto

        boost_where = Q.first_boost(regions, region_names)  # people first

        def direct_target(radiance):
            """Per-pixel variance target of the estimator's boosts (automatic quality)."""
            _, dl_dt = planck.brightness_temperature_tabulated(radiance[0], band, response)
            return Q.pixel_target_var(netd, dl_dt, boost_where)

        pooled = Q.Batches()
        back_face = None
        replicas = E.replica_count(plan.spp_sub[s.name]) if plan.estimator == "fast" else None
        estimator_s = 0.0  # the estimator's share of "render" (the rest: conversions, edges, stats)
        while True:
            t_est = time.perf_counter()
            extra = {}
            if plan.estimator == "fast":
                extra["info"] = info = {}
                if fast_auto and Q.targets(netd) is not None:
                    extra["direct_target"] = direct_target
            batch = band_renderer(
                scene,
                sensor_id,
                state,
                sub,
                lambda material: _subband_emissivity(self.sub_eps, material, s, sub),
                frame_rad,
                spp=plan.spp_sub[s.name],
                seed=(plan.seed + frame + AUTO_SEED_STRIDE * pooled.count) % 2**32,
                transmittance_of=lambda material: _subband_transmittance(self.sub_eps, material, s, sub),
                **extra,
            )
            estimator_s += time.perf_counter() - t_est
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
        judged = Q.verdict(away_from_edges, per_region, netd if plan.spp_auto else None)
        for name, rec in per_region.items():
            rec["met"] = judged["regions"].get(name)
        spp_used = plan.spp_sub[s.name] * pooled.count
        away_from_edges["spp_used"] = spp_used
        away_from_edges["spp_rule"] = _spp_rule(plan, s)
        away_from_edges["quality_met"] = judged["met"]
        quality = {
            "met": judged["met"],
            "image_met": judged["regions"].get("image"),
            "targets_k": Q.targets(netd) if plan.spp_auto else None,
            "regions": per_region,
            "batches": pooled.count,
            "replicas_per_pixel": pooled.count * (replicas or 1),
            "error_dof": pooled.dof if replicas else None,
            "thermal_noise_k": None if thermal_k is None else self._thermal_note,
            "at_cap": bool(plan.spp_auto and judged["met"] is False),
        }
        t = self._tick(timings, "render", t)
        t = self._tick(timings, "labels", t)  # the pixel-centre cast is the labels' (cached)

        rel = os.path.join(s.name, f"{frame:04d}")
        labels = plan.truth.annotate(
            scene,
            sensor_id,
            s,
            state,
            lambda part: _band_emissivity(self.band_eps, part.material, s),
            plan.out_dir,
            rel,
            write=self.write,
        )
        t = self._tick(timings, "labels", t)

        chained = self.chains.apply(s, m1, frame)  # sensor chain: the single call site for IR
        camera = Camera.from_pose(state.cameras[s.name], m1.shape[1], m1.shape[0])
        self.per_sensor[s.name]["cameras"].append((frame, camera))
        levels = writers.preview_levels(bt)
        grey = _preview_grey(bt, levels)
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
        self.write(
            rel + ".exr",
            writers.write_exr,
            os.path.join(plan.out_dir, rel + ".exr"),
            channels,
            metadata={
                "humv:sensor": s.path,
                "humv:frame": str(frame),
                "humv:band_um": f"{band[0]:g}-{band[1]:g}",
                "humv:spp": str(plan.spp * pooled.count),  # automatic quality: the samples spent
                "humv:quality_met": str(judged["met"]),
                "humv:subbands": str(len(sub)),
                "humv:preview": "R=G=B: brightness temperature stretched as the PNG (0 at the 1st, "
                "1 at the 99th percentile); display only",
                "humv:camera": os.path.join(s.name, CAMERA_FILE),
                **camera.exr_header(),
            },
            half=("R", "G", "B"),
        )
        plan.truth.image_written(rel, channels)
        self.write(
            rel + ".png", writers.write_preview_png, os.path.join(plan.out_dir, rel + ".png"), bt, levels
        )
        chain_record = self.chains.write(chained, plan.out_dir, rel, write=self.write)
        self._tick(timings, "write", t)  # in the foreground: queueing (the writer's time is write_background)

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
        frame_errors = _Accumulator()  # summed once per image, merged into the totals
        frame_errors.add(stderr_l, stderr_k)
        self.per_sensor[s.name]["errors"].merge(frame_errors)
        self.overall.merge(frame_errors)
        self.per_sensor[s.name]["frame_errors"] = {
            "sums": dict(frame_errors.sums),
            "counts": dict(frame_errors.counts),
            "maxima": frame_errors.maxima,
        }
        finite_bt = bt[np.isfinite(bt)]
        self.per_sensor[s.name]["frames"].append(
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
                    "cpu": time.process_time() - cpu0,
                },
            }
        )


def _preview_grey(bt: np.ndarray, levels: tuple[float, float]) -> np.ndarray:
    """The IR file's display channels: brightness temperature stretched between the PNG
    preview's ``levels`` (:func:`humv_usd.images.preview_levels`) to 0..1 (0 where not finite),
    so that viewers do not open it black."""
    lo, hi = levels
    grey = (bt - lo) / (hi - lo) if hi > lo else np.full(bt.shape, 0.5)
    return np.where(np.isfinite(grey), np.clip(grey, 0.0, 1.0), 0.0)


# ------------------------------------------------------------------------------- manifest
def _sensor_record(plan: _Plan, run: _FrameRenderer, s: SensorModel, done: list[dict]) -> dict:
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
        "subbands_um": [list(b) for b in plan.sub_of[s.name].bands],
        "subbands_requested": plan.n_of[s.name],
        "subbands_source": plan.n_source[s.name],
        "spp_per_subband": plan.spp_sub[s.name],
        "camera": os.path.join(s.name, CAMERA_FILE) if mine else None,
        "frames": [r["entry"] for r in mine],
        "timings_s": {**rec["timings"], "total": sum(rec["timings"].values())},
        "monte_carlo_error": R.merge_errors(mine),
        "monte_carlo_error_k": _interior_summary([r["entry"].get("monte_carlo_error_k") or {} for r in mine]),
        "quality": _quality_summary([r["entry"] for r in mine]),
    }


def _quality_summary(entries: list[dict]) -> dict:
    """Per sensor: whether the automatic quality met its targets on every frame (False when a
    frame stopped at the sample cap short of them, None when no frame was judged), the frames
    that fell short and the regions that did."""
    judged = [(e["frame"], e.get("quality") or {}) for e in entries]
    short = [(f, q) for f, q in judged if q.get("met") is False]
    verdicts = [q.get("met") for _, q in judged if q.get("met") is not None]
    regions = sorted(
        {name for _, q in short for name, rec in (q.get("regions") or {}).items() if rec.get("met") is False}
        | {"image" for _, q in short if q.get("image_met") is False}
    )
    return {
        "met": (all(verdicts) if verdicts else None),
        "frames_not_met": [f for f, _ in short],
        "regions_not_met": regions,
        "definition": "automatic quality (humv_usd.render.quality): mean per-pixel error away from edges "
        "<= NETD/3 and its p99 <= 0.1 K on the image and on every region class (label class of the "
        "pixel-centre hit) with enough pixels; per frame in frames[].quality",
    }


def _interior_summary(per_frame: list[dict]) -> dict:
    """Per-sensor error in K away from geometric edges (mean over frames of the per-frame means,
    worst per-frame 99th percentile) and on edges (pixel footprint: signal, reported apart)."""

    def values(key):
        return [f[key] for f in per_frame if f.get(key) is not None]

    mean, p99, edge = values("mean_k"), values("p99_k"), values("edge_mean_k")
    return {
        "mean_k": float(np.mean(mean)) if mean else None,
        "p99_max_k": float(np.max(p99)) if p99 else None,
        "edge_mean_k": float(np.mean(edge)) if edge else None,
        "definition": "per-pixel Monte Carlo standard error in K; mean and 99th percentile over pixels "
        "away from geometric edges (8-neighbours on the same part within 2 % depth), edge pixels apart",
        "not_estimable": None if mean else "spp < 2: one replica, no error estimate",
        "spp_used": sorted({f["spp_used"] for f in per_frame if f.get("spp_used") is not None}),
        "spp_rule": per_frame[-1].get("spp_rule") if per_frame else None,
    }


def _radiometry_record(plan: _Plan) -> dict:
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


def _estimator_settings(plan: _Plan) -> dict:
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


def _manifest(plan: _Plan, run: _FrameRenderer, ground_truth, totals: dict, done: list[dict]) -> dict:
    """The render folder's manifest (``OUT/manifest.json``): this call's settings and timings,
    the frames of all calls (from the records)."""
    eo_frames = {s.name: [r["entry"] for r in done if r["sensor"] == s.name] for s in plan.eo_run.sensors}
    return {
        "stage": os.path.abspath(plan.stage_path),
        "output_dir": plan.out_dir,
        "created_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "versions": _versions(plan.mi),
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
            **_estimator_settings(plan),
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
        "sensors": [_sensor_record(plan, run, s, done) for s in plan.rendered],
        "eo_sensors": plan.eo_run.manifest(eo_frames),
        "skipped_sensors": plan.skipped + plan.eo_run.skipped,
        "radiometry": _radiometry_record(plan),
        "sensor_chain": run.chains.status(),
        "scene_builds": run.scene_builds,
        "timings_s": totals,
        "monte_carlo_error": R.merge_errors([r for r in done if r["kind"] == "ir"]),
        "rendered_this_call": run.frames_rendered,
    }


def _band_emissivity(cache: dict, material, sensor: SensorModel) -> float:
    """Band emissivity of a material for a sensor (cached): the one function the thermal solve
    uses too (:func:`humv_usd.usd.materials.band_emissivity`)."""
    key = (material.path, sensor.name)
    if key not in cache:
        cache[key] = band_emissivity(material, sensor.wavelength_range_um, sensor.band_response)
    return cache[key]


def _subband_emissivity(cache: dict, material, sensor: SensorModel, sub) -> np.ndarray:
    """Sub-band emissivities (n,) of a material for a sensor (cached;
    :func:`humv_usd.usd.materials.subband_emissivity`)."""
    key = (material.path, sensor.name)
    if key not in cache:
        cache[key] = subband_emissivity(material, sensor.wavelength_range_um, sub.bands, sub.response)
    return cache[key]


def _subband_transmittance(cache: dict, material, sensor: SensorModel, sub) -> np.ndarray | None:
    """Sub-band transmittances (n,) of a see-through material (glass), None when opaque."""
    key = ("transmittance", material.path, sensor.name)
    if key not in cache:
        cache[key] = subband_transmittance(material, sub.bands, sub.response)
    return cache[key]


class _SensorChains:
    """The sensor chain (:mod:`humv_usd.physics.sensor`): optics, noise, counts, AGC per sensor
    and frame, after the render. One model per sensor prim; the noise generator is seeded from
    (seed, sensor index in the stage, frame), so outputs are reproducible."""

    def __init__(self, stage, seed: int, sensor_paths: list[str]):
        self.stage = stage
        self.seed = int(seed)
        self.index = {p: i for i, p in enumerate(sensor_paths)}
        self.models: dict = {}
        self.ran: dict[str, str] = {}
        self.reason = None
        self.chain = chain
        self.states: dict = {}

    def apply(self, sensor: SensorModel, radiance, frame: int, eo_space: str | None = None):
        """ChainOutput for one frame, or None when the chain is unavailable."""
        if self.chain is None:
            return None
        if sensor.path not in self.models:
            self.models[sensor.path] = read_sensor_model(self.stage.GetPrimAtPath(sensor.path))
        rng = np.random.default_rng([self.seed, self.index.get(sensor.path, 0), int(frame)])
        extra = {} if eo_space is None else {"eo_space": eo_space}
        # frame time and the sensor's state from its last frame (FPN drift since FFC, bolometer lag)
        extra["time_s"] = int(frame) / (self.stage.GetTimeCodesPerSecond() or 1.0)
        extra["state"] = self.states.setdefault(sensor.path, self.chain.ChainState())
        out = self.chain.apply_chain(radiance, self.models[sensor.path], rng, **extra)
        self.ran[sensor.name] = "ran"
        return out

    def write(self, out, out_dir, rel, write=None) -> dict | None:
        """Write ``<rel>_counts.png`` (16-bit raw counts) and ``<rel>_image8.png`` (8-bit AGC);
        ``write(what, fn, *args)`` runs the writes (default: now)."""
        if out is None:
            return None
        write = write or (lambda _what, fn, *args: fn(*args))
        write(
            rel + "_counts.png", writers.write_png16, os.path.join(out_dir, rel + "_counts.png"), out.counts
        )
        write(rel + "_image8.png", writers.write_png, os.path.join(out_dir, rel + "_image8.png"), out.image8)
        return {
            "counts_png": rel + "_counts.png",
            "image8_png": rel + "_image8.png",
            "noise_sigma": float(out.noise_sigma),
            "settings": out.settings,
        }

    def status(self) -> str:
        return self.reason or "ran: counts (16-bit PNG, EXR channel counts) and image8 (PNG) per frame"


# --- bench: spectral error against sub-band count, render time per sensor ----------------------

#: Ranges [m] at which the bench evaluates the path term when the stage has a path table.
BENCH_RANGES_M = (5.0, 15.0, 30.0, 60.0)


def spectra_from_atmosphere(atm, time_s: float = 0.0, sun_direction=None):
    """(AtmosphereSpectra, PathTable) from a :class:`humv_usd.atmosphere.model.Atmosphere`, for a
    bench on a stage whose atmosphere layer has no spectral tables."""

    wl = np.asarray(atm.wavelengths_um, dtype=float)
    spectra = AtmosphereSpectra(
        model=atm.source,
        wavelengths_um=wl,
        sky_zenith_deg=np.asarray(atm.sky_zenith_deg, dtype=float),
        sky_radiance=atm.sky_spectral_radiance(atm.sky_zenith_deg, time_s),
        solar_irradiance=atm.solar_spectral_irradiance([time_s])[0],
    )
    tau, rad = atm.path()
    table = radiometry.PathTable(
        f"atmosphere_for ({atm.source})",
        np.asarray(atm.path_ranges_m, dtype=float),
        wl,
        np.asarray(tau, dtype=float),
        np.asarray(rad, dtype=float),
    )
    return spectra, table


def subband_error_table(
    stage_path, counts=(1, 2, 3, 4, 6, 8, 16), frame=None, spectra=None, path_table=None, sun_direction=None
) -> dict:
    """Spectral (not Monte Carlo) error of the sub-band model against sub-band count.

    For every IR sensor of the stage, every material bound to a rendered mesh and the face
    temperatures of the frame (1st, 50th and 99th percentile over all faces), the at-sensor
    brightness temperature of a horizontal opaque Lambertian facet under the stage's sky (its
    spectral table, cosine-weighted over the hemisphere, else the blackbody at skyTemperature),
    the stage's sun (if up) and the sensor's path table at :data:`BENCH_RANGES_M` (if any) is
    computed with n sub-bands and on a fine spectral grid
    (:func:`humv_usd.render.radiometry.subband_error`). Returns, per sensor and n, the largest
    and the RMS error [K] over materials, temperatures and ranges. ``spectra``, ``path_table``
    and ``sun_direction`` replace what the stage has (see :func:`spectra_from_atmosphere`).
    """
    stage = open_stage(stage_path)
    exporter = StageExport(stage)
    frames = stage_frames(stage)
    frame = frames[0] if frame is None else int(frame)
    ir = [s for s in exporter.sensors if s.rendered and s.kind != "EO"]
    state = exporter.frame_state(frame, ir)
    time_code = Usd.TimeCode(frame)
    spectra = atmosphere_spectra(stage, time_code) if spectra is None else spectra
    sun_dir = (
        usd_environment.sun_direction(stage, time_code)
        if sun_direction is None
        else np.asarray(sun_direction, float)
    )
    temps = (
        np.concatenate([state.temperatures[m.path] for m in state.meshes])
        if state.meshes
        else np.array([300.0])
    )
    temps = np.percentile(temps, [1.0, 50.0, 99.0])
    materials = {part.material.path: part.material for m in state.meshes for part in m.parts}
    out: dict = {
        "frame": frame,
        "temperatures_k": temps.tolist(),
        "materials": sorted(materials),
        "reference": f"trapezoid on {radiometry.REFERENCE_NODES}+ nodes per band",
        "sensors": {},
    }
    for s in ir:
        band, resp = s.wavelength_range_um, s.band_response
        wl = spectra.wavelengths_um
        notes = {}
        if spectra.sky_radiance is not None and radiometry.covers(wl, band):
            sky_l = np.array(
                [
                    radiometry.hemisphere_mean(spectra.sky_zenith_deg, spectra.sky_radiance[:, j])
                    for j in range(wl.size)
                ]
            )
            sky = (wl, sky_l)
            notes["sky"] = "spectral table"
        else:
            x = np.linspace(band[0], band[1], 512)
            sky = (x, planck.spectral_radiance(x, state.sky_temperature_k))
            notes["sky"] = f"blackbody {state.sky_temperature_k:.1f} K"
        sun = None
        if (
            sun_dir is not None
            and sun_dir[2] > 0
            and spectra.solar_irradiance is not None
            and radiometry.covers(wl, band)
        ):
            sun = (wl, spectra.solar_irradiance, float(sun_dir[2]))
            notes["sun"] = f"cos(zenith) {sun_dir[2]:.3f}"
        table = read_path_table(stage, s, time_code) if path_table is None else path_table
        paths = [None]
        if table is not None and radiometry.covers(table.wavelengths_um, band):
            paths = []
            for r in BENCH_RANGES_M:
                tau = np.array(
                    [np.interp(r, table.ranges_m, table.transmittance[:, j]) for j in range(wl.size)]
                )
                lp = np.array([np.interp(r, table.ranges_m, table.radiance[:, j]) for j in range(wl.size)])
                paths.append((table.wavelengths_um, tau, lp))
            notes["path"] = f"table {table.prim} at {list(BENCH_RANGES_M)} m"
        rows = {}
        for n in counts:
            errs = []
            sub = radiometry.SubBands(band, resp, n)
            for mat in materials.values():
                for path in paths:
                    errs.append(
                        radiometry.subband_error(
                            band,
                            resp,
                            mat.wavelengths_um,
                            mat.emissivity,
                            temps,
                            n,
                            sky=sky,
                            sun=sun,
                            path=path,
                            subbands=sub,
                        )
                    )
            e = np.abs(np.concatenate(errs))
            rows[int(n)] = {"max_k": float(e.max()), "rms_k": float(np.sqrt(np.mean(e**2)))}
        out["sensors"][s.name] = {"band_um": list(band), "inputs": notes, "error_by_subbands": rows}
    return out
