"""``humv-usd bench pipeline``: median wall times of compose and render of a scenario, with the
render's Monte Carlo error.

"cli" runs the commands as a user does (a new process each: imports, asset loading and Mitsuba's
JIT included); "in-process" repeats the calls in one process (warm caches).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from humv_usd.pipeline.compose import compose as run_compose
from humv_usd.pipeline.render import render_stage
from humv_usd.scenario import load_scenario

STEPS = ("compose cli", "render cli", "compose in-process", "render in-process")


def bench_pipeline(scenario: Path, spp: int | None, repeat: int) -> dict:
    """Run times [s] per step (:data:`STEPS`, ``repeat`` runs each) and the render's mean
    per-pixel Monte Carlo error [K] of each in-process run: ``{"times": {step: [s, ...]},
    "error_k": [...]}``. Bad input: InputError before any timing."""
    load_scenario(scenario)
    cli = [sys.executable, "-m", "humv_usd.cli.main"]
    times: dict[str, list[float]] = {k: [] for k in STEPS}
    err_k = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            out = Path(tmp) / f"cli{i}"
            for name, args in (
                ("compose cli", ["compose", str(scenario), "-o", str(out)]),
                (
                    "render cli",
                    ["render", str(out / "stage.usda"), "-o", str(out / "render"), "-q"]
                    + ([] if spp is None else ["--spp", str(spp)]),
                ),
            ):
                t = time.perf_counter()
                subprocess.run(cli + args, check=True, capture_output=True)
                times[name].append(time.perf_counter() - t)
        for i in range(repeat):
            out = Path(tmp) / f"run{i}"
            t = time.perf_counter()
            run_compose(load_scenario(scenario), out)
            times["compose in-process"].append(time.perf_counter() - t)
            t = time.perf_counter()
            manifest = render_stage(out / "stage.usda", out / "render", spp=spp, seed=i)
            times["render in-process"].append(time.perf_counter() - t)
            err_k.append(manifest["monte_carlo_error"]["temperature_stderr_mean_k"])
    return {"times": times, "error_k": err_k}
