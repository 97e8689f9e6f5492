"""Where a dataset lives: a POSIX folder, or any fsspec URL (``s3://bucket/prefix``,
``gs://...``, ``file:///...``, ``memory://...``).

:class:`Location` gives the sweep one set of file operations, by paths relative to the dataset's
root ("renders/v0000/f0000-0003/task.json"):

* a plain path: the local file system, writes atomic (:mod:`humv_usd.fileio`), folders renamed
  into place (:mod:`humv_usd.sweep.store`);
* a URL (``://``): an fsspec file system. An object store has no atomic rename of folders and
  no exclusive create, but one object is written whole or not at all; so a task's files are
  uploaded first and its ``task.json`` (the done record) last (:meth:`Location.put_folder`),
  and a reader believes a chunk only when its record is there. The workers render into a local
  staging folder (:func:`local_cache`) and upload.

The fsspec back end of a protocol is its own package: ``s3fs`` for ``s3://``, ``gcsfs`` for
``gs://``, ``adlfs`` for ``az://`` (fsspec names the one missing); ``file://`` and
``memory://`` come with fsspec.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import fsspec

from humv_usd.errors import InputError
from humv_usd.fileio import atomic_path, jsonable, write_json, write_text_atomic


def is_url(location) -> bool:
    """True for an fsspec URL (``protocol://...``), False for a plain path."""
    return "://" in os.fspath(location)


def _json_text(data) -> str:
    """The text :func:`humv_usd.fileio.write_json` writes."""
    return json.dumps(jsonable(data), indent=2, allow_nan=False) + "\n"


def local_cache(url: str) -> Path:
    """This machine's working folder for the dataset at ``url`` (composed variants, staging):
    ``$HUMV_SWEEP_CACHE`` or the temporary folder, then ``humv-sweep/<hash of the URL>``."""
    base = Path(os.environ.get("HUMV_SWEEP_CACHE") or Path(tempfile.gettempdir()) / "humv-sweep")
    return base / hashlib.sha256(url.encode()).hexdigest()[:16]


class Location:
    """A dataset's root, local or behind fsspec (see the module doc)."""

    def __init__(self, location):
        self.url = os.fspath(location)
        self.remote = is_url(self.url)
        if self.remote:
            try:
                self.fs, root = fsspec.core.url_to_fs(self.url)
            except ImportError as exc:  # fsspec: "Install s3fs to access S3"
                raise InputError(f"dataset folder {self.url!r}: {exc}") from None
            except (ValueError, TypeError) as exc:
                raise InputError(f"dataset folder {self.url!r}: not a usable fsspec URL ({exc})") from None
            self.root = root.rstrip("/")
            self.path = None
        else:
            self.fs = None
            self.path = Path(self.url)
            self.root = str(self.path)

    def __str__(self) -> str:
        return self.url

    def full(self, rel: str) -> str:
        """The file system's path of ``rel`` (a local path, or the fsspec path without protocol)."""
        return f"{self.root}/{rel}" if rel else self.root

    def local(self, rel: str = "") -> Path:
        """The local path of ``rel`` (plain paths only)."""
        assert self.path is not None, "a remote dataset has no local path"
        return self.path / rel if rel else self.path

    # ------------------------------------------------------------------ reads
    def is_file(self, rel: str) -> bool:
        if not self.remote:
            return self.local(rel).is_file()
        return self.fs.isfile(self.full(rel))

    def exists(self, rel: str) -> bool:
        if not self.remote:
            return self.local(rel).exists()
        return self.fs.exists(self.full(rel))

    def read_bytes(self, rel: str) -> bytes:
        if not self.remote:
            return self.local(rel).read_bytes()
        return self.fs.cat_file(self.full(rel))

    def read_text(self, rel: str) -> str:
        return self.read_bytes(rel).decode("utf-8")

    def read_json(self, rel: str):
        return json.loads(self.read_text(rel))

    def glob(self, pattern: str) -> list[str]:
        """Paths relative to the root of the files matching ``pattern`` (e.g. ``renders/*/*/task.json``)."""
        if not self.remote:
            return sorted(p.relative_to(self.path).as_posix() for p in self.path.glob(pattern))
        prefix = self.root + "/"
        return sorted(p.removeprefix(prefix) for p in self.fs.glob(self.full(pattern)))

    @contextlib.contextmanager
    def local_copy(self, rel: str):
        """A local file holding ``rel`` (itself for a plain path; a temporary download otherwise)."""
        if not self.remote:
            yield self.local(rel)
            return
        with tempfile.TemporaryDirectory(prefix="humv-get-") as tmp:
            dst = Path(tmp) / Path(rel).name
            self.fs.get_file(self.full(rel), str(dst))
            yield dst

    def get_folder(self, rel: str, dst: Path, last: str | None = None) -> None:
        """Download every file under ``rel`` into ``dst`` (same relative layout), the file named
        ``last`` (a done record) removed first and fetched after all the others (concurrently on
        an asynchronous file system)."""
        prefix = self.full(rel).rstrip("/") + "/"
        pairs = [(path, dst / path.removeprefix(prefix)) for path in self.fs.find(self.full(rel))]
        record = [(path, target) for path, target in pairs if last and target == dst / last]
        rest = [pair for pair in pairs if pair not in record]
        if last:
            (dst / last).unlink(missing_ok=True)
        for parent in sorted({target.parent for _, target in pairs}):
            parent.mkdir(parents=True, exist_ok=True)
        if rest:
            self.fs.get([path for path, _ in rest], [str(target) for _, target in rest])
        for path, target in record:
            with atomic_path(target) as tmp:
                self.fs.get_file(path, tmp)

    # ------------------------------------------------------------------ writes
    @contextlib.contextmanager
    def writing(self, rel: str):
        """Yield a local temporary path (same file name) to write ``rel``; it is moved (local,
        atomically) or uploaded (one object) when the block ends without an exception."""
        if not self.remote:
            with atomic_path(self.local(rel)) as tmp:
                yield tmp
            return
        with tempfile.TemporaryDirectory(prefix="humv-put-") as tmp:
            src = Path(tmp) / Path(rel).name
            yield str(src)
            self.put_file(src, rel)

    def write_text(self, rel: str, text: str) -> None:
        if not self.remote:
            write_text_atomic(self.local(rel), text)
            return
        self._pipe(rel, text.encode("utf-8"))

    def write_json(self, rel: str, data) -> None:
        if not self.remote:
            write_json(self.local(rel), data)
            return
        self._pipe(rel, _json_text(data).encode("utf-8"))

    def _pipe(self, rel: str, data: bytes) -> None:
        """One object written whole (its parent folder made where the file system has folders)."""
        self.fs.makedirs(self.full(rel).rsplit("/", 1)[0], exist_ok=True)
        self.fs.pipe_file(self.full(rel), data)

    def put_file(self, src: Path, rel: str) -> int:
        """Upload (or copy) one local file; returns its size [bytes]."""
        if not self.remote:
            with atomic_path(self.local(rel)) as tmp:
                shutil.copyfile(src, tmp)
        else:
            self.fs.makedirs(self.full(rel).rsplit("/", 1)[0], exist_ok=True)
            self.fs.put_file(str(src), self.full(rel))
        return Path(src).stat().st_size

    def put_folder(self, src: Path, rel: str, last: str | None = None) -> int:
        """Upload every file under ``src`` to ``rel``/..., the file named ``last`` (the done
        record) after all the others; returns the bytes uploaded."""
        files = sorted(p for p in Path(src).rglob("*") if p.is_file())
        pairs = [(p, f"{rel}/{p.relative_to(src).as_posix()}") for p in files]
        first = [(p, r) for p, r in pairs if p.relative_to(src).as_posix() != last]
        self._put_many(first)  # then the record, once all of these are there
        for p, r in pairs:
            if p.relative_to(src).as_posix() == last:
                self.put_file(p, r)
        return sum(p.stat().st_size for p in files)

    def _put_many(self, pairs: list[tuple[Path, str]]) -> None:
        """Upload files (local path, relative path); concurrently on an asynchronous file system
        (s3fs, gcsfs: one ``put`` of lists), one by one otherwise."""
        if not self.remote or not pairs:
            for p, r in pairs:
                self.put_file(p, r)
            return
        for parent in sorted({self.full(r).rsplit("/", 1)[0] for _, r in pairs}):
            self.fs.makedirs(parent, exist_ok=True)
        self.fs.put([str(p) for p, _ in pairs], [self.full(r) for _, r in pairs])

    def copy(self, src_rel: str, dst_rel: str) -> None:
        """Copy a file within the dataset (a hard link locally when possible)."""
        if not self.remote:
            dst = self.local(dst_rel)
            dst.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.link(self.local(src_rel), dst)
            except OSError:
                shutil.copyfile(self.local(src_rel), dst)
            return
        self.fs.makedirs(self.full(dst_rel).rsplit("/", 1)[0], exist_ok=True)
        self.fs.copy(self.full(src_rel), self.full(dst_rel))

    def remove(self, rel: str) -> None:
        """Remove a file or a folder tree; nothing if it is not there."""
        if not self.remote:
            p = self.local(rel)
            if p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
            else:
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
            return
        with contextlib.suppress(FileNotFoundError):
            if self.fs.exists(self.full(rel)):
                self.fs.rm(self.full(rel), recursive=True)
