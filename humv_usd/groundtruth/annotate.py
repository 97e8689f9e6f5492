"""The render's ground-truth step: one call per sensor and frame, one at the end.

``GroundTruth(stage, annotators)`` is made once per render; :meth:`GroundTruth.annotate` takes the
Mitsuba scene (for the exact pixel-centre ray cast, :meth:`humv_usd.render.ir.IRScene.hits`),
the frame's :class:`~humv_usd.render.frame.FrameState` and the sensor, and returns the label
channels for the EXR plus the per-object annotations (also written next to the frame:
``<frame>.objects.json`` and the PNG masks); :meth:`GroundTruth.finish` writes ``coco.json`` and
``regions.json`` and returns the manifest's ``ground_truth`` section (what ran and what it cost).
"""

from __future__ import annotations

import copy
import hashlib
import os
import time
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd import images as writers
from humv_usd.errors import InputError
from humv_usd.fileio import write_json
from humv_usd.geometry.camera import CAMERA_FILE, Camera
from humv_usd.groundtruth import annotators as A
from humv_usd.groundtruth import boxes as B
from humv_usd.groundtruth import keypoints as K
from humv_usd.groundtruth import labels as L
from humv_usd.groundtruth import regions as R
from humv_usd.groundtruth.coco import CocoBuilder

#: EXR channels this package adds, with units (depth and instance_id are the render's).
CHANNELS = {
    "class_id": "1 (integer, uint32; humv_usd.groundtruth.labels.CLASSES: 0 background, 1 person, 2 ground, "
    "3 building, 4 prop, 5 panel, 6 vegetation, 7 vehicle, 8 other, 9 animal, 10 lamp, 11 hvac, "
    "12 fire)",
    "material_kind": "1 (integer, uint32; 0 background, 1 skin, 2 garment, 3 prop, 4 scene)",
    "body_region": "1 (integer, uint32; humv_usd.human.labels.BODY_REGIONS ids, 0 = not the body)",
    "jos3_segment": "1 (integer as float32; 0-based JOS-3 segment, -1 = none)",
    "normal_x": "1 (world space, x east; unit geometric normal of the hit triangle, front side; 0 for sky)",
    "normal_y": "1 (world space, y north)",
    "normal_z": "1 (world space, z up)",
    "surface_temperature": "K (kinetic temperature at the pixel-centre hit, the faces' temperatures "
    "interpolated as the render shades them; NaN for sky)",
    "emissivity": "1 (band emissivity of the hit material for this sensor; NaN for sky)",
}
_CHANNELS_OF = {
    "semantic": ("class_id", "material_kind"),
    "body_region": ("body_region", "jos3_segment"),
    "normal": ("normal_x", "normal_y", "normal_z"),
    "surface": ("surface_temperature", "emissivity"),
}
COCO_NAME = "coco.json"


@dataclass
class ImageTruth:
    depth: np.ndarray
    instance: np.ndarray
    channels: dict[str, np.ndarray]
    objects: list[dict] = field(default_factory=list)


def _safe_emissivity(emissivity_of, part) -> float:
    """Band emissivity of a part, NaN where the material's table does not cover the band."""
    try:
        return float(emissivity_of(part))
    except InputError:
        return float("nan")


