"""Which Dask workers run which tasks: GPU workers render, CPU workers compose.

A worker that owns a GPU declares the Dask resource :data:`GPU_RESOURCE` (``GPU=1``) and sees
only its own device (``CUDA_VISIBLE_DEVICES``); a worker meant for composes declares
:data:`CPU_RESOURCE` (``CPU=1``). The sweep's client reads the resources its workers declared and
then (:func:`task_resources`):

* render tasks ask for ``GPU=1`` when the renders run on CUDA: some worker declares a GPU and the
  backend is not forced to the CPU (``HUMV_USD_BACKEND=llvm`` or ``scalar``, where they render on
  the CPU workers); at most one render per GPU at a time;
* compose tasks never ask for a GPU; they ask for ``CPU=1`` when some worker declares it, which
  keeps them off the GPU workers (a compose there would hold the GPU's only task slot for the
  20-100 s of a compose while the device idles);
* a cluster whose workers declare nothing runs every task anywhere, as before.

A render task renders every sensor of its frames in one scene (:func:`humv_usd.pipeline.render.
render_stage`): its batch is ``[render] frames_per_task`` frames times the sensors. Its file
writes run on the render's writer threads (:mod:`humv_usd.pipeline.writer`) on the GPU worker's
host cores.

:func:`local_cluster` starts such a cluster on this machine (``humv-usd sweep --gpus N``): one
single-threaded worker per GPU, ``CUDA_VISIBLE_DEVICES`` its index, the CUDA backend forced (a
GPU that does not work is then an error, never a silent CPU render) and
:data:`GPU_WRITER_THREADS` writer threads, plus CPU workers with no
device visible and the LLVM backend. :func:`worker_commands` writes the ``dask worker`` command
lines of the same set-up for a cluster started by hand.
"""

from __future__ import annotations

import logging
import os

from humv_usd import mode
from humv_usd.errors import InputError
from humv_usd.pipeline.writer import THREADS_ENV

#: Dask resource a GPU worker declares (one per GPU) and a render task asks for
GPU_RESOURCE = "GPU"
#: Dask resource a worker for composes declares and a compose task asks for (when any worker has it)
CPU_RESOURCE = "CPU"
#: backend of the GPU workers of :func:`local_cluster` (:data:`humv_usd.mode.BACKENDS`)
GPU_WORKER_BACKEND = "cuda"
#: backend of its CPU workers
CPU_WORKER_BACKEND = "llvm"
#: writer threads of a GPU worker's renders (:data:`humv_usd.pipeline.writer.THREADS_ENV`): a
#: labelled 1024x768 LWIR frame's files cost 0.35 CPU-s on one core (EXR zip 0.23 of it; measured
#: on this project's 2-core machine, 2026-11-27), so 4 threads keep up with about 11 frames/s; the
#: H100 renders about 0.4 frames/s today (2.59 s per frame)
GPU_WRITER_THREADS = 4


def worker_kinds(workers: dict) -> tuple[int, int]:
    """(GPU workers, CPU-resource workers) of a scheduler's worker table
    (``Client.scheduler_info()["workers"]``: address -> info with ``resources``)."""
    gpu = sum(1 for w in workers.values() if (w.get("resources") or {}).get(GPU_RESOURCE, 0) > 0)
    cpu = sum(1 for w in workers.values() if (w.get("resources") or {}).get(CPU_RESOURCE, 0) > 0)
    return gpu, cpu


def renders_on_gpu(gpu_workers: int) -> bool:
    """Whether render tasks ask for a GPU: some worker has one and the render backend is CUDA (the
    backend auto-detected on those workers, or forced to ``cuda``; the client's
    ``HUMV_USD_BACKEND=llvm`` or ``scalar`` renders on the CPU workers instead). Without GPU
    workers renders run anywhere, as on a cluster that declares no resources."""
    forced = mode.forced_variant()  # the client's HUMV_USD_BACKEND / HUMV_USD_MITSUBA_VARIANT
    return gpu_workers > 0 and (forced is None or forced.startswith("cuda"))


