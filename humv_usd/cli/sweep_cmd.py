"""``humv-usd sweep`` (a grid / random sweep into one dataset, on Dask) and ``humv-usd bench sweep``
(registered on the ``humv-usd`` group by :func:`register`)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import click

from humv_usd.cli.common import reports_errors
from humv_usd.errors import InputError

#: Seconds between the status lines printed when stderr is not a terminal (a batch job's log).
LOG_EVERY_S = 60.0


class _Progress:
    """A rich live display of the sweep's events: tasks and images done, rate, ETA, failures. When
    stderr is not a terminal (nohup, SLURM, CI), where a live display shows nothing until the end,
    a plain status line every :data:`LOG_EVERY_S` seconds instead."""

    def __init__(self, quiet: bool):
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.console = Console(stderr=True)
        self.progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[info]}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=self.console,
            disable=quiet,
        )
        self.t0 = time.perf_counter()
        self.images = 0
        self.failures = 0
        self.retries = 0
        self.composed = 0
        self.lines = not quiet and not self.console.is_terminal
        self.last_line = -float("inf")
        self.counts = dict.fromkeys(
            ("variants", "tasks", "tasks_done", "frames", "frames_done", "frames_done_before"), 0
        )

    def __enter__(self):
        self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def __call__(self, event: dict) -> None:
        kind = event["type"]
        p = self.progress
        self._count(event)
        if kind == "start":
            self.variants = p.add_task("variants composed", total=event["variants"], info="")
            self.tasks = p.add_task("render tasks", total=event["tasks"], completed=event["done"], info="")
            self.frames = p.add_task("frames", total=event["frames"], completed=event["frames_done"], info="")
        elif kind == "compose":
            self.composed += 1
            p.update(self.variants, advance=1, info=f"{event['variant']} {event['seconds']:.1f} s")
        elif kind == "render":
            self.images += event["images"]
            rate = self.images / (time.perf_counter() - self.t0) * 3600.0
            p.update(self.tasks, advance=1, info=self._info())
            p.update(self.frames, advance=event["frames"], info=f"{rate:,.0f} images/h")
        elif kind == "retry":
            self.retries += 1
            p.console.print(f"retry {event['attempt']} of {event['task']}: {event['error']}")
            p.update(self.tasks, info=self._info())
        elif kind == "failed":
            self.failures += 1
            p.console.print(f"[red]failed[/red] {event['task']}: {event['error']}")
            p.update(self.tasks, info=self._info())
        elif kind == "assemble":
            p.console.print("assembling the dataset (COCO per sensor, index, card, YOLO)")
        if (
            self.lines
            and kind in ("start", "compose", "render")
            and (kind == "start" or time.perf_counter() - self.last_line >= LOG_EVERY_S)
        ):
            self.last_line = time.perf_counter()
            self.console.print(self.status_line(), highlight=False, soft_wrap=True)

    def _count(self, event: dict) -> None:
        c, kind = self.counts, event["type"]
        if kind == "start":
            c.update(variants=event["variants"], tasks=event["tasks"], tasks_done=event["done"])
            c.update(
                frames=event["frames"],
                frames_done=event["frames_done"],
                frames_done_before=event["frames_done"],
            )
        elif kind == "render":
            c["tasks_done"] += 1
            c["frames_done"] += event["frames"]

    def status_line(self) -> str:
        """Elapsed time, variants composed, tasks and frames done, this run's rate, ETA, failures."""
        c, elapsed = self.counts, time.perf_counter() - self.t0
        rate = self.images / elapsed * 3600.0 if elapsed > 0 else 0.0
        frames_rate = (c["frames_done"] - c["frames_done_before"]) / elapsed * 3600.0 if elapsed > 0 else 0.0
        left = c["frames"] - c["frames_done"]
        eta = f"{left / frames_rate:.1f} h" if frames_rate > 0 else "-"
        return (
            f"[{time.strftime('%H:%M:%S')}] {elapsed / 60.0:.1f} min: variants composed {self.composed} "
            f"(this run), render tasks {c['tasks_done']}/{c['tasks']}, frames {c['frames_done']}/{c['frames']}, "
            f"{rate:,.0f} images/h, ETA {eta}, failures {self.failures}, retries {self.retries}"
        )

    def _info(self) -> str:
        return f"failures {self.failures}, retries {self.retries}"