class GroundTruth:
    """Ground truth of one render (see the module doc).

    Parameters
    ----------
    stage : Usd.Stage
        The composed stage being rendered.
    annotators : list of str, optional
        Annotator names (:data:`humv_usd.groundtruth.annotators.ANNOTATORS`); default: the
        stage's list (root layer customLayerData, from the scenario's ``[annotations]``), else
        the default set.
    """

    def __init__(self, stage: Usd.Stage, annotators=None):
        self.stage = stage
        if annotators is None:
            self.annotators, self.source = A.from_stage(stage)
        else:
            self.annotators, self.source = (
                A.resolve(list(annotators) if not isinstance(annotators, str) else annotators),
                "argument",
            )
        self.want = set(self.annotators)
        self.timings = dict.fromkeys(("ray_cast",) + self.annotators, 0.0)
        self._mesh_labels: dict[str, L.MeshLabels] = {}
        self._objects: dict[str, L.ObjectInfo] = {}
        self._keypoint_prims = None
        # per (sensor, instance id): the geometry digest of the last frame, its boxes and (once
        # the object stood still for two frames) its whole-box unoccluded cast; one entry each
        self._still: dict[tuple[str, int], dict] = {}
        self.coco = CocoBuilder() if "coco" in self.want else None
        self.images: list[dict] = []
        self._region_records: list[dict] = []  # per image, from image_written (no re-read)
        self._regions_done: set[str] = set()  # EXRs whose region records are in memory
        self._out_dir: str | None = None  # the render folder (annotate's out_dir)

    def _tick(self, name, t0):
        t = time.perf_counter()
        self.timings[name] = self.timings.get(name, 0.0) + t - t0
        return t

    # --- per mesh --------------------------------------------------------------------------
    def _labels(self, mesh) -> L.MeshLabels:
        if mesh.path not in self._mesh_labels:
            self._mesh_labels[mesh.path] = L.mesh_labels(self.stage.GetPrimAtPath(mesh.path), mesh.face_count)
        return self._mesh_labels[mesh.path]

    def _object(self, mesh_path: str) -> L.ObjectInfo:
        if mesh_path not in self._objects:
            self._objects[mesh_path] = L.object_info(self.stage.GetPrimAtPath(mesh_path))
        return self._objects[mesh_path]

    # --- per sensor and frame ----------------------------------------------------------------
    def annotate(
        self, scene, sensor_id: str, sensor, state, emissivity_of, out_dir: str, rel: str, write=None
    ) -> ImageTruth:
        """Labels of one sensor at one frame.

        ``scene`` is the render's :class:`~humv_usd.render.ir.IRScene`, ``sensor`` the
        :class:`~humv_usd.physics.sensor.SensorModel`, ``state`` the frame's FrameState,
        ``emissivity_of(part)`` the band emissivity of a part's material for this sensor;
        ``rel`` the frame's output path without extension, relative to ``out_dir``;
        ``write(what, fn, *args)`` writes the label files (the render's background writer;
        default: now).
        """
        write = write or (lambda _what, fn, *args: fn(*args))
        self._out_dir = out_dir
        t = time.perf_counter()
        hits = scene.hits(sensor_id)
        t = self._tick("ray_cast", t)
        want = self.want
        channels: dict[str, np.ndarray] = {}
        parts = scene.parts
        images = {}
        tables = None
        if want & {"semantic", "body_region", "surface", "keypoints", "masks"}:
            meshes = {m.path: m for m in state.meshes}
            labels = {path: self._labels(m) for path, m in meshes.items()}
            eps = (
                [_safe_emissivity(emissivity_of, p) for p in parts]
                if "surface" in want
                else [np.nan] * len(parts)
            )
            tables = L.PartTables(parts, labels, state.temperatures, eps)
            images = tables.images(hits.part, hits.triangle)
            if "surface" in want and hasattr(scene, "corner_blend"):  # the field the render shades
                images["surface_temperature"] = tables.smooth_temperature(
                    scene, hits.part, hits.triangle, hits.position
                )
            t = self._tick("label_tables", t)
        for name, chans in _CHANNELS_OF.items():
            if name not in want:
                continue
            if name == "normal":
                for k, c in enumerate(chans):
                    channels[c] = hits.normal[..., k]
            else:
                for c in chans:
                    channels[c] = images[c]
        h, w = hits.instance.shape
        camera = Camera.from_pose(state.cameras[sensor.name], w, h)
        if "masks" in want:
            for suffix, pixels in (
                (".instance.png", L.colour_instances(hits.instance)),
                (".region.png", L.colour_regions(images["body_region"])),
                (".region_ids.png", np.asarray(images["body_region"], dtype=np.uint8)),
            ):
                write(rel + suffix, writers.write_png, os.path.join(out_dir, rel + suffix), pixels)
            t = self._tick("masks", t)
        objects = []
        if want & {"boxes", "keypoints", "occlusion", "coco"}:
            objects = self._objects_of(scene, tables, parts, state, camera, hits, sensor)
        if want & {"boxes", "keypoints", "occlusion"}:
            write_json(  # now (4 ms): the objects are shared with COCO below
                os.path.join(out_dir, rel + ".objects.json"),
                {
                    "sensor": sensor.name,
                    "frame": state.frame,
                    "width": w,
                    "height": h,
                    "camera": os.path.join(os.path.dirname(rel), CAMERA_FILE),
                    "objects": objects,
                },
            )
        if self.coco is not None:
            t = time.perf_counter()
            image_id = self.coco.add_image(
                rel + ".png",
                w,
                h,
                humv_sensor=sensor.name,
                humv_frame=state.frame,
                humv_exr=rel + ".exr",
                humv_camera=os.path.join(os.path.dirname(rel), CAMERA_FILE),
            )
            for obj in objects:
                self.coco.add_object(image_id, hits.instance == obj["instance_id"], obj)
            self._tick("coco", t)
        self.images.append({"sensor": sensor.name, "frame": state.frame, "exr": rel + ".exr"})
        return ImageTruth(depth=hits.depth, instance=hits.instance, channels=channels, objects=objects)

    def image_written(self, rel: str, channels: dict) -> None:
        """Region statistics of the image the render just wrote to ``rel + ".exr"`` (``rel`` as
        given to :meth:`annotate`), from its channels as stored (float32), so that
        :meth:`finish` need not read the EXRs back."""
        if "regions" not in self.want:
            return
        t = time.perf_counter()
        exr = rel + ".exr"
        item = next(i for i in reversed(self.images) if i["exr"] == exr)
        stored = {  # as stored (float32); image_regions reads only these
            k: np.asarray(v, dtype=np.float32)
            for k, v in channels.items()
            if np.ndim(v) == 2 and k in R.REGION_INPUTS
        }
        self._region_records += [{**item, **person} for person in R.image_regions(stored)]
        self._regions_done.add(exr)
        self._tick("regions", t)

    @staticmethod
    def _first_hit(scene, camera, tables, directions):
        """(depth along the axis [m], instance id, body region) of the first surface on rays
        from the camera centre (keypoint visibility)."""
        t, part, tri = scene.cast(camera.origin, directions)
        hit = part >= 0
        instance = np.array([scene.parts[p].instance_id if p >= 0 else 0 for p in part])
        return np.where(hit, t * (directions @ camera.forward), np.inf), instance, tables.region_at(part, tri)

    def _objects_of(self, scene, tables, parts, state, camera, hits, sensor) -> list[dict]:
        want = self.want
        by_id: dict[int, list] = {}
        for p in parts:
            if p.instance_id > 0:
                by_id.setdefault(int(p.instance_id), []).append(p)
        persons = {}
        if "keypoints" in want:
            if self._keypoint_prims is None:
                self._keypoint_prims = K.find_keypoint_prims(self.stage)
            cache = UsdGeom.XformCache(Usd.TimeCode(state.frame))
            for prim in self._keypoint_prims:
                info = L.object_info(prim)
                if info.instance_id in by_id:
                    persons[info.instance_id] = K.world_keypoints(prim, state.frame, cache)
        objects = []
        for ident, ps in sorted(by_id.items()):
            info = min((self._object(p.mesh_path) for p in ps), key=lambda o: len(o.prim))
            mask = hits.instance == ident
            obj = {
                "instance_id": ident,
                "class": info.class_name,
                "prim": info.prim,
                "visible_pixels": int(mask.sum()),
            }
            box_full = None
            if want & {"boxes", "occlusion", "coco"}:
                t = time.perf_counter()
                verts, tris = [], []
                n = 0
                for p in ps:
                    v = state.points[p.mesh_path][p.vertex_ids]
                    verts.append(v)
                    tris.append(p.triangles + n)
                    n += len(v)
                verts = np.concatenate(verts)
                tris = np.concatenate(tris)
                still, geometry = self._still_object(sensor.name, ident, camera, verts, tris)
                if not still:
                    geometry["box_full"] = B.full_box(camera, verts[tris])
                    geometry["box_3d"] = B.box_3d(verts)
                    geometry["box_3d_oriented"] = B.box_3d_oriented(verts, camera)
                box_full = geometry["box_full"]
                if "boxes" in want or "coco" in want:
                    obj["box_full"] = copy.deepcopy(box_full)
                    obj["box_visible"] = B.visible_box(mask)
                    obj["box_3d"] = copy.deepcopy(geometry["box_3d"])
                    obj["box_3d_oriented"] = copy.deepcopy(geometry["box_3d_oriented"])
                t = self._tick("boxes" if "boxes" in want else "coco", t)
                if "occlusion" in want:
                    if still:  # the object's own rays do not change: cast the whole box once
                        if geometry.get("cast") is None:
                            geometry["cast"] = B.unoccluded_mask(camera, verts, tris, box_full)
                        unoccluded = geometry["cast"] | mask  # = the cast outside the visible mask
                    else:
                        unoccluded = B.unoccluded_mask(camera, verts, tris, box_full, visible=mask)
                    obj["unoccluded_pixels"] = int(unoccluded.sum())
                    obj["occlusion"] = B.occlusion_fraction(
                        int((mask & unoccluded).sum()), int(unoccluded.sum())
                    )
                    t = self._tick("occlusion", t)
            if "keypoints" in want and info.class_name == "person":
                t = time.perf_counter()
                kp = persons.get(ident)
                if kp is None:
                    obj["keypoints"] = [0.0, 0.0, 0] * 17
                else:
                    vis = K.keypoint_visibility(
                        camera, kp, ident, lambda d: self._first_hit(scene, camera, tables, d)
                    )
                    obj["keypoints"] = vis["keypoints"]
                    obj["keypoints_world_m"] = kp.tolist()
                    obj["keypoints_depth_m"] = vis["depth_m"].tolist()
                t = self._tick("keypoints", t)
            objects.append(obj)
        return objects

    def _still_object(self, sensor_name: str, ident: int, camera: Camera, verts, tris) -> tuple[bool, dict]:
        """(whether the object and the camera are as in this sensor's last frame, the object's
        cached geometry entry). Static scenery (ground, buildings) under a fixed camera keeps its
        boxes and its unoccluded cast; anything that moved is computed again."""
        h = hashlib.blake2b(digest_size=16)
        for a in (camera.origin, camera.forward, camera.right, camera.up, verts, tris):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update(repr((camera.tan_x, camera.tan_y, camera.width, camera.height, tris.shape)).encode())
        digest = h.hexdigest()
        entry = self._still.get((sensor_name, ident))
        if entry is not None and entry["digest"] == digest:
            return True, entry
        entry = {"digest": digest}
        self._still[(sensor_name, ident)] = entry
        return False, entry

    def take_image(self, rel: str) -> dict:
        """The ground truth of the image ``rel`` (as given to :meth:`annotate`), taken out of
        this object so that memory stays flat over frames: ``image`` (sensor, frame, exr),
        ``coco_image`` and ``coco_annotations`` (ids local to the image: image 1, annotations
        1..n), ``regions`` (its region records). The render keeps it in the frame's record file
        and gives the records back to :meth:`finish`."""
        exr = rel + ".exr"
        image = next(i for i in self.images if i["exr"] == exr)
        self.images.remove(image)
        out: dict = {"image": image, "coco_image": None, "coco_annotations": [], "regions": None}
        if self.coco is not None:
            coco_image = next(i for i in self.coco.images if i.get("humv_exr") == exr)
            anns = [a for a in self.coco.annotations if a["image_id"] == coco_image["id"]]
            self.coco.images = [i for i in self.coco.images if i is not coco_image]
            self.coco.annotations = [a for a in self.coco.annotations if a["image_id"] != coco_image["id"]]
            out["coco_image"] = {**coco_image, "id": 1}
            out["coco_annotations"] = [{**a, "id": k + 1, "image_id": 1} for k, a in enumerate(anns)]
        if "regions" in self.want:
            if exr not in self._regions_done:  # not reported through image_written: read it back
                self._region_records += R.images_regions(self._out_dir or ".", [image])
            out["regions"] = [r for r in self._region_records if r["exr"] == exr]
            self._region_records = [r for r in self._region_records if r["exr"] != exr]
            self._regions_done.discard(exr)
        return out

    # --- end of render ----------------------------------------------------------------------
    def finish(
        self, out_dir: str, render_seconds: float | None = None, taken: list[dict] | None = None
    ) -> dict:
        """Write coco.json / regions.json; the manifest's ``ground_truth`` section.

        ``taken``: the images' ground truth as :meth:`take_image` gave it (e.g. read back from
        the render's frame records, also of earlier calls), in the order of the files; default
        what this object still holds."""
        files = {}
        if taken is None:
            taken = [self.take_image(os.path.splitext(i["exr"])[0]) for i in list(self.images)]
        if self.coco is not None:
            t = time.perf_counter()
            coco = CocoBuilder({"stage": self.stage.GetRootLayer().realPath})
            for item in taken:
                if item.get("coco_image") is None:
                    continue
                image_id = len(coco.images) + 1
                coco.images.append({**item["coco_image"], "id": image_id})
                coco.annotations += [
                    {**a, "id": len(coco.annotations) + k + 1, "image_id": image_id}
                    for k, a in enumerate(item["coco_annotations"])
                ]
            coco.write(os.path.join(out_dir, COCO_NAME))
            files["coco"] = COCO_NAME
            self._tick("coco", t)
        if "regions" in self.want and taken:
            t = time.perf_counter()
            R.write_regions(out_dir, [r for item in taken for r in (item.get("regions") or [])])
            files["regions"] = R.REGIONS_NAME
            self._tick("regions", t)
        total = sum(self.timings.values())
        per_frame = []
        if "masks" in self.want:
            per_frame += ["<frame>.instance.png", "<frame>.region.png", "<frame>.region_ids.png"]
        if self.want & {"boxes", "keypoints", "occlusion"}:
            per_frame.append("<frame>.objects.json")
        return {
            "annotators": list(self.annotators),
            "source": self.source,
            "available": list(A.ANNOTATORS),
            "channels": {
                c: CHANNELS[c] for name, chans in _CHANNELS_OF.items() if name in self.want for c in chans
            },
            "files": files,
            "per_frame_files": per_frame,
            "labels": "one ray per pixel centre from the render's own Mitsuba sensor (exact, no Monte Carlo)",
            "keypoint_visibility": {"tolerance_m": K.KEYPOINT_TOLERANCE_M, "regions": K.KEYPOINT_REGIONS},
            "timings_s": {**self.timings, "total": total},
            "timings_note": "ray_cast: the pixel-centre ray cast (depth, instance_id, normals); semantic, "
            "body_region and surface channels come from one table lookup (label_tables); "
            "per-frame PNG/JSON writes are in their annotator's time",
            "cost_relative_to_render": (total / render_seconds) if render_seconds else None,
        }

    def channel_units(self) -> dict:
        return {
            c: writers.channel_info(c, CHANNELS[c])
            for name, chans in _CHANNELS_OF.items()
            if name in self.want
            for c in chans
        }
