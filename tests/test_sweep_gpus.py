"""Sweeps that schedule GPUs (issue 31.3): GPU workers render, CPU workers compose, a batch of
frames per task renders the same images as one frame per task, and the dry run's estimate follows
the measured GPU rate and the knobs. No GPU here: the "GPU" workers declare the Dask resource and
render on the LLVM backend (:data:`humv_usd.sweep.cluster.GPU_WORKER_BACKEND` patched)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from test_sweep import TINY

from humv_usd import images
from humv_usd.cli.main import main
from humv_usd.sweep import cluster, plan
from humv_usd.sweep.run import run_sweep
from humv_usd.sweep.spec import load_sweep

#: 3 frames (0.5 s at 4 fps), one variant
BASE = TINY.replace("duration_s = 0.25", "duration_s = 0.5")


def _sweep(tmp_path: Path, frames_per_task: int, spp: int = 2, temps=(300.0,)) -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "tiny.toml").write_text(BASE)
    path = tmp_path / "sweep.toml"
    path.write_text(
        f"""
[sweep]
name = "tiny"
base = "tiny.toml"
[grid]
"scene.object.0.temperature_k" = {list(temps)}
[render]
spp = {spp}
frames_per_task = {frames_per_task}
"""
    )
    return path


def test_gpu_estimate_is_the_measured_rate_scaled_by_the_knobs(tmp_path):
    """Closed form: per image 2.59 s x pixels / (1024 x 768) x spp / 2, plus 3.6 s per task; GPUs
    divide the render time; the slower of render / GPUs and compose / CPU workers sets the wall."""
    pixels = 32 * 24
    per_image = 2.59 * pixels / (1024 * 768)

    def est(frames_per_task=1, spp=2, gpus=1, workers=1, temps=(300.0, 310.0), keys=None):
        sw = load_sweep(
            _sweep(tmp_path / f"{frames_per_task}_{spp}_{len(temps)}", frames_per_task, spp, temps)
        )
        keys = keys or {v.id: {} for v in sw.variants}  # nothing to compose
        return plan.estimate(sw, keys, workers, gpus=gpus)

    one = est()  # 2 variants x 3 frames, one frame per task
    assert one["render_s"] == pytest.approx(round(6 * per_image + 6 * 3.6, 1), abs=0.051)
    assert one["wall_s"] == pytest.approx(one["render_s"], abs=0.051)
    assert est(gpus=2)["wall_s"] == pytest.approx(one["render_s"] / 2, abs=0.051)
    batched = est(frames_per_task=3)  # one task per variant
    assert batched["render_s"] == pytest.approx(round(6 * per_image + 2 * 3.6, 1), abs=0.051)
    assert est(spp=8)["render_s"] == pytest.approx(round(4 * 6 * per_image + 6 * 3.6, 1), abs=0.051)
    assert one["render_on"] == "gpu" and "H100" in one["rates"] and "2026-11-27" in one["rates"]
    # compose-bound: 2 thermal layers of 3 frames on 1 CPU worker, against renders on 64 GPUs
    fixed, per_frame = plan.FIXED_SKIN_THERMAL_SECONDS  # the tiny scenario's model = "fixed"
    composing = est(gpus=64, keys={"v0000": {"thermal": "a"}, "v0001": {"thermal": "b"}})
    sc = load_sweep(tmp_path / "1_2_2" / "sweep.toml").variants[0].scenario  # plus the scene's term
    scene_s = plan.scene_thermal_seconds(plan.scene_meshes(sc), plan.sun_in_memory(sc))
    assert scene_s > 0.0
    assert composing["wall_s"] == pytest.approx(round(2 * (fixed + 3 * per_frame + scene_s), 1), abs=0.051)
    cpu = est(gpus=0)  # the CPU estimate is unchanged: (compose + render) / workers
    assert cpu["render_on"] == "cpu" and cpu["render_s"] == pytest.approx(
        round(6 * pixels * 2 / plan.SAMPLES_PER_SECOND_PER_WORKER + 6 * plan.SECONDS_PER_IMAGE, 1), abs=0.051
    )


def test_dry_run_with_gpus_names_the_rate_and_suggests_a_batch(tmp_path):
    path = _sweep(tmp_path, frames_per_task=1)
    res = CliRunner().invoke(
        main, ["sweep", str(path), "-o", str(tmp_path / "ds"), "--dry-run", "--gpus", "2"]
    )
    assert res.exit_code == 0, res.output
    assert "on 2 GPU(s)" in res.output and "one H100, cuda_ad_mono" in res.output
    assert f"frames_per_task = {plan.GPU_FRAMES_PER_TASK}" in res.output
    assert not (tmp_path / "ds").exists()


def test_gpus_with_an_existing_scheduler_is_one_line(tmp_path):
    path = _sweep(tmp_path, frames_per_task=1)
    res = CliRunner().invoke(
        main, ["sweep", str(path), "-o", str(tmp_path / "ds"), "--gpus", "1", "--scheduler", "tcp://x:1"]
    )
    assert res.exit_code == 2 and "--resources GPU=1" in res.output
    assert not (tmp_path / "ds").exists()


def test_task_resources_follow_the_workers_and_the_backend(monkeypatch):
    monkeypatch.delenv("HUMV_USD_BACKEND", raising=False)
    monkeypatch.delenv("HUMV_USD_MITSUBA_VARIANT", raising=False)
    table = {
        "a": {"resources": {"GPU": 1}},
        "b": {"resources": {"GPU": 1}},
        "c": {"resources": {"CPU": 1}},
        "d": {"resources": {}},
    }
    assert cluster.worker_kinds(table) == (2, 1)
    assert cluster.renders_on_gpu(2) and not cluster.renders_on_gpu(0)
    assert cluster.task_resources("render", 2, 1, True) == {"GPU": 1}
    assert cluster.task_resources("compose", 2, 1, True) == {"CPU": 1}
    assert cluster.task_resources("compose", 2, 0, True) is None  # no CPU-resource worker: anywhere
    assert cluster.task_resources("render", 0, 0, False) is None  # a cluster that declares nothing
    monkeypatch.setenv("HUMV_USD_BACKEND", "llvm")  # forced to the CPU: renders on the CPU workers
    assert not cluster.renders_on_gpu(2)
    assert cluster.task_resources("render", 2, 1, False) == {"CPU": 1}
    lines = cluster.worker_commands("tcp://head:8786", 2, 6)
    assert lines[1].startswith(
        "CUDA_VISIBLE_DEVICES=1 HUMV_USD_BACKEND=cuda HUMV_USD_WRITER_THREADS=4 dask worker tcp://head:8786"
    )
    assert "--resources GPU=1" in lines[0] and "--nworkers 6 --nthreads 1 --resources CPU=1" in lines[2]


def _images(dataset: Path) -> dict[str, dict[str, np.ndarray]]:
    """Every EXR of the dataset's renders by frame file name (the chunk folder left out)."""
    out = {}
    for exr in sorted((dataset / "renders").rglob("*.exr")):
        out[f"{exr.parent.name}/{exr.name}"] = images.read_exr(exr)
    return out


