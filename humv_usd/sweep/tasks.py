"""What a worker runs: stateless functions of plain arguments (picklable, so any Dask worker
with the package and the dataset folder can run them).

* :func:`compose_variant` composes one variant into ``variants/<id>/``, first taking every layer
  whose cache key is already in the shared store (so equal layers are built once per sweep),
  then publishing its own layers to the store.
* :func:`render_chunk` renders a chunk of frames of a composed variant into a staging folder
  and renames it into ``renders/<id>/<chunk>/`` when complete (:mod:`humv_usd.sweep.store`).

A dataset at an fsspec URL (:mod:`humv_usd.sweep.where`): the worker composes into its local
cache (:func:`humv_usd.sweep.where.local_cache`) and uploads the variant's folder, its
``compose.done.json`` last; a render downloads the composed variant once per machine (again
when its record changed), renders into a local staging folder and uploads the outputs, then
``task.json`` (the done record, with the upload's seconds and bytes) last.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import socket
import time
import traceback
from pathlib import Path

from humv_usd import mode
from humv_usd.fileio import write_json
from humv_usd.pipeline.compose import compose
from humv_usd.pipeline.render import render_stage
from humv_usd.scenario.load import validate
from humv_usd.sweep import store
from humv_usd.sweep.plan import layer_keys
from humv_usd.sweep.where import Location, local_cache


def _rss_mb() -> tuple[float, float]:
    """(current, peak) resident memory of this process [MB] (Linux /proc, getrusage; the peak over
    the whole process, the per-task resets of :func:`start_task_peak` included)."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        current = pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):
        current = float("nan")
    # getrusage and /proc/self/status read the kernel's split RSS counters at different moments
    return current, max(_process_peak_mb[0], _maxrss_mb(), task_peak_mb() or 0.0)


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


#: this process's peak resident memory before the last reset [MB]
_process_peak_mb = [0.0]
_task_peak_started: list[bool] = [False]


def start_task_peak() -> None:
    """Start measuring this task's own peak resident memory: reset the kernel's high-water mark of
    this process (Linux >= 4.0: writing 5 to ``/proc/self/clear_refs`` resets VmHWM, proc(5)). The
    reset also resets getrusage's ``ru_maxrss``, so the process peak is carried over here first.
    Without it (another OS) :func:`task_peak_mb` is None: a lifetime peak of a worker that renders
    many variants only says which task was the heaviest so far."""
    _process_peak_mb[0] = max(_process_peak_mb[0], _maxrss_mb())
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        _task_peak_started[0] = True
    except OSError:
        _task_peak_started[0] = False


def task_peak_mb() -> float | None:
    """This task's peak resident memory [MB] since :func:`start_task_peak` (VmHWM), or None."""
    if not _task_peak_started[0]:
        return None
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


#: glibc ``mallopt`` parameters (malloc.h) and the values a worker sets: blocks below
#: MMAP_THRESHOLD come from the heap (freed ones are reused), and up to TRIM_THRESHOLD of free
#: memory at the heap's top is kept instead of returned to the system.
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MALLOC_MMAP_THRESHOLD_BYTES = 32 * 2**20
MALLOC_TRIM_THRESHOLD_BYTES = 128 * 2**20
_malloc_tuned: bool | None = None


def tune_malloc() -> bool:
    """Let this worker's heap reuse the render's large temporaries (glibc only; once per process).

    A Dask nanny starts its worker with ``MALLOC_TRIM_THRESHOLD_=65536`` (distributed's
    ``distributed.nanny.pre-spawn-environ``, to hand memory back to the system). Setting any glibc
    threshold turns off glibc's dynamic mmap threshold, so every numpy temporary over 128 kB of a
    1024x768 frame (3-50 MB each, hundreds per frame) is a fresh ``mmap`` whose pages the kernel
    zeroes again on first touch. Measured on this 2-core machine, a 4-frame walk LWIR task
    (1024x768, one Dr.Jit thread): 12.3-12.5 s and 16.3 CPU-s with Dask's setting, 9.5 s and
    12.8 CPU-s with the thresholds set here (or with glibc's defaults), for about 0.4 GB more
    resident memory (2.0 against 1.6 GB). Done in the worker (``mallopt``) rather than in the
    cluster's environment, so workers of an existing cluster (``--scheduler``) get it too.
    Returns whether the thresholds are set."""
    global _malloc_tuned
    if _malloc_tuned is None:
        libc = mode.glibc()  # None: not glibc (musl, macOS), its own allocator's defaults
        _malloc_tuned = (
            libc is not None
            and libc.mallopt(M_MMAP_THRESHOLD, MALLOC_MMAP_THRESHOLD_BYTES) == 1
            and libc.mallopt(M_TRIM_THRESHOLD, MALLOC_TRIM_THRESHOLD_BYTES) == 1
        )
    return _malloc_tuned


