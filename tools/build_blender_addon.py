"""Zip the Blender add-on ``tools/blender_addon/humv_usd_avatar`` for Blender's installer.

    .venv/bin/python tools/build_blender_addon.py            # -> dist/humv_usd_avatar.zip
    .venv/bin/python tools/build_blender_addon.py -o other.zip

The zip holds the folder ``humv_usd_avatar/`` (the add-on's ``__init__.py`` and the README of
``tools/blender_addon``), which is what Edit > Preferences > Add-ons > Install from Disk (and
``bpy.ops.preferences.addon_install``) expects. The archive is reproducible (sorted names,
fixed time stamps), written atomically, and left untouched when its bytes would not change.
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "tools" / "blender_addon"
ADDON = "humv_usd_avatar"
DEFAULT_OUT = ROOT / "dist" / f"{ADDON}.zip"
_EPOCH = (1980, 1, 1, 0, 0, 0)  # earliest time a zip entry can carry


def addon_files() -> list[tuple[str, Path]]:
    """(name in the zip, file) pairs: the add-on's files and the README next to it."""
    folder = SOURCE / ADDON
    files = [
        (f"{ADDON}/{p.relative_to(folder).as_posix()}", p)
        for p in sorted(folder.rglob("*"))
        if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc"
    ]
    readme = SOURCE / "README.md"
    if readme.is_file():
        files.append((f"{ADDON}/README.md", readme))
    return sorted(files)


def zip_bytes() -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, path in addon_files():
            info = zipfile.ZipInfo(name, date_time=_EPOCH)
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, path.read_bytes())
    return buf.getvalue()


def _fileio():
    """The project's atomic writer, ``humv_usd/fileio.py``, loaded on its own: importing the
    ``humv_usd`` package would load USD, which zipping does not need."""
    spec = importlib.util.spec_from_file_location("_humv_usd_fileio", ROOT / "humv_usd" / "fileio.py")
    module = importlib.util.module_from_spec(spec)
    # registered before it runs: its dataclasses look their module up in sys.modules
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def build(out: str | Path = DEFAULT_OUT) -> tuple[Path, bool]:
    """Write the add-on zip to ``out`` (creating its folder); returns (path, written)."""
    out = Path(out)
    data = zip_bytes()
    if out.is_file() and out.read_bytes() == data:
        return out, False
    with _fileio().atomic_path(out) as tmp:
        Path(tmp).write_bytes(data)
    return out, True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "-o",
        "--out",
        type=Path,
        default=DEFAULT_OUT,
        help=f"zip to write (default: {DEFAULT_OUT.relative_to(ROOT)})",
    )
    args = parser.parse_args(argv)
    path, written = build(args.out)
    print(f"{path}  ({'written' if written else 'unchanged'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
