"""``humv-usd bench preview``: how long the editor's preview takes after each kind of edit.

The bench drives the page's own path, without a browser: a copy of the scenario is opened as a
:class:`~humv_usd.editor.document.ScenarioDocument`, edited through it and saved, and each preview
runs the steps of :func:`~humv_usd.editor.preview.preview_commands` as child processes
(:func:`~humv_usd.editor.jobs.humv_command`, as the page's jobs do), then
:func:`~humv_usd.editor.preview.make_preview`. Per preview it reports the wall time and the
children's CPU time of each step, the layers compose rebuilt with their build times (from the
stage folder's compose.json) and the total from the first command to the colour image. Wall
times depend on the machine's load; CPU seconds much less so.

The edits (:data:`EDITS`), in this order, each on top of the last: none (a cold output
folder), none again (everything cached), a person's heading, a person's activity (a pose), the
clock (start one hour later), the weather (air 2 K warmer), a sensor's NETD (render-only).
"""

from __future__ import annotations

import datetime as dt
import json
import os
import resource
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import tomlkit

from humv_usd.editor.document import ScenarioDocument
from humv_usd.editor.jobs import JobManager, humv_command
from humv_usd.editor.preview import (
    PREVIEW_SCENARIO,
    PREVIEW_STAGE_DIR,
    make_preview,
    preview_commands,
    preview_resolution,
    preview_scenario,
)
from humv_usd.errors import InputError
from humv_usd.fileio import write_text_atomic


def _heading(doc: ScenarioDocument) -> None:
    old = doc.get(("placement", 0, "heading_deg")) or 0.0
    doc.set_value(("placement", 0, "heading_deg"), float((old + 10.0) % 360.0))


def _pose(doc: ScenarioDocument) -> None:
    old = doc.get(("human", 0, "activity"))
    doc.set_value(("human", 0, "activity"), "wave" if old != "wave" else "stand")


def _clock(doc: ScenarioDocument) -> None:
    start = doc.scenario()["general"]["start"]
    doc.set_value(("general", "start"), start + dt.timedelta(hours=1))


def _weather(doc: ScenarioDocument) -> None:
    air = doc.scenario()["atmosphere"]["air_temperature_k"]
    doc.set_value(("atmosphere", "air_temperature_k"), float(air) + 2.0)


def _netd(doc: ScenarioDocument) -> None:
    old = doc.scenario()["sensor"][0]["netd_k"]
    doc.set_value(("sensor", 0, "netd_k"), round(float(old) * 0.8, 6))


#: the file that marks a work folder as this bench's (only such a folder is emptied)
MARKER = ".humv-bench-preview"

#: (name, what it changes, the edit; None: no edit)
EDITS = (
    ("cold", "nothing: an empty output folder", None),
    ("unchanged", "nothing: every layer cached", None),
    ("heading", "placement[0].heading_deg + 10", _heading),
    ("pose", "human[0].activity -> wave (or stand)", _pose),
    ("clock", "general.start + 1 h", _clock),
    ("weather", "atmosphere.air_temperature_k + 2 K", _weather),
    ("netd", "sensor[0].netd_k x 0.8 (render-only)", _netd),
)


@dataclass
class Step:
    """One child process of a preview."""

    command: str
    wall_s: float
    cpu_s: float
    returncode: int
    last_line: str


