"""``humv-usd bench labels``: agreement of a render's label channels with an independent ray cast.

The stage's frame is exported again (:class:`humv_usd.render.export.StageExport`: world points
posed by UsdSkel, fan triangles), every triangle goes into one embree BVH (embreex through
:mod:`humv_usd.geometry.raycast`, not Mitsuba), and the pixel-centre rays of :class:`~humv_usd.geometry.camera.Camera` find the
first triangle; its part's instance id and its face's body region are compared with the EXR's
``instance_id`` and ``body_region``. Disagreements are split into edge pixels (a 4-neighbour
has another id: the two casts round a ray that grazes a triangle edge differently) and the rest.
"""

from __future__ import annotations

import json
import os

import numpy as np

from humv_usd.errors import InputError
from humv_usd.geometry.camera import Camera
from humv_usd.geometry.raycast import RayCaster
from humv_usd.groundtruth import labels as L
from humv_usd.groundtruth.regions import read_image
from humv_usd.render.export import StageExport
from humv_usd.usd.layers import open_stage


def _edge(ids: np.ndarray) -> np.ndarray:
    e = np.zeros(ids.shape, dtype=bool)
    e[1:] |= ids[1:] != ids[:-1]
    e[:-1] |= ids[1:] != ids[:-1]
    e[:, 1:] |= ids[:, 1:] != ids[:, :-1]
    e[:, :-1] |= ids[:, 1:] != ids[:, :-1]
    return e


def label_agreement(render_dir, sensor: str | None = None, frame: int | None = None) -> dict:
    """Fractions of pixels whose instance id and body region agree with an embree ray cast."""
    with open(os.path.join(os.fspath(render_dir), "manifest.json"), encoding="utf-8") as f:
        manifest = json.load(f)
    sensors = [s for s in manifest["sensors"] if sensor is None or s["name"] == sensor]
    if not sensors or not sensors[0]["frames"]:
        raise InputError(f"--sensor = {sensor!r}: no rendered sensor of that name in {render_dir}")
    rec = sensors[0]
    fr = next((f for f in rec["frames"] if frame is None or f["frame"] == frame), None)
    if fr is None:
        raise InputError(f"--frame = {frame}: not rendered for sensor {rec['name']}")
    ch = read_image(os.path.join(os.fspath(render_dir), fr["exr"]))
    stage = open_stage(manifest["stage"])
    exporter = StageExport(stage)
    sen = next(s for s in exporter.sensors if s.name == rec["name"])
    state = exporter.frame_state(fr["frame"], [sen])
    verts, tris, inst, region = [], [], [], []
    n = 0
    for m in state.meshes:
        labels = L.mesh_labels(stage.GetPrimAtPath(m.path), m.face_count)
        for part in m.parts:
            v = state.points[m.path][part.vertex_ids]
            verts.append(v)
            tris.append(part.triangles + n)
            inst.append(np.full(len(part.triangles), part.instance_id))
            region.append(labels.region[part.triangle_face])
            n += len(v)
    caster = RayCaster(np.concatenate(verts), np.concatenate(tris))
    inst, region = np.concatenate(inst), np.concatenate(region)
    w, h = rec["resolution"]
    cam = Camera.from_pose(state.cameras[sen.name], w, h)
    dirs = cam.pixel_rays().reshape(-1, 3)
    first = caster.intersects_first(np.broadcast_to(cam.origin, dirs.shape), dirs)
    hit = first >= 0
    ref_inst = np.where(hit, inst[np.where(hit, first, 0)], 0).reshape(h, w)
    ref_region = np.where(hit, region[np.where(hit, first, 0)], 0).reshape(h, w)
    ours_inst = np.rint(ch["instance_id"]).astype(np.int64)
    same = ours_inst == ref_inst
    out = {
        "sensor": rec["name"],
        "frame": fr["frame"],
        "pixels": int(w * h),
        "triangles": int(len(caster.triangles)),
        "instance_agreement": float(same.mean()),
        "instance_disagreeing_off_edges": int((~same & ~_edge(ref_inst)).sum()),
        "instance_disagreeing_on_edges": int((~same & _edge(ref_inst)).sum()),
    }
    if "body_region" in ch:
        ours_region = np.rint(ch["body_region"]).astype(np.int64)
        same_r = ours_region == ref_region
        out["body_region_agreement"] = float(same_r.mean())
        out["body_region_disagreeing_off_edges"] = int((~same_r & ~_edge(ref_region)).sum())
        people = np.isin(ref_inst, np.unique(ours_inst[ours_region > 0]))
        out["body_region_agreement_on_people"] = float(same_r[people].mean()) if people.any() else None
    return out