@pytest.fixture(scope="module")
def unbatched(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("unbatched")
    run_sweep(load_sweep(_sweep(tmp, frames_per_task=1)), tmp / "dataset", workers=0)
    return _images(tmp / "dataset")


def _same_images(a: dict, b: dict) -> None:
    assert sorted(a) == sorted(b) and len(a) == 3
    for name in a:
        assert sorted(a[name]) == sorted(b[name])
        for channel, values in a[name].items():
            np.testing.assert_array_equal(values, b[name][channel], err_msg=f"{name} {channel}")


@pytest.mark.slow
def test_a_batch_of_frames_renders_the_same_images_as_one_frame_per_task(tmp_path, unbatched, monkeypatch):
    """One task of 3 frames against 3 tasks of one: the same images. Run in this process by an
    executor that reports one GPU worker and one CPU worker and records what each task asked for."""
    from humv_usd.sweep import run as run_mod

    asked = []

    class TwoKinds(run_mod._InProcess):
        gpu_workers = cpu_workers = 1

        def submit(self, fn, *args, key=None, resources=None):
            asked.append((fn.__name__, resources))
            return super().submit(fn, *args, key=key, resources=resources)

    monkeypatch.setattr(run_mod, "_InProcess", TwoKinds)
    monkeypatch.delenv("HUMV_USD_BACKEND", raising=False)
    run_sweep(load_sweep(_sweep(tmp_path, frames_per_task=3)), tmp_path / "dataset", workers=0)
    assert asked == [("compose_variant", {"CPU": 1}), ("render_chunk", {"GPU": 1})]
    assert [p.name for p in (tmp_path / "dataset" / "renders" / "v0000").iterdir()] == ["f0000-0002"]
    _same_images(unbatched, _images(tmp_path / "dataset"))


@pytest.mark.extended  # a Dask cluster of two worker processes: 41 s on the loaded 2-core machine
def test_renders_land_on_gpu_workers_and_composes_on_cpu_workers(tmp_path, unbatched, monkeypatch):
    """A local cluster of one fake GPU worker (resource GPU=1, LLVM backend) and one CPU worker:
    both render tasks (2 frames and 1) ran on the GPU worker, the compose on the CPU worker, and
    the images equal the in-process render's one frame per task."""
    monkeypatch.setattr(cluster, "GPU_WORKER_BACKEND", "llvm")  # the workers' env is built here
    monkeypatch.delenv("HUMV_USD_BACKEND", raising=False)
    result = run_sweep(
        load_sweep(_sweep(tmp_path, frames_per_task=2)), tmp_path / "dataset", workers=1, gpus=1
    )
    assert not result.failures and result.gpu_workers == 1 and result.workers == 2
    dataset = tmp_path / "dataset"
    renders = [json.loads(p.read_text()) for p in sorted(dataset.glob("renders/*/*/task.json"))]
    assert [r["frames"] for r in renders] == [[0, 1], [2]]
    assert {r["worker"] for r in renders} == {"gpu0"} and {r["backend"] for r in renders} == {"llvm"}
    composed = json.loads((dataset / "variants" / "v0000" / "compose.done.json").read_text())
    assert composed["worker"] == "cpu0"
    last = json.loads((dataset / ".sweep" / "last_run.json").read_text())
    assert last["task_resources"] == {"compose": {"CPU": 1}, "render": {"GPU": 1}}
    _same_images(unbatched, _images(dataset))
