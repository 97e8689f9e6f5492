"""Atomic writers for render outputs: multi-channel EXR, 8-bit PNG preview, JSON manifest.

Every file is written to a temporary name in the destination directory and moved into place with
``os.replace``, so a reader never sees a half-written file.
"""

from __future__ import annotations

import os

import numpy as np
import OpenEXR
import OpenImageIO as oiio

from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import atomic_path

#: EXR channels of the IR render, by logical name (the key the code uses), with units. The file
#: stores them under :data:`EXR_NAMES`; OpenEXR sorts channels by name, so read them by name
#: (:func:`read_exr` returns logical names).
EXR_CHANNELS = {
    "radiance": "W m^-2 sr^-1 (band radiance, response-weighted)",
    "brightness_temperature": "K",
    "radiance_stderr": "W m^-2 sr^-1 (Monte Carlo standard error of the pixel mean)",
    "depth": "m (distance along the optical axis; inf for sky)",
    "instance_id": "1 (integer, stored as uint32; 0 = sky/background)",
    "R": "1 (display only, half: brightness temperature stretched as the PNG preview, 0..1)",
    "G": "as R",
    "B": "as R",
}
#: Logical channel name -> EXR channel name, in the conventions OpenEXR tools, OpenImageIO, Blender
#: and Nuke read: ``Z`` is depth only (OpenImageIO's ``z_channel``), colour is ``R,G,B``, everything
#: else is ``layer.channel`` (CIE XYZ under ``CIE.``, labels under ``label.``). Names not listed
#: are written as given.
EXR_NAMES = {
    "depth": "Z",
    "X": "CIE.X",
    "Y": "CIE.Y",
    "Z": "CIE.Z",
    "Y_stderr": "CIE.Y_stderr",
    "radiance": "IR.radiance",
    "brightness_temperature": "IR.brightness_temperature",
    "radiance_stderr": "IR.radiance_stderr",
    "instance_id": "label.instance_id",
    "class_id": "label.class_id",
    "material_kind": "label.material_kind",
    "body_region": "label.body_region",
    "jos3_segment": "label.jos3_segment",
    "normal_x": "N.X",
    "normal_y": "N.Y",
    "normal_z": "N.Z",
    "surface_temperature": "surface.temperature",
    "emissivity": "surface.emissivity",
    "counts": "counts.Y",
    "counts_R": "counts.R",
    "counts_G": "counts.G",
    "counts_B": "counts.B",
}
LOGICAL_NAMES = {v: k for k, v in EXR_NAMES.items()}
#: Label ids stored as OpenEXR UINT (exact integers). ``jos3_segment`` (-1 = none) stays float32.
UINT_CHANNELS = frozenset({"instance_id", "class_id", "material_kind", "body_region"})
#: Display-only channels stored as half (the IR file's grey R,G,B preview).
_UINT32_MAX = 4294967295.0
#: Largest id a UINT channel stores exactly (:data:`humv_usd.usd.labels.MAX_INSTANCE_ID` is 2**24 - 1).
UINT_EXACT_MAX = 2**24
#: OpenEXR compression of every EXR written (lossless: the channels are data). Measured on a
#: 1024x768 walk LWIR frame (18 channels; ``humv-usd bench frame``): zip 9.2 MB, zips 9.3 MB, piz
#: 11.8 MB, rle 31.7 MB, none 51.9 MB; zip costs about 0.2 CPU-s more than none (OpenEXR's writer,
#: 0.30 CPU-s in all) and is written by the render's background writer, so its time overlaps the
#: next frame's render.
EXR_COMPRESSION = "zip"
#: zlib level of every PNG written (OIIO's default is 6). Measured on a 1024x768 walk LWIR frame,
#: one thread: 16-bit counts 0.19 -> 0.045 CPU-s (593 -> 620 kB), 8-bit AGC image 0.12 -> 0.03 CPU-s
#: (258 -> 290 kB), label masks 0.04 -> 0.03 CPU-s (5 -> 15 kB); noisy images compress barely
#: better at higher levels, and in a sweep these writes compete with the renders for the cores.
PNG_COMPRESSION_LEVEL = 1
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


