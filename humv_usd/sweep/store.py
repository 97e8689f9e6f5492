"""The dataset folder's bookkeeping: the lock, staging folders, done records and the layer store.

Layout (DATASET/)::

    .sweep/lock                  the lease of the sweep writing here (one at a time): pid, host,
                                 token, heartbeat (refreshed every HEARTBEAT_S seconds)
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

At an fsspec URL (:mod:`humv_usd.sweep.where`; an object store has no rename of folders) the
done record is ``renders/<id>/<chunk>/task.json`` itself, uploaded after every other file of the
task: one object is written whole or not at all, so a record means a complete chunk. A crash
mid-upload leaves files without a record, which the next run renders again and overwrites
(renders are deterministic for the same seeds); a retried task whose first try is still running
uploads identical files.

The lock is a lease: its holder rewrites the heartbeat every ``HEARTBEAT_S`` seconds; a lock
whose heartbeat is older than ``STALE_AFTER`` heartbeats is stale whatever its host (a crashed
client on another machine) and is taken over with one warning; on this host a lock of a dead
process is taken over at once. The hosts' clocks must agree to well under
``STALE_AFTER * HEARTBEAT_S`` (NTP). On a local file system the lock is created exclusively and
a take-over renames the stale file away (only one taker can); an object store has neither, so
there two sweeps starting in the same second could both believe they hold it: the lock is
written, read back after ``SETTLE_S`` and kept only if it is still ours (last writer wins),
which narrows that window but cannot close it.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import shutil
import socket
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path

from humv_usd.errors import InputError
from humv_usd.fileio import atomic_path
from humv_usd.sweep.where import Location

SWEEP_DIR = ".sweep"
LOCK_NAME = "lock"
LOCK_REL = f"{SWEEP_DIR}/{LOCK_NAME}"
#: how often the lock's holder refreshes its heartbeat [s]
HEARTBEAT_S = 30.0
#: a heartbeat older than this many HEARTBEAT_S is stale (its holder is gone)
STALE_AFTER = 4
#: object stores: wait this long after writing the lock before reading it back [s]
SETTLE_S = 1.0
#: a lock file that is not a lock (empty, not JSON, a list, no valid pid/heartbeat) and older than
#: this is taken over; younger, it may be a lock being written this instant [s]
UNREADABLE_GRACE_S = 10.0
#: largest process id a lock may name (Linux's pid_max limit, 2^22); others are not pids
MAX_PID = 4_194_304
TASK_RECORD = "task.json"
COMPOSE_RECORD = "compose.done.json"
log = logging.getLogger(__name__)


def sweep_dir(dataset: Path) -> Path:
    return Path(dataset) / SWEEP_DIR


def _valid_pid(value) -> int | None:
    """A lock's ``pid`` when it is one (an integer in 1..MAX_PID), else None: ``os.kill`` with 0
    or -1 would test a process group or every process, a huge one raises OverflowError."""
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_PID:
        return None
    return value


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _as_location(dataset) -> Location:
    return dataset if isinstance(dataset, Location) else Location(dataset)


def _read_lock(loc: Location) -> dict | None:
    held, _ = _lock_state(loc)
    return held


def _lock_state(loc: Location) -> tuple[dict | None, str | None]:
    """(the lock, None); (None, None) when there is none; (None, what is wrong) when the lock
    file is there but is no lock (empty, not UTF-8 JSON, not an object, a folder)."""
    try:
        text = loc.read_text(LOCK_REL)
    except FileNotFoundError:
        return None, None
    except IsADirectoryError:
        return None, "a folder"
    except (OSError, UnicodeDecodeError) as exc:
        if not loc.exists(LOCK_REL):
            return None, None
        if not loc.remote and loc.local(LOCK_REL).is_dir():
            return None, "a folder"
        return None, f"unreadable ({exc})"
    if not text.strip():
        return None, "empty"
    try:
        held = json.loads(text)
    except ValueError:
        return None, "not JSON"
    if not isinstance(held, dict):
        return None, f"a JSON {type(held).__name__}, not an object"
    return held, None


def _modified(loc: Location) -> float | None:
    """The lock file's modification time [s since the epoch] (None where unknown)."""
    try:
        if not loc.remote:
            return loc.local(LOCK_REL).stat().st_mtime
        return loc.fs.modified(loc.full(LOCK_REL)).timestamp()
    except (OSError, NotImplementedError, AttributeError, ValueError, TypeError):
        return None


