"""Resuming a render: which frames are done, what a killed render left, the stage digest.

Every finished image has a record (:mod:`humv_usd.pipeline.records`); a render renders only the
requested frames whose images are not done with the same settings and refuses (without
``force``) a folder holding images made with other settings.
"""

from __future__ import annotations

import hashlib
import logging
import os
from collections import defaultdict

from pxr import Usd

from humv_usd.errors import InputError
from humv_usd.fileio import remove_stale_temps, write_json
from humv_usd.geometry.camera import CAMERA_FILE
from humv_usd.physics.sensor import SensorModel
from humv_usd.pipeline import records as R

log = logging.getLogger(__name__)


def stage_digest(stage: Usd.Stage) -> str:
    """SHA-256 (16 hex digits) of the content of every layer file of the stage's layer stack:
    an image rendered from another stage content is another image."""
    h = hashlib.sha256()
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        path = layer.realPath
        h.update((path and os.path.basename(path) or layer.identifier).encode())
        h.update(
            R.file_sha256(path).encode() if path and os.path.isfile(path) else layer.ExportToString().encode()
        )
    return h.hexdigest()[:16]


def selected_sensors(plan) -> list[SensorModel]:
    return list(plan.rendered) + list(plan.eo_run.sensors)


def frames_to_render(plan, force: bool) -> list[int]:
    """The requested frames not done with this call's settings (all with ``force``), plus with
    ``force`` the frames of images made with other settings; refuse those without ``force``.
    Removes what a killed render left: temp files and the files of images without a record."""
    out_dir = plan.out_dir
    names = [s.name for s in selected_sensors(plan)]
    for folder in [out_dir, *(os.path.join(out_dir, n) for n in names)]:
        remove_stale_temps(folder)
    for n in names:
        remove_stale_temps(os.path.join(out_dir, R.RECORDS_DIR, n))
    if os.path.isdir(os.path.join(out_dir, R.RECORDS_DIR)):
        for sensor, frame in R.unrecorded_images(out_dir, names):
            log.info("removing the partial image %s/%04d of an interrupted render", sensor, frame)
            R.remove_image(out_dir, sensor, frame)
    os.makedirs(os.path.join(out_dir, R.RECORDS_DIR), exist_ok=True)
    records = R.read_records(out_dir)
    other = sorted(
        (key, rec)
        for key, rec in records.items()
        if key[0] in plan.wanted and rec.get("settings") != plan.wanted[key[0]]
    )
    if other and not force:
        (sensor, frame), rec = other[0]
        more = f" (and {len(other) - 1} more images)" if len(other) > 1 else ""
        raise InputError(
            f"{out_dir}: {sensor}/{frame:04d}{more} was rendered with other settings "
            f"({R.difference(rec.get('settings') or {}, plan.wanted[sensor])}); render into another "
            "folder, or pass --force to render them again with these settings"
        )
    todo = set(plan.frames) if force else set()
    todo |= {frame for (_, frame), _ in other}
    for f in plan.frames:
        if any(not R.is_done(out_dir, records.get((n, f)), plan.wanted[n]) for n in names):
            todo.add(f)
    if force:
        for sensor, frame in sorted({k for k, _ in other}):
            R.remove_image(out_dir, sensor, frame)
    log.info("rendering %d of %d requested frames", len(set(plan.frames) & todo), len(plan.frames))
    return sorted(todo)


def records_of_this_render(plan) -> list[dict]:
    """The records of the selected sensors with this call's settings, in the order one
    uninterrupted render writes them."""
    order = {s.name: i for i, s in enumerate(selected_sensors(plan))}
    records = [
        rec
        for (sensor, _), rec in R.read_records(plan.out_dir).items()
        if sensor in plan.wanted and rec.get("settings") == plan.wanted[sensor]
    ]
    return sorted(records, key=R.image_order(order))


def write_cameras(out_dir: str, done: list[dict]) -> None:
    """``<sensor>/camera.json`` of every sensor rendered (intrinsics, per-frame pose)."""
    by_sensor: dict[str, list[dict]] = defaultdict(list)
    for rec in done:
        by_sensor[rec["sensor"]].append(rec)
    for name, recs in by_sensor.items():
        cameras = R.merge_cameras(recs)
        if cameras is not None:
            write_json(os.path.join(out_dir, name, CAMERA_FILE), cameras)
