"""``render_stage``: render every infrared sensor of a composed stage, frame by frame."""

from __future__ import annotations

import logging
import os
import tempfile
import time
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd

from humv_usd import images as writers  # noqa: F401  (tests reach the writers through here)
from humv_usd import mode
from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import check_output_dir, folder_lock, jsonable, write_json
from humv_usd.geometry.camera import camera_file
from humv_usd.groundtruth import GroundTruth  # here: groundtruth imports render.writers
from humv_usd.physics.sensor import SensorModel
from humv_usd.pipeline import ir_pass, manifest, resume
from humv_usd.pipeline import records as R
from humv_usd.pipeline.budget import render_budget, require_fits
from humv_usd.pipeline.chains import SensorChains
from humv_usd.pipeline.manifest import MANIFEST_NAME, ErrorAccumulator
from humv_usd.pipeline.preflight import check_stage_for_render
from humv_usd.pipeline.writer import BackgroundWriter, pool_size
from humv_usd.render import bands, radiometry
from humv_usd.render import eo as eo_render
from humv_usd.render import estimator as E
from humv_usd.render.export import StageExport
from humv_usd.render.frame import stage_frames
from humv_usd.render.ir import IRScene, SensorSetup, subband_spp
from humv_usd.render.light import read_frame_light
from humv_usd.render.renderer import ESTIMATORS, choose_estimator
from humv_usd.usd.atmosphere import AtmosphereSpectra
from humv_usd.usd.layers import open_stage
from humv_usd.usd.sensor import check_subbands, override_resolution

