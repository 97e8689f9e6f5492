"""Atomic writers for render outputs: multi-channel EXR, 8-bit PNG preview, JSON manifest.

Every file is written to a temporary name in the destination directory and moved into place with
``os.replace``, so a reader never sees a half-written file.
"""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio

from humv_usd.fileio import atomic_path

#: EXR channels, in the order written, with units. OpenEXR stores channels sorted by name, so
#: read them by name. All are float32; ``instance_id`` holds integers 0..2**24-1 exactly.
EXR_CHANNELS = {
    "radiance": "W m^-2 sr^-1 (band radiance, response-weighted)",
    "brightness_temperature": "K",
    "radiance_stderr": "W m^-2 sr^-1 (Monte Carlo standard error of the pixel mean)",
    "depth": "m (distance along the optical axis; inf for sky)",
    "instance_id": "1 (integer stored as float32; 0 = sky/background)",
}
#: zlib level of the 16-bit counts PNGs (noisy data compress barely better at higher levels).
PNG16_COMPRESSION_LEVEL = 1
#: Percentiles of the brightness temperature mapped to 0 and 255 in the PNG preview.
PREVIEW_PERCENTILES = (1.0, 99.0)


def _write_oiio(path, pixels: np.ndarray, spec: oiio.ImageSpec) -> None:
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(tmp)
        if out is None:
            raise OSError(f"OpenImageIO cannot write {path}: {oiio.geterror()}")
        try:
            if not out.open(tmp, spec):
                raise OSError(f"OpenImageIO cannot open {tmp}: {out.geterror()}")
            if not out.write_image(pixels):
                raise OSError(f"OpenImageIO cannot write {tmp}: {out.geterror()}")
        finally:
            out.close()


def write_exr(path, channels: dict[str, np.ndarray], metadata: dict[str, str] | None = None) -> None:
    """Write float32 channels of equal shape (H, W) to an EXR file atomically.

    Parameters
    ----------
    path : path-like
        Destination ``.exr``.
    channels : dict of str to (H, W) array
        Channel name to values; written in this order as float32.
    metadata : dict of str to str, optional
        Extra header attributes.
    """
    names = list(channels)
    stack = np.stack([np.asarray(channels[n], dtype=np.float32) for n in names], axis=-1)
    h, w, c = stack.shape
    spec = oiio.ImageSpec(w, h, c, "float")
    spec.channelnames = tuple(names)
    spec.attribute("compression", "zip")
    for key, value in (metadata or {}).items():
        spec.attribute(key, str(value))
    _write_oiio(path, np.ascontiguousarray(stack), spec)


def preview_levels(values: np.ndarray) -> tuple[float, float]:
    """The 1st and 99th percentile of the finite values (the PNG stretch)."""
    finite = np.asarray(values, dtype=np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return 0.0, 0.0
    lo, hi = np.percentile(finite, PREVIEW_PERCENTILES)
    return float(lo), float(hi)


def write_preview_png(path, values: np.ndarray) -> tuple[float, float]:
    """Write an 8-bit grayscale PNG of ``values`` stretched between its 1st and 99th percentile.

    Returns the (low, high) levels mapped to 0 and 255. A constant image is mid-gray; non-finite
    values are black.
    """
    values = np.asarray(values, dtype=np.float64)
    lo, hi = preview_levels(values)
    if hi > lo:
        scaled = (values - lo) / (hi - lo)
    else:
        scaled = np.full(values.shape, 0.5)
    scaled = np.where(np.isfinite(scaled), scaled, 0.0)
    pixels = np.rint(np.clip(scaled, 0.0, 1.0) * 255.0).astype(np.uint8)
    h, w = pixels.shape
    spec = oiio.ImageSpec(w, h, 1, "uint8")
    spec.channelnames = ("Y",)
    _write_oiio(path, np.ascontiguousarray(pixels[..., None]), spec)
    return lo, hi


def write_png(path, pixels: np.ndarray) -> None:
    """Write uint8 pixels (H, W) gray or (H, W, 3) RGB to a PNG atomically (label masks)."""
    pixels = np.asarray(pixels, dtype=np.uint8)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, "uint8")
    spec.channelnames = ("Y",) if c == 1 else ("R", "G", "B", "A")[:c]
    _write_oiio(path, np.ascontiguousarray(pixels), spec)


def write_png16(path, counts: np.ndarray) -> None:
    """Write uint16 counts (H, W) gray or (H, W, 3) RGB to a 16-bit PNG atomically (raw
    sensor counts of :mod:`humv_usd.physics.sensor`)."""
    pixels = np.asarray(counts, dtype=np.uint16)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, "uint16")
    spec.channelnames = ("Y",) if c == 1 else ("R", "G", "B")[:c]
    # zlib level 1: 2-4x faster than OIIO's default 6 on sensor counts, files within 1 % in size
    spec.attribute("png:compressionLevel", PNG16_COMPRESSION_LEVEL)
    _write_oiio(path, np.ascontiguousarray(pixels), spec)