@click.command()
@click.argument("sweep_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--out",
    "out_dir",
    required=True,
    type=str,
    help="The dataset folder (new or to resume), or an fsspec URL (s3://bucket/prefix, gs://..., file://...).",
)
@click.option(
    "--dry-run",
    is_flag=True,
    help="Print the variants and the estimated cost of what is left to do (a dataset being resumed: "
    "its done tasks apart); run nothing.",
)
@click.option(
    "--scheduler",
    default=None,
    help="Address of an existing Dask scheduler (tcp://HOST:PORT); default: a local cluster of processes.",
)
@click.option(
    "--workers",
    default=None,
    type=click.IntRange(0, 4096),
    help="Local cluster size (default: one per core; 0: run in this process, one task at a time); "
    "with --gpus: the CPU workers (default: cores - GPUs, at least 1).",
)
@click.option(
    "--gpus",
    default=0,
    type=click.IntRange(0, 64),
    help="Start a local cluster with one render worker per GPU (Dask resource GPU=1, CUDA backend) "
    "beside --workers CPU workers for the composes; with --dry-run: estimate with the measured GPU "
    "rate on that many GPUs. On an existing cluster (--scheduler) give GPU workers "
    "`--resources GPU=1` instead (docs/user/gpu.md).",
)
@click.option(
    "--limit",
    default=None,
    type=click.IntRange(1, None),
    help="Run only the first N variants (a later run without it adds the others).",
)
@click.option("--quiet", is_flag=True, help="No progress display.")
@click.option("--yes", is_flag=True, help="Run even when the estimated writes exceed the free disk.")
@reports_errors
def sweep(
    sweep_file: Path, out_dir: str, dry_run: bool, scheduler, workers, gpus, limit, quiet: bool, yes: bool
):
    """Expand SWEEP_FILE (a base scenario + grid and random axes) into variants, compose and render
    them as tasks on Dask (one per variant and frame chunk) and assemble one dataset in OUT.
    Re-running the same command resumes: only what is missing runs."""

    from humv_usd.fileio import check_output_dir
    from humv_usd.sweep.spec import load_sweep
    from humv_usd.sweep.where import Location, is_url

    # fail fast, before reading anything
    Location(out_dir) if is_url(out_dir) else check_output_dir(out_dir, "dataset folder")
    sw = load_sweep(sweep_file)  # every variant validated: InputError names the axis
    if dry_run:
        _dry_run(sw, out_dir, workers, limit, gpus)
        return
    from humv_usd.sweep.run import run_sweep

    with _Progress(quiet) as progress:
        result = run_sweep(
            sw,
            out_dir,
            scheduler=scheduler,
            workers=workers,
            on_event=progress,
            limit=limit,
            yes=yes,
            gpus=gpus,
        )
    s = result.dataset_summary
    variants = f"{s['variants']} variants"
    if limit is not None:  # the dataset holds only what ran so far: say so, not the sweep's count
        variants = f"{s['variants_with_images']} of {s['variants']} variants (--limit {limit})"
    click.echo(
        f"{result.dataset}: {variants}, {s['frames']} frames, {s['images']} images "
        f"({result.already_done} of {result.tasks} tasks were done before; ran {result.ran}, "
        f"composed {result.composed}, retries {result.retries}, failed {len(result.failures)}); "
        f"{result.seconds:.1f} s on {result.workers} worker(s)"
        + (f" ({result.gpu_workers} with a GPU)" if result.gpu_workers else "")
        + f", {result.frames_per_hour:,.0f} images/h"
    )
    for f in result.failures:
        click.echo(f"  failed: {f['task']}: {f['error']}", err=True)
    if result.failures:
        raise SystemExit(1)


