"""Sweep datasets behind fsspec (file://, memory://) and the sweep lock as a lease."""

from __future__ import annotations

import errno
import io
import json
import logging
import os
import socket
import time
import uuid

import fsspec
import pytest
import test_sweep
from click.testing import CliRunner
from test_sweep import _write

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.sweep import store, where
from humv_usd.sweep.spec import load_sweep

#: the tiny sweep run uninterrupted into a POSIX folder (test_sweep's module fixture)
reference = test_sweep.reference


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """Each test's own local cache (composed variants, staging) of remote datasets."""
    monkeypatch.setenv("HUMV_SWEEP_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(store, "SETTLE_S", 0.0)
    return tmp_path / "cache"


def _memory_url() -> str:
    return f"memory://humv-test-{uuid.uuid4().hex[:8]}/dataset"


# ----------------------------------------------------------------------- datasets at a URL
def test_a_url_without_its_filesystem_or_memory_with_workers_is_one_line(tmp_path, cache):
    path = _write(tmp_path)
    r = CliRunner().invoke(main, ["sweep", str(path), "-o", "s3://bucket/prefix", "--quiet"])
    assert r.exit_code == 2 and "s3fs" in r.output and len(r.output.strip().splitlines()) == 1
    r = CliRunner().invoke(main, ["sweep", str(path), "-o", _memory_url(), "--workers", "2", "--quiet"])
    assert r.exit_code == 2 and "--workers 0" in r.output
    assert not cache.exists()


@pytest.mark.slow
def test_memory_dataset_equals_the_posix_one_and_a_cut_upload_is_redone(
    reference, tmp_path, cache, monkeypatch
):
    from humv_usd.sweep.run import run_sweep

    _, path, posix, _ = reference
    url = _memory_url()
    fs, root = fsspec.core.url_to_fs(url)
    cut = "renders/v0001/f0000-0000"
    real_put = where.Location._put_many

    def flaky_put(self, pairs):  # the connection drops after two files of one chunk
        if pairs and pairs[0][1].startswith(cut + "/"):
            real_put(self, pairs[:2])
            raise ConnectionError("connection reset by peer")
        return real_put(self, pairs)

    monkeypatch.setattr(where.Location, "_put_many", flaky_put)
    first = run_sweep(load_sweep(path), url, workers=0)
    assert [f["task"] for f in first.failures] == [f"render {cut.removeprefix('renders/')}"]
    # the cut chunk has files but no done record, and the dataset lists the 7 complete ones
    assert fs.find(f"{root}/{cut}") and not fs.exists(f"{root}/{cut}/task.json")
    assert first.dataset_summary["images"] == 7
    assert json.loads(fs.cat_file(f"{root}/coco/cam.json"))["images"].__len__() == 7

    monkeypatch.setattr(where.Location, "_put_many", real_put)
    again = run_sweep(load_sweep(path), url, workers=0)
    assert again.already_done == 7 and again.ran == 1 and again.composed == 0 and again.failures == []
    # the same labels, byte for byte, as the uninterrupted POSIX run
    assert fs.cat_file(f"{root}/coco/cam.json") == (posix / "coco" / "cam.json").read_bytes()
    for p in sorted((posix / "renders").rglob("*.objects.json")):
        rel = p.relative_to(posix).as_posix()
        assert fs.cat_file(f"{root}/{rel}") == p.read_bytes(), rel
    records = [json.loads(fs.cat_file(p)) for p in fs.glob(f"{root}/renders/*/*/task.json")]
    assert len(records) == 8 and all(r["upload_bytes"] > 0 and r["upload_seconds"] >= 0 for r in records)
    import pyarrow.parquet as pq

    index = pq.read_table(io.BytesIO(fs.cat_file(f"{root}/index.parquet")))
    assert index.num_rows == 8
    assert fs.isfile(f"{root}/card/contact_cam.png") and fs.isfile(f"{root}/yolo/pose/cam/data.yaml")
    assert not fs.exists(f"{root}/.sweep/lock") and not list((cache).rglob("staging/*"))

    # a fresh machine (empty cache) re-rendering one chunk downloads the composed variant first
    import shutil

    shutil.rmtree(cache)
    fs.rm(f"{root}/renders/v0002/f0001-0001/task.json")
    from humv_usd.sweep import run as run_mod

    seen = {}
    real_drop = run_mod.drop_local_cache

    def spy(url_):  # the local copy as the render used it, before the sweep's end removes it
        local = next(cache.glob("*/variants/v0002"))
        seen.update(
            done=(local / "compose.done.json").read_bytes(), stage=(local / "stage.usda").read_bytes()
        )
        return real_drop(url_)

    monkeypatch.setattr(run_mod, "drop_local_cache", spy)
    third = run_sweep(load_sweep(path), url, workers=0)
    assert third.ran == 1 and third.composed == 0 and third.failures == []
    assert seen["done"] == fs.cat_file(f"{root}/variants/v0002/compose.done.json")
    assert seen["stage"] == fs.cat_file(f"{root}/variants/v0002/stage.usda")
    # the workers' local copies are removed when the sweep ends (the dataset keeps everything)
    assert third.local_cache_freed > 1000 and not list(cache.glob("*/variants/*"))
    assert fs.cat_file(f"{root}/coco/cam.json") == (posix / "coco" / "cam.json").read_bytes()


@pytest.mark.slow
def test_cli_file_url_dataset_loads_with_hugging_face(tmp_path, cache):
    out = tmp_path / "ds"
    r = CliRunner().invoke(
        main, ["sweep", str(_write(tmp_path)), "-o", f"file://{out}", "--workers", "0", "--quiet"]
    )
    assert r.exit_code == 0, r.output
    import datasets

    ds = datasets.load_dataset("parquet", data_files=str(out / "index.parquet"), split="train")
    assert ds.num_rows == 8 and all((out / row["image"]).is_file() for row in ds)
    assert len(list(out.glob("renders/*/*/task.json"))) == 8
    assert not (out / ".sweep" / "staging").exists() and not (out / ".sweep" / "lock").exists()
    # resume lists the done records: nothing runs
    r = CliRunner().invoke(
        main, ["sweep", str(_write(tmp_path)), "-o", f"file://{out}", "--workers", "0", "--quiet"]
    )
    assert r.exit_code == 0 and "8 of 8 tasks were done before; ran 0" in r.output


# ----------------------------------------------------------------------- the lock as a lease
def _locations(tmp_path):
    return [where.Location(tmp_path / "posix"), where.Location(_memory_url())]


def _plant(loc, doc) -> None:
    loc.write_text(store.LOCK_REL, json.dumps(doc))


@pytest.mark.parametrize("kind", [0, 1], ids=["posix", "memory"])
def test_a_stale_lock_of_another_host_is_taken_over_with_one_warning(tmp_path, cache, caplog, kind):
    loc = _locations(tmp_path)[kind]
    _plant(loc, {"pid": 4242, "host": "node-17", "token": "old", "heartbeat": 1000.0})
    now = 1000.0 + store.STALE_AFTER * 30.0 + 1.0
    with caplog.at_level(logging.WARNING, logger="humv_usd.sweep.store"):
        with store.dataset_lock(loc, heartbeat_s=30.0, clock=lambda: now):
            held = json.loads(loc.read_text(store.LOCK_REL))
            assert held["pid"] == os.getpid() and held["heartbeat"] == now
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert (
        len(warnings) == 1
        and "pid 4242 on node-17" in warnings[0]
        and "no heartbeat for 121 s" in warnings[0]
    )
    assert not loc.exists(store.LOCK_REL)


@pytest.mark.parametrize("kind", [0, 1], ids=["posix", "memory"])
def test_a_live_lock_of_another_host_is_refused_naming_holder_host_and_age(tmp_path, cache, kind):
    loc = _locations(tmp_path)[kind]
    doc = {"pid": 4242, "host": "node-17", "token": "theirs", "heartbeat": 1000.0}
    _plant(loc, doc)
    now = 1000.0 + (store.STALE_AFTER - 1) * 30.0  # three beats missed: slow, not dead
    with pytest.raises(InputError) as info:
        with store.dataset_lock(loc, heartbeat_s=30.0, clock=lambda: now):
            pass
    (line,) = str(info.value).splitlines()
    assert "another sweep (pid 4242 on node-17, heartbeat 90 s ago)" in line
    assert json.loads(loc.read_text(store.LOCK_REL)) == doc  # untouched


def test_the_holder_beats_and_a_second_sweep_meanwhile_is_refused(tmp_path, cache):
    loc = where.Location(tmp_path)
    with store.dataset_lock(loc, heartbeat_s=0.05) as lease:
        first = json.loads(loc.read_text(store.LOCK_REL))["heartbeat"]
        deadline = time.time() + 5.0
        while json.loads(loc.read_text(store.LOCK_REL))["heartbeat"] == first and time.time() < deadline:
            time.sleep(0.02)
        assert json.loads(loc.read_text(store.LOCK_REL))["heartbeat"] > first
        with pytest.raises(InputError, match=f"pid {os.getpid()} on {socket.gethostname()}, heartbeat"):
            with store.dataset_lock(loc, heartbeat_s=0.05):
                pass
        assert not lease.lost
    assert not loc.exists(store.LOCK_REL)


def test_a_holder_whose_lock_was_taken_over_notices(tmp_path, cache, caplog):
    loc = where.Location(tmp_path)
    with caplog.at_level(logging.WARNING, logger="humv_usd.sweep.store"):
        with store.dataset_lock(loc, heartbeat_s=0.05) as lease:
            _plant(loc, {"pid": 7, "host": "node-3", "token": "new", "heartbeat": time.time()})
            deadline = time.time() + 5.0
            while not lease.lost and time.time() < deadline:
                time.sleep(0.02)
            assert lease.lost
            from humv_usd.sweep.run import _check_lease

            with pytest.raises(InputError, match="another sweep took over this dataset's lock"):
                _check_lease(lease, loc)  # the sweep's loop stops at its next step
    assert any("taken over by pid 7 on node-3" in r.getMessage() for r in caplog.records)
    assert json.loads(loc.read_text(store.LOCK_REL))["token"] == "new"  # not removed at the end


# ----------------------------------------------------------------------- hostile lock files (issue 26)
def _plant_text(loc, text: str, age_s: float) -> None:
    path = loc.local(store.LOCK_REL)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    t = time.time() - age_s
    os.utime(path, (t, t))


HOSTILE = {
    "empty": "",
    "garbage": "\x00\x01 not a lock",
    "list": "[1, 2, 3]",
    "pid string": json.dumps({"pid": "4242", "host": socket.gethostname()}),
    "huge pid": json.dumps({"pid": 10**30, "host": socket.gethostname()}),
    "pid -1": json.dumps({"pid": -1, "host": socket.gethostname()}),
    "nan heartbeat": '{"pid": 4242, "host": "node-17", "heartbeat": NaN}',
    "future heartbeat": json.dumps({"pid": 4242, "host": "node-17", "heartbeat": time.time() + 10 * 3.15e7}),
}


@pytest.mark.parametrize("kind", list(HOSTILE))
def test_a_hostile_lock_goes_stale_and_is_taken_over(tmp_path, caplog, kind):
    """Empty, garbage, list, bad-pid, NaN and future-heartbeat locks were refused for ever."""
    loc = where.Location(tmp_path)
    _plant_text(loc, HOSTILE[kind], age_s=store.STALE_AFTER * store.HEARTBEAT_S + 60.0)
    with caplog.at_level(logging.WARNING, logger="humv_usd.sweep.store"):
        with store.dataset_lock(loc):
            assert json.loads(loc.read_text(store.LOCK_REL))["pid"] == os.getpid()
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "taking over" in warnings[0], warnings
    if kind == "future heartbeat":
        assert "in the future (clock skew?)" in warnings[0]
    assert not loc.exists(store.LOCK_REL)
    assert os.listdir(tmp_path / store.SWEEP_DIR) == []  # no tomb or temp file left


@pytest.mark.parametrize("kind", list(HOSTILE))
def test_a_fresh_hostile_lock_is_refused_in_one_line_and_kept(tmp_path, kind):
    """Just written, it may belong to a sweep starting now: refused, naming when to try again
    or the holder, never a traceback."""
    loc = where.Location(tmp_path)
    _plant_text(loc, HOSTILE[kind], age_s=1.0)
    with pytest.raises(InputError) as info:
        with store.dataset_lock(loc):
            pass
    (line,) = str(info.value).splitlines()
    assert "try again" in line or "is writing this dataset" in line
    assert loc.local(store.LOCK_REL).read_text() == HOSTILE[kind]


def test_a_folder_where_the_lock_goes_is_one_line(tmp_path):
    loc = where.Location(tmp_path)
    loc.local(store.LOCK_REL).mkdir(parents=True)
    with pytest.raises(InputError, match="is a folder, not a sweep lock"):
        with store.dataset_lock(loc):
            pass
    assert loc.local(store.LOCK_REL).is_dir()


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT])
def test_a_full_disk_while_locking_leaves_no_lock(tmp_path, monkeypatch, code):
    """ENOSPC while writing the lock left an empty lock that blocked every later run."""
    loc = where.Location(tmp_path)

    def full(fd, data):
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(store, "_write_all", full)
    with pytest.raises(InputError) as info:
        with store.dataset_lock(loc):
            pass
    (line,) = str(info.value).splitlines()
    assert "cannot create the sweep lock" in line and os.strerror(code) in line
    assert os.listdir(tmp_path / store.SWEEP_DIR) == []
    monkeypatch.undo()
    with store.dataset_lock(loc):  # the next run is not blocked
        pass
