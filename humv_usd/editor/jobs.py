"""Compose, render and sweep jobs started from the page.

A job is one or more ``humv-usd`` commands (steps, e.g. compose then render) run one after the
other as child processes of the editor's server, each an argument list (never a shell, never a
command line built from user text). Its output is kept in memory
line by line, so a page that was closed and opened again shows the whole log; the job keeps
running when no page is open. Cancel sends SIGTERM to the job's process group.

A job started ``warm`` (the preview and the 3D view: short commands run after every edit) runs
its ``humv-usd`` steps in one long-lived worker process (:mod:`humv_usd.cli.warm`) instead of a
new process each: imports and the JOS-3 compile are paid once (a fast preview after a heading
edit: 11 -> 6 CPU-s; an unchanged one 4.3 -> 0.5). Its output and exit codes are the command
line's; cancel ends the worker, and the next warm step starts a new one.
"""

from __future__ import annotations

import itertools
import json
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

log = logging.getLogger(__name__)

#: lines kept per job (older ones are dropped, the count says how many)
MAX_LINES = 5000
#: the line (prefix) that ends a command's output in the warm worker, followed by its exit code
WARM_SENTINEL = "\x1ehumv-usd-warm exit "
#: the warm worker (:mod:`humv_usd.cli.warm`): one process that runs humv-usd commands in turn
WARM_COMMAND = [sys.executable, "-m", "humv_usd.cli.warm"]