def _given_heartbeat(held: dict) -> float | None:
    beat = held.get("heartbeat")
    if isinstance(beat, bool) or not isinstance(beat, (int, float)) or not math.isfinite(beat):
        return None
    return float(beat)


def _heartbeat(loc: Location, held: dict, now: float | None = None, heartbeat_s: float = HEARTBEAT_S):
    """When the holder last showed it is alive [s since the epoch]: its heartbeat, or the lock
    file's modification time for a lock without a usable one (written before leases, NaN, not
    a number) or whose heartbeat lies more than ``STALE_AFTER`` beats in the future of ``now``
    (clock skew, or a hand-edited lock: it would never go stale)."""
    beat = _given_heartbeat(held)
    if beat is not None and (now is None or beat - now <= STALE_AFTER * heartbeat_s):
        return beat
    return _modified(loc)


def _stale_reason(loc: Location, held: dict, now: float, heartbeat_s: float) -> str | None:
    """Why a lock someone else holds can be taken over, or None when it is live."""
    pid = _valid_pid(held.get("pid"))
    if pid is not None and held.get("host") == socket.gethostname() and not _pid_alive(pid):
        return f"pid {pid} on this host is gone"
    given = _given_heartbeat(held)
    limit = STALE_AFTER * heartbeat_s
    if given is not None and given - now > limit:
        skew = f"its heartbeat is {given - now:.0f} s in the future (clock skew?)"
        modified = _modified(loc)
        if modified is None or now - modified > limit or modified - now > limit:
            return skew + (f" and the file is {now - modified:.0f} s old" if modified is not None else "")
        return None
    beat = _heartbeat(loc, held, now, heartbeat_s)
    if beat is None:
        return None
    if beat - now > limit:  # the file's time is in the future too: no live holder wrote it
        return f"its time is {beat - now:.0f} s in the future (clock skew?)"
    if now - beat > limit:
        return f"no heartbeat for {now - beat:.0f} s (more than {STALE_AFTER} x {heartbeat_s:g} s)"
    return None


def _holder_text(loc: Location, held: dict, now: float) -> str:
    beat = _heartbeat(loc, held, now)
    age = f", heartbeat {now - beat:.0f} s ago" if beat is not None else ""
    return f"pid {held.get('pid')} on {held.get('host')}{age}"


