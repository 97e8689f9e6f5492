"""``humv-usd bench frame``: what one frame of a multi-frame render costs, and where it goes.

Renders frames 0..N of one sensor (the scene built once, per-frame updates, labels on, the
background writer on) and reports the median over frames 1..N (frame 0 builds the scene and
compiles the kernels) of the wall time per frame, measured between the ends of consecutive frames
(so a frame that waits for the previous frame's files pays for it), with its breakdown from the
manifest's per-frame timings: the estimator (:func:`humv_usd.render.estimator.render_band_fast`),
the conversions around it (brightness temperature, error in K, edges, statistics), labels, the
foreground part of the writes (queueing, preview levels, region statistics) and the writer
thread's time (overlapped with the next frame), plus labels as a fraction of the render and the
process CPU per frame. Issue 13: a 1024x768 walk LWIR frame with labels in <= 2 s, labels <= 0.2x.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from pathlib import Path

from humv_usd.errors import InputError
from humv_usd.pipeline.compose import compose
from humv_usd.pipeline.render import render_stage
from humv_usd.scenario import load_scenario


def _stage_of(path: Path, workdir: str) -> Path:
    """A composed stage: the given ``stage.usda`` (or folder), or SCENARIO.toml composed here."""
    if path.suffix == ".toml":
        out = Path(workdir) / "stage"
        compose(load_scenario(path), out)
        return out / "stage.usda"
    stage = path / "stage.usda" if path.is_dir() else path
    if not stage.is_file():
        raise InputError(f"{path}: expected a scenario .toml, a composed stage.usda or its folder")
    return stage


def bench_frames(path, sensor: str | None = None, frames: int = 8, spp: int | None = None) -> dict:
    """Render frames 0..``frames`` of ``sensor`` (default: the first IR sensor) and time them.

    Returns a dict: ``per_frame`` (one row per timed frame: wall, cpu, estimator, estimator_cpu,
    conversions, labels, labels_cpu, write, load_export [s]; the CPU columns are the process's CPU
    time, all threads, the background writer's included), ``median`` of each, ``labels_fraction`` (median labels /
    median render), ``writer_s_per_frame`` (the background writer's wall time per frame),
    ``writer_cpu_s_per_frame`` (its CPU), ``sensor``, ``resolution``, ``frames_timed``, ``load_average``.
    """
    if frames < 1:
        raise InputError(f"--frames = {frames}: expected >= 1 timed frames (frame 0 is the warm-up)")
    with tempfile.TemporaryDirectory(prefix="humv_bench_frame_") as tmp:
        stage = _stage_of(Path(path), tmp)
        ends: list[float] = []
        manifest = render_stage(
            stage,
            Path(tmp) / "render",
            frames=list(range(frames + 1)),
            spp=spp,
            sensors=[sensor] if sensor else None,
            progress=lambda done, total, text: ends.append(time.perf_counter()),
        )
    ir = manifest["sensors"]
    if not ir:
        raise InputError(f"{path}: no infrared sensor rendered (sensor {sensor!r})")
    s = ir[0]
    entries = sorted(s["frames"], key=lambda e: e["frame"])
    rows = []
    for i, entry in enumerate(entries[1:], start=1):
        t = entry["timings_s"]
        est = t.get("estimator", t["render"])
        rows.append(
            {
                "frame": entry["frame"],
                "wall": ends[i] - ends[i - 1] if i < len(ends) else None,
                "cpu": t["cpu"],
                "estimator": est,
                "estimator_cpu": t.get("estimator_cpu"),
                "conversions": t["render"] - est,
                "labels": t["labels"],
                "labels_cpu": t.get("labels_cpu"),
                "write": t["write"],
                "load_export": t["load_export"],
                "render": t["render"],
            }
        )
    keys = [k for k in rows[0] if k != "frame"] if rows else []
    median = {
        k: statistics.median(v) if (v := [r[k] for r in rows if r[k] is not None]) else None for k in keys
    }
    timings = manifest["timings_s"]
    return {
        "sensor": s["name"],
        "resolution": s["resolution"],
        "frames_timed": len(rows),
        "per_frame": rows,
        "median": median,
        "outside_estimator_s": median["wall"] - median["estimator"] if rows else None,
        "labels_fraction": median["labels"] / median["render"] if rows and median["render"] > 0 else None,
        "writer_s_per_frame": timings.get("write_background", 0.0) / max(1, len(entries)),
        "writer_cpu_s_per_frame": timings.get("write_background_cpu", 0.0) / max(1, len(entries)),
        "load_average": list(os.getloadavg()),
        "spp_used": s["monte_carlo_error_k"].get("spp_used"),
    }
