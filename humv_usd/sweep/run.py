"""The sweep's client: validates, takes the dataset lock, submits the tasks that are not done
yet to Dask (or runs them in this process), retries failed tasks a bounded number of times,
reports progress through a callback and assembles the dataset at the end.

Scheduling: variant ``v``'s compose task is submitted once the composes it shares layers with
(:func:`humv_usd.sweep.plan.compose_dependencies`) have finished, so a shared layer is built
once and copied from the store; its render tasks are submitted when its compose has finished.
Render tasks take their inputs from the variant's composed stage only.

Default executor: a local Dask cluster of worker processes (one single-threaded worker per
core; each render uses Mitsuba's own threads). ``scheduler="tcp://HOST:PORT"`` uses an existing
Dask cluster whose workers see the dataset folder at the same path, or reach the same fsspec URL
(``s3://bucket/prefix``: :mod:`humv_usd.sweep.where`). ``workers=0`` runs every task in this
process, one at a time (tests, debugging; the only choice for ``memory://``).

GPUs (:mod:`humv_usd.sweep.cluster`): ``gpus=N`` starts a local cluster of N GPU workers (one per
GPU, Dask resource ``GPU=1``) and CPU workers (``CPU=1``); on any cluster whose workers declare
these resources, render tasks ask for a GPU when the renders run on CUDA and composes stay on the
CPU workers. ``last_run.json`` records the workers of each kind and what each task kind asked for.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import os
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import tomlkit

from humv_usd.errors import InputError
from humv_usd.fileio import check_output_dir
from humv_usd.sweep import cluster, store
from humv_usd.sweep.dataset import assemble
from humv_usd.sweep.plan import (
    RenderTask,
    compose_dependencies,
    estimate,
    held_work,
    layer_keys,
    render_tasks,
    require_disk,
)
from humv_usd.sweep.spec import Sweep, _plain
from humv_usd.sweep.tasks import compose_variant, drop_local_cache, error_text, render_chunk
from humv_usd.sweep.where import Location, local_cache

log = logging.getLogger(__name__)


@dataclass
class SweepResult:
    dataset: Path
    variants: int
    tasks: int
    already_done: int
    ran: int = 0
    frames_rendered: int = 0
    images_rendered: int = 0
    composed: int = 0
    retries: int = 0
    failures: list[dict] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 0
    local_cache_freed: int = 0  # bytes of the workers' local copies removed at the end (URL datasets)
    gpu_workers: int = 0  # workers declaring the GPU resource
    resources: dict = field(default_factory=dict)  # task kind -> the Dask resources it asked for
    dataset_summary: dict = field(default_factory=dict)

    @property
    def frames_per_hour(self) -> float:
        return self.images_rendered / self.seconds * 3600.0 if self.seconds > 0 else 0.0

    def as_dict(self) -> dict:
        return {
            "dataset": str(self.dataset),
            "variants": self.variants,
            "render_tasks": self.tasks,
            "already_done": self.already_done,
            "ran": self.ran,
            "composed": self.composed,
            "frames_rendered": self.frames_rendered,
            "images_rendered": self.images_rendered,
            "retries": self.retries,
            "failures": self.failures,
            "seconds": self.seconds,
            "workers": self.workers,
            "gpu_workers": self.gpu_workers,
            "task_resources": self.resources,
            "local_cache_freed_bytes": self.local_cache_freed,
            "images_per_hour": self.frames_per_hour,
        }


class _InProcess:
    """Runs each task at submit, in this process (``workers=0``)."""

    render_threads = None  # the render's own default (every core)

    workers = 0
    gpu_workers = cpu_workers = 0

    def submit(self, fn, *args, key=None, resources=None):
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args))
        except Exception as exc:  # noqa: BLE001 (reported as the task's failure)
            fut.set_exception(exc)
        return fut

    def wait_any(self, futures):
        return cf.wait(futures, return_when=cf.FIRST_COMPLETED).done

    def run_everywhere(self, fn, *args) -> list:
        return [fn(*args)]

    def close(self):
        pass


#: LocalCluster options: no dashboard, and the scheduler's HTTP server (health, metrics) on a free
#: port (with ``dashboard_address=None`` it still takes 8787 and, when another cluster on the
#: machine has it, warns "Port 8787 is already in use")
NO_DASHBOARD = {"dashboard_address": None, "scheduler_kwargs": {"dashboard_address": ":0"}}


def _pin_worker(cpus_per_worker: int):
    """A worker plugin that binds local worker ``i`` (its name) and every thread of its process to
    its own ``cpus_per_worker`` cores, ``[i k, (i + 1) k)`` modulo the cores (Linux)."""
    import distributed

    class PinWorker(distributed.WorkerPlugin):
        name = "humv-usd-pin-worker"

        def setup(self, worker):
            cores = sorted(os.sched_getaffinity(0))
            first = int(worker.name) * cpus_per_worker
            mine = {cores[(first + j) % len(cores)] for j in range(cpus_per_worker)}
            for tid in os.listdir("/proc/self/task"):  # threads started later inherit it
                os.sched_setaffinity(int(tid), mine)

    return PinWorker()


class _Dask:
    """A dask.distributed client: on a new local cluster of processes, or an existing scheduler.
    ``cpus_per_worker`` (local clusters, Linux): bind each worker to that many cores of its own
    and give its renders as many Dr.Jit threads (the bench's one-core-per-worker scaling run)."""

    def __init__(
        self, scheduler: str | None, workers: int | None, cpus_per_worker: int | None = None, gpus: int = 0
    ):
        import distributed

        self._distributed = distributed
        # Dask logs every worker start and stop at INFO: keep it at the command line's level or quieter
        logging.getLogger("distributed").setLevel(max(logging.WARNING, logging.getLogger().level))
        self.cluster = None
        if scheduler:
            self.client = distributed.Client(scheduler, timeout="30s")
        elif gpus:  # one worker per GPU and CPU workers for the composes (sweep.cluster)
            cpu = workers or max(1, (os.cpu_count() or 1) - gpus)
            self.cluster = cluster.local_cluster(gpus, cpu)
            self.client = distributed.Client(self.cluster)
            self.client.wait_for_workers(gpus + cpu, timeout=120)
        else:
            n = workers or os.cpu_count() or 1
            self.cluster = distributed.LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                silence_logs=logging.ERROR,
                **NO_DASHBOARD,
            )
            self.client = distributed.Client(self.cluster)
        table = self.client.scheduler_info(n_workers=-1)["workers"]
        self.workers = len(table)
        self.gpu_workers, self.cpu_workers = cluster.worker_kinds(table)
        # Dr.Jit threads per render: this machine's cores shared by the local workers (2 workers
        # on 2 cores: 1 each, not 2 each competing); an existing cluster keeps its own setting
        self.render_threads = (
            max(1, (os.cpu_count() or 1) // max(1, self.workers)) if self.cluster is not None else None
        )
        if cpus_per_worker and self.cluster is not None and not gpus:
            self.client.register_plugin(_pin_worker(cpus_per_worker))
            self.render_threads = cpus_per_worker
        self.run_id = uuid.uuid4().hex[:8]

    def submit(self, fn, *args, key=None, resources=None):
        return self.client.submit(fn, *args, key=f"{key}-{self.run_id}", pure=False, resources=resources)

    def wait_any(self, futures):
        return self._distributed.wait(futures, return_when="FIRST_COMPLETED").done

    def run_everywhere(self, fn, *args) -> list:
        """``fn(*args)`` on every worker now connected (``Client.run``)."""
        return list(self.client.run(fn, *args).values())

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def write_variant_files(loc: Location, sweep: Sweep) -> None:
    """``.sweep/sweep.json`` and each variant's ``scenario.toml`` (what it composes)."""
    doc = {
        "name": sweep.name,
        "digest": sweep.digest(),
        "sweep_file": str(sweep.path.resolve()),
        "base": str(sweep.base_path),
        "render": sweep.render,
        "variants": [{"id": v.id, "params": v.params, "render_seed": v.render_seed} for v in sweep.variants],
    }
    loc.write_json(f"{store.SWEEP_DIR}/sweep.json", doc)
    for v in sweep.variants:
        text = f"# variant {v.id} of sweep {sweep.name}: {_plain(v.params)}\n" + tomlkit.dumps(v.raw)
        loc.write_text(f"variants/{v.id}/scenario.toml", text)


def run_sweep(
    sweep: Sweep,
    dataset,
    scheduler: str | None = None,
    workers: int | None = None,
    on_event: Callable[[dict], None] | None = None,
    limit: int | None = None,
    cpus_per_worker: int | None = None,
    yes: bool = False,
    gpus: int = 0,
) -> SweepResult:
    """Run what is missing of ``sweep`` into ``dataset`` and assemble the dataset; see the module
    doc. ``limit``: run only the first ``limit`` variants (a later run without it adds the rest).
    ``cpus_per_worker``: bind each local worker to that many cores of its own (see :class:`_Dask`).
    ``gpus``: a local cluster of that many GPU workers plus ``workers`` CPU workers
    (:mod:`humv_usd.sweep.cluster`).
    Raises InputError (nothing written) for a folder that cannot be written, a folder of another
    sweep or one another live sweep is writing, and (unless ``yes``) a local folder without the
    free disk the estimate of what is left needs (:func:`plan.estimate`)."""
    t0 = time.perf_counter()
    if gpus and (scheduler or workers == 0):
        how = "--scheduler" if scheduler else "--workers 0"
        raise InputError(
            f"--gpus {gpus} starts a local cluster; with {how} it cannot: start GPU workers with "
            f"`dask worker SCHEDULER --nthreads 1 --resources {cluster.GPU_RESOURCE}=1` (docs/user/gpu.md)"
        )
    loc = _location(dataset, scheduler, workers)
    dataset = loc.url if loc.remote else loc.path
    emit = on_event or (lambda event: None)
    keys = {v.id: layer_keys(v.scenario) for v in sweep.variants}
    tasks = render_tasks(sweep)
    if limit is not None:
        wanted = {v.id for v in sweep.variants[:limit]}
        tasks = [t for t in tasks if t.variant in wanted]
    if not loc.remote:  # before the lock: a refused new folder is not created
        require_disk(estimate(sweep, keys, 1, *held_work(sweep, loc, limit)), loc.path, yes)
    with store.dataset_lock(loc) as lease:
        store.check_sweep_record(loc, sweep.digest())
        write_variant_files(loc, sweep)
        removed = store.clean_staging(local_cache(loc.url) if loc.remote else loc.path)
        if removed:
            log.info("removed %d unfinished staging folder(s)", removed)
        store.clear_failures(loc)
        finished = store.done_tasks(loc)
        done = [t for t in tasks if (t.variant, t.chunk) in finished]
        result = SweepResult(dataset, len(sweep.variants), len(tasks), already_done=len(done))
        todo = [t for t in tasks if t not in set(done)]
        emit(
            {
                "type": "start",
                "variants": len(sweep.variants),
                "tasks": len(tasks),
                "done": len(done),
                "frames": sum(len(t.frames) for t in tasks),
                "frames_done": sum(len(t.frames) for t in done),
            }
        )
        if todo:
            executor = (
                _InProcess()
                if workers == 0 and not scheduler
                else _Dask(scheduler, workers, cpus_per_worker, gpus)
            )
            result.workers, result.gpu_workers = executor.workers, executor.gpu_workers
            try:
                on_gpu = cluster.renders_on_gpu(executor.gpu_workers)
                result.resources = {
                    kind: cluster.task_resources(kind, executor.gpu_workers, executor.cpu_workers, on_gpu)
                    for kind in ("compose", "render")
                }
                _Loop(sweep, loc, keys, todo, executor, result, emit, lease).run()
                if loc.remote:  # the workers' local copies: every task has ended
                    try:
                        result.local_cache_freed = sum(executor.run_everywhere(drop_local_cache, loc.url))
                    except Exception as exc:  # noqa: BLE001 (a worker gone: its copy stays, nothing lost)
                        log.warning("could not remove the workers' local copies: %s", exc)
            finally:
                executor.close()
        _check_lease(lease, loc)
        emit({"type": "assemble"})
        result.dataset_summary = assemble(loc, sweep, tasks)
        if not loc.remote:
            store.clean_staging(loc.path)
    result.seconds = time.perf_counter() - t0
    loc.write_json(f"{store.SWEEP_DIR}/last_run.json", result.as_dict())
    emit({"type": "finished", **result.as_dict()})
    return result


def _location(dataset, scheduler, workers) -> Location:
    """The dataset's Location: a checked, absolute folder, or an fsspec URL (``memory://`` lives
    in this process only: it needs ``workers=0``)."""
    loc = Location(dataset)
    if not loc.remote:
        return Location(check_output_dir(dataset, "dataset folder").resolve())
    if loc.url.startswith("memory://") and (workers != 0 or scheduler):
        raise InputError(
            f"dataset folder {loc.url!r}: memory:// lives in one process; run it with --workers 0"
        )
    return loc


def _check_lease(lease, loc: Location) -> None:
    """Stop when another sweep took the lock over (this one looked dead to it)."""
    if lease is not None and lease.lost:
        raise InputError(
            f"{loc}: another sweep took over this dataset's lock (this one missed its heartbeats); stopped"
        )


class _Loop:
    """Submits tasks as their inputs become ready, retries, and reports (see the module doc)."""

    def __init__(
        self, sweep, loc: Location, keys, todo: list[RenderTask], executor, result, emit, lease=None
    ):
        self.lease = lease
        self.sweep, self.loc, self.dataset, self.executor, self.result, self.emit = (
            sweep,
            loc,
            loc.url,
            executor,
            result,
            emit,
        )
        self.by_id = {v.id: v for v in sweep.variants}
        self.renders: dict[str, list[RenderTask]] = {}
        for t in todo:
            self.renders.setdefault(t.variant, []).append(t)
        need = [vid for vid in self.renders if not store.compose_done(loc, vid)]
        all_deps = compose_dependencies({vid: keys[vid] for vid in need})
        self.waiting = {vid: set(all_deps[vid]) for vid in need}
        self.running: dict = {}
        self.retries = sweep.render["retries"]
        self.settings = {k: sweep.render[k] for k in ("spp", "sensors", "annotators", "subbands")}
        self.settings["render_threads"] = getattr(executor, "render_threads", None)

    def run(self) -> None:
        for vid in self.renders:
            if vid not in self.waiting:
                self._submit_renders(vid)
        self._submit_ready_composes()
        while self.running:
            _check_lease(self.lease, self.loc)
            for fut in self.executor.wait_any(list(self.running)):
                kind, name, attempt, payload = self.running.pop(fut)
                try:
                    exc = fut.exception()
                except Exception as cancelled:  # noqa: BLE001 (a cancelled future raises here)
                    exc = cancelled
                if exc is None:
                    self._finished(kind, name, fut.result(), payload)
                elif attempt < self.retries:
                    self.result.retries += 1
                    self.emit(
                        {"type": "retry", "task": name, "attempt": attempt + 1, "error": error_text(exc)}
                    )
                    self._resubmit(kind, name, attempt + 1, payload)
                else:
                    self._failed(kind, name, exc, attempt + 1, payload)

    def _submit_ready_composes(self) -> None:
        for vid in [v for v, deps in self.waiting.items() if not deps]:
            del self.waiting[vid]
            self._resubmit("compose", vid, 0, None)

    def _resubmit(self, kind, name, attempt, payload) -> None:
        if kind == "compose":
            v = self.by_id[name]
            fut = self.executor.submit(
                compose_variant,
                str(self.dataset),
                v.id,
                v.raw,
                str(self.sweep.base_path),
                key=f"compose-{name}",
                resources=self.result.resources.get("compose"),
            )
        else:
            t: RenderTask = payload
            settings = dict(self.settings, seed=self.by_id[t.variant].render_seed)
            fut = self.executor.submit(
                render_chunk,
                str(self.dataset),
                t.variant,
                t.chunk,
                list(t.frames),
                settings,
                key=f"render-{name}",
                resources=self.result.resources.get("render"),
            )
        self.running[fut] = (kind, name, attempt, payload)

    def _submit_renders(self, vid: str) -> None:
        for t in self.renders.get(vid, []):
            self._resubmit("render", t.name, 0, t)

    def _release(self, vid: str) -> None:
        for deps in self.waiting.values():
            deps.discard(vid)
        self._submit_ready_composes()

    def _finished(self, kind, name, record, payload) -> None:
        if kind == "compose":
            self.result.composed += 1
            self.emit(
                {
                    "type": "compose",
                    "variant": name,
                    "seconds": record["seconds"],
                    "rebuilt": record["rebuilt"],
                }
            )
            self._submit_renders(name)
            self._release(name)
            return
        self.result.ran += 1
        n_sensors = max(1, _sensor_count(self.by_id[payload.variant], self.sweep.render["sensors"]))
        self.result.frames_rendered += len(payload.frames)
        self.result.images_rendered += len(payload.frames) * n_sensors
        self.emit(
            {
                "type": "render",
                "task": name,
                "frames": len(payload.frames),
                "images": len(payload.frames) * n_sensors,
                "seconds": record["seconds"],
                "peak_rss_mb": record.get("peak_rss_mb"),
            }
        )

    def _failed(self, kind, name, exc, attempts, payload) -> None:
        text = error_text(exc)
        store.record_failure(self.loc, f"{kind}-{name}", text, attempts)
        self.result.failures.append({"task": f"{kind} {name}", "error": text, "attempts": attempts})
        self.emit({"type": "failed", "task": f"{kind} {name}", "error": text})
        if kind == "compose":  # its renders cannot run
            for t in self.renders.get(name, []):
                self.result.failures.append(
                    {"task": f"render {t.name}", "error": f"compose {name} failed", "attempts": 0}
                )
                self.emit({"type": "failed", "task": f"render {t.name}", "error": f"compose {name} failed"})
            self._release(name)


def _sensor_count(variant, sensors) -> int:
    return sum(1 for s in variant.scenario["sensor"] if not sensors or s["id"] in sensors)
