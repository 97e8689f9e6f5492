"""What the editor may touch: files under the scenario's folder and the output folder only.

Every path that comes from the page (a link, a file key, an upload name) goes through
:func:`inside` before it is opened; uploads are size-limited and keep only a plain file name.
Nothing here (or anywhere in the editor) builds a shell command from user text: jobs are argument
lists (:mod:`humv_usd.editor.jobs`).
"""

from __future__ import annotations

import re
from pathlib import Path

from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import atomic_path

#: largest upload accepted [bytes] (a BVH take, a weather series, a USD asset)
MAX_UPLOAD_BYTES = 64 * 1024 * 1024
#: file types a user may upload into the scenario folder
UPLOAD_SUFFIXES = (".bvh", ".csv", ".usd", ".usda", ".usdc", ".usdz", ".toml", ".obj", ".gltf", ".glb")
_PLAIN_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\- ]{0,200}$")


def inside(root: Path, relative: str, what: str = "path") -> Path:
    """``root / relative`` resolved (symlinks followed), refused unless it stays under ``root``.

    Raises
    ------
    InputError
        For absolute paths, ``..`` escapes, NUL bytes or a symlink leading out of ``root``.
    """
    text = str(relative)
    if "\x00" in text:
        raise InputError(bad_value(what, text, "contains a NUL byte"))
    base = Path(root).resolve()
    candidate = Path(text)
    if candidate.is_absolute():
        raise InputError(bad_value(what, text, f"expected a path relative to {base}"))
    resolved = (base / candidate).resolve()
    if resolved != base and base not in resolved.parents:
        raise InputError(bad_value(what, text, f"outside {base} (the editor reads and writes only there)"))
    return resolved


def upload_target(root: Path, name: str, size: int) -> Path:
    """Where an upload named ``name`` of ``size`` bytes goes under ``root``; refused when too
    large, of a type the scenario cannot use, or not a plain file name."""
    if size > MAX_UPLOAD_BYTES:
        raise InputError(bad_value("upload", name, f"{size} bytes; at most {MAX_UPLOAD_BYTES} bytes"))
    if not _PLAIN_NAME.match(name) or ".." in name:
        raise InputError(
            bad_value("upload", name, "expected a plain file name (letters, digits, _ - . space)")
        )
    if not name.lower().endswith(UPLOAD_SUFFIXES):
        raise InputError(bad_value("upload", name, "allowed types: " + ", ".join(UPLOAD_SUFFIXES)))
    return inside(root, name, "upload")


class UploadExists(InputError):
    """An upload would replace a file of the same name: only on an explicit replace."""


def store_upload(root: Path, name: str, data: bytes, replace: bool = False, check=None) -> Path:
    """Write an upload under ``root`` atomically (temp file + rename); returns its path.

    Parameters
    ----------
    root : Path
        The scenario's folder.
    name : str
        The upload's file name (checked by :func:`upload_target`).
    data : bytes
        Its content.
    replace : bool
        Replace a file of that name (the page asks first); without it an existing file is kept.
    check : callable, optional
        ``check(path, data)`` raises :class:`InputError` when ``data`` must not replace ``path``
        (the scenario being edited replaced by bytes that are not a valid scenario).

    Raises
    ------
    UploadExists
        When a file of that name exists and ``replace`` is False.
    InputError
        For a bad name, size or type, a folder of that name, or content ``check`` refuses.
    """
    target = upload_target(root, name, len(data))
    if target.is_dir():
        raise InputError(bad_value("upload", name, "a folder of that name exists"))
    if target.exists() and not replace:
        raise UploadExists(
            bad_value("upload", name, "a file of that name exists; choose Replace to overwrite it")
        )
    if check is not None:
        check(target, data)
    with atomic_path(target) as tmp:
        Path(tmp).write_bytes(data)
    return target


def sweep_base(root: Path, sweep_path: Path, sweep_doc) -> Path | None:
    """The base scenario a sweep file names (``[sweep] base``), refused unless it resolves under
    ``root`` like every other file the editor reads; None when the file names no base (the sweep
    loader reports that)."""
    head = sweep_doc.get("sweep") if hasattr(sweep_doc, "get") else None
    base = head.get("base") if hasattr(head, "get") else None
    if not isinstance(base, str):
        return None
    where = Path(sweep_path).resolve().parent
    try:
        relative = str(where.relative_to(Path(root).resolve()) / base)
    except ValueError:
        raise InputError(bad_value("sweep file", str(sweep_path), f"outside {root}")) from None
    return inside(root, relative, "sweep.base")