@dataclass
class PreviewTiming:
    """One preview after one edit."""

    edit: str
    what: str
    wall_s: float = 0.0
    steps: list[Step] = field(default_factory=list)
    rebuilt: dict[str, float] = field(default_factory=dict)  # layer -> build seconds
    compose_s: float = 0.0  # compose's own total (compose.json), without the process start
    error: str = ""

    @property
    def cpu_s(self) -> float:
        return sum(s.cpu_s for s in self.steps)

    def line(self) -> str:
        steps = ", ".join(f"{s.command} {s.wall_s:.1f} s ({s.cpu_s:.1f} CPU-s)" for s in self.steps)
        layers = ", ".join(f"{n} {t:.1f}" for n, t in self.rebuilt.items()) or "none"
        text = (
            f"{self.edit:9s} {self.wall_s:6.1f} s wall, {self.cpu_s:5.1f} CPU-s: {steps}; "
            f"rebuilt [s]: {layers}"
        )
        return text + (f"; FAILED: {self.error}" if self.error else "")


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _process_cpu(pid: int | None) -> float:
    """CPU seconds of a running process so far (Linux /proc; 0 elsewhere or when it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, TypeError):
        return 0.0


def _warm_pid(jobs: JobManager) -> int | None:
    warm = jobs._warm  # noqa: SLF001 (the bench reads the manager's worker to time it)
    return warm.pid if warm is not None and warm.poll() is None else None


def run_preview(
    doc: ScenarioDocument, out: Path, sensor: str, quality: str, jobs: JobManager | None = None
) -> tuple[list[Step], str]:
    """One preview as the page runs it (each command a job of ``jobs``; with a JobManager the
    page's warm worker, without one a process per command); returns its steps and an error
    line ('' when the image was made)."""
    scenario = doc.scenario()
    source = doc.path
    if quality == "fast":
        source = out / PREVIEW_SCENARIO
        write_text_atomic(source, tomlkit.dumps(preview_scenario(doc.raw(), scenario, doc.folder)))
    steps = []
    manager = jobs or JobManager()
    for args in preview_commands(source, out, sensor, preview_resolution(scenario, sensor), quality):
        t, c = time.perf_counter(), _children_cpu()
        pid = _warm_pid(manager) if jobs is not None else None
        w0 = _process_cpu(pid)
        job = manager.start("preview", [humv_command(*args)], out, cwd=doc.folder, warm=jobs is not None)
        while not job.finished:
            time.sleep(0.02)
        if jobs is not None and pid is None:  # started by this step: all its CPU is the step's
            pid, w0 = _warm_pid(manager), 0.0
        cpu = _children_cpu() - c + (_process_cpu(pid) - w0 if pid is not None else 0.0)
        lines = [x for x in job.lines if x.strip() and not x.startswith(("$ ", "["))]
        steps.append(Step(args[0], time.perf_counter() - t, cpu, job.returncode or 0, (lines or [""])[-1]))
        if job.returncode:
            return steps, f"{args[0]} exit {job.returncode}: {(lines or [''])[-1]}"
    try:
        make_preview(out / "preview", sensor)
    except (FileNotFoundError, KeyError, OSError) as exc:
        return steps, str(exc)
    return steps, ""


def bench_preview(
    scenario_file: Path,
    work_dir: Path,
    sensor: str | None = None,
    quality: str = "fast",
    edits=None,
    warm: bool = True,
) -> list[PreviewTiming]:
    """Copy ``scenario_file`` into ``work_dir`` (new, empty, or emptied when this bench made
    it), then preview ``sensor`` (default: the first infrared one, else the first) after each edit of :data:`EDITS` (or those named in
    ``edits``) at ``quality``; ``warm``: in the page's warm worker (:mod:`humv_usd.cli.warm`),
    else a process per command; see the module doc."""
    work_dir = Path(work_dir)
    if work_dir.exists() and any(work_dir.iterdir()):
        if not (work_dir / MARKER).is_file():  # never empty a folder this bench did not make
            raise InputError(f"-o {work_dir}: not empty and not a folder of this bench; name a new folder")
        shutil.rmtree(work_dir)
    work_dir.mkdir(parents=True, exist_ok=True)
    (work_dir / MARKER).write_text("humv-usd bench preview: this folder is emptied by the next run\n")
    copy = work_dir / Path(scenario_file).name
    shutil.copy(scenario_file, copy)
    doc = ScenarioDocument(copy)
    if doc.problems():
        raise InputError(f"{scenario_file}: not valid: {doc.problems()[0]}")
    scenario = doc.scenario()
    if sensor is None:
        ir = [s["id"] for s in scenario["sensor"] if s["band"] not in ("EO", "NIR", "SWIR")]
        sensor = (ir or [s["id"] for s in scenario["sensor"]])[0]
    out = work_dir / "out"
    stage_dir = out / PREVIEW_STAGE_DIR if quality == "fast" else out
    results = []
    jobs = JobManager() if warm else None
    try:
        results = _previews(doc, out, sensor, quality, stage_dir, edits, jobs)
    finally:
        if jobs is not None:
            jobs.shutdown()
    return results


def _previews(doc, out, sensor, quality, stage_dir, edits, jobs) -> list[PreviewTiming]:
    results = []
    for name, what, edit in EDITS:
        if edits and name not in edits:
            continue
        if edit is not None:
            edit(doc)
            doc.save()
        t = time.perf_counter()
        steps, error = run_preview(doc, out, sensor, quality, jobs)
        timing = PreviewTiming(name, what, time.perf_counter() - t, steps, error=error)
        try:
            report = json.loads((stage_dir / "compose.json").read_text())
            timing.compose_s = report.get("seconds_total", 0.0)
            timing.rebuilt = {
                e["name"]: e["seconds"] for e in report["layers"] if e.get("state") == "rebuilt"
            }
        except (OSError, ValueError, KeyError):
            pass
        results.append(timing)
    return results
