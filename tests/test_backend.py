"""Backend choice (humv_usd.mode): the GPU when a CUDA driver is there and works, else the CPU;
forced backends are honoured or refused, never silently replaced."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from humv_usd import mode

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def clean_env(monkeypatch):
    for key in (mode.VARIANT_ENV, mode.BACKEND_ENV):
        monkeypatch.delenv(key, raising=False)
    return monkeypatch


def test_cuda_driver_makes_the_gpu_the_candidate(clean_env, tmp_path):
    (tmp_path / "libcuda.so.1").write_bytes(b"")
    clean_env.setattr(mode, "CUDA_GLOBS", (str(tmp_path / "libcuda.so*"),))
    variant, reason = mode._choose_variant()
    assert variant == "cuda_ad_mono"
    assert str(tmp_path / "libcuda.so.1") in reason and "else" in reason  # the CPU fallback is named


def test_no_cuda_driver_means_the_cpu(clean_env):
    clean_env.setattr(mode, "CUDA_GLOBS", ("/nonexistent/libcuda.so*",))
    variant, _ = mode._choose_variant()
    assert variant in ("llvm_ad_mono", "scalar_rgb")


@pytest.mark.parametrize(
    "name,variant", [("cuda", "cuda_ad_mono"), ("llvm", "llvm_ad_mono"), ("scalar", "scalar_rgb")]
)
def test_backend_env_forces_the_variant(clean_env, name, variant):
    clean_env.setenv(mode.BACKEND_ENV, name)
    clean_env.setattr(mode, "CUDA_GLOBS", ("/nonexistent/libcuda.so*",))
    chosen, reason = mode._choose_variant()
    assert chosen == variant and mode.BACKEND_ENV in reason


def test_bad_backend_names_are_refused(clean_env):
    clean_env.setenv(mode.BACKEND_ENV, "opencl")
    with pytest.raises(ValueError, match="HUMV_USD_BACKEND = 'opencl'.*auto, cuda, llvm, scalar"):
        mode._choose_variant()
    with pytest.raises(ValueError, match="backend = 'metal'"):
        mode.set_backend("metal")


def _render_variant(env_extra: dict) -> subprocess.CompletedProcess:
    """Mitsuba's variant as configured in a fresh process (one variant per process)."""
    env = {k: v for k, v in os.environ.items() if k not in (mode.VARIANT_ENV, mode.BACKEND_ENV)}
    env.update(env_extra, PYTHONPATH=str(ROOT))
    code = "from humv_usd import mode; mode.mitsuba(); print(mode.variant(), mode.backend())"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_forced_gpu_without_a_gpu_is_an_error_not_a_fallback():
    if mode._cuda_driver() is not None:
        pytest.skip("this machine has a CUDA driver: the forced GPU may work here")
    run = _render_variant({mode.BACKEND_ENV: "cuda"})
    assert run.returncode != 0
    assert "backend = 'cuda': cuda_ad_mono does not work here" in run.stderr
    auto = _render_variant({})
    assert auto.returncode == 0, auto.stderr
    assert auto.stdout.split() in (["llvm_ad_mono", "llvm"], ["scalar_rgb", "scalar"])


def test_label_ray_casts_follow_the_render_to_the_gpu(monkeypatch):
    """Labels' casts go to Mitsuba (OptiX on the GPU) when the render runs on CUDA or when
    embreex is missing; Embree otherwise."""
    from humv_usd.geometry import raycast

    monkeypatch.setattr(raycast, "loaded_backend", lambda: "llvm")
    has_embree = raycast.importlib.util.find_spec("embreex") is not None
    assert raycast.default_backend() == ("embree" if has_embree else "mitsuba")
    monkeypatch.setattr(raycast, "loaded_backend", lambda: "cuda")
    assert raycast.default_backend() == "mitsuba"
    monkeypatch.setattr(raycast, "loaded_backend", lambda: None)
    real = raycast.importlib.util.find_spec
    monkeypatch.setattr(raycast.importlib.util, "find_spec", lambda n: None if n == "embreex" else real(n))
    assert raycast.default_backend() == "mitsuba"
