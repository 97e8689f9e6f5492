"""The one place that imports Mitsuba and chooses its variant.

Everything else gets the configured module from :func:`mitsuba`. Infrared bands need a *mono*
variant: the spectral variants sample only 360-830 nm. Preferred is ``cuda_ad_mono`` where a GPU
works, else ``llvm_ad_mono`` (vectorised, multi-threaded). Dr.Jit's LLVM backend loads ``libLLVM`` at run time; Debian's LLVM 15 crashes
its code generation on AVX-512 CPUs, so when ``DRJIT_LIBLLVM_PATH`` is unset this module points
it at Debian's LLVM 19 before Mitsuba is imported. Without a usable LLVM 19 it warns once and
falls back to ``scalar_rgb`` with gray (equal-channel) spectra, which keeps the radiometry right
(the luminance weights sum to 1, and the ``moment`` AOVs' Y channels are then the gray values)
but is much slower.

**Backends.** The same Dr.Jit code runs on the CPU (``llvm_ad_*``) or on an NVIDIA GPU
(``cuda_ad_*``, ray tracing through the driver's OptiX). The GPU is chosen automatically when the
CUDA driver library is present and a test kernel runs on it; otherwise the CPU. ``llvm_ad_mono``
stays the tested default (CI has no GPU). The backend is forced with ``HUMV_USD_BACKEND``
(``auto``, ``cuda``, ``llvm`` or ``scalar``; the CLI's ``--backend`` sets it), or a variant
exactly with ``HUMV_USD_MITSUBA_VARIANT`` (one of :data:`SUPPORTED_VARIANTS`). A forced backend
that does not work is an error, never a silent fallback. The manifest records the variant and
why it was chosen.

The visible (EO) render uses the spectral variant of the same backend (``cuda_ad_spectral``,
``llvm_ad_spectral`` or ``scalar_spectral``): ``mitsuba(spectral=True)``.
"""

from __future__ import annotations

import functools
import glob
import os
import sys
import threading
import warnings

from humv_usd.errors import InputError, bad_value

#: Variants the renderer knows how to drive, best first.
SUPPORTED_VARIANTS = ("cuda_ad_mono", "llvm_ad_mono", "scalar_rgb")
#: Environment variable that forces one of :data:`SUPPORTED_VARIANTS`.
VARIANT_ENV = "HUMV_USD_MITSUBA_VARIANT"
#: Environment variable that forces a backend (:data:`BACKENDS`); the CLI's ``--backend``.
BACKEND_ENV = "HUMV_USD_BACKEND"
#: Backend names and their infrared variant ("auto": the GPU if it works, else the CPU).
BACKENDS = {"auto": None, "cuda": "cuda_ad_mono", "llvm": "llvm_ad_mono", "scalar": "scalar_rgb"}
#: Globs for the CUDA driver library (the GPU backend loads it at run time).
CUDA_GLOBS = (
    "/usr/lib/*/libcuda.so*",
    "/usr/lib64/libcuda.so*",
    "/usr/local/nvidia/lib*/libcuda.so*",
    "/usr/local/cuda/lib64/stubs/libcuda.so",
)
#: Globs for Debian's LLVM 19 shared library.
LLVM19_GLOBS = ("/usr/lib/*/libLLVM.so.19*", "/usr/lib/*/libLLVM-19.so*", "/usr/lib/llvm-19/lib/libLLVM*.so*")

_lock = threading.Lock()
_state: dict = {}


def _find_llvm19() -> str | None:
    for pattern in LLVM19_GLOBS:
        hits = sorted(glob.glob(pattern))
        if hits:
            return hits[0]
    return None


def _cuda_driver() -> str | None:
    """Path of the CUDA driver library, if one is installed (no GPU is touched)."""
    for pattern in CUDA_GLOBS:
        hits = [h for h in sorted(glob.glob(pattern)) if "/stubs/" not in h]
        if hits:
            return hits[0]
    return None


def forced_variant() -> str | None:
    """The variant forced by :data:`VARIANT_ENV` or :data:`BACKEND_ENV` (None: choose)."""
    forced = os.environ.get(VARIANT_ENV, "").strip()
    if forced:
        if forced not in SUPPORTED_VARIANTS:
            raise InputError(
                bad_value(VARIANT_ENV, forced, f"expected one of {', '.join(SUPPORTED_VARIANTS)}")
            )
        return forced
    backend = os.environ.get(BACKEND_ENV, "").strip().lower()
    if backend:
        if backend not in BACKENDS:
            raise InputError(bad_value(BACKEND_ENV, backend, f"expected one of {', '.join(BACKENDS)}"))
        return BACKENDS[backend]
    return None