def _dry_run(sw, out_dir: str, workers, limit, gpus: int = 0) -> None:
    """The variants, then the counts and the estimated cost of what is left (a dataset folder of
    this sweep: its done tasks and composed variants apart; another sweep's: refused as the run
    would; ``limit``: the variants after the first ``limit`` apart)."""
    import os

    from humv_usd.sweep import store
    from humv_usd.sweep.plan import GPU_FRAMES_PER_TASK, disk_text, estimate, held_work, layer_keys
    from humv_usd.sweep.where import Location, is_url

    loc = Location(out_dir if is_url(out_dir) else Path(out_dir).resolve())
    store.check_sweep_record(loc, sw.digest())
    done, composed = held_work(sw, loc, limit)
    keys = {v.id: layer_keys(v.scenario) for v in sw.variants}
    n_workers = workers if workers else (os.cpu_count() or 1)
    if gpus and not workers:  # the CPU workers beside the GPU workers, as run_sweep starts them
        n_workers = max(1, (os.cpu_count() or 1) - gpus)
    for v in sw.variants:
        click.echo(f"{v.id}  " + ", ".join(f"{k}={val}" for k, val in v.params.items()))
    est = estimate(sw, keys, n_workers, done, composed, gpus=gpus)
    click.echo(
        f"{est['variants']} variants, {est['render_tasks']} render tasks, {est['frames']} frames, "
        f"{est['images']} images"
    )
    if est["tasks_done"] or est["variants_composed"]:
        click.echo(
            f"already in {loc}: {est['tasks_done']} render tasks ({est['frames_done']} frames), "
            f"{est['variants_composed']} variants composed; left: {est['images_todo']} images, "
            f"{est['variants_to_compose']} variants to compose"
        )
    click.echo(
        f"{est['megasamples']} Msamples to render; {est['layers_to_build']} of {est['layers']} layers "
        "to compose (the others shared or already built)"
    )
    if gpus:
        click.echo(
            f"estimated cost: compose {est['compose_s']:.0f} s of one CPU worker, render {est['render_s']:.0f} s "
            f"of one GPU ({est['frames_per_task']} frames per task); about {est['wall_h']:.2f} h on {gpus} "
            f"GPU(s) and {n_workers} CPU worker(s) ({est['frames_per_hour']:,} images/h)"
        )
        if est["frames_per_task"] < GPU_FRAMES_PER_TASK:
            click.echo(
                f"hint: [render] frames_per_task = {GPU_FRAMES_PER_TASK} keeps a GPU task's first-frame "
                f"cost under 10 % (now {est['frames_per_task']})"
            )
    else:
        click.echo(
            f"estimated cost: compose {est['compose_s']:.0f} s + render {est['render_s']:.0f} s of one worker; "
            f"about {est['wall_h']:.2f} h on {n_workers} worker(s) ({est['frames_per_hour']:,} images/h)"
        )
    click.echo(f"rates: {est['rates']}")
    where = "" if loc.remote else f" ({disk_text(est, loc.path)})"
    click.echo(f"estimated disk: {est['disk_gb']:.1f} GB{where}")


@click.command("sweep")
@click.argument("scenario", default="examples/walk.toml", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--variants", default=2, show_default=True, type=click.IntRange(1, 1000), help="Headings.")
@click.option(
    "--frames", default=8, show_default=True, type=click.IntRange(1, 100_000), help="Frames per run."
)
@click.option(
    "--spp",
    default=None,
    type=click.IntRange(1, 1 << 20),
    help="Samples per pixel (default: the render's automatic quality, infrared to NETD/3).",
)
@click.option("--resolution", default="320x240", show_default=True, help="LWIR image size WxH.")
@click.option(
    "--long",
    "long_frames",
    default=0,
    show_default=True,
    type=int,
    help="Frames of the memory run (0: skip).",
)
@click.option(
    "--frames-per-task",
    default=4,
    show_default=True,
    type=click.IntRange(1, 100_000),
    help="Frames per task of the throughput runs (a sweep's [render] frames_per_task).",
)
@click.option(
    "-o", "--out", "out_dir", default=None, help="Keep the bench datasets here (default: a temp folder)."
)
@reports_errors
def bench_sweep(
    scenario: Path,
    variants: int,
    frames: int,
    spp: int,
    resolution: str,
    long_frames: int,
    frames_per_task: int,
    out_dir,
):
    """Labeled LWIR frames per hour for a walk-like sweep of SCENARIO, speed-up of 2 workers over 1, memory
    per worker over a long sweep, and the scheduler's cost per task."""
    from humv_usd.bench.sweep import run_bench

    w, h = (int(x) for x in resolution.lower().split("x"))
    report = run_bench(
        scenario,
        frames=frames,
        spp=spp,
        resolution=(w, h),
        variants=variants,
        long_frames=long_frames,
        out_dir=out_dir,
        frames_per_task=frames_per_task,
    )
    click.echo(json.dumps(report, indent=2))


@click.group()
def dataset():
    """Sweep datasets: check one the way its consumers read it."""


@dataset.command("check")
@click.argument("dataset_dir", type=click.Path(file_okay=False, path_type=Path))
@reports_errors
def dataset_check(dataset_dir: Path):
    """Read DATASET_DIR as pycocotools (load, COCOeval for boxes and keypoints), Hugging Face
    datasets (the index, its split column and paths) and Ultralytics (the YOLO layout rules)
    read it; print each problem, exit 1 when there are any (2: not a dataset)."""
    from humv_usd.sweep.check import check_dataset

    if not dataset_dir.is_dir():
        raise InputError(f"dataset check: {dataset_dir}: not a folder")
    problems = check_dataset(dataset_dir)
    if problems and problems[0].endswith("not assembled yet)"):
        raise InputError(problems[0])
    for line in problems:
        click.echo(f"{dataset_dir}: {line}", err=True)
    if problems:
        sys.exit(1)
    click.echo(f"{dataset_dir}: ok (pycocotools, Hugging Face datasets and the YOLO layout rules read it)")


def register(main, bench) -> None:
    main.add_command(sweep)
    main.add_command(dataset)
    bench.add_command(bench_sweep)