log = logging.getLogger(__name__)

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
DEFAULT_ESTIMATOR = "fast"
#: Samples per pixel when the caller gives none, per estimator.
DEFAULT_SPP = {"fast": E.DEFAULT_SPP, "path": 16}
#: Samples per pixel of the visible (EO) path tracer (`--estimator path`) when the caller gives
#: none; the fast EO estimator then picks them (humv_usd.render.eo_fast: automatic quality).
EO_DEFAULT_SPP = 16
TIMING_KEYS = ("load_export", "render", "labels", "write")


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
    resolution=None,
    require_images=False,
) -> dict:
    r"""Render the infrared sensors of a composed HumV-USD stage.

    ``resolution`` (W, H): every sensor at this pixel count and its own field of view
    (:func:`humv_usd.usd.sensor.override_resolution`, in the stage's session layer; part of the
    images' settings).

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
    require_images : bool, default False
        When every selected sensor is skipped (e.g. an EO camera on a stage without sun or sky),
        raise InputError (one line per sensor with the reason) before anything is written,
        instead of writing a manifest of zero images (``humv-usd render``: exit 2).

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
    pool_size()  # HUMV_USD_WRITER_THREADS checked before anything is written
    check_stage_for_render(stage_path, frames_given=frames is not None)  # what check flags as errors
    if estimator not in ESTIMATORS:
        raise InputError(bad_value("estimator", estimator, f"expected one of {', '.join(ESTIMATORS)}"))
    out_dir = os.path.abspath(check_output_dir(out_dir))
    with folder_lock(out_dir, "humv-usd render", wait=wait):
        args = (stage_path, out_dir, frames, spp, sensors, seed, max_depth, annotators, subbands)
        how = (estimator, eo_spp, spp_auto, resolution)
        return _render_locked(t_start, args, how, force, yes, progress, require_images)


def _render_locked(t_start, args, how, force, yes=False, progress=None, require_images=False) -> dict:
    """``args`` and ``how`` (estimator, EO spp, automatic spp, resolution) as :func:`_plan` takes them."""
    out_dir = args[1]
    totals = dict.fromkeys(TIMING_KEYS, 0.0)
    t = time.perf_counter()
    plan = _plan(*args, *how)
    totals["load_export"] += time.perf_counter() - t
    skipped = plan.skipped + plan.eo_run.skipped
    if require_images and skipped and not (plan.rendered or plan.eo_run.sensors):
        raise InputError(
            "",
            [
                f"nothing to render: sensor {s['name']} ({s['band']}) is skipped: {s['reason']}"
                for s in skipped
            ],
        )
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
    todo = resume.frames_to_render(plan, force)

    run = _FrameRenderer(plan, totals)
    frames_to_render = todo if (plan.rendered or plan.eo_run.sensors) else []
    run.progress = progress  # counts the images rendered in this call only
    run.units_total = len(frames_to_render) * (len(plan.rendered) + len(plan.eo_run.sensors))
    t_writes = time.perf_counter()
    # frame N is written while N+1 renders, on a pool of writer threads (HUMV_USD_WRITER_THREADS)
    with BackgroundWriter(frames_ahead=WRITE_FRAMES_AHEAD, threads=pool_size()) as writer:
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
    done = resume.records_of_this_render(plan)
    resume.write_cameras(out_dir, done)

    t = time.perf_counter()
    taken = [r["truth"] for r in done if r.get("truth")]
    ground_truth = plan.truth.finish(out_dir, totals["render"], taken=taken)
    totals["labels"] += time.perf_counter() - t
    totals["total"] = time.perf_counter() - t_start
    record = manifest.build(plan, run, ground_truth, totals, done)
    write_json(os.path.join(out_dir, MANIFEST_NAME), record)
    return jsonable(record)


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
    resolution=None,
) -> _Plan:
    """Open the stage, select frames and sensors, and set up the radiometry (sub-bands per IR
    sensor; sky map and sun from the environment at the first frame) and the EO run."""
    stage = open_stage(stage_path)
    if resolution is not None:  # the same cameras at another pixel count (session layer)
        for line in override_resolution(stage, resolution):
            log.info("resolution: %s", line)
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
    est, why = choose_estimator(estimator, max_depth)  # the one rule, as for the EO sensors
    note = why or f"requested: {estimator}"
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
    light0 = read_frame_light(stage, frame_list[0])  # the light at the first frame
    spectra0, sun0, dni0 = light0.spectra, light0.sun_direction, light0.dni_w_m2
    use_sky_map = any(
        spectra0.sky_radiance is not None
        and radiometry.covers(spectra0.wavelengths_um, s.wavelength_range_um)
        for s in rendered
    )
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
    digest = resume.stage_digest(stage)
    if resolution is not None:  # the session layer is not in the digest
        digest += f"@{int(resolution[0])}x{int(resolution[1])}"
    ir_how = {"estimator": manifest.estimator_key(est), "spp_mode": manifest.spp_mode(spp_auto)}
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
                "errors": ErrorAccumulator(),
                "cameras": [],
            }
            for s in plan.rendered
        }
        self.overall = ErrorAccumulator()
        self.chains = SensorChains(plan.stage, plan.seed, [s.path for s in plan.exporter.sensors])
        self.band_eps: dict[tuple[str, str], float] = {}
        self.sub_eps: dict[tuple[str, str], np.ndarray] = {}
        self.closure: dict = {}  # Kirchhoff closure per (material, sensor), render.bands.check_closure
        self.closure_records: dict[tuple[str, str], dict] = {}
        self.closure_key = None
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

    def write_after(self, what: str, fn, *args, **kwargs) -> None:
        """:meth:`write`, started only after every file queued before it is written (a record)."""
        if self.writer is None:
            fn(*args, **kwargs)
        else:
            self.writer.submit_after(what, fn, *args, **kwargs)

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
            self.write_after(
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
        if state.topology_key != self.closure_key:  # new meshes: their materials against Kirchhoff
            self._check_closure(state)
        shared = plan.eo_run.shares_scene  # one scene for every sensor (EO path tracer: its own)
        if plan.rendered or shared:
            self._update_scene(state)
        light = read_frame_light(plan.stage, frame)  # once per frame, for every sensor pass
        self.totals["load_export"] += time.perf_counter() - t
        for s in plan.rendered:
            ir_pass.render_sensor(self, s, state, frame, light)
            self._advance(1, f"frame {frame} {s.name}")
        if plan.eo_run.sensors:  # visible sensors: spectral render of the same frame (render.eo)
            t = time.perf_counter()
            plan.eo_run.frame(
                state,
                frame,
                self.chains,
                write=self.write,
                light=light,
                shared=self.scene if shared else None,
            )
            self.totals["eo"] = self.totals.get("eo", 0.0) + time.perf_counter() - t
            self._advance(len(plan.eo_run.sensors), f"frame {frame} EO")

    def _check_closure(self, state) -> None:
        """Each material of the frame's meshes in each sensor's band: eps + rho + tau = 1 with one
        table taken as given per band (:func:`humv_usd.render.bands.check_closure`)."""
        plan = self.plan
        for s in plan.rendered + plan.eo_run.sensors:
            for m in state.meshes:
                for part in m.parts:
                    rec = bands.check_closure(self.closure, part.material, s)
                    if rec is not None:
                        self.closure_records[(part.material.path, s.name)] = rec
        self.closure_key = state.topology_key

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
        ids = self._scene_sensor_ids()
        if self.scene is None or state.topology_key != self.scene_key:
            setups = [
                SensorSetup(sid, s.resolution[0], s.resolution[1], state.cameras[s.name]) for s, sid in ids
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
        for s, sid in ids:
            self.scene.set_camera(sid, state.cameras[s.name])
        self.scene.update()

    def _scene_sensor_ids(self) -> list[tuple[SensorModel, str]]:
        """The sensors of the frame's one scene with their ids in it: the infrared sensors and,
        when they share it (:attr:`humv_usd.render.eo.EORender.shares_scene`), the EO sensors."""
        plan = self.plan
        ids = [(s, plan.sensor_ids[s.name]) for s in plan.rendered]
        if plan.eo_run.shares_scene:
            ids += [(s, plan.eo_run.ids[s.name]) for s in plan.eo_run.sensors]
        return ids
