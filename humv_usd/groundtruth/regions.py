"""Per-body-region image statistics (the seed's Table 2) and the comparison with a real image.

The seed (HumanView, Sec. 4.2, Fig. 11, Table 2) segments the person in a simulated and a real
LWIR image into body regions and compares the mean image intensity per region. Here, per sensor,
frame and person, for each Table 2 region (:data:`humv_usd.human.labels.SEED_TABLE2_REGIONS`:
unions of our 19 regions; "Hat" is the head, "Torso" abdomen + back + pelvis, "Full body" every
region) over the pixels whose ``body_region`` channel is in it (garment pixels carry the region
of the body under them; props and the background are left out):

- mean and standard deviation (population, ddof = 0) of the image quantity: ``counts`` when the
  EXR has that channel (the sensor chain's digital counts), else band ``radiance``
  [W m^-2 sr^-1]; for EO sensors the rendered luminance ``Y`` (CIE Y of the radiance);
- mean and standard deviation of the apparent (brightness) temperature [K].

Real image comparison (``humv-usd regions RENDER_DIR --real IMAGE --masks MASKS``):

- IMAGE: any single-channel image OpenImageIO reads (PNG, TIFF, EXR...); for several channels
  the first is used. Its values are compared with the simulated quantity chosen by
  ``--quantity`` (default: counts if present, else radiance, else Y), so give them in the same units.
- MASKS: a single-channel PNG of the same size whose pixel values are body region ids
  (:data:`humv_usd.human.labels.BODY_REGIONS`: 1 head, 2 face, 3 neck, 4 chest, 5 abdomen,
  6 back, 7 pelvis, 8-10 left upper arm / lower arm / hand, 11-13 right ..., 14-16 left upper
  leg / lower leg / foot, 17-19 right ...; 0 = not the person). The render writes this format
  for every frame as ``<frame>.region_ids.png`` (annotator ``masks``), which a user can start
  from when drawing masks on a real image.

The difference printed is simulated minus real, per region, of the means.
"""

from __future__ import annotations

import json
import os

import numpy as np

from humv_usd import images
from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import write_json
from humv_usd.human import labels as AL

#: Table 2 regions in the seed's order, each as a set of our region ids.
TABLE2: dict[str, np.ndarray] = {
    name: np.array([AL.REGION_ID[r] for r in regions]) for name, regions in AL.SEED_TABLE2_REGIONS.items()
}
TEMPERATURE_CHANNELS = ("brightness_temperature", "apparent_temperature")
QUANTITIES = ("counts", "radiance", "Y", "temperature")
_TABLE2_TOP = int(max(ids.max() for ids in TABLE2.values()))
#: The channels :func:`image_regions` reads.
REGION_INPUTS = frozenset({"body_region", "instance_id", "counts", "radiance", "Y", *TEMPERATURE_CHANNELS})
REGIONS_NAME = "regions.json"


def read_image(path, with_format: bool = False):
    """All channels of an image file as float64 (H, W) arrays, by logical channel name
    (:func:`humv_usd.images.logical_name`: an EXR's ``label.body_region`` is ``body_region``),
    holding the values as stored: integer files and channels (8/16-bit PNG counts, uint32 ids)
    keep their integers (OpenImageIO would otherwise rescale them to 0..1). ``with_format`` also
    returns the pixel format name (e.g. "uint16", "float")."""
    try:
        channels, spec = images.read_exr(path, with_spec=True)
    except OSError as e:
        raise InputError(str(e)) from None
    channels = {name: np.asarray(v).astype(np.float64) for name, v in channels.items()}
    return (channels, str(spec.format)) if with_format else channels


def _stats(values: np.ndarray) -> tuple[float | None, float | None]:
    v = values[np.isfinite(values)]
    if v.size == 0:
        return None, None
    return float(v.mean()), float(v.std())


def region_stats(
    region: np.ndarray,
    value: np.ndarray,
    temperature: np.ndarray | None = None,
    select: np.ndarray | None = None,
) -> dict[str, dict]:
    """Per Table 2 region: pixel count, mean/std of ``value`` and of ``temperature`` [K]."""
    region = np.asarray(region)
    out = {}
    # non-negative integer ids: membership by a lookup table (np.isin sorts every time)
    lookup = region.dtype.kind in "iu" and region.size > 0 and region.min() >= 0
    top = max(int(region.max()), _TABLE2_TOP) + 1 if lookup else 0
    for name, ids in TABLE2.items():
        if lookup:
            member = np.zeros(top, dtype=bool)
            member[ids] = True
            m = member[region]
        else:
            m = np.isin(region, ids)
        if select is not None:
            m &= select
        mean, std = _stats(value[m])
        row = {"pixels": int(m.sum()), "mean": mean, "std": std}
        if temperature is not None:
            row["temperature_mean_k"], row["temperature_std_k"] = _stats(temperature[m])
        out[name] = row
    return out


