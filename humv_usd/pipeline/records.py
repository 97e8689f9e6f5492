"""Per-frame records of a render folder: what makes a render resumable and consistent.

Every image (one sensor at one frame) that the render finished gets a record,
``RENDER/.frames/<sensor>/<frame:04d>.json``, written atomically after all of the image's files:
the settings that made it (:func:`settings`), the SHA-256 of each of its files, its manifest
entry, camera pose, Monte Carlo error sums and ground truth (COCO image and annotations,
region statistics). An image is done when its record exists, its settings are the call's and
its files are on disk with those hashes (:func:`is_done`); everything else is rendered again.
The per-render files (manifest.json, coco.json, regions.json, <sensor>/camera.json) are rebuilt
from all records at the end of every call, so frames rendered by separate calls accumulate and
the result equals one uninterrupted run. Nothing per frame stays in memory.

API for tools built on render folders (e.g. sweeps): :func:`read_records`, :func:`settings`,
:func:`is_done`, :func:`image_order`, :func:`merge_cameras`.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
from pathlib import Path

from humv_usd.fileio import write_json

RECORDS_DIR = ".frames"
RECORD_VERSION = 2  # 2: settings name the estimator and spp mode
_FRAME_FILE = re.compile(r"^(\d{4,})[._]")


def frame_of(name: str) -> int | None:
    """The frame of an image file name (``0012.exr``, ``0012_counts.png``), else None."""
    found = _FRAME_FILE.match(name)
    return int(found.group(1)) if found else None


def record_path(out_dir, sensor: str, frame: int) -> Path:
    return Path(out_dir) / RECORDS_DIR / sensor / f"{int(frame):04d}.json"


def frame_files(out_dir, sensor: str, frame: int) -> list[Path]:
    """The files of one image: ``<sensor>/<frame:04d>.*`` and ``<sensor>/<frame:04d>_*``."""
    folder = Path(out_dir) / sensor
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.is_file() and frame_of(p.name) == int(frame))


def file_sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def settings(
    stage_digest: str,
    spp: int,
    seed: int,
    max_depth: int,
    annotators,
    subbands=None,
    estimator: str | None = None,
    spp_mode: str | None = None,
) -> dict:
    """What makes an image: two images with equal settings (and frame, sensor) are the same
    render (same seeds: identical pixels). ``estimator``: the infrared estimator and its
    parameters (None for EO images); ``spp_mode``: "fixed" (every image ``spp`` samples), or the
    automatic-quality rule (then ``spp`` is the batch size and the samples spent vary per image:
    they are in its entry)."""
    return {
        "stage": stage_digest,
        "spp": int(spp),
        "spp_mode": spp_mode,
        "seed": int(seed),
        "max_depth": int(max_depth),
        "annotators": list(annotators),
        "subbands": None if subbands is None else int(subbands),
        "estimator": estimator,
    }


def difference(old: dict, new: dict) -> str:
    """The settings that differ, as ``spp 4 -> 8, seed 0 -> 5``."""
    keys = [k for k in sorted(old.keys() | new.keys()) if old.get(k) != new.get(k)]
    return ", ".join(f"{k} {old.get(k)!r} -> {new.get(k)!r}" for k in keys)


def write_record(out_dir, sensor: str, frame: int, record: dict) -> dict:
    """Hash the image's files and write its record (atomically, last: the image is done)."""
    files = {str(p.relative_to(out_dir)): file_sha256(p) for p in frame_files(out_dir, sensor, frame)}
    record = {"version": RECORD_VERSION, "sensor": sensor, "frame": int(frame), **record, "files": files}
    write_json(record_path(out_dir, sensor, frame), record)
    return record


def read_records(out_dir) -> dict[tuple[str, int], dict]:
    """Every readable record of a render folder by (sensor, frame); unreadable ones are left out
    (their images count as not rendered)."""
    out = {}
    root = Path(out_dir) / RECORDS_DIR
    if not root.is_dir():
        return out
    for path in sorted(root.glob("*/[0-9]*.json")):
        try:
            rec = json.loads(path.read_text(encoding="utf-8"))
            out[(rec["sensor"], int(rec["frame"]))] = rec
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return out


