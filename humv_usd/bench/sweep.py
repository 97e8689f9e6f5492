"""``humv-usd bench sweep``: throughput, scaling, memory and scheduler cost of a sweep.

Method (all on a local Dask cluster of processes, like a default ``humv-usd sweep``):

1. *Walk-like variants*: the scenario (default ``examples/walk.toml``, a walking person in front
   of the HUMVVEX LWIR camera) with its LWIR camera at ``resolution``, ``variants`` headings
   (grid ``placement.0.heading_deg``), ``frames`` frames each, ``frames_per_task`` frames per task (the sweep's default, 4).
2. *1 worker*: the sweep run into a fresh folder (compose + render). Its compose time is reported
   apart; the render part gives labeled LWIR frames per hour (every frame with ground truth:
   labels, boxes, keypoints, COCO).
3. *2 workers*: the same render tasks into a second folder that starts from the first one's
   composed variants (so both runs render the same tasks; compose is not part of the speed-up).
   Its steady rate is workers x frames per task / the median task time (what a long sweep
   approaches once the cluster's start, the first task's warm-up and the assembly are amortized).
3b. *1 worker on 1 core*: the same render tasks again, on a 1-worker cluster bound to one core
   (``run_sweep(cpus_per_worker=1)``). On a machine whose cores one worker already uses (its
   Dr.Jit threads, its writer thread), 2 workers against 1 cannot approach 2x; against one worker
   per core they show how the sweep scales as workers (cores, nodes) are added.
4. *Memory*: each task records its worker's resident memory at the end (``/proc/self/statm``),
   the worker's peak so far and the task's own peak (``tasks.start_task_peak``); with
   ``long_frames`` > 0 a one-worker sweep of that many frames (tiny 64 x 48 images, 1 spp,
   ``long_frames_per_task`` = 10 frames per task) gives the RSS of the task at 5 % of the run
   against the last one.
5. *Scheduler cost per task*: 200 no-op tasks on a 1-worker cluster, wall time / 200.

Speed-up and rates depend on what else runs on the machine; the report says how many cores it saw.
"""

from __future__ import annotations

import json
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from humv_usd.sweep import store
from humv_usd.sweep.run import NO_DASHBOARD, run_sweep
from humv_usd.sweep.spec import load_sweep

SWEEP_TEXT = """
[sweep]
name = "bench_{tag}"
base = "{base}"

[set]
"sensor.0.resolution" = [{w}, {h}]
"general.duration_s" = {duration}

[grid]
"placement.0.heading_deg" = {headings}

[render]
{spp}frames_per_task = {per_task}
"""


def _sweep_file(
    folder: Path,
    base: Path,
    tag: str,
    resolution,
    frames: int,
    spp: int | None,
    variants: int,
    per_task: int = 1,
) -> Path:
    fps = 15.0
    headings = [round(90.0 + 360.0 * i / max(1, variants), 3) for i in range(variants)]
    text = SWEEP_TEXT.format(
        tag=tag,
        base=base.resolve(),
        w=resolution[0],
        h=resolution[1],
        duration=(frames - 1) / fps,
        headings=headings,
        spp="" if spp is None else f"spp = {spp}\n",  # None: the render's automatic quality
        per_task=int(per_task),
    )
    path = folder / f"{tag}.toml"
    path.write_text(text)
    return path


def _task_records(dataset: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((dataset / "renders").glob(f"*/*/{store.TASK_RECORD}"))]


#: Frames per task of the throughput runs: the sweep's own default (``[render] frames_per_task``).
DEFAULT_FRAMES_PER_TASK = 4
#: Frames per task of the memory run: a 1,000-frame variant's layers take seconds to open (its
#: clothing and thermal layers hold every frame), which a task per frame would pay 1,000 times.
LONG_FRAMES_PER_TASK = 10


def _noop():
    return None


def scheduler_cost(n: int = 200) -> float:
    """Seconds per no-op task on a 1-worker local cluster (submit → result, in flight together)."""
    import distributed

    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, **NO_DASHBOARD
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        client.submit(_noop, pure=False).result()  # warm up
        t = time.perf_counter()
        futures = [client.submit(_noop, pure=False) for _ in range(n)]
        client.gather(futures)
        return (time.perf_counter() - t) / n