#: a worker hands its memory caches back (:func:`humv_usd.mode.release_memory`) after a render
#: task that leaves it this much above its resident memory after its first render task
RELEASE_GROWTH = 1.05
_first_task_rss: list[float] = []


def release_memory_if_grown() -> bool:
    """After a render task: when this worker's resident memory exceeds its first render task's by
    :data:`RELEASE_GROWTH`, release Dr.Jit's and glibc's caches (a worker rendering many variants
    collects Dr.Jit blocks of many sizes; one rendering one variant stays below the mark and
    never pays the release). Returns whether it released."""
    rss, _ = _rss_mb()
    if not _first_task_rss:
        _first_task_rss.append(rss)
        return False
    if not rss > _first_task_rss[0] * RELEASE_GROWTH:
        return False
    mode.release_memory()
    return True


def worker_name() -> str | None:
    """The name of the Dask worker running this task (``gpu0``, ``cpu1`` on a cluster of
    :func:`humv_usd.sweep.cluster.local_cluster`), or None outside a worker."""
    try:
        from distributed import get_worker

        return str(get_worker().name)
    except (ImportError, ValueError):
        return None


def compose_variant(dataset: str, variant: str, raw: dict, base_path: str) -> dict:
    """Compose one variant (see the module doc); returns what was built and taken from the store.
    At an fsspec URL the variant is composed in this worker's local cache and uploaded, its
    record last."""
    t0 = time.perf_counter()
    tune_malloc()
    start_task_peak()
    loc = Location(dataset)
    scenario = validate(raw, Path(base_path))
    keys = layer_keys(scenario)
    if loc.remote:
        out = local_cache(loc.url) / "variants" / variant
        taken = store.seed_layers_remote(loc, keys, out)
    else:
        out = Path(dataset) / "variants" / variant
        taken = store.seed_layers(Path(dataset), keys, out)
    try:
        report = compose(scenario, out)
    finally:
        mode.release_memory()  # a compose's layers and arrays: not what the next task needs
    if loc.remote:
        store.publish_layers_remote(loc, keys, out)
    else:
        store.publish_layers(Path(dataset), keys, out)
    record = {
        "variant": variant,
        "seconds": time.perf_counter() - t0,
        "task_peak_rss_mb": task_peak_mb(),
        "rebuilt": report.rebuilt,
        "from_store": taken,
        "keys": keys,
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "worker": worker_name(),
    }
    write_json(out / store.COMPOSE_RECORD, record)
    if loc.remote:
        loc.put_folder(out, f"variants/{variant}", last=store.COMPOSE_RECORD)
    return record


def _local_variant(loc: Location, variant: str) -> Path:
    """The composed variant in this machine's cache, downloaded when missing or out of date."""
    local = local_cache(loc.url) / "variants" / variant
    rel = f"variants/{variant}/{store.COMPOSE_RECORD}"
    remote_record = loc.read_text(rel)
    mine = local / store.COMPOSE_RECORD
    if not mine.is_file() or mine.read_text() != remote_record:
        loc.get_folder(f"variants/{variant}", local, last=store.COMPOSE_RECORD)
    return local


def render_chunk(dataset: str, variant: str, chunk: str, frames: list[int], settings: dict) -> dict:
    """Render ``frames`` of a composed variant; the outputs land in ``renders/<variant>/<chunk>``
    in one rename, with ``task.json`` (frames, seconds, Monte Carlo error, memory)."""
    tune_malloc()
    start_task_peak()
    if Location(dataset).remote:
        return _render_chunk_remote(Location(dataset), variant, chunk, frames, settings)
    dataset_dir = Path(dataset)
    final = store.render_folder(dataset_dir, variant, chunk)
    if (final / store.TASK_RECORD).is_file():  # landed by an earlier try
        return json.loads((final / store.TASK_RECORD).read_text())
    t0 = time.perf_counter()
    staging = store.staging_folder(dataset_dir, f"{variant}/{chunk}")
    try:
        record = _render_into(dataset_dir / "variants" / variant, staging, variant, chunk, frames, settings)
        record["seconds"] = time.perf_counter() - t0
        write_json(staging / store.TASK_RECORD, record)
        store.commit(staging, final)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return record


