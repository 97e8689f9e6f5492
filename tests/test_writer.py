"""The render's background writer: jobs in order, nothing after a failure, errors surface."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from humv_usd import images
from humv_usd.errors import InputError, WriteError
from humv_usd.pipeline import records as R
from humv_usd.pipeline.writer import BackgroundWriter


def test_jobs_run_in_order_on_one_thread_and_a_record_follows_its_files(tmp_path):
    done, threads = [], set()

    def job(i):
        time.sleep(0.01 * (i % 2))  # a slow job before a quick one keeps its place
        threads.add(threading.get_ident())
        done.append(i)

    with BackgroundWriter(frames_ahead=1) as w:
        for frame in range(3):
            for i in range(4):
                w.submit(f"job {i}", job, frame * 4 + i)
            w.end_frame()
    assert done == list(range(12))
    assert len(threads) == 1 and threading.get_ident() not in threads

    # real files: the record hashes the EXR and the PNG written before it
    out = tmp_path / "r"
    (out / "s").mkdir(parents=True)
    with BackgroundWriter() as w:
        w.submit("exr", images.write_exr, out / "s" / "0000.exr", {"radiance": np.ones((4, 6))})
        w.submit("png", images.write_png, out / "s" / "0000.instance.png", np.zeros((4, 6), np.uint8))
        w.submit("record", R.write_record, out, "s", 0, {"settings": {}})
    rec = R.read_records(out)[("s", 0)]
    assert sorted(rec["files"]) == ["s/0000.exr", "s/0000.instance.png"]


def test_end_frame_bounds_the_frames_in_flight():
    gate = threading.Event()
    started = []
    w = BackgroundWriter(frames_ahead=1)
    w.submit("slow", lambda: (started.append(1), gate.wait(5)))
    w.end_frame()  # frame 0 may stay in flight
    w.submit("next", started.append, 2)
    t = threading.Timer(0.2, gate.set)
    t.start()
    t0 = time.perf_counter()
    w.end_frame()  # frame 1 closes: frame 0 must be finished first
    assert time.perf_counter() - t0 > 0.1
    w.close()
    assert started == [1, 2]


def test_a_failed_write_stops_later_jobs_and_surfaces_as_one_line(tmp_path):
    ran = []

    gate = threading.Event()

    def boom():
        gate.wait(5)  # fails after the record is queued
        raise OSError(28, "No space left on device")

    w = BackgroundWriter()
    w.submit("s/0000.exr", boom)
    w.submit("the record of s/0000", ran.append, "record")  # must not run: its file is missing
    gate.set()
    with pytest.raises(WriteError) as err:
        w.end_frame()
        w.end_frame()  # the failure surfaces at the latest when the frame after is closed
    assert ran == []
    assert "s/0000.exr" in str(err.value) and "No space left" in str(err.value)
    assert "\n" not in str(err.value)
    with pytest.raises(WriteError):
        w.submit("more", ran.append, 1)
    with pytest.raises(WriteError):
        w.close()
    assert ran == []


def test_bad_input_in_the_writer_stays_bad_input():
    w = BackgroundWriter()
    w.submit("ids", images.write_exr, "/nonexistent/x.exr", {"instance_id": np.full((2, 2), 2**24 + 1)})
    with pytest.raises(InputError):
        w.close()


def test_the_caller_error_wins_and_queued_frames_finish(tmp_path):
    ran = []
    with pytest.raises(KeyError):
        with BackgroundWriter() as w:
            w.submit("a", lambda: (time.sleep(0.05), ran.append("a")))
            raise KeyError("render failed")
    assert ran == ["a"]


def test_a_pool_writes_files_side_by_side_and_the_record_waits_for_all_of_them(tmp_path):
    """Three writer threads: a frame's files run at once (each waits for the others to start, so
    one thread alone would time out), and the record queued after them starts only when every
    one has finished."""
    started = threading.Barrier(3, timeout=5)
    finished, seen_by_record, threads = [], [], set()

    def file_job(i):
        started.wait()  # all three at once: needs three threads
        time.sleep(0.05 * (i == 0))  # the first queued finishes last
        threads.add(threading.get_ident())
        finished.append(i)

    with BackgroundWriter(frames_ahead=1, threads=3) as w:
        for i in range(3):
            w.submit(f"file {i}", file_job, i)
        w.submit_after("record", lambda: seen_by_record.append(sorted(finished)))
        w.end_frame()
    assert seen_by_record == [[0, 1, 2]]
    assert len(threads) == 3


def test_a_pool_runs_no_record_after_a_failed_file():
    ran = []

    def boom():
        time.sleep(0.05)  # fails after the record is queued and a sibling file has run
        raise OSError(28, "No space left on device")

    w = BackgroundWriter(threads=4)
    w.submit("s/0000.exr", boom)
    w.submit("s/0000.png", ran.append, "png")
    w.submit_after("the record of s/0000", ran.append, "record")
    with pytest.raises(WriteError, match="s/0000.exr"):
        w.close()
    assert ran == ["png"]  # the sibling file ran; the record did not


@pytest.mark.parametrize("value", ["0", "65", "two"])
def test_the_pool_size_knob_is_checked(monkeypatch, value):
    from humv_usd.pipeline import writer

    monkeypatch.setenv(writer.THREADS_ENV, "3")
    assert writer.pool_size() == 3
    monkeypatch.delenv(writer.THREADS_ENV)
    assert writer.pool_size() == writer.DEFAULT_THREADS
    monkeypatch.setenv(writer.THREADS_ENV, value)
    with pytest.raises(InputError, match=f"{writer.THREADS_ENV} = '{value}': expected an integer 1..64"):
        writer.pool_size()
