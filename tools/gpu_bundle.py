"""Build the Python packages the render needs, for a GPU machine without network, as one archive.

A lent GPU machine (docs/user/gpu.md) has Python 3.12, numpy 2.x and scipy but no network, and is
sent at most 64 MiB with the working tree. This downloads (here, where pip works) the wheels of
the render's packages that machine lacks (:data:`CARRY`, the versions of ``requirements.lock``)
for that Python, unpacks them into ``OUT/site``, strips Mitsuba to the variants and plugins the
render loads (:data:`MITSUBA_VARIANTS`, :data:`MITSUBA_PLUGINS`, measured from a render's
``/proc/self/maps``), adds pvlib's ASTM G173 table (all the render reads of pvlib, see
``tools/gpu_check.py``'s ``RENDER_PACKAGES``) and writes ``OUT/site.tar.xz``::

    python tools/gpu_bundle.py .carry            # once, here; .carry ignored by git
    # on the GPU machine (run's carry = [".carry"]):
    tar -xJf .carry/site.tar.xz -C /tmp && export PYTHONPATH=/tmp/site:$PWD
    python3 tools/gpu_check.py needs && python3 tools/gpu_check.py render STAGE --out /tmp/g --backend cuda --export $OUT/g

It prints the archive's size against the 64 MiB limit.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: distributions to carry (the GPU machine's image has numpy, scipy, pillow, pandas, matplotlib
#: and pytest); colour-science only for the tests' CIE reference (tests/test_render_eo.py, which
#: the band and night tests import)
CARRY = ("mitsuba", "drjit", "usd-core", "OpenEXR", "OpenImageIO", "ephem", "pycocotools", "colour-science")
#: Mitsuba variants kept: the render's (``humv_usd.mode``: IR mono and EO spectral on CUDA and
#: LLVM, and the scalar fallback)
MITSUBA_VARIANTS = (
    "cuda_ad_mono",
    "cuda_ad_spectral",
    "llvm_ad_mono",
    "llvm_ad_spectral",
    "scalar_rgb",
    "scalar_spectral",
)
#: Mitsuba plugins kept: those a render loaded (LWIR, EO, NIR and SWIR with the fast estimator
#: and the path tracer, lamps, windows, sky maps; read from /proc/self/maps, 2026-11-27) and the
#: point lamp, the one scene element type (``render.lights``) those stages did not hold
MITSUBA_PLUGINS = (
    "area",
    "box",
    "constant",
    "d65",
    "diffuse",
    "directional",
    "envmap",
    "hdrfilm",
    "independent",
    "mesh_attribute",
    # the scene loader's own shape-merging pass (not named by a scene dict: a scene of an
    # envmap alone asked for it on an H200, 2026-11-27)
    "merge",
    "moment",
    "path",
    "perspective",
    "ply",
    "point",
    "rectangle",
    "regular",
    "spot",
    "uniform",
)
#: the platforms pip may pick for the GPU machine (x86-64 Linux)
PLATFORMS = (
    "manylinux_2_28_x86_64",
    "manylinux_2_27_x86_64",
    "manylinux_2_17_x86_64",
    "manylinux2014_x86_64",
)
#: what a machine is sent at most (the working tree, this archive included)
LIMIT_BYTES = 64 * 2**20


def pinned_versions(lock: Path = ROOT / "requirements.lock") -> dict[str, str]:
    """``name -> version`` of the ``name==version`` lines of the lock file (names lower-case)."""
    out = {}
    for line in lock.read_text().splitlines():
        m = re.match(r"^([A-Za-z0-9_.\-]+)==([^\s;#]+)", line.strip())
        if m:
            out[m.group(1).lower()] = m.group(2)
    return out


def download(out: Path, python: str) -> list[Path]:
    """The wheels of :data:`CARRY` at their pinned versions for ``python`` (e.g. "3.12")."""
    versions = pinned_versions()
    wheels = out / "wheels"
    wheels.mkdir(parents=True, exist_ok=True)
    specs = []
    for name in CARRY:
        if name.lower() not in versions:
            raise SystemExit(f"gpu_bundle: {name} is not pinned in requirements.lock")
        specs.append(f"{name}=={versions[name.lower()]}")
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:"]
    cmd += ["--python-version", python, "--implementation", "cp", "-d", str(wheels)]
    for p in PLATFORMS:
        cmd += ["--platform", p]
    subprocess.run(cmd + specs, check=True)
    return sorted(wheels.glob("*.whl"))


def strip_mitsuba(site: Path) -> int:
    """Remove the Mitsuba variants and plugins the render does not load, its headers, CMake
    files and type stubs; returns the bytes removed."""
    root = site / "mitsuba"
    removed = 0

    def rm(path: Path) -> None:
        nonlocal removed
        if path.is_dir():
            removed += sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
            shutil.rmtree(path)
        elif path.exists():
            removed += path.stat().st_size
            path.unlink()

    variant = re.compile(r"^((?:cuda|llvm)_ad|scalar)_[a-z_]+\.cpython-")
    for f in root.glob("*.so"):
        if variant.match(f.name) and f.name.split(".cpython-")[0] not in MITSUBA_VARIANTS:
            rm(f)
    for f in (root / "plugins").glob("*.so"):
        if f.stem not in MITSUBA_PLUGINS:
            rm(f)
    for name in ("include", "cmake"):
        rm(root / name)
    for f in root.rglob("*.pyi"):
        rm(f)
    return removed


def build(out: Path, python: str = "3.12") -> Path:
    """Download, unpack, strip and archive; returns the archive's path."""
    site = out / "site"
    if site.exists():
        shutil.rmtree(site)
    site.mkdir(parents=True)
    for wheel in download(out, python):
        with zipfile.ZipFile(wheel) as z:
            z.extractall(site)
    removed = strip_mitsuba(site)
    import pvlib  # the ASTM G173 table only (humv_usd.physics.sun.reference_solar_spectrum)

    table = Path(pvlib.__file__).parent / "data" / "ASTMG173.csv"
    (site / "pvlib" / "data").mkdir(parents=True)
    shutil.copy(table, site / "pvlib" / "data" / table.name)
    for cache in site.rglob("__pycache__"):
        shutil.rmtree(cache, ignore_errors=True)
    archive = out / "site.tar.xz"
    with tarfile.open(archive, "w:xz", preset=6) as tar:
        tar.add(site, arcname="site")
    size = archive.stat().st_size
    print(f"{archive}: {size / 2**20:.1f} MiB ({removed / 2**20:.0f} MiB of Mitsuba left out), ", end="")
    print(f"{'within' if size < LIMIT_BYTES else 'OVER'} the {LIMIT_BYTES / 2**20:.0f} MiB a machine is sent")
    return archive


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="folder for the wheels, the unpacked site and site.tar.xz")
    ap.add_argument("--python", default="3.12", help="the GPU machine's Python (default 3.12)")
    args = ap.parse_args(argv)
    archive = build(Path(args.out), args.python)
    return 0 if archive.stat().st_size < LIMIT_BYTES else 1


if __name__ == "__main__":
    sys.exit(main())