def _create_lock(loc: Location, doc: dict) -> bool:
    """Write the lock if there is none; False when one is there. Exclusive on a local file
    system; on an object store best effort (see the module doc)."""
    text = json.dumps(doc)
    if not loc.remote:
        return _create_local(loc.local(LOCK_REL), text.encode("utf-8"), doc["token"])
    if loc.exists(LOCK_REL):
        return False
    loc.write_text(LOCK_REL, text)
    time.sleep(SETTLE_S)
    return (_read_lock(loc) or {}).get("token") == doc["token"]


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _create_local(path: Path, data: bytes, token: str) -> bool:
    """Create ``path`` holding ``data`` only if it does not exist; False when it does. The lock
    appears whole: written to a temp file first, then hard-linked into place (link fails when
    the name exists), so no one ever reads an empty or half-written lock, and a write that
    fails (ENOSPC, EDQUOT) leaves no lock. File systems without hard links: an exclusive create,
    removed again if the write fails."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{token}.tmp")
    fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
    try:
        try:
            _write_all(fd, data)
            os.fsync(fd)
        finally:
            os.close(fd)
        try:
            os.link(tmp, path)
            return True
        except FileExistsError:
            return False
        except OSError:  # no hard links here (EPERM, ENOTSUP, EXDEV)
            pass
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        try:
            _write_all(fd, data)
        except BaseException:
            os.close(fd)
            path.unlink(missing_ok=True)
            raise
        os.close(fd)
        return True
    finally:
        tmp.unlink(missing_ok=True)


def _remove_stale(loc: Location, stale: dict | None) -> None:
    """Remove the stale lock ``stale`` (and only it: a lock another taker wrote meanwhile stays);
    ``stale`` None: a lock file that is no lock (see :func:`_lock_state`)."""
    if not loc.remote:
        path = loc.local(LOCK_REL)
        tomb = path.with_name(f"{LOCK_NAME}.stale-{uuid.uuid4().hex[:8]}")
        try:
            os.rename(path, tomb)  # only one taker moves this file
        except FileNotFoundError:
            return
        try:
            moved = json.loads(tomb.read_text())
        except (OSError, ValueError):
            moved = None
        if stale is not None and moved != stale:  # a newer lock was moved: put it back
            with contextlib.suppress(OSError):
                os.link(tomb, path)
        tomb.unlink(missing_ok=True)
        return
    if _lock_state(loc)[0] == stale:
        loc.remove(LOCK_REL)


class _Lease:
    """The heartbeat of a held lock: a daemon thread rewriting ``heartbeat`` every
    ``heartbeat_s`` while the lock is still ours."""

    def __init__(self, loc: Location, doc: dict, heartbeat_s: float, clock: Callable[[], float]):
        self.loc, self.doc, self.heartbeat_s, self.clock = loc, doc, heartbeat_s, clock
        self.stop = threading.Event()
        self.lost = False
        self.thread = threading.Thread(target=self._run, name="humv-sweep-lock", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.wait(self.heartbeat_s):
            held = _read_lock(self.loc)
            if held is None or held.get("token") != self.doc["token"]:
                self.lost = True
                log.warning(
                    "%s: the sweep lock was taken over by %s; this sweep no longer holds it",
                    self.loc,
                    "nobody" if held is None else f"pid {held.get('pid')} on {held.get('host')}",
                )
                return
            self.doc["heartbeat"] = self.clock()
            try:
                if self.loc.remote:
                    self.loc.write_text(LOCK_REL, json.dumps(self.doc))
                else:
                    with atomic_path(self.loc.local(LOCK_REL)) as tmp:
                        Path(tmp).write_text(json.dumps(self.doc))
            except OSError as exc:  # a full disk or a network error: try again at the next beat
                log.warning("%s: cannot refresh the sweep lock (%s)", self.loc, exc)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


@contextlib.contextmanager
def dataset_lock(dataset, heartbeat_s: float = HEARTBEAT_S, clock: Callable[[], float] = time.time):
    """Hold DATASET/.sweep/lock while a sweep writes (a lease, see the module doc): refuse when
    another live sweep holds it (one line naming its pid, host and the age of its heartbeat);
    take over a stale one with one warning. ``dataset``: a folder, an fsspec URL or a Location;
    ``clock``: the time [s since the epoch] (tests)."""
    loc = _as_location(dataset)
    me = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "token": uuid.uuid4().hex,
        "started": clock(),
        "heartbeat": clock(),
        "heartbeat_s": heartbeat_s,
    }
    for _ in range(3):
        try:
            if _create_lock(loc, me):
                break
        except OSError as exc:  # a full disk, a quota, a read-only folder: no lock is left behind
            raise InputError(
                f"{loc}: cannot create the sweep lock {loc.full(LOCK_REL)} ({exc.strerror or exc})"
            ) from None
        held, wrong = _lock_state(loc)
        if held is None and wrong is None:  # removed meanwhile: try again
            continue
        if wrong == "a folder":
            raise InputError(
                f"{loc}: {loc.full(LOCK_REL)} is a folder, not a sweep lock; remove it if no sweep is running"
            )
        if wrong is not None:
            age = clock() - (_modified(loc) or clock())
            if 0.0 <= age < UNREADABLE_GRACE_S:  # perhaps being written this instant
                raise InputError(
                    f"{loc}: the sweep lock {loc.full(LOCK_REL)} is {wrong} and {age:.0f} s old (another "
                    f"sweep starting?); try again in {UNREADABLE_GRACE_S:g} s"
                )
            log.warning("%s: taking over the sweep lock, which is %s (written %.0f s ago)", loc, wrong, age)
            _remove_stale(loc, None)
            continue
        why = _stale_reason(loc, held, clock(), heartbeat_s)
        if why is None:
            raise InputError(
                f"{loc}: another sweep ({_holder_text(loc, held, clock())}) is writing this dataset; "
                f"wait for it, or remove {loc.full(LOCK_REL)} if that process is gone"
            )
        log.warning(
            "%s: taking over the lock of sweep pid %s on %s: %s", loc, held.get("pid"), held.get("host"), why
        )
        _remove_stale(loc, held)
    else:
        raise InputError(f"{loc}: cannot take the lock {loc.full(LOCK_REL)}")
    lease = _Lease(loc, me, heartbeat_s, clock)
    try:
        yield lease
    finally:
        lease.close()
        held = _read_lock(loc)
        if held and held.get("token") == me["token"]:
            loc.remove(LOCK_REL)


def check_sweep_record(dataset: Path, digest: str, force: bool = False) -> None:
    """A dataset folder belongs to one sweep: refuse a different one (same variants and render
    settings resume; anything else would mix two datasets)."""
    loc = _as_location(dataset)
    rel = f"{SWEEP_DIR}/sweep.json"
    if force or not loc.is_file(rel):
        return
    try:
        old = loc.read_json(rel).get("digest")
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


def done_tasks(dataset) -> set[tuple[str, str]]:
    """(variant, chunk) of every finished render task: one listing of the done records."""
    return {tuple(rel.split("/")[1:3]) for rel in _as_location(dataset).glob(f"renders/*/*/{TASK_RECORD}")}


def compose_done(dataset, variant: str) -> bool:
    return _as_location(dataset).is_file(f"variants/{variant}/{COMPOSE_RECORD}")


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


def store_rel(layer: str, key: str) -> str:
    return f"{SWEEP_DIR}/layers/{layer}/{key}.usda"


def seed_layers_remote(loc: Location, keys: dict[str, str], compose_dir: Path) -> list[str]:
    """:func:`seed_layers` from the store of a dataset at an fsspec URL (downloads)."""
    taken = []
    for layer, key in keys.items():
        dst = compose_dir / "layers" / f"{layer}.usda"
        if dst.is_file() or not loc.is_file(store_rel(layer, key)):
            continue
        with loc.local_copy(store_rel(layer, key)) as src, atomic_path(dst) as tmp:
            shutil.copyfile(src, tmp)
        taken.append(layer)
    return taken


def publish_layers_remote(loc: Location, keys: dict[str, str], compose_dir: Path) -> None:
    """:func:`publish_layers` to the store of a dataset at an fsspec URL (uploads; an equal key
    means an equal layer, so two writers of one key write the same object)."""
    for layer, key in keys.items():
        src = compose_dir / "layers" / f"{layer}.usda"
        if src.is_file() and not loc.is_file(store_rel(layer, key)):
            loc.put_file(src, store_rel(layer, key))


def record_failure(dataset, task: str, error: str, attempts: int) -> None:
    _as_location(dataset).write_json(
        f"{SWEEP_DIR}/failed/{task.replace('/', '_')}.json",
        {"task": task, "error": error, "attempts": attempts},
    )


def clear_failures(dataset) -> None:
    _as_location(dataset).remove(f"{SWEEP_DIR}/failed")
