"""The dataset folder's bookkeeping: the lock, staging folders, done records and the layer store.

Layout (DATASET/)::

    .sweep/lock                  pid and host of the sweep writing here (one at a time)
    .sweep/sweep.json            the sweep's digest, variants and settings
    .sweep/staging/<task>-<uid>/ a render task's outputs while it runs
    .sweep/layers/<layer>/<key>.usda  every composed layer by cache key (shared between variants)
    .sweep/failed/<task>.json    a task that failed after its retries (its error)
    variants/<id>/               the variant's scenario.toml, composed stage and compose.done.json
    renders/<id>/f<first>-<last>/ a finished render task: render outputs + task.json

A render task writes into its own staging folder and renames it into ``renders/`` when it is
complete (one ``rename``: atomic on a POSIX file system); the renamed folder is the task's done
record. A crash leaves at most a staging folder, removed by the next run. Two tasks finishing
the same chunk (a retried task whose first try was still running) cannot both land: the second
rename fails and its copy is removed.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import socket
import uuid
from pathlib import Path

from humv_usd.errors import InputError
from humv_usd.fileio import atomic_path, write_json

SWEEP_DIR = ".sweep"
LOCK_NAME = "lock"
TASK_RECORD = "task.json"
COMPOSE_RECORD = "compose.done.json"
log = logging.getLogger(__name__)


def sweep_dir(dataset: Path) -> Path:
    return Path(dataset) / SWEEP_DIR


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _read_lock(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


@contextlib.contextmanager
def dataset_lock(dataset: Path):
    """Hold DATASET/.sweep/lock (pid, host) while a sweep writes; refuse when another live sweep
    holds it. A lock left by a dead process on this host (a crash, kill -9) is taken over."""
    path = sweep_dir(dataset) / LOCK_NAME
    path.parent.mkdir(parents=True, exist_ok=True)
    me = {"pid": os.getpid(), "host": socket.gethostname()}
    for _ in range(3):
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            held = _read_lock(path)
            if held and held.get("host") == me["host"] and not _pid_alive(int(held.get("pid", -1))):
                log.info("taking over the lock of dead sweep pid %s", held.get("pid"))
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()
                continue
            if held is None:  # being written this instant by another sweep, or garbage
                raise InputError(
                    f"{dataset}: another sweep is starting in this folder ({path}); try again"
                ) from None
            raise InputError(
                f"{dataset}: another sweep (pid {held.get('pid')} on {held.get('host')}) is writing this "
                f"dataset; wait for it, or remove {path} if that process is gone"
            ) from None
        with os.fdopen(fd, "w") as f:
            json.dump(me, f)
        break
    else:
        raise InputError(f"{dataset}: cannot take the lock {path}")
    try:
        yield path
    finally:
        held = _read_lock(path)
        if held and held.get("pid") == me["pid"]:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()


def check_sweep_record(dataset: Path, digest: str, force: bool = False) -> None:
    """A dataset folder belongs to one sweep: refuse a different one (same variants and render
    settings resume; anything else would mix two datasets)."""
    path = sweep_dir(dataset) / "sweep.json"
    if not path.is_file() or force:
        return
    try:
        old = json.loads(path.read_text()).get("digest")
    except (OSError, ValueError):
        return
    if old != digest:
        raise InputError(
            f"{dataset}: holds another sweep (digest {old}, this one {digest}: other variants or render "
            "settings); use a new folder"
        )


def clean_staging(dataset: Path) -> int:
    """Remove staging folders of tasks that did not finish (the lock guarantees no live task of
    this dataset is writing). Returns how many were removed."""
    staging = sweep_dir(dataset) / "staging"
    n = 0
    if staging.is_dir():
        for p in staging.iterdir():
            shutil.rmtree(p, ignore_errors=True)
            n += 1
    return n


def staging_folder(dataset: Path, name: str) -> Path:
    path = sweep_dir(dataset) / "staging" / f"{name.replace('/', '_')}-{uuid.uuid4().hex[:8]}"
    path.mkdir(parents=True)
    return path


def render_folder(dataset: Path, variant: str, chunk: str) -> Path:
    return Path(dataset) / "renders" / variant / chunk


def commit(staging: Path, final: Path) -> bool:
    """Rename a complete staging folder into place; False (and the copy removed) when another
    try of the same task landed first."""
    final.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.rename(staging, final)
        return True
    except OSError:
        if (final / TASK_RECORD).is_file():
            shutil.rmtree(staging, ignore_errors=True)
            return False
        raise


def task_done(dataset: Path, variant: str, chunk: str) -> bool:
    return (render_folder(dataset, variant, chunk) / TASK_RECORD).is_file()


def compose_done(dataset: Path, variant: str) -> bool:
    return (Path(dataset) / "variants" / variant / COMPOSE_RECORD).is_file()


# ---------------------------------------------------------------- the shared layer store
def store_path(dataset: Path, layer: str, key: str) -> Path:
    return sweep_dir(dataset) / "layers" / layer / f"{key}.usda"


def seed_layers(dataset: Path, keys: dict[str, str], compose_dir: Path) -> list[str]:
    """Copy the store's layers with the variant's keys into its compose folder (compose then
    finds them cached). Returns the layers taken from the store."""
    taken = []
    for layer, key in keys.items():
        src = store_path(dataset, layer, key)
        dst = compose_dir / "layers" / f"{layer}.usda"
        if not src.is_file() or dst.is_file():
            continue
        with atomic_path(dst) as tmp:
            shutil.copyfile(src, tmp)
        taken.append(layer)
    return taken


def publish_layers(dataset: Path, keys: dict[str, str], compose_dir: Path) -> None:
    """Put the variant's composed layers into the store (atomically; first writer wins)."""
    for layer, key in keys.items():
        dst = store_path(dataset, layer, key)
        src = compose_dir / "layers" / f"{layer}.usda"
        if dst.is_file() or not src.is_file():
            continue
        with atomic_path(dst) as tmp:
            shutil.copyfile(src, tmp)


def record_failure(dataset: Path, task: str, error: str, attempts: int) -> None:
    write_json(
        sweep_dir(dataset) / "failed" / f"{task.replace('/', '_')}.json",
        {"task": task, "error": error, "attempts": attempts},
    )


def clear_failures(dataset: Path) -> None:
    shutil.rmtree(sweep_dir(dataset) / "failed", ignore_errors=True)
