"""Compose cost against people count and frame count (issue 31.2: composes that keep up).

Each point of a grid (people x frames) is the crowd scenario of :mod:`humv_usd.bench.crowd`
(examples/walk.toml's site and weather, its camera cut to 64x48 pixels, N people walking east
past each other) with the chosen thermal model, composed from scratch by ``humv-usd compose`` in a
child process (no layer cache shared between points). A row per point: the wall seconds of every
layer (compose.json) and the child's CPU seconds (user + system, ``getrusage``). Then, per layer,
a least-squares fit ``seconds = base + per_person (N - 1) + per_frame (frames - 1)`` over the
rows says how the cost grows (its residual says how far it is from linear).

    humv-usd bench compose --people 1,2 --frames 1,4 --thermal jos3
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from humv_usd.bench.crowd import crowd_scenario
from humv_usd.fileio import write_text_atomic

#: frame rate of the bench scenarios [1/s] (frames - 1 = duration x fps)
FPS = 8.0


def _child_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def compose_point(folder: Path, people: int, frames: int, thermal: str) -> dict:
    """Compose one grid point in ``folder`` (a fresh child process); its row."""
    folder.mkdir(parents=True, exist_ok=True)
    scenario = folder / "scenario.toml"
    write_text_atomic(scenario, crowd_scenario(people, (frames - 1) / FPS, FPS, thermal))
    cmd = [sys.executable, "-m", "humv_usd.cli.main", "compose", str(scenario), "-o", str(folder / "stage")]
    cpu0, t0 = _child_cpu_s(), time.perf_counter()
    proc = subprocess.run([*cmd, "--yes", "-q"], capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _child_cpu_s() - cpu0
    if proc.returncode != 0:
        raise RuntimeError(f"compose of {people} people x {frames} frames failed: {proc.stderr[-1500:]}")
    report = json.loads((folder / "stage" / "compose.json").read_text(encoding="utf-8"))
    return {
        "people": people,
        "frames": frames,
        "thermal": thermal,
        "wall_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "layer_s": {e["name"]: round(float(e["seconds"]), 3) for e in report["layers"] if "seconds" in e},
    }


def _per_tool(layer_s: dict) -> dict:
    """Seconds per tool: the per-person layers (``avatar_p0``, ``avatar_p1``, ...) summed as
    ``avatar_*``."""
    out: dict = {}
    for name, sec in layer_s.items():
        head, _, tail = name.rpartition("_")
        key = f"{head}_*" if head and tail[:1] == "p" and tail[1:].isdigit() else name
        out[key] = out.get(key, 0.0) + sec
    return out


def growth(rows: list[dict]) -> dict:
    """Per tool (per-person layers summed, :func:`_per_tool`; and ``cpu_s``, ``wall_s`` of the
    whole compose): the least-squares
    ``base``, ``per_person`` and ``per_frame`` seconds and the RMS residual [s]. A term the
    grid does not vary is left out (None)."""
    people = np.array([r["people"] for r in rows], dtype=float) - 1.0
    frames = np.array([r["frames"] for r in rows], dtype=float) - 1.0
    cols = [np.ones(len(rows))]
    names = ["base"]
    for name, x in (("per_person", people), ("per_frame", frames)):
        if np.ptp(x) > 0:
            cols.append(x)
            names.append(name)
    a = np.stack(cols, axis=1)
    per_tool = [_per_tool(r["layer_s"]) for r in rows]
    layers = sorted({k for t in per_tool for k in t})
    series = {k: [t.get(k, 0.0) for t in per_tool] for k in layers}
    series["cpu_s"] = [r["cpu_s"] for r in rows]
    series["wall_s"] = [r["wall_s"] for r in rows]
    out = {}
    for k, y in series.items():
        y = np.asarray(y, dtype=float)
        coef, *_ = np.linalg.lstsq(a, y, rcond=None)
        fit = dict.fromkeys(("base", "per_person", "per_frame"))
        fit.update({n: round(float(c), 3) for n, c in zip(names, coef)})
        fit["rms_residual"] = round(float(np.sqrt(np.mean((a @ coef - y) ** 2))), 3)
        out[k] = fit
    return out


def bench_compose(
    people: list[int], frames: list[int], thermal: str = "jos3", keep: str | Path | None = None, echo=None
) -> dict:
    """Compose every (people, frames) point; {"rows": [...], "growth": :func:`growth`,
    "cpus": ...}. ``echo``: called with each row as it is done."""
    base = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="humv-bench-compose-"))
    rows = []
    try:
        for n in people:
            for f in frames:
                row = compose_point(base / f"p{n}_f{f}", n, f, thermal)
                rows.append(row)
                if echo is not None:
                    echo(row)
    finally:
        if not keep:
            shutil.rmtree(base, ignore_errors=True)
    return {"rows": rows, "growth": growth(rows) if len(rows) > 1 else {}, "cpus": os.cpu_count()}
