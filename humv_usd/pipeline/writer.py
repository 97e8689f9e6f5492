"""A background writer: the files of one frame are written while the next frame renders.

One thread runs the write jobs in the order they were given (a frame's EXR, PNGs and label files,
then its record, :func:`humv_usd.pipeline.records.write_record`, which hashes those files), so a
record is written only after all of its image's files are complete and renamed into place
(every file is written atomically, :mod:`humv_usd.fileio`). After the first failed job no later
job runs: no record can follow a missing file. The failure is raised in the rendering thread at
its next call (:meth:`BackgroundWriter.submit`, :meth:`BackgroundWriter.end_frame`,
:meth:`BackgroundWriter.close`): :class:`humv_usd.errors.InputError` as it is (exit 2), anything
else as :class:`humv_usd.errors.WriteError` naming the job (one line, exit 1). At most
``frames_ahead`` frames of jobs wait, so memory stays bounded when writing is the slower side.
"""

from __future__ import annotations

import collections
import concurrent.futures
import threading
import time

from humv_usd.errors import InputError, WriteError


class BackgroundWriter:
    """Run write jobs in order on one thread; surface the first failure in the caller.

    Parameters
    ----------
    frames_ahead : int
        Frames whose jobs may still be running when :meth:`end_frame` returns (0: write in the
        foreground, every frame waits for its files).
    """

    def __init__(self, frames_ahead: int = 1):
        self.frames_ahead = int(frames_ahead)
        self._pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="humv-writer")
        self._frames: collections.deque[list[concurrent.futures.Future]] = collections.deque([[]])
        self._failed: BaseException | None = None
        self._lock = threading.Lock()
        self.seconds = 0.0  # time spent in jobs (the writer thread's wall time)
        self.cpu_seconds = 0.0  # the writer thread's CPU time in jobs

    def submit(self, what: str, fn, *args, **kwargs) -> None:
        """Queue ``fn(*args, **kwargs)``; ``what`` names it in an error (e.g. the file)."""
        self._raise_failure()
        self._frames[-1].append(self._pool.submit(self._run, what, fn, args, kwargs))

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
