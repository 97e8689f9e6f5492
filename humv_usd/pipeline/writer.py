"""A background writer: the files of one frame are written while the next frame renders.

A pool of ``threads`` writer threads runs the write jobs (a frame's EXR, PNGs and label files)
side by side; a job queued with :meth:`BackgroundWriter.submit_after` (a frame's record,
:func:`humv_usd.pipeline.records.write_record`, which hashes those files) starts only once every
job queued before it has finished, so a record is written only after all of its image's files are
complete and renamed into place (every file is written atomically, :mod:`humv_usd.fileio`). With
one thread every job runs in the order it was given. OpenEXR's and OpenImageIO's writers release
the GIL while they compress (measured: a Python loop in the rendering thread paused
at most 0.09 s during a 3.6 s zip write of a 1024x768 LWIR frame on a loaded machine), so writer
threads compress in parallel with the render and with each other. After the first failed job no
job that starts later runs: no record can follow a missing file. The failure is raised in the
rendering thread at its next call (:meth:`BackgroundWriter.submit`,
:meth:`BackgroundWriter.end_frame`, :meth:`BackgroundWriter.close`):
:class:`humv_usd.errors.InputError` as it is (exit 2), anything else as
:class:`humv_usd.errors.WriteError` naming the job (one line, exit 1). At most ``frames_ahead``
frames of jobs wait, so memory stays bounded when writing is the slower side.
"""

from __future__ import annotations

import collections
import concurrent.futures
import os
import threading
import time

from humv_usd.errors import InputError, WriteError, bad_value

#: environment variable sizing the render's writer pool (:func:`pool_size`)
THREADS_ENV = "HUMV_USD_WRITER_THREADS"
#: writer threads of a render when :data:`THREADS_ENV` is unset: two, so that one frame's EXR
#: compresses while another job (PNGs, labels, the previous frame's EXR) runs; a 1024x768 LWIR
#: frame's files take about 0.5 CPU-s, an EO frame's about 2.5 CPU-s (issue 31)
DEFAULT_THREADS = 2
#: most writer threads :data:`THREADS_ENV` may ask for
MAX_THREADS = 64


def pool_size() -> int:
    """Writer threads of a render: :data:`THREADS_ENV` (1..:data:`MAX_THREADS`) or
    :data:`DEFAULT_THREADS`; a bad value is an InputError naming the variable."""
    text = os.environ.get(THREADS_ENV, "").strip()
    if not text:
        return DEFAULT_THREADS
    try:
        n = int(text)
    except ValueError:
        n = None
    if n is None or not 1 <= n <= MAX_THREADS:
        raise InputError(bad_value(THREADS_ENV, text, f"expected an integer 1..{MAX_THREADS}"))
    return n


class BackgroundWriter:
    """Run write jobs on a pool of threads; surface the first failure in the caller.

    Parameters
    ----------
    frames_ahead : int
        Frames whose jobs may still be running when :meth:`end_frame` returns (0: write in the
        foreground, every frame waits for its files).
    threads : int
        Writer threads (1: every job in order on one thread).
    """

    def __init__(self, frames_ahead: int = 1, threads: int = 1):
        self.frames_ahead = int(frames_ahead)
        self.threads = max(1, int(threads))
        self._pool = concurrent.futures.ThreadPoolExecutor(self.threads, thread_name_prefix="humv-writer")
        self._frames: collections.deque[list[concurrent.futures.Future]] = collections.deque([[]])
        self._failed: BaseException | None = None
        self._lock = threading.Lock()
        self.seconds = 0.0  # time spent in jobs (the writer thread's wall time)
        self.cpu_seconds = 0.0  # the writer thread's CPU time in jobs

    def submit(self, what: str, fn, *args, **kwargs) -> None:
        """Queue ``fn(*args, **kwargs)``; ``what`` names it in an error (e.g. the file)."""
        self._raise_failure()
        self._frames[-1].append(self._pool.submit(self._run, what, fn, args, kwargs))

    def submit_after(self, what: str, fn, *args, **kwargs) -> None:
        """Queue ``fn(*args, **kwargs)`` to start once every job queued before it has finished
        (a frame's record after its files). The pool takes jobs in the order they were queued,
        so the earlier jobs are running or done when this one starts: waiting cannot deadlock."""
        self._raise_failure()
        earlier = [f for jobs in self._frames for f in jobs]
        self._frames[-1].append(self._pool.submit(self._run_after, earlier, what, fn, args, kwargs))

    def _run_after(self, earlier, what, fn, args, kwargs):
        concurrent.futures.wait(earlier)
        return self._run(what, fn, args, kwargs)

    def _run(self, what, fn, args, kwargs):
        if self._failed is not None:
            return None  # a job before failed: nothing after it runs (no record after a missing file)
        t, c = time.perf_counter(), time.thread_time()
        try:
            return fn(*args, **kwargs)
        except InputError as exc:
            self._fail(exc)
        except Exception as exc:  # noqa: BLE001 -- surfaced in the rendering thread as one line
            self._fail(WriteError(f"writing {what} failed: {type(exc).__name__}: {exc}".replace("\n", " ")))
        except BaseException as exc:  # KeyboardInterrupt, SystemExit: raised as they are
            self._fail(exc)
        finally:
            with self._lock:
                self.seconds += time.perf_counter() - t
                self.cpu_seconds += time.thread_time() - c
        return None

    def _fail(self, exc: BaseException) -> None:
        with self._lock:
            if self._failed is None:
                self._failed = exc

    def _raise_failure(self) -> None:
        if self._failed is not None:
            raise self._failed

    def end_frame(self) -> None:
        """Close the current frame's jobs; wait until at most ``frames_ahead`` frames are open."""
        self._frames.append([])
        while len(self._frames) - 1 > self.frames_ahead:
            concurrent.futures.wait(self._frames.popleft())
        self._raise_failure()

    def close(self) -> None:
        """Wait for every job and stop the thread; raise the first failure."""
        for jobs in self._frames:
            concurrent.futures.wait(jobs)
        self._frames = collections.deque([[]])
        self._pool.shutdown(wait=True)
        self._raise_failure()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
            return False
        try:  # the caller failed: finish what was queued (completed frames keep their records)
            self.close()
        except Exception:  # noqa: BLE001 -- the caller's error is the one to report
            pass
        return False