def task_resources(kind: str, gpu_workers: int, cpu_workers: int, on_gpu: bool) -> dict | None:
    """The Dask resources a ``kind`` ("compose" or "render") task asks for (see the module doc)."""
    if kind == "render":
        return {GPU_RESOURCE: 1} if on_gpu else ({CPU_RESOURCE: 1} if cpu_workers else None)
    return {CPU_RESOURCE: 1} if cpu_workers else None


def worker_specs(gpus: int, cpu_workers: int, devices: list[str] | None = None) -> dict:
    """SpecCluster worker specs: ``gpus`` GPU workers (device ``devices[i]``, default ``i``) and
    ``cpu_workers`` CPU workers, each a single-threaded worker process under a nanny."""
    from distributed import Nanny

    devices = devices or [str(i) for i in range(gpus)]
    specs = {}
    for i in range(gpus):
        specs[f"gpu{i}"] = {
            "cls": Nanny,
            "options": {
                "nthreads": 1,
                "resources": {GPU_RESOURCE: 1},
                "env": {
                    "CUDA_VISIBLE_DEVICES": devices[i],
                    mode.BACKEND_ENV: GPU_WORKER_BACKEND,
                    THREADS_ENV: str(GPU_WRITER_THREADS),
                },
            },
        }
    for i in range(cpu_workers):
        specs[f"cpu{i}"] = {
            "cls": Nanny,
            "options": {
                "nthreads": 1,
                "resources": {CPU_RESOURCE: 1},
                "env": {"CUDA_VISIBLE_DEVICES": "", mode.BACKEND_ENV: CPU_WORKER_BACKEND},
            },
        }
    return specs


def local_cluster(gpus: int, cpu_workers: int):
    """A Dask cluster of worker processes on this machine: ``gpus`` GPU workers (GPUs
    ``0..gpus-1``, or the ones ``CUDA_VISIBLE_DEVICES`` lists) and ``cpu_workers`` CPU workers;
    no dashboard."""
    from distributed import Scheduler, SpecCluster

    if gpus < 1 or cpu_workers < 1:
        raise InputError(f"--gpus {gpus} with {cpu_workers} CPU workers: expected >= 1 of each")
    visible = [d.strip() for d in os.environ.get("CUDA_VISIBLE_DEVICES", "").split(",") if d.strip()]
    if visible and len(visible) < gpus:
        raise InputError(
            f"--gpus = {gpus}: CUDA_VISIBLE_DEVICES lists {len(visible)} device(s) ({','.join(visible)})"
        )
    scheduler = {"cls": Scheduler, "options": {"dashboard_address": ":0"}}
    return SpecCluster(
        workers=worker_specs(gpus, cpu_workers, visible[:gpus] or None),
        scheduler=scheduler,
        silence_logs=logging.ERROR,
        name="humv-usd-sweep",
    )


def worker_commands(scheduler: str, gpus: int, cpu_workers: int) -> list[str]:
    """The ``dask worker`` command lines of :func:`local_cluster`'s set-up on one machine of a
    cluster whose scheduler is at ``scheduler`` (run each in its own shell or service)."""
    lines = [
        f"CUDA_VISIBLE_DEVICES={i} {mode.BACKEND_ENV}={GPU_WORKER_BACKEND} {THREADS_ENV}={GPU_WRITER_THREADS} "
        f"dask worker {scheduler} "
        f"--nworkers 1 --nthreads 1 --resources {GPU_RESOURCE}=1 --name $(hostname)-gpu{i}"
        for i in range(gpus)
    ]
    if cpu_workers:
        lines.append(
            f'CUDA_VISIBLE_DEVICES="" {mode.BACKEND_ENV}={CPU_WORKER_BACKEND} dask worker {scheduler} '
            f"--nworkers {cpu_workers} --nthreads 1 --resources {CPU_RESOURCE}=1"
        )
    return lines
