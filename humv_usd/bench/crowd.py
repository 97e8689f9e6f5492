"""Compose memory and time of a crowd (issue 29.5): N people walking, each steering round the
others (placement ``avoidance = "socialForce"``), composed by ``humv-usd compose`` in a child
process whose peak resident set size is read from ``getrusage(RUSAGE_CHILDREN)``.

    python -m humv_usd.bench.crowd --people 10 --duration 1.5 --fps 30 --thermal fixed OUT

The scenario is examples/walk.toml's site and weather with its camera cut to 64x48 pixels; the
people start on a 3 m x 9 m block west of the origin and walk east, every second one on a
diagonal, so their paths cross; outfits: T-shirt, leggings, shoes. The result (JSON on stdout
and in OUT/bench_crowd.json): frames, people, peak RSS [MB], wall time [s], the layer texts
written [MB] and compose.json's seconds per layer.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

WALK_TOML = Path(__file__).resolve().parents[2] / "examples" / "walk.toml"


def crowd_scenario(people: int, duration_s: float, fps: float, thermal: str = "fixed") -> str:
    """The scenario text (see the module doc)."""
    src = WALK_TOML.read_text(encoding="utf-8")
    head = src[: src.index("[[human]]")]
    tail = src[src.index("[scene]") :]
    head = head.replace("fps = 15.0", f"fps = {fps}").replace(
        "duration_s = 2.0", f"duration_s = {duration_s}"
    )
    tail = tail.replace("resolution = [1024, 768]", "resolution = [64, 48]")
    tail = tail.replace('model = "jos3"', f'model = "{thermal}"', 1)
    out = []
    for i in range(people):
        x0, y0 = -6.0 + 1.5 * (i % 3), -4.5 + 1.0 * i
        waypoints = f"[[{x0 + 12.0:.1f}, {-y0 if i % 2 else y0:.1f}]]"
        out.append(
            f"""
[[human]]
id = "p{i}"
sex = "{"male" if i % 2 == 0 else "female"}"
age_yr = {25 + 3 * i}
stature_m = {1.60 + 0.025 * (i % 9):.3f}
mass_kg = {58 + 3 * i}.0
activity = "walk"
speed_m_s = {1.1 + 0.05 * (i % 5):.2f}
clothing = ["tshirt_black", "leggings", "shoes"]

[[placement]]
human = "p{i}"
position_m = [{x0:.1f}, {y0:.1f}, 0.0]
heading_deg = 90.0
waypoints_m = {waypoints}
avoidance = "socialForce"
"""
        )
    return head + "".join(out) + "\n" + tail


def bench_crowd(out: Path, people: int, duration_s: float, fps: float, thermal: str = "fixed") -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = out / "crowd.toml"
    scenario.write_text(crowd_scenario(people, duration_s, fps, thermal), encoding="utf-8")
    t = time.perf_counter()
    cmd = [
        sys.executable,
        "-m",
        "humv_usd.cli.main",
        "compose",
        str(scenario),
        "-o",
        str(out / "stage"),
        "--yes",
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    peak_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    layers = out / "stage" / "layers"
    report = json.loads((out / "stage" / "compose.json").read_text())
    result = {
        "people": people,
        "frames": int(round(duration_s * fps)) + 1,
        "fps": fps,
        "thermal": thermal,
        "peak_rss_mb": round(peak_kb / 1024.0, 1),
        "wall_s": round(seconds, 1),
        "layer_text_mb": round(sum(p.stat().st_size for p in layers.glob("*.usda")) / 1e6, 1),
        "layer_seconds": {e["name"]: e["seconds"] for e in report["layers"] if "seconds" in e},
        "cpus": os.cpu_count(),
    }
    (out / "bench_crowd.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return result


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--people", type=int, default=10)
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--thermal", default="fixed", choices=("fixed", "twoNode", "jos3"))
    a = ap.parse_args(argv)
    sys.stdout.write(json.dumps(bench_crowd(a.out, a.people, a.duration, a.fps, a.thermal), indent=2) + "\n")


if __name__ == "__main__":
    main()