def run_bench(
    scenario="examples/walk.toml",
    frames: int = 8,
    spp: int | None = None,
    resolution=(320, 240),
    variants: int = 2,
    long_frames: int = 0,
    out_dir=None,
    frames_per_task: int = DEFAULT_FRAMES_PER_TASK,
    long_frames_per_task: int = LONG_FRAMES_PER_TASK,
) -> dict:
    """The numbers of the module doc, as a dict."""
    base = Path(scenario)
    root = Path(out_dir) if out_dir else Path(tempfile.mkdtemp(prefix="humv_bench_sweep_"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        sw = load_sweep(_sweep_file(root, base, "walk", resolution, frames, spp, variants, frames_per_task))
        one = run_sweep(sw, root / "one_worker", workers=1)
        compose_s = sum(
            r["seconds"]
            for r in (
                json.loads((p / store.COMPOSE_RECORD).read_text())
                for p in sorted((root / "one_worker" / "variants").iterdir())
            )
        )
        tasks1 = _task_records(root / "one_worker")
        render1 = sum(t["seconds"] for t in tasks1)
        shutil.copytree(root / "one_worker" / "variants", root / "two_workers" / "variants")
        shutil.copytree(root / "one_worker" / ".sweep" / "layers", root / "two_workers" / ".sweep" / "layers")
        t = time.perf_counter()
        two = run_sweep(sw, root / "two_workers", workers=2)
        two_wall = time.perf_counter() - t
        tasks2 = _task_records(root / "two_workers")
        task2_median = statistics.median(t["seconds"] for t in tasks2)
        shutil.copytree(root / "one_worker" / "variants", root / "one_core" / "variants")
        shutil.copytree(root / "one_worker" / ".sweep" / "layers", root / "one_core" / ".sweep" / "layers")
        t = time.perf_counter()
        one_core = run_sweep(sw, root / "one_core", workers=1, cpus_per_worker=1)
        one_core_wall = time.perf_counter() - t
        one_render_wall = one.seconds - compose_s
        report = {
            "cores": os.cpu_count(),
            "load_average_1min": os.getloadavg()[0],
            "scenario": str(base),
            "variants": len(sw.variants),
            "frames_per_variant": frames,
            "resolution": list(resolution),
            "spp": spp,
            "frames_per_task": frames_per_task,
            "images": one.images_rendered,
            "compose_s_1_worker": compose_s,
            "one_worker_wall_s": one.seconds,
            "one_worker_render_wall_s": one_render_wall,
            "task_seconds_median": statistics.median(t["seconds"] for t in tasks1),
            "labeled_lwir_frames_per_hour_1_worker": one.images_rendered / one_render_wall * 3600.0,
            "two_workers_wall_s": two_wall,
            "labeled_lwir_frames_per_hour_2_workers": two.images_rendered / two_wall * 3600.0,
            "speedup_2_vs_1": one_render_wall / two_wall,
            "task_seconds_median_2_workers": task2_median,
            "steady_frames_per_hour_2_workers": two.workers * frames_per_task * 3600.0 / task2_median,
            "one_worker_one_core_wall_s": one_core_wall,
            "labeled_lwir_frames_per_hour_1_worker_1_core": one_core.images_rendered / one_core_wall * 3600.0,
            "speedup_2_workers_vs_1_worker_on_1_core": one_core_wall / two_wall,
            "cores_of_the_1_core_worker": max(t["cores"] for t in _task_records(root / "one_core")),
            "scheduler_and_startup_s_1_worker": one_render_wall - render1,
            "scheduler_cost_per_task_s": scheduler_cost(),
            "peak_rss_mb_per_task_max": max(t["peak_rss_mb"] for t in tasks1),
        }
        if long_frames:
            sw_long = load_sweep(
                _sweep_file(root, base, "long", (64, 48), long_frames, 1, 1, long_frames_per_task)
            )
            run_sweep(sw_long, root / "long", workers=1)
            recs = sorted(_task_records(root / "long"), key=lambda r: r["frames"][0])
            early = recs[max(0, len(recs) // 20 - 1)]
            report["memory"] = {
                "frames": sum(len(r["frames"]) for r in recs),
                "tasks": len(recs),
                "frames_per_task": long_frames_per_task,
                "rss_mb_at_5_percent": early["rss_mb"],
                "rss_mb_last": recs[-1]["rss_mb"],
                "peak_rss_mb_at_5_percent": early["peak_rss_mb"],
                "peak_rss_mb_last": recs[-1]["peak_rss_mb"],
                "task_peak_rss_mb_at_5_percent": early.get("task_peak_rss_mb"),
                "task_peak_rss_mb_last": recs[-1].get("task_peak_rss_mb"),
                "growth_percent": 100.0 * (recs[-1]["rss_mb"] / early["rss_mb"] - 1.0),
            }
        return report
    finally:
        if not out_dir:
            shutil.rmtree(root, ignore_errors=True)
