"""``humv-usd bench sweep`` on a tiny sweep: the report's counts and the one-core scaling run."""

import sys

import pytest

from humv_usd.bench.sweep import run_bench


@pytest.mark.skipif(sys.platform != "linux", reason="binds workers to cores with sched_setaffinity")
def test_bench_sweep_reports_rates_scaling_and_binds_the_one_core_worker(tmp_path):
    r = run_bench(
        "examples/walk.toml",
        frames=2,
        spp=1,
        resolution=(48, 32),
        variants=1,
        out_dir=tmp_path,
        frames_per_task=1,
    )
    assert r["images"] == 2 and r["frames_per_task"] == 1
    # the one-core run rendered the same tasks on a worker bound to one core
    assert r["cores_of_the_1_core_worker"] == 1
    for key in (
        "labeled_lwir_frames_per_hour_1_worker",
        "labeled_lwir_frames_per_hour_2_workers",
        "labeled_lwir_frames_per_hour_1_worker_1_core",
        "steady_frames_per_hour_2_workers",
        "speedup_2_vs_1",
        "speedup_2_workers_vs_1_worker_on_1_core",
    ):
        assert 0.0 < r[key] < 1e7, key
    # steady rate: 2 workers x 1 frame per task / the median task
    assert r["steady_frames_per_hour_2_workers"] == pytest.approx(
        2 * 3600.0 / r["task_seconds_median_2_workers"]
    )
    for run in ("one_worker", "two_workers", "one_core"):
        assert len(list((tmp_path / run / "renders").glob("*/*/task.json"))) == 2
