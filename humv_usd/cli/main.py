"""The ``humv-usd`` command line.

Exit codes follow Pixar's USD tools: 0 success, 1 failure (e.g. check findings, a missing
asset), 2 bad input (one line per problem on stderr naming key, value and allowed range; no
traceback and nothing written).
"""

from __future__ import annotations

import logging
import os
import signal
import statistics
import sys
import tempfile
import threading
from pathlib import Path

import click

from humv_usd.cli.common import PROG, progress_display, reports_errors, set_verbosity
from humv_usd.errors import InputError
from humv_usd.pipeline.budget import MAX_FRAMES_PER_CALL, MAX_SPP


def parse_frames(text: str | None) -> list[int] | None:
    """``"0:10"`` (inclusive), ``"0,5,9"`` or ``"3"`` → frame list; None → all frames. A range of
    more than :data:`MAX_FRAMES_PER_CALL` frames is refused before any list is built."""
    if text is None:
        return None
    bad = f"--frames = {text!r}: expected FIRST:LAST, a comma list or one integer frame number"
    try:
        if ":" not in text:
            return [int(x) for x in text.split(",") if x.strip()]
        a, b = text.split(":", 1)
        first, last = int(a), int(b)
    except ValueError:
        raise InputError(bad) from None
    if last < first:
        raise InputError(bad)
    if last - first + 1 > MAX_FRAMES_PER_CALL:
        raise InputError(
            f"--frames = {text!r}: {last - first + 1:,} frames; at most {MAX_FRAMES_PER_CALL:,} "
            "per call (render the stage's range in parts)"
        )
    return list(range(first, last + 1))


def parse_resolution(text: str | None) -> tuple[int, int] | None:
    """``"160x128"`` -> (160, 128); None -> None; anything else one InputError line."""
    if text is None:
        return None
    w, sep, h = text.lower().partition("x")
    # ASCII digits only: str.isdigit() also takes '²', which int() refuses (a traceback, fuzzing)
    digits = all(part.strip().isascii() and part.strip().isdigit() for part in (w, h))
    if not (sep and digits) or int(w) < 1 or int(h) < 1:
        raise InputError(f"--resolution = {text!r}: expected WIDTHxHEIGHT in pixels, e.g. 160x128")
    return int(w), int(h)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="humv-usd", prog_name=PROG)
@click.option("-v", "--verbose", count=True, help="More log output on stderr (-v info, -vv debug).")
def main(verbose: int = 0):
    """HumV-USD: USD-native physics-based EO/IR simulation of human signatures."""
    # the library logs through `logging` (warnings through `warnings`); the command line shows them
    level = logging.WARNING if verbose == 0 else logging.INFO if verbose == 1 else logging.DEBUG
    logging.basicConfig(level=level, format=f"{PROG}: %(levelname)s: %(message)s", stream=sys.stderr)
    logging.captureWarnings(True)