def image_regions(channels: dict[str, np.ndarray], quantity: str | None = None) -> list[dict]:
    """Per person (instance id with body-region pixels) region statistics of one EXR image."""
    if "body_region" not in channels:
        raise InputError("the EXR has no body_region channel (render with the body_region annotator)")
    # IR: the chain's counts, else band radiance; EO: luminance Y (relative, as rendered)
    quantity = quantity or next((c for c in ("counts", "radiance", "Y") if c in channels), "radiance")
    temp_name = next((c for c in TEMPERATURE_CHANNELS if c in channels), None)
    temperature = channels[temp_name] if temp_name else None
    if quantity == "temperature":
        if temperature is None:
            raise InputError(bad_value("quantity", quantity, "the EXR has no temperature channel"))
        value = temperature
    elif quantity in channels:
        value = channels[quantity]
    else:
        raise InputError(
            bad_value(
                "quantity",
                quantity,
                "expected a channel of the EXR: "
                + ", ".join(c for c in QUANTITIES if c in channels or c == "temperature"),
            )
        )
    region = np.asarray(channels["body_region"])
    region = np.rint(region) if region.dtype.kind == "f" else region
    # only pixels of a body region count anywhere: keep those (in order), then float64 as stored
    keep = np.flatnonzero(region.ravel() > 0)
    region = region.ravel()[keep].astype(np.int64)
    instance = channels.get("instance_id")
    instance = np.zeros_like(region) if instance is None else np.asarray(instance).ravel()[keep]
    instance = (np.rint(instance) if instance.dtype.kind == "f" else instance).astype(np.int64)
    value = np.asarray(value).ravel()[keep].astype(np.float64)
    temperature = None if temperature is None else np.asarray(temperature).ravel()[keep].astype(np.float64)
    people = sorted(set(np.unique(instance).tolist()))
    return [
        {
            "instance_id": int(i),
            "quantity": quantity,
            "regions": region_stats(region, value, temperature, select=instance == i),
        }
        for i in people
    ]


def render_regions(render_dir, quantity: str | None = None) -> list[dict]:
    """Region statistics of every EXR listed in ``RENDER_DIR/manifest.json``."""
    manifest_path = os.path.join(os.fspath(render_dir), "manifest.json")
    try:
        with open(manifest_path, encoding="utf-8") as f:
            manifest = json.load(f)
    except FileNotFoundError:
        raise InputError(f"{render_dir}: not a render folder (no manifest.json)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"{manifest_path}: cannot read ({exc})") from None
    images = [
        {"sensor": sensor["name"], "frame": frame["frame"], "exr": frame["exr"]}
        for key in ("sensors", "eo_sensors")  # infrared, then EO (luminance Y)
        for sensor in manifest.get(key, [])
        for frame in sensor.get("frames", [])
    ]
    return images_regions(render_dir, images, quantity)


def images_regions(render_dir, images: list[dict], quantity: str | None = None) -> list[dict]:
    """Region statistics of the given EXRs (dicts with sensor, frame, exr relative to render_dir)."""
    out = []
    for item in images:
        channels = read_image(os.path.join(os.fspath(render_dir), item["exr"]))
        for person in image_regions(channels, quantity):
            out.append({"sensor": item["sensor"], "frame": item["frame"], "exr": item["exr"], **person})
    return out


def write_regions(render_dir, records: list[dict]) -> str:
    path = os.path.join(os.fspath(render_dir), REGIONS_NAME)
    write_json(
        path,
        {
            "regions": {k: [int(i) for i in v] for k, v in TABLE2.items()},
            "region_names": list(AL.BODY_REGION_NAMES),
            "std": "population standard deviation (ddof = 0) over the region's pixels",
            "images": records,
        },
    )
    return path


def real_regions(image_path, masks_path, select_shape=None) -> dict[str, dict]:
    """Per Table 2 region statistics of a real image under a region-id mask PNG."""
    image = read_image(image_path)
    values = next(iter(image.values()))
    masks, fmt = read_image(masks_path, with_format=True)
    if fmt not in ("uint8", "uint16"):
        raise InputError(
            bad_value(f"{masks_path} pixel format", fmt, "expected an 8- or 16-bit PNG of region ids")
        )
    region = np.rint(next(iter(masks.values()))).astype(np.int64)
    if region.shape != values.shape:
        raise InputError(
            bad_value(
                f"{masks_path} size",
                list(region.shape[::-1]),
                f"expected the size of {image_path}: {list(values.shape[::-1])}",
            )
        )
    if select_shape is not None and tuple(values.shape) != tuple(select_shape):
        raise InputError(
            bad_value(
                f"{image_path} size",
                list(values.shape[::-1]),
                f"expected the rendered size {list(select_shape)[::-1]}",
            )
        )
    bad = (region < 0) | (region > len(AL.BODY_REGIONS))
    if bad.any():
        raise InputError(
            bad_value(f"{masks_path}", int(region[bad][0]), f"expected region ids 0..{len(AL.BODY_REGIONS)}")
        )
    return region_stats(region, values)


def _fmt(x, width=9, digits=2):
    return f"{'-':>{width}}" if x is None else f"{x:>{width}.{digits}f}"


def format_table(record: dict, real: dict | None = None) -> str:
    """The Table 2 layout for one image and person (and the real image's columns)."""
    q = record["quantity"]
    head = (
        f"{'#':>2} {'region':<16} {'pixels':>7} {q + ' mean':>14} {'std':>9} {'T mean [K]':>10} {'T std':>6}"
    )
    if real is not None:
        head += f" {'real mean':>10} {'real std':>9} {'sim-real':>9}"
    lines = [
        f"sensor {record['sensor']}, frame {record['frame']}, person instance {record['instance_id']}",
        head,
    ]
    for k, (name, row) in enumerate(record["regions"].items(), start=1):
        line = (
            f"{k:>2} {name:<16} {row['pixels']:>7} {_fmt(row['mean'], 14, 4)} {_fmt(row['std'], 9, 4)} "
            f"{_fmt(row.get('temperature_mean_k'), 10)} {_fmt(row.get('temperature_std_k'), 6)}"
        )
        if real is not None:
            r = real[name]
            diff = None if r["mean"] is None or row["mean"] is None else row["mean"] - r["mean"]
            line += f" {_fmt(r['mean'], 10, 4)} {_fmt(r['std'], 9, 4)} {_fmt(diff, 9, 4)}"
        lines.append(line)
    return "\n".join(lines)
