"""The physics pages' error-against-run-time data, from the project's own benches (``make
docs-data``; minutes on the 2-core machine, run it niced and commit the CSVs).

Writes ``docs/physics/data/*.csv``; ``make docs`` plots them (``humv_docs.py``, matplotlib, at
build time: the CSVs are the single source of the figures). Each CSV starts with ``#`` lines
that say which bench made it, with which command, on which commit and when.

- ``render_error_time.csv``: ``humv-usd bench render docs/physics/data/render_bench.toml`` (the
  first tutorial's scene at 640x512; the fast IR estimator at 1-8 spp and 4 or 16 sub-bands, the path tracer's former default, against a 256-spp
  path-traced reference): Monte Carlo error and largest region bias against wall and CPU time.
- ``subband_error.csv``: the same run's spectral error of the sub-band model against the
  sub-band count.
- ``eo_error_time.csv``: the same run's EO camera (at half its 720x540): the fast EO estimator at
  2-8 spp and 4 or 16 visible bins and the spectral path tracer's former default, against a
  64-spp spectral path-traced reference: Y's error relative to the mean Y against time.
- ``qrad_error_time.csv``: ``humv_usd.bench.thermal.bench_qrad`` (what ``humv-usd bench
  thermal`` runs) on the capsule avatar: the absorbed radiation's relative error against the
  brute-force reference by method, map size and rays, against CPU time.
- ``garment_time_steps.csv`` and ``skin_time_steps.csv``: the same bench's garment and mean
  skin temperature (two-node and JOS-3) error against the time step (Radau / fine-step
  references).
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "docs" / "physics" / "data"
RENDER_ARGS = [
    "docs/physics/data/render_bench.toml",
    "--spp",
    "1,2,4,8",
    "--subbands",
    "4,16",
    "--eo-spp",
    "2,4,8",
    "--eo-bins",
    "4,16",
    "--eo-scale",
    "0.5",
]
QRAD = dict(facets=10000, resolutions=(45, 90, 180), fast_rays=(16, 64, 256), adaptive_rays=(32, 64, 128))


def _header(command: str) -> list[str]:
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    when = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return [
        f"# {command}",
        f"# commit {commit}, {when}, {os.cpu_count()} CPUs (shared, niced); regenerate: make docs-data",
    ]


def _write(name: str, header: list[str], fields: list[str], rows: list[dict]) -> None:
    DATA.mkdir(parents=True, exist_ok=True)
    tmp = DATA / f".{name}.tmp"
    with open(tmp, "w", newline="") as f:
        f.write("\n".join(header) + "\n")
        w = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: _fmt(r.get(k)) for k in fields})
    os.replace(tmp, DATA / name)
    sys.stdout.write(f"wrote {DATA / name} ({len(rows)} rows)\n")


def _fmt(v):
    if isinstance(v, float):
        return f"{v:.6g}"
    return "" if v is None else v


def render_data() -> None:
    humv = Path(sys.executable).with_name("humv-usd")
    with tempfile.TemporaryDirectory() as tmp:
        prefix = Path(tmp) / "render"
        cmd = [str(humv), "bench", "render", *RENDER_ARGS, "-o", str(prefix)]
        subprocess.run(cmd, cwd=ROOT, check=True)
        result = json.loads(prefix.with_suffix(".json").read_text())
    header = _header("humv-usd bench render " + " ".join(RENDER_ARGS))
    rows = []
    for sensor, rec in result["sensors"].items():
        ref = rec["reference"]
        rows.append(
            {
                "sensor": sensor,
                "estimator": "reference",
                "spp": ref["spp"],
                "subbands": ref["subbands"],
                "wall_s": ref["wall_s"],
                "mc_error_mean_k": ref["noise"]["mean_k"],
                "mc_error_p99_k": ref["noise"]["p99_k"],
                "ray_cast_s": rec["ray_cast_s"],
                "netd_k": rec["netd_k"],
            }
        )
        for r in rec["rows"]:
            worst = max(r["bias_by_region"].values(), key=lambda b: abs(b["bias_k"]))
            rows.append(
                {
                    "sensor": sensor,
                    "estimator": r["estimator"],
                    "spp": r["spp"],
                    "subbands": r["subbands"],
                    "wall_s": r["wall_s"],
                    "cpu_s": r["cpu_s"],
                    "mc_error_mean_k": r["noise"]["mean_k"],
                    "mc_error_p99_k": r["noise"]["p99_k"],
                    "max_abs_bias_k": abs(worst["bias_k"]),
                    "bias_sigma_k": worst["sigma_k"],
                    "default": int(bool(r["default"])),
                    "ray_cast_s": rec["ray_cast_s"],
                    "netd_k": rec["netd_k"],
                }
            )
    _write(
        "render_error_time.csv",
        header,
        [
            "sensor",
            "estimator",
            "spp",
            "subbands",
            "wall_s",
            "cpu_s",
            "mc_error_mean_k",
            "mc_error_p99_k",
            "max_abs_bias_k",
            "bias_sigma_k",
            "default",
            "ray_cast_s",
            "netd_k",
        ],
        rows,
    )
    spectral = []
    for sensor, rec in result["spectral_error"]["sensors"].items():
        for n, e in rec["error_by_subbands"].items():
            spectral.append({"sensor": sensor, "subbands": int(n), "max_k": e["max_k"], "rms_k": e["rms_k"]})
    _write("subband_error.csv", header, ["sensor", "subbands", "max_k", "rms_k"], spectral)
    eo_rows = []
    for sensor, rec in result["eo"]["sensors"].items():
        ref = rec["reference"]
        eo_rows.append(
            {
                "sensor": sensor,
                "estimator": "reference",
                "spp": ref["spp"],
                "wall_s": ref["wall_s"],
                "cpu_s": ref["cpu_s"],
                "rel_error_mean": ref["noise"]["mean"],
                "rel_error_p99": ref["noise"]["p99"],
            }
        )
        for r in rec["rows"]:
            biases = [b for b in r["bias_by_region"].values() if b["bias_rel_xyz"][1] is not None]
            worst = max(biases, key=lambda b: abs(b["bias_rel_xyz"][1])) if biases else None
            eo_rows.append(
                {
                    "sensor": sensor,
                    "estimator": r["estimator"],
                    "spp": r["spp"],
                    "bins": r["bins"],
                    "wall_s": r["wall_s"],
                    "cpu_s": r["cpu_s"],
                    "rel_error_mean": r["noise"]["mean"],
                    "rel_error_p99": r["noise"]["p99"],
                    "max_abs_bias_rel_y": None if worst is None else abs(worst["bias_rel_xyz"][1]),
                    "bias_sigma_rel_y": None if worst is None else worst["sigma_rel_y"],
                    "default": int(bool(r["default"])),
                }
            )
    _write(
        "eo_error_time.csv",
        header,
        [
            "sensor",
            "estimator",
            "spp",
            "bins",
            "wall_s",
            "cpu_s",
            "rel_error_mean",
            "rel_error_p99",
            "max_abs_bias_rel_y",
            "bias_sigma_rel_y",
            "default",
        ],
        eo_rows,
    )


def thermal_data() -> None:
    from humv_usd.bench.thermal import bench_qrad
    from humv_usd.bench.thermal_steps import garment_time_steps, skin_time_steps

    rows = bench_qrad(**QRAD)
    _write(
        "qrad_error_time.csv",
        _header(f"humv_usd.bench.thermal.bench_qrad({', '.join(f'{k}={v}' for k, v in QRAD.items())})"),
        [
            "method",
            "resolution",
            "rays",
            "facets",
            "seconds",
            "cpu_seconds",
            "rms_rel_error",
            "max_rel_error",
        ],
        rows,
    )
    g = garment_time_steps()
    _write(
        "garment_time_steps.csv",
        _header("humv_usd.bench.thermal_steps.garment_time_steps() (humv-usd bench thermal)"),
        ["case", "step_s", "max_error_k", "common_error_k", "seconds"],
        g,
    )
    s = skin_time_steps("two_node") + skin_time_steps("jos3")
    _write(
        "skin_time_steps.csv",
        _header(
            "humv_usd.bench.thermal_steps.skin_time_steps('two_node' and 'jos3') (humv-usd bench thermal)"
        ),
        ["model", "step_s", "max_error_k", "seconds"],
        s,
    )


if __name__ == "__main__":
    which = set(sys.argv[1:]) or {"render", "thermal"}
    if "thermal" in which:
        thermal_data()
    if "render" in which:
        render_data()