def is_done(out_dir, record: dict | None, wanted: dict) -> bool:
    """The record's settings are ``wanted`` and its files are all there, unchanged."""
    if record is None or record.get("settings") != wanted or record.get("version") != RECORD_VERSION:
        return False
    for rel, sha in record.get("files", {}).items():
        path = Path(out_dir) / rel
        if not path.is_file() or file_sha256(path) != sha:
            return False
    return bool(record.get("files"))


def remove_image(out_dir, sensor: str, frame: int) -> None:
    """Remove an image's files and record."""
    for p in frame_files(out_dir, sensor, frame):
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
    with contextlib.suppress(FileNotFoundError):
        record_path(out_dir, sensor, frame).unlink()


def unrecorded_images(out_dir, sensors) -> list[tuple[str, int]]:
    """(sensor, frame) of image files without a record: left by a render killed in the middle
    of the image (its files may be partial)."""
    records = read_records(out_dir)
    out = set()
    for sensor in sensors:
        folder = Path(out_dir) / sensor
        if not folder.is_dir():
            continue
        for p in folder.iterdir():
            frame = frame_of(p.name)
            if p.is_file() and frame is not None and (sensor, frame) not in records:
                out.add((sensor, frame))
    return sorted(out)


def image_order(sensor_order: dict[str, int]):
    """Sort key of records as one uninterrupted run writes them: by frame, then sensor
    (``sensor_order``: infrared sensors before EO ones, each in stage order)."""
    return lambda rec: (rec["frame"], sensor_order.get(rec["sensor"], len(sensor_order)), rec["sensor"])


def merge_cameras(records: list[dict]) -> dict | None:
    """One sensor's camera file from its records' one-frame camera files (frame order), as
    :func:`humv_usd.geometry.camera.camera_file` writes it for all frames at once."""
    cams = [r["camera"] for r in sorted(records, key=lambda r: r["frame"]) if r.get("camera")]
    if not cams:
        return None
    first = dict(cams[0])
    rows = []
    for cam in cams:
        row = dict(cam["frames"][0])
        row.pop("K", None)
        if cam["K"] != first["K"]:
            row["K"] = cam["K"]
        rows.append(row)
    first["frames"] = rows
    return first


def merge_errors(records: list[dict]) -> dict:
    """Pixel-weighted Monte Carlo error statistics over records (their ``error_sums``)."""
    sums: dict[str, float] = {}
    counts: dict[str, int] = {}
    maxima: dict[str, float] = {}
    for rec in records:
        part = rec.get("error_sums") or {}
        for name, v in part.get("sums", {}).items():
            sums[name] = sums.get(name, 0.0) + v
        for name, v in part.get("counts", {}).items():
            counts[name] = counts.get(name, 0) + v
        for name, v in part.get("maxima", {}).items():
            maxima[name] = max(maxima.get(name, v), v)

    def mean(n):
        return sums[n] / counts[n] if counts.get(n) else None

    return {
        "radiance_stderr_mean": mean("radiance_stderr"),
        "radiance_stderr_max": maxima.get("radiance_stderr"),
        "temperature_stderr_mean_k": mean("temperature_stderr"),
        "temperature_stderr_max_k": maxima.get("temperature_stderr"),
    }


def remove_empty_dirs(out_dir) -> None:
    root = Path(out_dir) / RECORDS_DIR
    if root.is_dir():
        for d in sorted(root.iterdir(), reverse=True):
            with contextlib.suppress(OSError):
                d.rmdir()
        with contextlib.suppress(OSError):
            root.rmdir()


__all__ = [
    "RECORDS_DIR",
    "difference",
    "file_sha256",
    "frame_of",
    "frame_files",
    "image_order",
    "is_done",
    "merge_cameras",
    "merge_errors",
    "read_records",
    "record_path",
    "remove_image",
    "settings",
    "unrecorded_images",
    "write_record",
]