def exr_name(name: str) -> str:
    """The EXR channel name of a logical channel name (:data:`EXR_NAMES`)."""
    return EXR_NAMES.get(name, name)


def logical_name(exr_channel: str) -> str:
    """The logical channel name of an EXR channel name (inverse of :func:`exr_name`)."""
    return LOGICAL_NAMES.get(exr_channel, exr_channel)


def channel_info(name: str, unit: str, half: tuple[str, ...] = ()) -> dict:
    """The manifest entry of a logical channel: its EXR name, unit and stored type."""
    dtype = "uint32" if name in UINT_CHANNELS else "half" if name in half else "float32"
    return {"exr": exr_name(name), "unit": unit, "dtype": dtype}


#: OpenEXR compression of :data:`EXR_COMPRESSION`'s names.
_EXR_COMPRESSION = {
    "zip": OpenEXR.ZIP_COMPRESSION,
    "zips": OpenEXR.ZIPS_COMPRESSION,
    "piz": OpenEXR.PIZ_COMPRESSION,
    "none": OpenEXR.NO_COMPRESSION,
}


def _exr_header_value(value):
    """A header attribute as OpenEXR stores it: 4x4 -> M44f, 3x3 -> M33f, anything else a string."""
    arr = np.asarray(value) if not isinstance(value, str) else None
    if arr is not None and arr.shape in ((4, 4), (3, 3)):
        return np.ascontiguousarray(arr, dtype=np.float32)
    return str(value)


def write_exr(
    path, channels: dict[str, np.ndarray], metadata: dict | None = None, half: tuple[str, ...] = ()
) -> None:
    """Write channels of equal shape (H, W) to an EXR file atomically.

    Parameters
    ----------
    path : path-like
        Destination ``.exr``.
    channels : dict of str to (H, W) array
        Logical channel name to values; stored under :func:`exr_name`, as uint32 for
        :data:`UINT_CHANNELS` (exact integers), half for ``half``, else float32.
    metadata : dict, optional
        Extra header attributes: 4x4 arrays as matrices (e.g. OpenEXR's ``worldToCamera``,
        ``worldToNDC``), 3x3 arrays as 3x3 matrices, anything else as a string.
    half : tuple of str
        Logical names stored as half (display-only channels).
    """
    names = list(channels)
    for n in names:
        if n in UINT_CHANNELS and np.size(channels[n]) and np.max(channels[n]) > UINT_EXACT_MAX:
            raise InputError(
                bad_value(n, int(np.max(channels[n])), f"ids 0..{UINT_EXACT_MAX} (exact in the EXR)")
            )
    # OpenEXR's own writer, each channel in its stored type: OpenImageIO took 0.62 CPU-s for a
    # 1024x768 walk LWIR frame (18 channels, zip) against 0.30 here, most of the difference its
    # conversion of one float buffer to each channel's type
    pixels = {}
    for n in names:
        dtype = np.uint32 if n in UINT_CHANNELS else np.float16 if n in half else np.float32
        values = np.asarray(channels[n])
        if dtype is np.uint32 and values.dtype.kind in "fi":  # ids as floats or signed: clamped as OIIO did
            values = np.maximum(np.nan_to_num(np.rint(values)), 0)  # the max is checked above
        pixels[exr_name(n)] = np.ascontiguousarray(values, dtype=dtype)
    header = {"compression": _EXR_COMPRESSION[EXR_COMPRESSION], "type": OpenEXR.scanlineimage}
    for key, value in (metadata or {}).items():
        header[key] = _exr_header_value(value)
    with atomic_path(path) as tmp:
        try:
            with OpenEXR.File(header, pixels) as exr:
                exr.write(os.fspath(tmp))
        except RuntimeError as exc:  # OpenEXR's errors (disk full, bad shapes): an OSError like the others
            raise OSError(f"OpenEXR cannot write {path}: {exc}") from None


