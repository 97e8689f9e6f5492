"""Issue 15: renders resume. A render killed (SIGKILL, SIGTERM, Ctrl-C) at any moment and run
again renders only what is missing and ends identical to one uninterrupted run; other settings
are refused (or re-rendered with --force); frames of separate calls accumulate; temp files and
partial images of a killed run are cleaned up."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from test_render import _small_scene

from humv_usd.errors import InputError
from humv_usd.pipeline import records as R
from humv_usd.pipeline.render import render_stage

ROOT = Path(__file__).resolve().parents[1]
FRAMES = 6
SPP = 4


@pytest.fixture(scope="module")
def stage(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("stage")
    st = _small_scene(folder / "stage.usda", end=FRAMES - 1)
    st.Save()
    return folder / "stage.usda"


@pytest.fixture(scope="module")
def reference(stage, tmp_path_factory) -> Path:
    """One uninterrupted render of every frame."""
    out = tmp_path_factory.mktemp("ref") / "out"
    render_stage(stage, out, spp=SPP, seed=3)
    return out


#: manifest keys that hold this call's run times, date or history, not the result
VOLATILE = {
    "created_utc",
    "timings_s",
    "rendered_this_call",
    "scene_builds",
    "output_dir",
    "cost_relative_to_render",
}


def stable(doc):
    if isinstance(doc, dict):
        return {k: stable(v) for k, v in doc.items() if k not in VOLATILE}
    if isinstance(doc, list):
        return [stable(v) for v in doc]
    return doc


CAP_DATE = re.compile(rb"capDate\x00string\x00\x13\x00\x00\x00[0-9: ]{19}")


def result(out: Path) -> dict[str, object]:
    """Every visible file's bytes (the manifest without run times, EXRs without the date
    OpenImageIO stamps them with), by relative path."""
    files: dict[str, object] = {}
    for p in sorted(out.rglob("*")):
        rel = p.relative_to(out)
        if p.is_dir() or any(part.startswith(".") for part in rel.parts):
            continue
        if p.name == "manifest.json":
            files[str(rel)] = stable(json.loads(p.read_text()))
        else:
            files[str(rel)] = CAP_DATE.sub(b"capDate", p.read_bytes())
    return files


def assert_same(out: Path, reference: Path) -> None:
    got, want = result(out), result(reference)
    assert got.keys() == want.keys(), sorted(got.keys() ^ want.keys())
    for rel in want:
        assert got[rel] == want[rel], rel


# ------------------------------------------------------------------ in-process behaviour
def test_frames_of_separate_calls_accumulate_into_one_run(stage, reference, tmp_path):
    out = tmp_path / "out"
    for frames in ([3], [0, 1], [5], [2, 4]):
        render_stage(stage, out, frames=frames, spp=SPP, seed=3)
    assert_same(out, reference)
    manifest = render_stage(stage, out, spp=SPP, seed=3)  # everything done: renders nothing
    assert manifest["rendered_this_call"] == []
    assert_same(out, reference)


def test_other_settings_are_refused_or_rendered_again_with_force(stage, tmp_path):
    out = tmp_path / "out"
    render_stage(stage, out, frames=[0, 1, 2], spp=SPP, seed=3)
    before = result(out)
    with pytest.raises(InputError) as err:
        render_stage(stage, out, frames=[0], spp=8, seed=5)
    assert len(err.value.problems) == 1
    assert "lwir/0000 (and 2 more images)" in str(err.value) and "spp 4 -> 8" in str(err.value)
    assert "seed 3 -> 5" in str(err.value) and "--force" in str(err.value)
    assert result(out) == before  # nothing touched
    manifest = render_stage(stage, out, frames=[0], spp=8, seed=5, force=True)
    assert manifest["rendered_this_call"] == [0, 1, 2]  # what differed is rendered again
    assert [f["frame"] for f in manifest["sensors"][0]["frames"]] == [0, 1, 2]
    records = R.read_records(out)
    assert {r["settings"]["spp"] for r in records.values()} == {8}
    assert manifest["settings"]["spp"] == 8


def test_damaged_and_partial_images_and_temp_files_are_redone(stage, reference, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    exr = out / "lwir" / "0002.exr"
    exr.write_bytes(exr.read_bytes()[:1000])  # truncated after its record was written
    R.record_path(out, "lwir", 4).unlink()  # killed before its record: files without a record
    (out / "lwir" / ".0004.a1b2c3.tmp.exr").write_bytes(b"partial")
    (out / "lwir" / "0007.exr").write_bytes(b"half an image of a frame the stage lacks")
    manifest = render_stage(stage, out, spp=SPP, seed=3)
    assert manifest["rendered_this_call"] == [2, 4]
    assert_same(out, reference)
    assert not list(out.rglob(".*.tmp*"))


def test_a_manifest_lists_every_recorded_frame_after_rerendering_one(stage, reference, tmp_path):
    """The issue's case: re-rendering frame 0 into a folder holding all frames keeps them listed."""
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    manifest = render_stage(stage, out, frames=[0], spp=SPP, seed=3, force=True)
    assert manifest["rendered_this_call"] == [0]
    assert_same(out, reference)


