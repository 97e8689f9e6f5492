"""Atomic file writes: every output goes to a temp name beside it and is renamed into place."""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
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