@dataclass
class Job:
    """One command running (or finished) under the editor."""

    id: int
    kind: str  # compose, render, preview, sweep
    steps: list[list[str]]
    out_dir: Path
    step: int = 0
    lines: list[str] = field(default_factory=list)
    dropped: int = 0
    state: str = "starting"  # running, done, failed, cancelled
    returncode: int | None = None
    started: float = field(default_factory=time.time)
    ended: float | None = None
    process: subprocess.Popen | None = None
    on_done: list = field(default_factory=list)
    warm: bool = False  # run its humv-usd steps in the warm worker when it is free
    sensor: str | None = None  # a preview's sensor
    quality: str | None = None  # a preview's quality (editor.preview.QUALITIES)
    notes: list[str] = field(default_factory=list)  # what a fast preview lowered
    #: progress inside a step: (step index, folder, glob, expected count) of the files it writes
    watch: tuple[int, Path, str, int] | None = None

    def files_done(self) -> tuple[int, int] | None:
        """(files written, files expected) of the watched step, None without one."""
        if self.watch is None:
            return None
        _, folder, pattern, expected = self.watch
        return min(sum(1 for _ in folder.glob(pattern)), expected), expected

    @property
    def seconds(self) -> float:
        return (self.ended or time.time()) - self.started

    @property
    def progress(self) -> float:
        """Fraction finished (0..1): steps done, and within the watched step its files written."""
        if self.state == "done":
            return 1.0
        done = float(self.step)
        files = self.files_done()
        if files is not None and self.watch[0] == self.step and files[1] > 0:
            done += files[0] / files[1]
        return done / max(len(self.steps), 1)

    @property
    def finished(self) -> bool:
        return self.state in ("done", "failed", "cancelled")

    def add(self, line: str) -> None:
        self.lines.append(line.rstrip("\n"))
        if len(self.lines) > MAX_LINES:
            del self.lines[0]
            self.dropped += 1

    def cancel(self) -> None:
        """Stop the job (its whole process group)."""
        if self.process is not None and self.process.poll() is None:
            self.state = "cancelled"
            try:
                os.killpg(self.process.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass


def humv_command(*args: str) -> list[str]:
    """The argument list running ``humv-usd ARGS`` with this interpreter (``-v``: progress lines)."""
    return [sys.executable, "-m", "humv_usd.cli.main", "-v", *args]


class JobManager:
    """The jobs of one editor server (kept for its lifetime)."""

    def __init__(self):
        self.jobs: dict[int, Job] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._warm: subprocess.Popen | None = None  # the warm worker, started on first use
        self._warm_cwd: Path | None = None
        self._warm_busy = threading.Lock()  # one command at a time in it

    def start(
        self,
        kind: str,
        steps: list[list[str]],
        out_dir: Path,
        cwd: Path,
        on_done=None,
        watch=None,
        warm: bool = False,
    ) -> Job:
        """Run ``steps`` (argument lists; no shell) one after the other in ``cwd``, stopping at the
        first that fails; ``on_done(job)`` runs when the job ends; ``watch`` (step, folder, glob,
        expected count) measures a step's progress by the files it has written. ``warm``: run
        its ``humv-usd`` steps in the warm worker (:mod:`humv_usd.cli.warm`: no imports per
        step) when no other job uses it, else as processes of their own."""
        if not steps or not all(isinstance(a, list) and all(isinstance(x, str) for x in a) for a in steps):
            raise TypeError("a job is a list of argument lists of strings")
        job = Job(next(self._ids), kind, steps, Path(out_dir), watch=watch, warm=warm)
        if on_done:
            job.on_done.append(on_done)
        job.state = "running"
        with self._lock:
            self.jobs[job.id] = job
        threading.Thread(target=self._run, args=(job, Path(cwd)), daemon=True).start()
        return job

    def warm_up(self, cwd: Path) -> None:
        """Start the warm worker now (it imports while the user edits), unless it runs."""
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        if self._warm_busy.acquire(blocking=False):
            try:
                self._warm_process(Path(cwd), env)
            finally:
                self._warm_busy.release()

    def _warm_process(self, cwd: Path, env: dict) -> subprocess.Popen:
        """The warm worker in ``cwd``, started anew when it is gone (cancelled, crashed)."""
        if self._warm is None or self._warm.poll() is not None or self._warm_cwd != cwd:
            self._stop_warm()
            self._warm = subprocess.Popen(
                WARM_COMMAND,
                cwd=cwd,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                stdin=subprocess.PIPE,
                text=True,
                bufsize=1,
                env=env,
                start_new_session=True,
            )
            self._warm_cwd = cwd
        return self._warm

    def _stop_warm(self) -> None:
        if self._warm is not None and self._warm.poll() is None:
            try:
                os.killpg(self._warm.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            self._warm.wait()
        self._warm = None

    def _run_warm(self, job: Job, argv: list[str], cwd: Path, env: dict) -> int:
        """One ``humv-usd`` step in the warm worker: its output lines go to the job; its exit
        code (a cancel or a crash ends the worker: then the worker's own exit status)."""
        process = self._warm_process(cwd, env)
        job.process = process
        try:
            process.stdin.write(json.dumps(argv[3:]) + "\n")
            process.stdin.flush()
        except OSError:  # it died before the command: a new one
            process = job.process = self._warm_process(cwd, env)
            process.stdin.write(json.dumps(argv[3:]) + "\n")
            process.stdin.flush()
        for line in process.stdout:
            if line.startswith(WARM_SENTINEL):
                return int(line[len(WARM_SENTINEL) :].strip() or 1)
            job.add(line)
        return process.wait() or 1  # the worker ended inside the command

    def _run(self, job: Job, cwd: Path) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        for step, argv in enumerate(job.steps):
            job.step = step
            if job.state == "cancelled":
                break
            job.add("$ humv-usd " + " ".join(argv[4:] if argv[:3] == humv_command()[:3] else argv))
            if job.warm and argv[:3] == humv_command()[:3] and self._warm_busy.acquire(blocking=False):
                try:
                    job.returncode = self._run_warm(job, argv, cwd, env)
                finally:
                    self._warm_busy.release()
                if job.returncode != 0:
                    break
                continue
            job.process = subprocess.Popen(
                argv,
                cwd=cwd,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                text=True,
                bufsize=1,
                env=env,
                start_new_session=True,  # its own process group: cancel stops its children too
            )
            assert job.process.stdout is not None
            for line in job.process.stdout:
                job.add(line)
            job.returncode = job.process.wait()
            if job.returncode != 0:
                break
        job.ended = time.time()
        if job.state != "cancelled":
            job.state = "done" if job.returncode == 0 else "failed"
        job.add(f"[{job.state}: exit {job.returncode}, {job.seconds:.1f} s]")
        for callback in job.on_done:
            try:
                callback(job)
            except Exception:  # a page callback must not kill the follower thread
                log.exception("job %d: callback failed", job.id)

    def latest(self, kind: str | None = None) -> Job | None:
        jobs = [j for j in self.jobs.values() if kind is None or j.kind == kind]
        return jobs[-1] if jobs else None

    def shutdown(self) -> None:
        """Cancel every running job (server stop) and stop the warm worker."""
        for job in self.jobs.values():
            job.cancel()
        self._stop_warm()


def outputs(out_dir: Path) -> list[Path]:
    """The files worth a link in an output folder: stage, manifests, COCO, region tables, images
    (PNG previews and EXRs), relative to ``out_dir``, at most 200."""
    names = ("stage.usda", "compose.json", "manifest.json", "coco.json", "regions.json", "regions.csv")
    found: list[Path] = []
    if not out_dir.is_dir():
        return found
    for path in sorted(out_dir.rglob("*")):
        if not path.is_file() or any(part.startswith(".") for part in path.relative_to(out_dir).parts):
            continue
        if path.name in names or path.name.endswith((".png", ".exr", ".objects.json", ".usda")):
            found.append(path.relative_to(out_dir))
        if len(found) >= 200:
            break
    return found