def test_automatic_quality_resumes_and_the_estimator_is_a_setting(stage, tmp_path):
    """spp not given (automatic quality): the same command resumes although the samples spent
    vary per image, and the manifest rebuilt from records carries every frame's error in K;
    another estimator is refused (one line) or rendered again with force."""
    out = tmp_path / "out"
    first = render_stage(stage, out, frames=[1], seed=3)
    assert first["settings"]["spp_auto"] and first["rendered_this_call"] == [1]
    again = render_stage(stage, out, frames=[0, 1], seed=3)
    assert again["rendered_this_call"] == [0]
    frames = again["sensors"][0]["frames"]
    assert [f["frame"] for f in frames] == [0, 1]
    per_frame = [f["monte_carlo_error_k"] for f in frames]
    assert all(f["mean_k"] is not None and f["spp_used"] >= 2 for f in per_frame)
    summary = again["sensors"][0]["monte_carlo_error_k"]
    assert summary["spp_used"] == sorted({f["spp_used"] for f in per_frame})
    assert summary["mean_k"] == pytest.approx(sum(f["mean_k"] for f in per_frame) / 2)
    assert summary["p99_max_k"] == max(f["p99_k"] for f in per_frame)
    assert summary["not_estimable"] is None and summary["spp_rule"].startswith("automatic")
    assert render_stage(stage, out, seed=3, frames=[0, 1])["rendered_this_call"] == []
    records = R.read_records(out)
    assert {r["settings"]["estimator"].split()[0] for r in records.values()} == {"fast"}
    before = result(out)
    with pytest.raises(InputError) as err:
        render_stage(stage, out, frames=[0], seed=3, estimator="path")
    assert len(err.value.problems) == 1 and "\n" not in str(err.value)
    assert "estimator 'fast" in str(err.value) and "-> 'path'" in str(err.value)
    assert "spp_mode 'automatic" in str(err.value) and "--force" in str(err.value)
    assert result(out) == before  # nothing touched
    with pytest.raises(InputError, match="spp_mode 'automatic"):
        render_stage(stage, out, frames=[0], spp=2, seed=3)  # same spp, but given: other images
    forced = render_stage(stage, out, frames=[0], seed=3, estimator="path", force=True)
    assert forced["rendered_this_call"] == [0, 1] and forced["settings"]["estimator"] == "path"
    assert {r["settings"]["estimator"] for r in R.read_records(out).values()} == {"path"}
    assert [f["frame"] for f in forced["sensors"][0]["frames"]] == [0, 1]


