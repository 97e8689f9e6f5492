"""Compose cost against people count and frame count (issue 31.2: composes that keep up).

Each point of a grid (people x frames) is the crowd scenario of :mod:`humv_usd.bench.crowd`
(examples/walk.toml's site and weather, its camera cut to 64x48 pixels, N people walking east
past each other) with the chosen thermal model, composed from scratch by ``humv-usd compose`` in a
child process (no layer cache shared between points). A row per point: the wall seconds of every
layer (compose.json) and the child's CPU seconds (user + system, ``getrusage``). Then, per layer,
a least-squares fit ``seconds = base + per_person (N - 1) + per_frame (frames - 1)`` over the
rows says how the cost grows (its residual says how far it is from linear).

    humv-usd bench compose --people 1,2 --frames 1,4 --thermal jos3

With ``--scenario FILE`` (a scenario, or a sweep file with ``--variant N``) it composes that one
scenario from scratch instead, in a child process, and prints its CPU seconds (wall time is noise
on a shared machine, CPU seconds much less so); with ``--stages`` the child runs under cProfile
with a CPU-time clock and the row adds CPU seconds by stage (:func:`stage_cpu_seconds`: each
layer tool's build and the thermal tool's main parts, cumulative, so a part is inside its tool's
total; cProfile's own overhead inflates Python-heavy parts, so compare stages between profiled
runs and totals between unprofiled ones).

    humv-usd bench compose --scenario examples/walk.toml [--stages]
    humv-usd bench compose --scenario examples/table1.toml --variant 66
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from humv_usd.bench.crowd import crowd_scenario
from humv_usd.errors import InputError
from humv_usd.fileio import write_text_atomic
from humv_usd.pipeline.compose import compose
from humv_usd.pipeline.graph import discover_tools
from humv_usd.scenario import load_scenario
from humv_usd.sweep.spec import load_sweep

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


#: Parts of the thermal tool whose CPU seconds a profiled compose reports: name -> (source file
#: relative to the package, function); cumulative (a part includes what it calls).
THERMAL_STAGES = {
    "thermal.garment_stacks": ("physics/garment.py", "_stack_solve"),
    "thermal.physiology": ("thermal/physiology.py", "simulate_physiology"),
    "thermal.q_rad": ("thermal/qrad.py", "absorbed_radiation"),
    "thermal.surfaces": ("thermal/surfaces.py", "surface_temperatures"),
    "thermal.views": ("thermal/views.py", "face_views"),
}


def _tool_stages() -> dict:
    """name -> (source file relative to the package, entry function) of every layer tool."""
    out = {}
    for tool in discover_tools().values():
        rel = Path(tool.module.__file__).as_posix().rsplit("/humv_usd/", 1)[-1]
        entry = "build_one" if tool.per_human else "build"
        out[tool.name.replace("_{id}", "_*")] = (rel, entry)
    return out


def stage_cpu_seconds(profile: str | Path) -> dict:
    """CPU seconds by stage from a cProfile dump of a compose (``time.process_time`` clock):
    ``total``, every layer tool (per-person tools summed, ``avatar_*``), the thermal tool's
    parts (:data:`THERMAL_STAGES`) and ``imports`` (module imports, which a long-lived sweep
    worker pays once)."""
    stats = pstats.Stats(str(profile)).stats
    wanted = {**_tool_stages(), **THERMAL_STAGES}
    out = dict.fromkeys(["total", *wanted, "imports"], 0.0)
    for (filename, _, func), (_, _, tottime, cumtime, _) in stats.items():
        out["total"] += tottime
        name = Path(filename).as_posix()
        for stage, (rel, entry) in wanted.items():
            if func == entry and name.endswith("/humv_usd/" + rel):
                out[stage] += cumtime
        if func == "_find_and_load" and "importlib" in name:
            out["imports"] = max(out["imports"], cumtime)
    return {k: round(v, 2) for k, v in out.items()}


def _load(scenario: str | Path, variant: int | None):
    if variant is None:
        return load_scenario(scenario)
    sweep = load_sweep(scenario)
    if not 0 <= variant < len(sweep.variants):
        raise InputError(
            f"--variant {variant}: the sweep {scenario} has variants 0..{len(sweep.variants) - 1}"
        )
    return sweep.variants[variant].scenario


def profile_compose(
    scenario: str | Path, variant: int | None, out: str | Path, profile: str | Path | None
) -> None:
    """Compose ``scenario`` (its variant ``variant`` if it is a sweep file) into ``out`` from
    scratch, with ``profile`` under cProfile (CPU-time clock) and its dump there (the child of
    :func:`scenario_point`)."""
    sc = _load(scenario, variant)
    if profile is None:
        compose(sc, out, yes=True)
        return
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    try:
        compose(sc, out, yes=True)
    finally:
        prof.disable()
        prof.dump_stats(str(profile))


def scenario_point(
    scenario: str | Path, variant: int | None = None, keep: str | Path | None = None, stages: bool = False
) -> dict:
    """Compose one scenario from scratch in a child process: its row (wall and CPU seconds,
    seconds per layer from compose.json and, with ``stages``, under cProfile, CPU seconds by
    stage, :func:`stage_cpu_seconds`)."""
    _load(scenario, variant)  # a bad file or variant fails here, before the child starts
    base = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="humv-bench-compose-"))
    try:
        base.mkdir(parents=True, exist_ok=True)
        prof = base / "compose.prof"
        args = [str(scenario), str(base / "stage"), str(prof) if stages else "-"]
        args += [] if variant is None else [str(variant)]
        cmd = [sys.executable, "-m", "humv_usd.bench.compose_cost", *args]
        cpu0, t0 = _child_cpu_s(), time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - t0, _child_cpu_s() - cpu0
        if proc.returncode != 0:
            raise RuntimeError(f"compose of {scenario} failed: {proc.stderr[-1500:]}")
        report = json.loads((base / "stage" / "compose.json").read_text(encoding="utf-8"))
        row = {
            "scenario": str(scenario),
            "variant": variant,
            "profiled": stages,
            "wall_s": round(wall, 2),
            "cpu_s": round(cpu, 2),
            "layer_s": {e["name"]: round(float(e["seconds"]), 3) for e in report["layers"] if "seconds" in e},
        }
        if stages:
            row["stage_cpu_s"] = stage_cpu_seconds(prof)
        return row
    finally:
        if not keep:
            shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":  # the child of scenario_point: SCENARIO OUT PROFILE|- [VARIANT]
    profile_compose(
        sys.argv[1],
        int(sys.argv[4]) if len(sys.argv) > 4 else None,
        sys.argv[2],
        None if sys.argv[3] == "-" else sys.argv[3],
    )