def read_exr(path, with_spec: bool = False):
    """All channels of an image file by logical name (:func:`logical_name`), each in its stored
    type (float32, uint32 ids, half as float32; integer PNGs keep their integers). ``with_spec``
    also returns the OpenImageIO ImageSpec (header attributes)."""
    inp = oiio.ImageInput.open(os.fspath(path))
    if inp is None:
        raise OSError(f"{path}: cannot read the image ({oiio.geterror().strip() or 'unknown format'})")
    try:
        spec = inp.spec()
        # one decode: a file of one type in that type; mixed types as float64, where float and
        # half are exact and UINT comes scaled by 1/(2**32-1) (exact in float64, undone below)
        fmt = oiio.DOUBLE if spec.channelformats else spec.format
        pixels = inp.read_image(0, 0, 0, spec.nchannels, fmt)
        if pixels is None:
            raise OSError(f"{path}: cannot read the pixels: {inp.geterror()}")
    finally:
        inp.close()
    pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
    channels = {}
    for i, name in enumerate(spec.channelnames):
        kind = str(spec.channelformat(i))
        values = pixels[..., i]
        if kind == "uint" and values.dtype == np.float64:
            values = np.rint(values * _UINT32_MAX).astype(np.uint32)
        elif values.dtype in (np.float64, np.float16):
            values = values.astype(np.float32)
        channels[logical_name(name)] = values
    return (channels, spec) if with_spec else channels


def preview_levels(values: np.ndarray, keep: np.ndarray | None = None) -> tuple[float, float]:
    """The 1st and 99th percentile of the finite values (the PNG stretch), widened to the same
    percentiles of the ``keep`` pixels (a mask: the labelled people) so that they stay readable:
    a person is often under 3 % of the pixels and would otherwise saturate (a tracked walker:
    81 % of its pixels at 0 or 255). Still a linear stretch, so the levels map back to values."""
    values = np.asarray(values, dtype=np.float64)
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return 0.0, 0.0
    lo, hi = np.percentile(finite, PREVIEW_PERCENTILES)
    if keep is not None:
        kept = values[np.asarray(keep, dtype=bool) & np.isfinite(values)]
        if kept.size:
            k_lo, k_hi = np.percentile(kept, PREVIEW_PERCENTILES)
            lo, hi = min(lo, k_lo), max(hi, k_hi)
    return float(lo), float(hi)


def write_preview_png(
    path, values: np.ndarray, levels: tuple[float, float] | None = None
) -> tuple[float, float]:
    """Write an 8-bit grayscale PNG of ``values`` stretched between its 1st and 99th percentile
    (``levels``, when the caller has them from :func:`preview_levels`).

    Returns the (low, high) levels mapped to 0 and 255. A constant image is mid-gray; non-finite
    values are black.
    """
    values = np.asarray(values, dtype=np.float64)
    lo, hi = preview_levels(values) if levels is None else levels
    if hi > lo:
        scaled = (values - lo) / (hi - lo)
    else:
        scaled = np.full(values.shape, 0.5)
    scaled = np.where(np.isfinite(scaled), scaled, 0.0)
    pixels = np.rint(np.clip(scaled, 0.0, 1.0) * 255.0).astype(np.uint8)
    h, w = pixels.shape
    spec = oiio.ImageSpec(w, h, 1, "uint8")
    spec.channelnames = ("Y",)
    spec.attribute("png:compressionLevel", PNG_COMPRESSION_LEVEL)
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
    spec.attribute("png:compressionLevel", PNG_COMPRESSION_LEVEL)
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
    spec.attribute("png:compressionLevel", PNG_COMPRESSION_LEVEL)
    _write_oiio(path, np.ascontiguousarray(pixels), spec)