def set_backend(name: str) -> None:
    """Force a backend (:data:`BACKENDS`) for this process; call before Mitsuba is first used."""
    if name not in BACKENDS:
        raise InputError(bad_value("backend", name, f"expected one of {', '.join(BACKENDS)}"))
    if "mi" in _state and BACKENDS[name] not in (None, _state["variant"]):
        raise RuntimeError(f"backend {name!r} asked for after Mitsuba started with {_state['variant']}")
    os.environ[BACKEND_ENV] = name


def _choose_variant() -> tuple[str, str]:
    """(variant, reason) decided before Mitsuba is imported; a GPU variant is only a candidate,
    confirmed by a test kernel once Mitsuba is loaded (:func:`mitsuba`)."""
    forced = forced_variant()
    if forced is not None:
        how = VARIANT_ENV if os.environ.get(VARIANT_ENV, "").strip() else BACKEND_ENV
        if forced == "llvm_ad_mono" and not os.environ.get("DRJIT_LIBLLVM_PATH"):
            path = _find_llvm19()
            if path is not None and "drjit" not in sys.modules:
                os.environ["DRJIT_LIBLLVM_PATH"] = path
        return forced, f"forced by {how}"
    # the CPU fallback needs its LLVM library chosen before Dr.Jit loads, GPU or not
    llvm = _choose_llvm()
    cuda = _cuda_driver()
    if cuda is not None:
        return "cuda_ad_mono", f"CUDA driver {cuda}; else {llvm[0]} ({llvm[1]})"
    return llvm


def _choose_llvm() -> tuple[str, str]:
    """(variant, reason) of the CPU backend: ``llvm_ad_mono`` with LLVM 19, else ``scalar_rgb``."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return "llvm_ad_mono", "DRJIT_LIBLLVM_PATH set by the user"
    if "drjit" in sys.modules:
        # Too late to choose the library; trust whatever Dr.Jit found.
        return "llvm_ad_mono", "drjit already imported"
    path = _find_llvm19()
    if path is None:
        return "scalar_rgb", (
            "no LLVM 19 found (" + ", ".join(LLVM19_GLOBS) + ") and DRJIT_LIBLLVM_PATH is unset; the "
            "default LLVM 15 crashes Dr.Jit on AVX-512 CPUs. Install Debian's libllvm19 for the fast "
            "llvm_ad_mono variant"
        )
    os.environ["DRJIT_LIBLLVM_PATH"] = path
    return "llvm_ad_mono", f"DRJIT_LIBLLVM_PATH={path}"


def _forced_failed(variant: str, reason: str, error: str) -> str:
    """One line for a forced backend that does not run here (names the key, value and options)."""
    key = VARIANT_ENV if os.environ.get(VARIANT_ENV, "").strip() else "backend"
    value = variant if key == VARIANT_ENV else variant.split("_", 1)[0]
    return bad_value(
        key, value, f"{variant} does not work here ({error}; {reason}); use auto, llvm or scalar"
    )


def _llvm_works(mi, variant: str = "llvm_ad_mono") -> str | None:
    """None if a tiny kernel runs on ``variant``'s backend (LLVM or CUDA), else the error text."""
    try:
        if variant not in mi.variants():
            return f"this Mitsuba build has no {variant}"
        mi.set_variant(variant)
        import drjit as dr

        x = mi.Float([1.0, 2.0, 3.0]) * 2.0
        dr.eval(x)
        if list(x.numpy()) != [2.0, 4.0, 6.0]:
            return "wrong result from a test kernel"
        return None
    except Exception as exc:  # ImportError, RuntimeError from an unusable backend
        return f"{type(exc).__name__}: {exc}"


#: Spectral variant of the EO render for each infrared variant (same backend).
SPECTRAL_VARIANTS = {
    "cuda_ad_mono": "cuda_ad_spectral",
    "llvm_ad_mono": "llvm_ad_spectral",
    "scalar_rgb": "scalar_spectral",
}


