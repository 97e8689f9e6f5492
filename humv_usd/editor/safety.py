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