def test_progress_counts_only_the_images_rendered_in_this_call(stage, reference, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    R.record_path(out, "lwir", 2).unlink()
    seen = []
    render_stage(stage, out, spp=SPP, seed=3, progress=lambda done, total, text: seen.append((done, total)))
    assert seen == [(1, 1)]
    assert_same(out, reference)


# ------------------------------------------------------------------ killed renders
#: render with os.replace hooked: on its n-th call (each file of each image is one replace)
#: the process is killed with SIGKILL or SIGTERM, or Ctrl-C is simulated (KeyboardInterrupt)
KILLER = textwrap.dedent(
    """
    import os, signal, sys
    how, n = sys.argv[1], int(sys.argv[2])
    real, calls = os.replace, [0]
    def hook(*a, **k):
        calls[0] += 1
        if calls[0] == n:
            if how == "ctrl-c":
                raise KeyboardInterrupt
            os.kill(os.getpid(), getattr(signal, how))
        return real(*a, **k)
    os.replace = hook
    from humv_usd.pipeline.render import render_stage
    render_stage(sys.argv[3], sys.argv[4], spp=int(sys.argv[5]), seed=3)
    """
)

#: (signal, n-th file write): >= 10 moments, from the first file to the last aggregate
KILLS = [
    ("SIGKILL", 1),
    ("SIGKILL", 2),
    ("SIGKILL", 7),
    ("SIGKILL", 9),
    ("SIGKILL", 16),
    ("SIGKILL", 30),
    ("SIGKILL", 45),
    ("SIGKILL", 55),
    ("SIGKILL", 58),
    ("SIGKILL", 61),
    ("SIGTERM", 23),
    ("ctrl-c", 12),
    ("ctrl-c", 40),
]


@pytest.mark.slow
@pytest.mark.parametrize(("how", "n"), KILLS)
def test_a_killed_render_resumes_to_the_uninterrupted_result(stage, reference, tmp_path, how, n):
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-c", KILLER, how, str(n), str(stage), str(out), str(SPP)],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=600,
    )
    expected = {"SIGKILL": -signal.SIGKILL, "SIGTERM": -signal.SIGTERM, "ctrl-c": -signal.SIGINT}[how]
    assert proc.returncode in (expected, 0), proc.stderr[-2000:]
    killed = proc.returncode != 0
    done_before = {f for (_, f), rec in R.read_records(out).items() if R.is_done(out, rec, rec["settings"])}
    manifest = render_stage(stage, out, spp=SPP, seed=3)
    if killed:  # nothing finished is rendered again; nothing unfinished is kept
        assert set(manifest["rendered_this_call"]) == set(range(FRAMES)) - done_before
    assert_same(out, reference)  # nothing lost, duplicated or corrupt
    assert not [p for p in out.rglob(".*") if p.is_file()]  # no temp file, no lock left


def test_flushing_the_kernel_cache_changes_no_pixel(stage, reference, tmp_path, monkeypatch):
    """The render drops Dr.Jit's kernel cache every few frames (flat memory): the kernels
    compiled again give the same images."""
    from humv_usd.pipeline import render as render_module

    monkeypatch.setattr(render_module, "KERNEL_CACHE_FRAMES", 1)
    render_stage(stage, tmp_path / "out", spp=SPP, seed=3)
    assert_same(tmp_path / "out", reference)


#: the CLI with os.replace failing on its n-th call (a full disk): the write happens on the
#: render's background writer thread
FAILING_WRITE = textwrap.dedent(
    """
    import errno, os, sys
    n = int(sys.argv[1])
    real, calls = os.replace, [0]
    def hook(*a, **k):
        calls[0] += 1
        if calls[0] == n:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(*a, **k)
    os.replace = hook
    sys.argv = ["humv-usd", "render", sys.argv[2], "-o", sys.argv[3], "--spp", sys.argv[4], "--seed", "3"]
    from humv_usd.cli.main import main
    main()
    """
)


@pytest.mark.slow
def test_a_failed_background_write_is_one_line_exit_1_and_resumes(stage, reference, tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-c", FAILING_WRITE, "9", str(stage), str(out), str(SPP)],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 1, proc.stderr[-2000:]
    errors = [line for line in proc.stderr.splitlines() if "error" in line.lower()]
    assert len(errors) == 1 and "No space left on device" in errors[0] and "Traceback" not in proc.stderr
    records = R.read_records(out)
    assert len(records) < FRAMES  # the image whose file failed has no record
    assert all(R.is_done(out, rec, rec["settings"]) for rec in records.values())
    render_stage(stage, out, spp=SPP, seed=3)
    assert_same(out, reference)
    assert not [p for p in out.rglob(".*") if p.is_file()]
