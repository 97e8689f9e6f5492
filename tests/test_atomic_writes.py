"""Issue 15: compose writes its files as one change (a kill leaves the old set or the new one),
check and render refuse a mixed set, and one writer per folder (a lock naming the other)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.fileio import (
    LOCK_NAME,
    PENDING_NAME,
    commit_files,
    discard_staged,
    finish_pending,
    folder_lock,
    stage_text,
)
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import load_scenario
from humv_usd.usd.check import check_stage
from humv_usd.usd.layers import open_stage

ROOT = Path(__file__).resolve().parents[1]
HUMVVEX = ROOT / "examples" / "humvvex_fixed.toml"  # the closed-form thermal model: fast
PYTHON = sys.executable

#: runs a Python call with ``os.<name>`` replaced by a hook that kills the process (SIGKILL,
#: nothing is cleaned up) on its n-th call, before the call happens
KILLER = textwrap.dedent(
    """
    import os, signal, sys
    name, n = sys.argv[1], int(sys.argv[2])
    real, calls = getattr(os, name), [0]
    def hook(*a, **k):
        calls[0] += 1
        if calls[0] == n:
            os.kill(os.getpid(), signal.SIGKILL)
        return real(*a, **k)
    setattr(os, name, hook)
    exec(sys.argv[3])
    """
)


def killed_run(name: str, n: int, code: str, *args) -> int:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [PYTHON, "-c", KILLER, name, str(n), code, *map(str, args)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode in (0, -signal.SIGKILL), proc.stderr[-2000:]
    return proc.returncode


def texts(folder: Path) -> dict[str, str]:
    """The USD files of a composed folder (root and layers) by relative path."""
    return {
        str(p.relative_to(folder)): p.read_text()
        for p in sorted(folder.rglob("*.usda"))
        if not p.name.startswith(".")  # temp files of a killed writer are not part of the set
    }


# ------------------------------------------------------------------ several files as one change
COMMIT = "from humv_usd.fileio import commit_files; from pathlib import Path; d = Path(sys.argv[4]); "
COMMIT += "commit_files(d, {d / f'{i}.txt': 'new' for i in range(4)}, remove=[d / 'gone.txt'])"


@pytest.mark.parametrize(
    ("call", "n"), [("chmod", k) for k in (1, 3, 5)] + [("replace", k) for k in range(1, 7)]
)
def test_commit_files_killed_leaves_old_or_new(tmp_path, call, n):
    d = tmp_path / "d"
    d.mkdir()
    for i in range(4):
        (d / f"{i}.txt").write_text("old")
    (d / "gone.txt").write_text("old")
    killed_run(call, n, COMMIT, d)
    journal = (d / PENDING_NAME).is_file()
    finish_pending(d)  # what the next writer does first
    contents = {(d / f"{i}.txt").read_text() for i in range(4)}
    assert contents in ({"old"}, {"new"}), (call, n, contents)
    assert (d / "gone.txt").exists() == (contents == {"old"})
    if journal:
        assert contents == {"new"}


def test_commit_files_skips_unchanged_and_reports_written(tmp_path):
    (tmp_path / "a.txt").write_text("same")
    written = commit_files(tmp_path, {tmp_path / "a.txt": "same", tmp_path / "b.txt": "new"})
    assert written == [tmp_path / "b.txt"]
    assert not (tmp_path / PENDING_NAME).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]
    assert commit_files(tmp_path, {tmp_path / "b.txt": "new"}) == []


# ------------------------------------------------------------------ compose killed while it writes
@pytest.fixture(scope="module")
def two_sets(tmp_path_factory):
    """Scenario files A and B (B: other stature, so avatar, clothing, thermal and the root
    change) and their cleanly composed folders."""
    base = tmp_path_factory.mktemp("sets")
    a, b = base / "a.toml", base / "b.toml"
    # held ground and wall temperatures: every layer is still written (thermal included), without
    # the slab's spin-up and view factors, which made each compose here several times longer
    text = HUMVVEX.read_text()
    text = text.replace('material = "concrete"\n', 'material = "concrete"\ntemperature_k = 297.0\n', 1)
    text = text.replace(
        'material = "painted_metal"\n', 'material = "painted_metal"\ntemperature_k = 293.0\n', 1
    )
    assert text.count("temperature_k = 29") == 2
    a.write_text(text)
    b.write_text(text.replace("stature_m = 1.78", "stature_m = 1.70"))
    out_a, out_b = base / "out_a", base / "out_b"
    compose(load_scenario(a), out_a)
    compose(load_scenario(b), out_b)
    return a, b, out_a, out_b


COMPOSE = "from humv_usd.pipeline.compose import compose; from humv_usd.scenario import load_scenario; "
COMPOSE += "compose(load_scenario(sys.argv[4]), sys.argv[5])"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("call", "n"), [("chmod", k) for k in (1, 2, 4)] + [("replace", k) for k in range(1, 8)]
)
def test_compose_killed_while_writing_is_never_a_mixed_set(tmp_path, two_sets, call, n):
    """A compose from A to B killed at a moment of its write phase: check and render accept
    the folder only when it is all A or all B; the next compose ends identical to a clean B."""
    a, b, out_a, out_b = two_sets
    out = tmp_path / "o"
    shutil.copytree(out_a, out)
    old, new = texts(out_a), texts(out_b)
    assert old != new and old.keys() == new.keys()
    code = killed_run(call, n, COMPOSE, b, out)
    now = texts(out)
    findings = check_stage(out / "stage.usda")
    try:
        open_stage(out / "stage.usda")
        render_accepts = True
    except InputError:
        render_accepts = False
    if now not in (old, new):  # a mixed set on disk: both gates must refuse it
        assert any(f.startswith("humv:layerSet") for f in findings), (call, n, code, findings)
        assert not render_accepts
    elif not (out / PENDING_NAME).exists():  # all old or all new, and no write under way
        assert render_accepts and not any(f.startswith("humv:layerSet") for f in findings)
    else:  # killed after the commit point: refused until compose finishes the write
        assert not render_accepts and any("interrupted" in f for f in findings)
    compose(load_scenario(b), out)  # finishes an interrupted write, or writes B
    assert texts(out) == new
    assert not check_stage(out / "stage.usda")
    leftovers = [p.name for p in out.rglob(".*") if p.is_file()]
    assert leftovers == [], leftovers


def test_a_layer_from_another_compose_is_refused(tmp_path, two_sets):
    _, _, out_a, out_b = two_sets
    out = tmp_path / "o"
    shutil.copytree(out_a, out)
    shutil.copy(out_b / "layers" / "avatar_p1.usda", out / "layers" / "avatar_p1.usda")
    findings = check_stage(out / "stage.usda")
    assert any(f.startswith("humv:layerSet:") and "avatar_p1.usda" in f for f in findings), findings
    with pytest.raises(InputError, match="avatar_p1.usda.*another compose"):
        open_stage(out / "stage.usda")
    result = CliRunner().invoke(main, ["render", str(out / "stage.usda"), "-o", str(tmp_path / "r")])
    assert result.exit_code == 2 and "avatar_p1.usda" in result.stderr
    assert not (tmp_path / "r").exists()


def test_an_interrupted_write_is_refused_until_compose_finishes_it(tmp_path, two_sets):
    a, _, out_a, _ = two_sets
    out = tmp_path / "o"
    shutil.copytree(out_a, out)
    (out / PENDING_NAME).write_text('{"replace": [], "remove": []}\n')
    assert any("interrupted" in f for f in check_stage(out / "stage.usda"))
    with pytest.raises(InputError, match="interrupted"):
        open_stage(out / "stage.usda")
    compose(load_scenario(a), out)
    assert not (out / PENDING_NAME).exists() and not check_stage(out / "stage.usda")


# ------------------------------------------------------------------ one writer per folder
HOLD = "import sys, time; from humv_usd.fileio import folder_lock\n"
HOLD += "with folder_lock(sys.argv[1], 'humv-usd render'): print('held', flush=True); time.sleep(float(sys.argv[2]))"


def _holder(folder: Path, seconds: float) -> subprocess.Popen:
    proc = subprocess.Popen(
        [PYTHON, "-c", HOLD, str(folder), str(seconds)],
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        stdout=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_second_writer_is_refused_naming_the_first(tmp_path):
    proc = _holder(tmp_path / "out", 30)
    try:
        with pytest.raises(InputError, match=rf"being written by humv-usd render \(pid {proc.pid},"):
            with folder_lock(tmp_path / "out", "humv-usd compose"):
                pass
        result = CliRunner().invoke(main, ["compose", str(HUMVVEX), "-o", str(tmp_path / "out")])
        assert result.exit_code == 2, result.output
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and f"pid {proc.pid}" in lines[0], result.stderr
        assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [LOCK_NAME]
    finally:
        proc.kill()
        proc.wait()


def test_a_lock_left_by_a_killed_writer_is_stale_and_taken_over(tmp_path):
    proc = _holder(tmp_path / "out", 30)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert (tmp_path / "out" / LOCK_NAME).is_file()  # left behind: kill -9 runs no clean-up
    with folder_lock(tmp_path / "out", "humv-usd compose"):
        assert str(os.getpid()) in (tmp_path / "out" / LOCK_NAME).read_text()
    assert list((tmp_path / "out").iterdir()) == []  # the lock file goes with the lock


def test_wait_waits_for_the_other_writer(tmp_path):
    proc = _holder(tmp_path / "out", 1.0)
    t = time.perf_counter()
    try:
        with folder_lock(tmp_path / "out", "humv-usd compose", wait=True, poll_s=0.05):
            assert f'"pid": {os.getpid()}' in (tmp_path / "out" / LOCK_NAME).read_text()
    finally:
        proc.kill()
        proc.wait()
    assert time.perf_counter() - t > 0.5  # it waited for the holder's second


def test_discarded_staging_leaves_no_folder_it_made(tmp_path):
    """A failed compose left an empty layers/ folder (stage_text made it): discarding the staged
    texts removes the folders staging created, and keeps those that were there or hold files."""
    (tmp_path / "kept").mkdir()
    staged = [
        stage_text(tmp_path / "new" / "deeper" / "a.usda", "a"),
        stage_text(tmp_path / "new" / "deeper" / "b.usda", "b"),
        stage_text(tmp_path / "kept" / "c.usda", "c"),
        stage_text(tmp_path / "busy" / "d.usda", "d"),
    ]
    (tmp_path / "busy" / "user.txt").write_text("not ours")
    discard_staged(staged)
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")) == [
        "busy",
        "busy/user.txt",
        "kept",
    ]