@main.command()
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out_dir",
    required=True,
    type=str,  # checked by check_output_dir: one error line, not click's usage block
    help="Output folder: stage.usda and layers/.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Overwrite layers edited by hand (default: stop and say which; put edits in a user layer, "
    "a sublayer you add to OUT/stage.usda, which compose keeps).",
)
@click.option(
    "--wait",
    is_flag=True,
    help="If another humv-usd process is writing OUT, wait for it (default: stop with one line naming it).",
)
@click.option(
    "--yes",
    is_flag=True,
    help="Go ahead even when the estimated memory or disk exceeds this machine's (default: stop "
    "with the estimate and the key to change).",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress display and no per-layer lines.")
@click.option("-v", "--verbose", count=True, help="Log each step on stderr (-v info, -vv debug).")
@reports_errors
def compose(scenario: Path, out_dir: str, force: bool, wait: bool, yes: bool, quiet: bool, verbose: int):
    """Compose SCENARIO (TOML) into OUT/stage.usda with one layer per part; rebuilds only the
    layers whose inputs changed (OUT/compose.json says which and why)."""
    from humv_usd.fileio import check_output_dir
    from humv_usd.pipeline.compose import compose as run_compose
    from humv_usd.scenario import load_scenario

    set_verbosity(verbose)
    out_dir = check_output_dir(out_dir)  # fail fast, before reading anything
    _require_replaceable(out_dir)
    with progress_display("compose", quiet) as progress:
        try:
            loaded = load_scenario(scenario)
            report = run_compose(loaded, out_dir, force=force, wait=wait, yes=yes, progress=progress)
        except OSError as exc:  # a full disk, a quota, a file system gone read-only mid-run
            from humv_usd.errors import WriteError
            from humv_usd.fileio import PENDING_NAME

            done = (
                "the change is journaled: the next compose completes it"
                if (out_dir / PENDING_NAME).exists()
                else "nothing was changed"
            )
            raise WriteError(f"{exc.filename or out_dir}: {exc.strerror or exc}; {done}") from None
    _warn_enclosed(loaded, report.stage_path)
    for name, wrote, seconds in [] if quiet else report.layers:
        state = "written" if wrote else "unchanged"
        why = report.states[name].why if name in report.states else ""
        click.echo(f"  {name:<16} {state:<9} {seconds * 1000:7.1f} ms  {why}")
    for part, reason in [] if quiet else report.skipped:
        click.echo(f"  {part:<16} skipped   ({reason})")
    for name in report.removed:
        click.echo(f"  {name:<16} removed   (no longer in the scenario)")
    click.echo(f"{report.stage_path}  ({report.summary()})")


def _warn_enclosed(scenario, stage_path: Path) -> None:
    """A camera or person inside an asset (or any scene object but a box, which the scenario's
    warnings cover): one warning line each (issue 26)."""
    from pxr import Usd

    from humv_usd.usd.check import enclosed_in_scene_objects

    boxes = {o["id"] for o in scenario["scene"]["object"]} if scenario["scene"] else set()
    for line in enclosed_in_scene_objects(Usd.Stage.Open(str(stage_path)), skip=boxes):
        logging.getLogger("humv_usd").warning(line)


def _require_replaceable(out_dir: Path) -> None:
    """The files a compose into ``out_dir`` replaces can be replaced: one line before any work
    for an immutable or read-only one (issue 26: compose renamed the layers into place, then
    failed on an immutable stage.usda, half-written)."""
    for path in [out_dir / "stage.usda", out_dir / "compose.json", *sorted(out_dir.glob("layers/*.usda"))]:
        if path.exists() and not os.access(path, os.W_OK):
            raise InputError(
                f"{path}: read-only or immutable, and compose replaces it; make it writable "
                "(chmod u+w, chattr -i) or compose into another folder"
            )


@main.command()
@click.argument("stage", type=click.Path(path_type=Path))  # a folder: open_stage says what to pass
@click.option(
    "-o",
    "--out",
    "out_dir",
    required=True,
    type=str,  # checked by check_output_dir: one error line, not click's usage block
    help="Output folder.",
)
@click.option(
    "--frames",
    default=None,
    help="Frames to render: FIRST:LAST, a comma list, or "
    "one number (default: the stage's whole frame range).",
)
@click.option(
    "--spp",
    default=None,
    type=click.IntRange(1, MAX_SPP),
    help="Samples per pixel (fast estimator: camera samples shared by all sub-bands, default 2, more until NETD/3; "
    "path: split over the sub-bands, default 16). 1 renders but cannot estimate the error.",
)
@click.option(
    "--estimator",
    default="fast",
    show_default=True,
    type=click.Choice(["fast", "path"]),
    help="Estimator: fast (sub-bands on one path, control variate, stratified; EO: 12 visible "
    "sub-bands, spp until 1 % of mean Y) or path (Mitsuba's path tracer per sub-band, EO spectral: "
    "the reference). See `humv-usd bench render`.",
)
@click.option(
    "--backend",
    default=None,
    type=click.Choice(["auto", "cuda", "llvm", "scalar"]),
    help="Where Dr.Jit runs: cuda (NVIDIA GPU), llvm (CPU), scalar (slow reference) or auto "
    "(default: $HUMV_USD_BACKEND, else the GPU when one works, else the CPU). Recorded in the manifest.",
)
@click.option("-q", "--quiet", is_flag=True, help="No progress display; only the summary line.")
@click.option("-v", "--verbose", count=True, help="Log each frame and sensor on stderr (-v info, -vv debug).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1))
@click.option("--sensor", "sensors", multiple=True, help="Render only this sensor (repeatable).")
@click.option(
    "--annotators",
    default=None,
    help="Ground-truth annotators, comma-separated "
    "(default: the scenario's [annotations], else all; see humv_usd.groundtruth).",
)
@click.option(
    "--subbands",
    default=None,
    type=int,
    help="Sub-bands per infrared band for every sensor (1-64; default: each sensor's `subbands`, else 16; see `humv-usd bench render`).",
)
@click.option(
    "--resolution",
    default=None,
    metavar="WxH",
    help="Render every sensor at this pixel count at its own field of view (the pixel pitch scales; "
    "e.g. 160x128 for a quick look at a 640x512 camera).",
)
@click.option(
    "--wait",
    is_flag=True,
    help="If another humv-usd process is writing OUT, wait for it (default: stop with one line naming it).",
)
@click.option(
    "--force",
    is_flag=True,
    help="Render the frames again even when done, and re-render images of OUT made with other "
    "settings (default: render only what is missing; refuse other settings).",
)
@click.option(
    "--yes",
    is_flag=True,
    help="Go ahead even when the estimated memory or disk exceeds this machine's (default: stop "
    "with the estimate and the key to change).",
)
@reports_errors
def render(
    stage: Path,
    out_dir: str,
    frames,
    spp,
    estimator,
    backend,
    quiet,
    verbose,
    seed: int,
    sensors,
    annotators,
    subbands,
    resolution,
    wait: bool,
    force: bool,
    yes: bool,
):
    """Render every sensor of STAGE (IR in sub-bands, EO spectral) to EXR + PNG with a manifest."""
    from humv_usd import mode
    from humv_usd.fileio import check_output_dir
    from humv_usd.pipeline.render import render_stage

    if backend is not None:
        mode.set_backend(backend)
    set_verbosity(verbose)
    out_dir = check_output_dir(out_dir)  # fail fast, before opening the stage
    with progress_display("render", quiet) as progress:
        manifest = render_stage(
            stage,
            out_dir,
            frames=parse_frames(frames),
            spp=spp,
            sensors=list(sensors) or None,
            seed=seed,
            annotators=None if annotators is None else annotators.split(","),
            subbands=subbands,
            estimator=estimator,
            progress=progress,
            wait=wait,
            force=force,
            yes=yes,
            resolution=parse_resolution(resolution),
            require_images=True,  # every sensor skipped: one line each and exit 2, nothing written
        )
    echo_render_summary(manifest, out_dir, estimator)


def echo_render_summary(manifest: dict, out_dir, estimator: str) -> None:
    """The lines `humv-usd render` prints after a render: the manifest's path, image count and
    time, the Monte Carlo error, per IR sensor the error away from edges ("n/a" where there is
    nothing to estimate it on) and the render time per frame, and skipped sensors."""
    settings = manifest["settings"]
    if settings["estimator"] != estimator:
        click.echo(f"  estimator: {settings['estimator']} ({settings['estimator_note']})", err=True)
    err = manifest["monte_carlo_error"]
    rendered = sum(len(s["frames"]) for s in manifest["sensors"] + manifest.get("eo_sensors", []))
    click.echo(
        f"{out_dir}/manifest.json  {rendered} image(s) ({len(manifest['rendered_this_call'])} frame(s) "
        f"rendered now), {manifest['timings_s']['total']:.2f} s"
    )
    from humv_usd.physics.sensor import REFLECTIVE_BANDS

    # thermal cameras (NIR/SWIR errors are relative, EO's per sensor in the manifest)
    thermal = [s for s in manifest["sensors"] if s.get("band") not in REFLECTIVE_BANDS]
    if thermal and err["temperature_stderr_mean_k"] is None:
        click.echo(
            f"  Monte Carlo error: not estimable at spp {manifest['settings']['spp']} "
            "(needs at least 2 samples per pixel; the manifest's error fields are null)"
        )
    elif thermal:
        click.echo(
            f"  Monte Carlo error per pixel: mean {err['temperature_stderr_mean_k']:.4f} K, "
            f"max {err['temperature_stderr_max_k']:.4f} K "
            f"({err['radiance_stderr_mean']:.4g} / {err['radiance_stderr_max']:.4g} "
            "W m-2 sr-1)"
        )
    rendered_now = len(manifest["rendered_this_call"])  # the timings are this call's
    for sensor in manifest["sensors"]:
        away = sensor.get("monte_carlo_error_k") or {}
        if away.get("mean_k") is not None:
            per_frame = (
                f"; {sensor['timings_s']['render'] / rendered_now:.2f} s render per frame"
                if rendered_now
                else ""
            )
            quality = sensor.get("quality") or {}
            verdict = ""
            if quality.get("met") is True:
                verdict = "; quality target met"
            elif quality.get("met") is False:  # issue 25: a frame at the spp cap short of its target says so
                verdict = (
                    f"; quality target NOT met in {len(quality['frames_not_met'])} frame(s) at the spp cap "
                    f"({', '.join(quality['regions_not_met']) or 'image'})"
                )
            # NIR/SWIR (reflected light, no NETD): relative to the mean radiance, not in K
            unit = _percent if away.get("unit") else _kelvin
            person = "" if away.get("unit") else _person_error(sensor)
            click.echo(
                f"  {sensor['name']}: error away from edges mean {unit(away['mean_k'], 4)}, p99 "
                f"{unit(away.get('p99_max_k'), 4)}; edge pixels {unit(away.get('edge_mean_k'), 3)} "
                f"(footprint){per_frame}{person}{verdict}"
            )
    for sensor in manifest.get("eo_sensors", []):  # EO: the error of Y relative to the mean Y
        rel = sensor.get("monte_carlo_error_relative") or {}
        quality = sensor.get("quality") or {}
        if rel.get("mean") is None:
            continue
        verdict = ""
        if quality.get("met") is True:
            verdict = "; quality target met"
        elif quality.get("met") is False:
            verdict = (
                f"; quality target NOT met in {len(quality['frames_not_met'])} frame(s) at the spp cap "
                f"({', '.join(quality['regions_not_met']) or 'image'})"
            )
        p99 = rel.get("p99_max")
        click.echo(
            f"  {sensor['name']}: error of Y away from edges mean {100.0 * rel['mean']:.2f} %, p99 "
            f"{'n/a' if p99 is None else f'{100.0 * p99:.2f} %'} of the mean Y{verdict}"
        )
    for item in manifest.get("skipped_sensors", []):
        click.echo(f"  skipped sensor {item['name']} ({item['band']}): {item['reason']}")


def _person_error(sensor: dict) -> str:
    """ "; person 0.0114 K (0.0372 K with the thermal layer's noise)": the largest per-frame mean
    error of the person's pixels away from edges, the render's alone and, where larger, with the
    thermal layer's stated face noise (issue 25.3: the image's error hid the person's, and the
    stopping rule sees the render's error only); "" without person pixels."""
    rows = [
        ((f.get("quality") or {}).get("regions") or {}).get("person")
        for f in sensor.get("frames", [])
        if isinstance(f, dict)
    ]
    rows = [r for r in rows if r and r.get("mean_k") is not None]
    if not rows:
        return ""
    render = max(r["mean_k"] for r in rows)
    total = max(r.get("total_error_mean_k") or r["mean_k"] for r in rows)
    noise = f" ({total:.4f} K with the thermal layer's noise)" if total > render else ""
    return f"; person {render:.4f} K{noise}"


def _percent(value, digits: int) -> str:
    """A relative error as a percentage of the mean radiance, or "n/a" (see :func:`_kelvin`)."""
    return "n/a" if value is None else f"{100.0 * value:.{max(digits - 2, 1)}f} % of the mean radiance"


def _kelvin(value, digits: int) -> str:
    """``value`` [K] with ``digits`` decimals, or "n/a" when it could not be estimated (e.g. no
    pixel away from edges in a tiny image, or no edge pixel)."""
    return "n/a" if value is None else f"{value:.{digits}f} K"


@main.command()
@click.argument("stages", nargs=-1, required=True, type=click.Path(path_type=Path))
def check(stages):
    """Run USD's validators and HumV's layer rules on each STAGE."""
    from humv_usd.usd.check import check_stage

    worst = 0
    for path in stages:
        try:
            findings = check_stage(path)
        except InputError as exc:
            for line in exc.problems:
                click.echo(f"{PROG}: error: {line}", err=True)
            worst = 2
            continue
        for line in findings:
            click.echo(f"{path}: {line}")
        if findings:
            worst = max(worst, 1)
        else:
            click.echo(f"{path}: ok")
    sys.exit(worst)


@main.group()
def bench():
    """Benchmarks: median run times and error estimates."""


@bench.command("pipeline")
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--spp", default=None, type=click.IntRange(1, 1 << 20), help="Samples per pixel (default: the render's)."
)
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(1, 100))
@reports_errors
def bench_pipeline(scenario: Path, spp: int, repeat: int):
    """Median wall times of compose and render of SCENARIO, with the render's MC error.

    "cli" runs the commands as a user does (a new process each: imports, asset loading and
    Mitsuba's JIT included); "in-process" repeats the calls in one process (warm caches).
    """
    from humv_usd.bench.pipeline import bench_pipeline as run_bench

    result = run_bench(scenario, spp, repeat)
    click.echo(f"scenario {scenario}, {spp or 'default'} spp, {repeat} runs each (median, min..max)")
    for name, values in result["times"].items():
        click.echo(f"  {name:<19} {statistics.median(values):7.3f} s  ({min(values):.3f}..{max(values):.3f})")
    click.echo(
        f"  Monte Carlo error: mean per-pixel standard error "
        f"{statistics.median(result['error_k']):.4f} K (median over runs)"
    )


@bench.command("preview")
@click.argument("scenario", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--sensor", default=None, help="The previewed sensor's id (default: the first infrared one).")
@click.option(
    "--quality",
    default="fast",
    show_default=True,
    type=click.Choice(["fast", "full"]),
    help="The editor's preview quality (fast: its own preview-quality stage; full: the real compose).",
)
@click.option(
    "--edits",
    default=None,
    help="Comma-separated subset of: cold, unchanged, heading, pose, clock, weather, netd (default: all).",
)
@click.option(
    "--warm/--no-warm",
    default=True,
    show_default=True,
    help="Run the commands in the editor's warm worker (as the page does), or each as a new process.",
)
@click.option(
    "-o",
    "--out",
    "work_dir",
    default="out/bench_preview",
    show_default=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Work folder (new, or one this bench made: emptied first): the scenario's copy and the editor's output folder.",
)
@reports_errors
def bench_preview(
    scenario: Path, sensor: str | None, quality: str, edits: str | None, warm: bool, work_dir: Path
):
    """The editor's preview of SCENARIO after each kind of edit, as the page runs it: wall and
    CPU seconds per step and the layers compose rebuilt (issue 26, 7)."""
    from humv_usd.bench.preview import EDITS
    from humv_usd.bench.preview import bench_preview as run_bench

    names = [e.strip() for e in edits.split(",")] if edits else None
    unknown = sorted(set(names or []) - {e[0] for e in EDITS})
    if unknown:
        raise InputError(
            f"--edits = {edits!r}: unknown {', '.join(unknown)}; allowed: {', '.join(e[0] for e in EDITS)}"
        )
    how = "the warm worker" if warm else "a process per command"
    click.echo(f"editor preview of {scenario} ({quality} quality, {how}), work folder {work_dir}")
    for timing in run_bench(scenario, work_dir, sensor, quality, names, warm):
        click.echo(timing.line())


@bench.command("clothing")
@click.option(
    "--garments",
    default="tshirt_white,trousers,jacket,cap",
    show_default=True,
    help="Comma-separated garments (humv_usd.catalog.garments.GARMENTS).",
)
@click.option("--activity", default="walk", show_default=True)
@click.option("--frames", default=30, show_default=True, type=click.IntRange(1, 10000))
@reports_errors
def bench_clothing(garments: str, activity: str, frames: int):
    """Fit an outfit to a walking avatar: intersections before/after the fix, air gaps, and the
    median per-frame time of the fix."""
    import json

    from humv_usd.bench.clothing import bench_outfit
    from humv_usd.catalog.garments import GARMENTS

    names = [g.strip() for g in garments.split(",") if g.strip()]
    unknown = [g for g in names if g not in GARMENTS]
    if unknown:
        raise InputError(f"--garments = {unknown[0]!r}: allowed garments: {', '.join(GARMENTS)}")
    click.echo(json.dumps(bench_outfit(names, activity=activity, frames=frames), indent=2))


@bench.command("avatar")
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(1, 50))
@reports_errors
def bench_avatar(repeat: int):
    """Body fit errors over a grid, contact figures for walk/run on flat and 5-degree ground,
    and the median time to author a 10 s, 30 fps walk (the `humv-usd avatar` command)."""
    from humv_usd.bench.avatar import author_times, body_fit_errors, contact_figures

    click.echo("body fit, age 30, average build: |error| of stature and of mesh mass [%]")
    for sex, (worst_h, worst_m) in body_fit_errors().items():
        click.echo(f"  {sex:<6} stature 1.5-2.0 m x mass 50-110 kg: max {worst_h:.2e} % / {worst_m:.2e} %")
    click.echo("ground contact, 10 s at 30 fps, male 1.78 m / 80 kg (sole vertices) [cm]:")
    for c in contact_figures():
        click.echo(
            f"  {c['activity']:<4} {c['speed_m_s']} m/s {c['ground']:<6} gap {100 * c['max_gap_m']:.2f}  "
            f"penetration {100 * c['max_penetration_m']:.2f}  "
            f"stance slip {100 * c['max_slip_m']:.2f}"
        )
    times = author_times(repeat)
    click.echo(
        f"author a 10 s, 30 fps walk (humv-usd avatar, new process): median "
        f"{statistics.median(times):.2f} s ({min(times):.2f}..{max(times):.2f})"
    )


@bench.command("thermal")
@click.option(
    "--facets",
    default=30000,
    show_default=True,
    type=click.IntRange(100, 10**7),
    help="Facets of the q_rad bench mesh (capsule avatar).",
)
@click.option(
    "--resolutions",
    default="45,90,180",
    show_default=True,
    help="Radiance-map sizes n (n x n); the largest is the brute-force reference.",
)
@click.option("--rays", default="16,64,256", show_default=True, help="Rays per facet of the fast method.")
@click.option(
    "--adaptive-rays",
    default="32,64,128",
    show_default=True,
    help="Mean rays per facet of the adaptive method.",
)
@click.option(
    "--scenario",
    "scenario",
    default=None,
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Bench q_rad on this scenario's first (clothed) person at frame 0 instead "
    "of the capsule avatar (composed into a temporary folder).",
)
@click.option(
    "--png",
    "png",
    default="thermal_bench.png",
    show_default=True,
    type=str,  # checked by check_output_file: one error line, not click's usage block
    help="Error-vs-run-time plot.",
)
@click.option("--quick", is_flag=True, help="Skip the physiology time-step sweep (slow JOS-3).")
@reports_errors
def bench_thermal(
    facets: int,
    resolutions: str,
    rays: str,
    adaptive_rays: str,
    scenario: Path | None,
    png: Path,
    quick: bool,
):
    """q_rad error against run time (methods x map resolutions), skin and garment temperature
    error against the time step, the garment balance's extreme-grid counts, and the run time of
    1 h of physiology (two-node, JOS-3)."""
    from humv_usd.bench.thermal import bench_qrad, physiology_run_times, plot_thermal_bench
    from humv_usd.bench.thermal_steps import garment_time_steps as garment_steps
    from humv_usd.bench.thermal_steps import skin_time_steps as skin_steps
    from humv_usd.fileio import check_output_file
    from humv_usd.physics.garment import extreme_grid_counts

    def ints(text, name):
        try:
            return tuple(int(x) for x in text.split(",") if x.strip())
        except ValueError:
            raise InputError(f"--{name} = {text!r}: expected comma-separated integers") from None

    png = check_output_file(png, "--png")  # fail fast, before the (long) bench
    case, what = None, "capsule avatar"
    if scenario is not None:
        from humv_usd.bench.thermal import avatar_case
        from humv_usd.pipeline.compose import compose as run_compose
        from humv_usd.scenario import load_scenario

        sc = load_scenario(scenario)
        if not sc["human"]:
            raise InputError(f"--scenario {scenario}: the scenario has no [[human]]")
        tmp = tempfile.mkdtemp(prefix="humv-bench-")
        run_compose(sc, tmp)
        case, what = avatar_case(sc, Path(tmp) / "stage.usda"), f"{scenario.name} person"
    rows = bench_qrad(
        facets=facets,
        resolutions=ints(resolutions, "resolutions"),
        fast_rays=ints(rays, "rays"),
        adaptive_rays=ints(adaptive_rays, "adaptive-rays"),
        case=case,
    )
    click.echo(
        f"q_rad on {rows[0]['facets']} facets ({what}) vs brute force at "
        f"{rows[0]['resolution']}x{rows[0]['resolution']}:"
    )
    click.echo("  method    map  rays  wall [s]  cpu [s]  rms rel. err  max rel. err  own estimate")
    for r in rows:
        click.echo(
            f"  {r['method']:<8} {r['resolution']:>4} {str(r['rays'] or '-'):>5} "
            f"{r['seconds']:9.3f} {r['cpu_seconds']:8.3f}  {r['rms_rel_error']:12.2e}  "
            f"{r['max_rel_error']:12.2e}  {r['rms_rel_error_estimate']:12.2e}"
        )
    ok = [r for r in rows if not r["reference"] and r["cpu_seconds"] <= 1.0 and r["rms_rel_error"] <= 0.01]
    click.echo(
        "  goal (<= 1 s cpu at <= 1 % rms): "
        + (
            "met by " + ", ".join(f"{r['method']} {r['resolution']} {r['rays'] or ''}".strip() for r in ok)
            if ok
            else "not met"
        )
    )

    g_rows = garment_steps()
    click.echo(
        "garment temperature error vs time step (implicit step; Radau reference; sun ramp + wind drop):"
    )
    for r in g_rows:
        click.echo(
            f"  {r['case']:<14} dt {r['step_s']:7.0f} s  max |dT| {r['max_error_k']:.2e} K"
            f" at step ends, {r['common_error_k']:.2e} K every "
            f"{max(x['step_s'] for x in g_rows):.0f} s  ({r['seconds']:.3f} s)"
        )
    s_rows = []
    for model in ("two_node",) + (() if quick else ("jos3",)):
        s_rows += skin_steps(model)
    click.echo("mean skin temperature error vs physiology time step (1 h, exercise bout):")
    for r in s_rows:
        click.echo(
            f"  {r['model']:<9} dt {r['step_s']:7.0f} s  max |dT| {r['max_error_k']:.2e} K"
            f"  ({r['seconds']:.3f} s)"
        )

    plot_thermal_bench(rows, g_rows, s_rows, what, png)
    click.echo(f"  plot: {png}")

    counts = extreme_grid_counts()
    click.echo("garment balance extreme grid: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    for model, median_s in physiology_run_times().items():
        click.echo(f"1 h of {model} physiology at 60 s steps: median {median_s:.3f} s")


def _register_tools():
    from humv_usd.cli.avatar_cmd import avatar

    main.add_command(avatar)
    from humv_usd.cli.adopt_cmd import adopt

    main.add_command(adopt)
    from humv_usd.cli.edit_cmd import edit

    main.add_command(edit)
    from humv_usd.cli.groundtruth_cmd import (
        register as register_groundtruth,  # regions, coco-merge, bench labels
    )

    register_groundtruth(main, bench)
    from humv_usd.cli.bench_render_cmd import bench_render

    bench.add_command(bench_render)
    from humv_usd.cli.sweep_cmd import register as register_sweep  # sweep, bench sweep

    register_sweep(main, bench)
    from humv_usd.cli.memory_cmd import bench_memory

    bench.add_command(bench_memory)
    from humv_usd.cli.bench_frame_cmd import bench_frame

    bench.add_command(bench_frame)
    from humv_usd.cli.detector_cmd import bench_detector

    bench.add_command(bench_detector)
    from humv_usd.cli.bench_places_cmd import bench_places

    bench.add_command(bench_places)
    from humv_usd.cli.bench_compose_cmd import bench_compose

    bench.add_command(bench_compose)
    from humv_usd.cli.bench_skinning_cmd import bench_skinning

    bench.add_command(bench_skinning)


_register_tools()
# loaded: Ctrl-C raises KeyboardInterrupt again, which each command reports as one line
# (humv_usd/__init__.py quietened it while the imports ran)
if signal.getsignal(signal.SIGINT) is not signal.default_int_handler and (
    threading.current_thread() is threading.main_thread()
):
    signal.signal(signal.SIGINT, signal.default_int_handler)

if __name__ == "__main__":
    main()