def mitsuba(spectral: bool = False):
    """The Mitsuba module with the renderer's variant set (configured on first call).

    Parameters
    ----------
    spectral : bool, default False
        False: the infrared variant (:data:`SUPPORTED_VARIANTS`). True: the matching spectral
        variant for the visible (EO) render (:data:`SPECTRAL_VARIANTS`, 360-830 nm). Mitsuba
        has one current variant per process: call this before every use of a scene, and the
        variant is switched back and forth as needed.

    Returns
    -------
    module
        ``mitsuba``, with ``mitsuba.variant()`` one of :data:`SUPPORTED_VARIANTS` (or its
        spectral counterpart).
    """
    with _lock:
        if "mi" in _state:
            mi = _state["mi"]
            want = SPECTRAL_VARIANTS[_state["variant"]] if spectral else _state["variant"]
            if mi.variant() != want:
                mi.set_variant(want)  # someone else switched it, or EO <-> IR
            return mi
        variant, reason = _choose_variant()
        forced = forced_variant() is not None
        import mitsuba as mi

        if variant == "cuda_ad_mono":
            error = _llvm_works(mi, "cuda_ad_mono")
            if error is not None:
                if forced:
                    raise InputError(_forced_failed("cuda_ad_mono", reason, error))
                reason = f"cuda_ad_mono unusable ({error}); {reason.split('; else ', 1)[-1]}"
                variant = "llvm_ad_mono"
        if variant == "llvm_ad_mono":
            error = _llvm_works(mi)
            if error is not None:
                if forced:
                    raise InputError(_forced_failed("llvm_ad_mono", reason, error))
                reason = f"llvm_ad_mono unusable ({error})"
                variant = "scalar_rgb"
        if variant == "scalar_rgb" and not forced:
            warnings.warn(
                f"humv_usd.render: falling back to Mitsuba scalar_rgb (slow): {reason}",
                RuntimeWarning,
                stacklevel=2,
            )
        mi.set_variant(SPECTRAL_VARIANTS[variant] if spectral else variant)
        _state.update(mi=mi, variant=variant, reason=reason)
        return mi


def variant() -> str:
    """Name of the configured (infrared) Mitsuba variant (configures it if needed; does not
    switch the current variant once configured)."""
    if "variant" not in _state:
        mitsuba()
    return _state["variant"]


def variant_reason() -> str:
    """Why that variant was chosen (for the manifest)."""
    if "reason" not in _state:
        mitsuba()
    return _state["reason"]


def is_vectorized() -> bool:
    """True for a JIT (LLVM or CUDA) variant: whole arrays of rays per call."""
    return not variant().startswith("scalar")


def backend() -> str:
    """``cuda``, ``llvm`` or ``scalar``: where the configured variant runs."""
    return variant().split("_", 1)[0]


def loaded_backend() -> str | None:
    """:func:`backend` if Mitsuba is configured in this process, else None (loads nothing)."""
    return _state["variant"].split("_", 1)[0] if "variant" in _state else None


def release_kernel_cache() -> None:
    """Drop Dr.Jit's cache of compiled kernels (they are compiled again when next needed).

    The render traces new kernels as frames change, and Dr.Jit keeps every compiled kernel in
    memory: over a long render the cache grows by about 0.7 MB per frame until the kernels
    repeat (measured with ``humv-usd bench memory``: +50 MB between frames 30 and 100 of a walk,
    flat with the cache flushed). The render calls this every few frames."""
    if "mi" not in _state:
        return  # Mitsuba not loaded: nothing to drop
    import drjit

    flush = getattr(drjit, "flush_kernel_cache", None)
    if flush is not None:
        flush()


#: frames rendered in this process since Dr.Jit's kernel cache was last dropped (across render
#: calls: a sweep worker renders 4 frames per call and would never reach the interval otherwise)
_frames_since_flush = [0]


def frame_rendered(every: int) -> bool:
    """Count one rendered frame; drop the kernel cache (:func:`release_kernel_cache`) every
    ``every`` frames of this process. Returns whether it was dropped."""
    _frames_since_flush[0] += 1
    if _frames_since_flush[0] < every:
        return False
    _frames_since_flush[0] = 0
    release_kernel_cache()
    return True


def release_memory() -> None:
    """Hand the memory caches of this process back to the system: Dr.Jit's kernels and its cache
    of freed arrays (``flush_malloc_cache``), then glibc's free heap pages (``malloc_trim``).

    Dr.Jit keeps every freed array for reuse by size. A worker that renders many variants collects
    blocks of many sizes: measured on examples/table1.toml's variants, 2 frames of one variant
    leave 1.79 GB resident, 1.43 GB after ``malloc_trim`` and 0.50 GB after flushing Dr.Jit's cache
    too; over 600 frames of mixed variants a worker grew from 2.3 to 3.4 GB without it. Costs the
    next render its first allocations (and kernels) again."""
    if "mi" in _state:
        import drjit

        release_kernel_cache()
        flush = getattr(drjit, "flush_malloc_cache", None)
        if flush is not None:
            flush()
    c = glibc()
    if c is not None:
        c.malloc_trim(0)


@functools.cache
def glibc():
    """This process's glibc (``ctypes.CDLL``) for its malloc controls (``mallopt``,
    ``malloc_trim``), or None elsewhere (macOS, musl). Looked up once: ``find_library`` runs
    ``ldconfig -p`` in a child process (2 ms here, more forked from a worker of some GB)."""
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("c")
    if not name or os.uname().sysname != "Linux":
        return None
    try:
        c = ctypes.CDLL(name)
        return c if hasattr(c, "mallopt") and hasattr(c, "malloc_trim") else None
    except OSError:
        return None