def set_render_threads(count: int) -> None:
    """Dr.Jit's worker threads in this process (the render's kernels run on them)."""
    mode.mitsuba()
    import drjit as dr

    if dr.thread_count() != count:
        dr.set_thread_count(count)


def _render_into(variant_dir: Path, staging: Path, variant, chunk, frames, settings) -> dict:
    """Render the frames of the composed variant in ``variant_dir`` into ``staging``; the record.
    ``settings["render_threads"]`` (when set) is the Dr.Jit thread count of this worker's renders."""
    t0 = time.perf_counter()
    if settings.get("render_threads"):
        set_render_threads(int(settings["render_threads"]))
    manifest = render_stage(
        variant_dir / "stage.usda",
        staging,
        frames=list(frames),
        spp=settings["spp"],
        sensors=settings.get("sensors"),
        seed=settings["seed"],
        annotators=settings.get("annotators"),
        subbands=settings.get("subbands"),
    )
    task_peak = task_peak_mb()  # before a release: what the task itself held
    released = release_memory_if_grown()
    rss, peak = _rss_mb()
    return {
        "variant": variant,
        "chunk": chunk,
        "frames": list(frames),
        "seconds": time.perf_counter() - t0,
        "render_seconds": manifest["timings_s"].get("total"),
        "monte_carlo_error": manifest.get("monte_carlo_error"),
        "rss_mb": rss,  # after the task (and the release, when there was one)
        "peak_rss_mb": peak,  # of the worker process so far
        "task_peak_rss_mb": task_peak,  # of this task alone (None where it cannot be measured)
        "memory_released": released,
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count(),
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "worker": worker_name(),
        "backend": mode.loaded_backend(),  # cuda, llvm or scalar: where this task rendered
        "frames_per_task": len(frames),
    }


def _render_chunk_remote(loc: Location, variant: str, chunk: str, frames, settings) -> dict:
    final = f"renders/{variant}/{chunk}"
    if loc.is_file(f"{final}/{store.TASK_RECORD}"):  # landed by an earlier try
        return loc.read_json(f"{final}/{store.TASK_RECORD}")
    t0 = time.perf_counter()
    local = _local_variant(loc, variant)
    staging = store.staging_folder(local_cache(loc.url), f"{variant}/{chunk}")
    try:
        record = _render_into(local, staging, variant, chunk, frames, settings)
        t_up = time.perf_counter()
        record["upload_bytes"] = loc.put_folder(staging, final)  # every output, then the record
        record["upload_seconds"] = time.perf_counter() - t_up
        record["seconds"] = time.perf_counter() - t0
        write_json(staging / store.TASK_RECORD, record)
        loc.put_file(staging / store.TASK_RECORD, f"{final}/{store.TASK_RECORD}")
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return record


def drop_local_cache(url: str) -> int:
    """Remove this machine's working folder of the dataset at ``url`` (composed variants
    downloaded or composed here, staging); run on every worker when a sweep ends, when none of its
    tasks is running. The dataset itself keeps everything; a later run downloads what it needs.
    Returns the bytes freed."""
    folder = local_cache(url)
    freed = 0
    for dirpath, _, files in os.walk(folder):  # workers of one machine share the folder: races
        for name in files:  # with another worker's removal are ignored
            try:
                freed += os.lstat(os.path.join(dirpath, name)).st_size
            except OSError:
                pass
    shutil.rmtree(folder, ignore_errors=True)
    return freed


def error_text(exc: BaseException) -> str:
    """One line for a failed task (the exception) plus its last traceback line."""
    tb = traceback.format_exception(type(exc), exc, exc.__traceback__)
    where = tb[-2].strip().splitlines()[0] if len(tb) > 1 else ""
    return f"{type(exc).__name__}: {exc}" + (f" [{where}]" if where else "")
