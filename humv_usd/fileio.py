"""Atomic file writes: every output goes to a temp name beside it and is renamed into place."""

from __future__ import annotations

import contextlib
import filecmp
import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from humv_usd.errors import InputError, bad_value


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path`` (same extension); move it into place on success.

    The temp file gets the usual mode (0666 & ~umask; mkstemp alone would leave 0600). On any
    exception the temp file is removed and ``path`` is untouched.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    stem, ext = os.path.splitext(os.path.basename(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{stem}.", suffix=f".tmp{ext}", dir=directory)
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.remove(tmp)
        raise


def write_text_atomic(path, text: str) -> bool:
    """Write text atomically. Returns False (and writes nothing, keeping the mtime) when the file
    already holds exactly this text."""
    path = Path(path)
    try:
        if path.read_text(encoding="utf-8") == text:
            return False
    except (FileNotFoundError, UnicodeDecodeError, IsADirectoryError):
        pass
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
    return True


def jsonable(obj):
    """Replace non-finite floats by None (JSON has no inf/NaN) and numpy scalars by Python ones."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_json(path, data) -> None:
    """Write ``data`` as indented JSON atomically (non-finite floats become null)."""
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(jsonable(data), f, indent=2, allow_nan=False)
            f.write("\n")


#: longest file or folder name most file systems accept (ext4, xfs, btrfs, APFS, NTFS: 255 bytes)
NAME_MAX = 255
#: longest path Linux accepts in one system call (PATH_MAX)
PATH_MAX = 4096


def check_output_dir(out_dir, what: str = "output folder") -> Path:
    """Check before any work that ``out_dir`` can be (or already is) a writable folder.

    Returns the folder as a Path. Raises InputError (one line naming the folder, the reason
    and what is allowed) for an empty path, an existing file (or a file where a parent folder
    should be), a name longer than NAME_MAX bytes or a path longer than PATH_MAX, and a folder
    (or the nearest existing parent) where nothing can be written (read-only, /proc, no
    permission). Writability is probed by making and removing a hidden temporary folder, so
    that it also holds for root and read-only mounts, where ``os.access`` says yes. Nothing is
    left behind.
    """
    text = os.fspath(out_dir)
    shown = text if len(text) <= 80 else f"{text[:60]}... ({len(text)} characters)"

    def fail(reason: str):
        raise InputError(f"{what} {shown!r}: {reason}")

    if not text.strip():
        raise InputError(bad_value(what, text, "expected a folder path (empty means nowhere)"))
    path = Path(text)
    if len(os.fsencode(text)) >= PATH_MAX:
        fail(f"path of {len(os.fsencode(text))} bytes; at most {PATH_MAX - 1}")
    for part in path.parts:
        if len(os.fsencode(part)) > NAME_MAX:
            fail(f"a folder name of {len(os.fsencode(part))} bytes; at most {NAME_MAX} per name")
    if path.exists() and not path.is_dir():
        fail("is a file, expected a folder (new or existing)")
    existing = path
    while not existing.exists():
        if existing.is_symlink():  # mkdir would fail with FileExistsError (a traceback, issue 26)
            fail(f"{existing} is a symbolic link to a missing target or a loop of links")
        parent = existing.parent
        if parent == existing:
            break
        existing = parent
    if existing != path and not existing.is_dir():
        fail(f"{existing} is a file, so no folder can be made under it")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".humv-write-probe-", dir=existing))
    except OSError as exc:
        fail(f"cannot write in {existing} ({exc.strerror or exc})")
    return path


def check_output_file(path, what: str = "output file") -> Path:
    """Check before any work that a file can be written at ``path``: not empty, not a folder,
    a name of at most NAME_MAX bytes, and a parent folder that is (or can be made) writable
    (:func:`check_output_dir`). Returns the path; raises InputError (one line) otherwise."""
    text = os.fspath(path)
    if not text.strip():
        raise InputError(bad_value(what, text, "expected a file path (empty means nowhere)"))
    target = Path(text)
    if len(os.fsencode(target.name)) > NAME_MAX:
        raise InputError(
            f"{what} {text[:60]!r}...: a file name of {len(os.fsencode(target.name))} bytes; at most {NAME_MAX}"
        )
    if target.is_dir() or text.endswith(os.sep):
        raise InputError(f"{what} {text!r}: is a folder, expected a file path")
    check_output_dir(target.parent if str(target.parent) else ".", f"{what}'s folder")
    return target


# ------------------------------------------------------------------ several files as one write
#: the journal of a write of several files (:func:`commit_files`), in the folder they live in
PENDING_NAME = ".humv-pending.json"


def _make_parents(path: Path) -> tuple[Path, ...]:
    """Create the missing folders above ``path``; return those it created, outermost first
    (for :func:`_remove_made`, so that a failed write leaves no folder it made)."""
    missing = []
    parent = path.parent
    while not parent.exists():
        missing.append(parent)
        if parent.parent == parent:
            break
        parent = parent.parent
    path.parent.mkdir(parents=True, exist_ok=True)
    return tuple(reversed(missing))


def _remove_made(folders) -> None:
    """Remove the folders a failed write created (:func:`_make_parents`), innermost first,
    where they are still empty (another writer's or the user's files keep them)."""
    for folder in sorted(set(folders), key=lambda f: len(f.parts), reverse=True):
        with contextlib.suppress(OSError):
            folder.rmdir()


def _temp_beside(path: Path) -> Path:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    os.close(fd)
    return Path(tmp)


@dataclass(frozen=True)
class StagedText:
    """A text already written to a temp file beside its target (:func:`stage_text`), for
    :func:`commit_files`: a writer that makes many large files can write each as soon as it
    is made and drop it from memory, and still commit them all as one change."""

    tmp: Path
    #: the folders :func:`stage_text` created for it (removed again by :func:`discard_staged`)
    made: tuple[Path, ...] = ()

    def read(self) -> str:
        return self.tmp.read_text(encoding="utf-8")

    def same_as(self, path: Path) -> bool:
        try:
            return filecmp.cmp(self.tmp, path, shallow=False)
        except (FileNotFoundError, IsADirectoryError):
            return False


def stage_text(path, text: str) -> StagedText:
    """Write ``text`` to a temp file beside ``path`` (named as :func:`remove_stale_temps`
    removes it after a kill) and return it for :func:`commit_files`."""

    def write(tmp: Path) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    return stage_file(path, write)


def stage_file(path, write) -> StagedText:
    """Call ``write(tmp)`` on a temp file beside ``path`` (same suffix, e.g. ``.tmp.exr``, so
    that image writers pick the format from it) and return it for :func:`commit_files`, which
    moves it into place with the other files of its change (any file, text or binary)."""
    path = Path(path)
    made = _make_parents(path)
    try:
        tmp = _temp_beside(path)
        try:
            write(tmp)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.remove(tmp)
            raise
    except BaseException:
        _remove_made(made)
        raise
    return StagedText(tmp, made)


def discard_staged(texts) -> None:
    """Remove the temp files of the :class:`StagedText` values of ``texts`` (a failed change),
    and the folders staging them created, where nothing else is in them."""
    staged = [text for text in texts if isinstance(text, StagedText)]
    for text in staged:
        with contextlib.suppress(FileNotFoundError):
            os.remove(text.tmp)
    _remove_made(f for text in staged for f in text.made)


def commit_files(folder, texts: dict, remove=()) -> list[Path]:
    """Write several text files under ``folder`` (and remove ``remove``) as one change.

    A kill at any moment leaves the old files or, once the journal ``folder/PENDING_NAME`` is
    written, the new ones: every new text goes to a temp file beside its target first; then
    the journal (written atomically: the commit point) lists the renames and removals; then they
    are done and the journal removed. :func:`finish_pending` completes a change that a kill
    interrupted after the commit point (and removes the temp files of one interrupted before
    it). Files whose text is already on disk are not rewritten. Returns the paths written.
    """
    folder = Path(folder)
    replace, written, made = [], [], []
    try:
        for path, text in texts.items():
            path = Path(path)
            if isinstance(text, StagedText):  # written already: keep it only if it changes the file
                if text.same_as(path):
                    os.remove(text.tmp)
                    continue
                os.chmod(text.tmp, 0o666 & ~_umask())
                replace.append((text.tmp, path))
                written.append(path)
                continue
            try:
                if path.read_text(encoding="utf-8") == text:
                    continue
            except (FileNotFoundError, UnicodeDecodeError, IsADirectoryError):
                pass
            made += _make_parents(path)
            tmp = _temp_beside(path)
            replace.append((tmp, path))
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(text)
            os.chmod(tmp, 0o666 & ~_umask())
            written.append(path)
        removals = [Path(p) for p in remove if Path(p).exists()]
        if not replace and not removals:
            return []
        journal = {
            "replace": [[os.path.relpath(t, folder), os.path.relpath(p, folder)] for t, p in replace],
            "remove": [os.path.relpath(p, folder) for p in removals],
        }
        write_json(folder / PENDING_NAME, journal)  # the commit point
    except BaseException:
        for tmp, _ in replace:
            with contextlib.suppress(FileNotFoundError):
                os.remove(tmp)
        discard_staged(texts.values())
        _remove_made(made)
        raise
    finish_pending(folder)
    return written


def finish_pending(folder) -> bool:
    """Complete the change :func:`commit_files` journaled in ``folder`` (renames whose temp
    file is still there, removals), then drop the journal. Returns whether there was one.
    Call it while holding the folder's lock (:func:`folder_lock`)."""
    folder = Path(folder)
    journal_path = folder / PENDING_NAME
    try:
        journal = json.loads(journal_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return False
    except (OSError, ValueError):  # written atomically, so never partial; unreadable: drop it
        journal = {}
    for tmp, final in journal.get("replace", []):
        with contextlib.suppress(FileNotFoundError):  # already moved before the kill
            os.replace(folder / tmp, folder / final)
    for name in journal.get("remove", []):
        with contextlib.suppress(FileNotFoundError):
            os.remove(folder / name)
    os.remove(journal_path)
    return True


def remove_stale_temps(folder, patterns=(".*.tmp.*",)) -> list[Path]:
    """Remove temp files a killed writer left in ``folder`` (:func:`atomic_path` names them
    ``.<stem>.<random>.tmp<ext>``). Call it while holding the folder's lock."""
    removed = []
    folder = Path(folder)
    if not folder.is_dir():
        return removed
    for pattern in patterns:
        for p in folder.glob(pattern):
            if p.is_file() and ".tmp" in p.name and p.name != PENDING_NAME:
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
                    removed.append(p)
    return removed


# ------------------------------------------------------------------ one writer per folder
#: the lock file of a folder being written (holds the writer's pid and command)
LOCK_NAME = ".humv.lock"


def _lock_holder(path: Path) -> str:
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
        return f"{info.get('command', 'humv-usd')} (pid {info.get('pid')}, started {info.get('started')})"
    except (OSError, ValueError):
        return "another process (pid unknown)"


@contextlib.contextmanager
def folder_lock(folder, command: str, wait: bool = False, poll_s: float = 0.2):
    """Hold the write lock of ``folder`` (created if missing) while the block runs.

    The lock is an ``fcntl.flock`` on ``folder/LOCK_NAME``, so the kernel drops it when its
    holder dies (kill -9 included): a lock file left behind by a dead process is stale and
    taken over (its pid is in the file, not in the lock). When another live process holds it,
    raise InputError naming that process (pid, command, start), or with ``wait`` poll until it
    is free. The lock file is removed on release, and a folder the lock created is removed
    again when it is still empty.
    """
    import datetime as _dt
    import fcntl
    import time

    folder = Path(folder)
    created = not folder.exists()
    path = folder / LOCK_NAME
    while True:
        folder.mkdir(parents=True, exist_ok=True)  # again: a writer we waited for may remove it
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666 & ~_umask())
        except FileNotFoundError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            if not wait:
                if created:
                    with contextlib.suppress(OSError):
                        folder.rmdir()
                raise InputError(
                    f"{folder}: being written by {_lock_holder(path)}; wait for it to finish, "
                    "or pass --wait to wait here"
                ) from None
            time.sleep(poll_s)
            continue
        try:  # the file may have been removed (and made anew) by the holder we waited for
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        info = {
            "pid": os.getpid(),
            "command": command,
            "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        }
        os.ftruncate(fd, 0)
        os.write(fd, (json.dumps(info) + "\n").encode())
        yield folder
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.remove(path)
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
        if created:
            with contextlib.suppress(OSError):
                folder.rmdir()  # only when empty
