"""COCO JSON (Lin et al. 2014, cocodataset.org/#format-data) with RLE segmentation.

One file per render (``RENDER_DIR/coco.json``): one COCO image per sensor and frame (its
``file_name`` is the frame's PNG preview, relative to the render folder), one annotation per
object with visible pixels: ``segmentation`` (compressed RLE from ``pycocotools.mask.encode``),
``area`` (visible pixels), ``bbox`` [x, y, w, h] of the visible mask (COCO's convention),
``iscrowd`` 0, for persons ``keypoints`` (COCO-17) and ``num_keypoints`` on every annotation
(0 where there are none: pycocotools' keypoint evaluation reads it from all). HumV extras on each
annotation: ``humv_instance_id``, ``humv_prim``, ``bbox_full`` [x, y, w, h] (projected geometry,
occluded parts included), ``bbox_3d`` (world AABB [m]), ``bbox_3d_oriented`` (yaw-only oriented box: centre, size,
yaw, corners in world and image, see :mod:`humv_usd.groundtruth.boxes`), ``occlusion``. Category ids are
:data:`humv_usd.groundtruth.labels.CLASSES` indices (1 = person); the person category carries
COCO's keypoint names and skeleton.

:func:`merge` joins per-render files into one dataset file: image and annotation ids are
renumbered, file names made relative to the merged file's folder.
"""

from __future__ import annotations

import json
import os

import numpy as np

from humv_usd.errors import InputError
from humv_usd.fileio import write_json
from humv_usd.groundtruth.keypoints import COCO_SKELETON
from humv_usd.groundtruth.labels import CLASSES
from humv_usd.human import labels as AL


def categories() -> list[dict]:
    out = []
    for cid, name in enumerate(CLASSES):
        if cid == 0:
            continue
        cat = {"id": cid, "name": name, "supercategory": "person" if name == "person" else "thing"}
        if name == "person":
            cat["keypoints"] = list(AL.COCO_KEYPOINTS)
            cat["skeleton"] = COCO_SKELETON
        out.append(cat)
    return out


def encode_mask(mask: np.ndarray) -> dict:
    """Compressed RLE of a boolean (H, W) mask, JSON-ready (``counts`` as a str)."""
    from pycocotools import mask as mask_util

    rle = mask_util.encode(np.asfortranarray(mask.astype(np.uint8)))
    return {"size": [int(s) for s in rle["size"]], "counts": rle["counts"].decode("ascii")}


def xyxy_to_xywh(box):
    return None if box is None else [box[0], box[1], box[2] - box[0], box[3] - box[1]]


class CocoBuilder:
    """Accumulates images and annotations of one render."""

    def __init__(self, info: dict | None = None):
        self.images: list[dict] = []
        self.annotations: list[dict] = []
        self.info = info or {}

    def add_image(self, file_name: str, width: int, height: int, **extra) -> int:
        image_id = len(self.images) + 1
        self.images.append(
            {"id": image_id, "file_name": file_name, "width": int(width), "height": int(height), **extra}
        )
        return image_id

    def add_object(self, image_id: int, mask: np.ndarray, obj: dict) -> None:
        """One annotation from an object's visible mask and its per-object record."""
        area = int(mask.sum())
        if area == 0:
            return
        from pycocotools import mask as mask_util

        rle = encode_mask(mask)
        bbox = mask_util.toBbox({"size": rle["size"], "counts": rle["counts"].encode("ascii")}).tolist()
        ann = {
            "id": len(self.annotations) + 1,
            "image_id": image_id,
            "category_id": CLASSES.index(obj["class"]),
            "segmentation": rle,
            "area": area,
            "bbox": [float(v) for v in bbox],
            "iscrowd": 0,
            "humv_instance_id": obj["instance_id"],
            "humv_prim": obj["prim"],
        }
        if "box_full" in obj:
            ann["bbox_full"] = xyxy_to_xywh(obj["box_full"])
        if "box_3d" in obj:
            ann["bbox_3d"] = obj["box_3d"]
        if "box_3d_oriented" in obj:
            ann["bbox_3d_oriented"] = obj["box_3d_oriented"]
        if "occlusion" in obj:
            ann["occlusion"] = obj["occlusion"]
        if obj.get("keypoints") is not None:
            kp = obj["keypoints"]
            ann["keypoints"] = kp
            ann["num_keypoints"] = int(sum(1 for v in kp[2::3] if v > 0))
        else:  # pycocotools' keypoint evaluation reads num_keypoints of every annotation
            ann["num_keypoints"] = 0
        self.annotations.append(ann)

    def document(self) -> dict:
        return {
            "info": {"description": "HumV-USD render", **self.info},
            "licenses": [],
            "images": self.images,
            "annotations": self.annotations,
            "categories": categories(),
        }

    def write(self, path) -> None:
        write_json(path, self.document())


#: image-entry keys holding a path relative to the COCO file's folder (relinked by :func:`merge`)
RELATIVE_PATH_KEYS = ("file_name", "humv_exr", "humv_camera")


def merge(paths, out_path) -> dict:
    """Merge per-render COCO files into one (ids renumbered; the image, EXR and camera-file paths
    relinked relative to ``out_path``)."""
    out_dir = os.path.dirname(os.path.abspath(os.fspath(out_path)))
    merged = {
        "info": {"description": "HumV-USD dataset", "sources": []},
        "licenses": [],
        "images": [],
        "annotations": [],
        "categories": None,
    }
    for path in paths:
        path = os.fspath(path)
        try:
            with open(path, encoding="utf-8") as f:
                doc = json.load(f)
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(f"{path}: cannot read a COCO file ({exc})") from None
        if not all(k in doc for k in ("images", "annotations", "categories")):
            raise InputError(f"{path}: not a COCO file (expected images, annotations, categories)")
        if merged["categories"] is None:
            merged["categories"] = doc["categories"]
        elif [c["name"] for c in doc["categories"]] != [c["name"] for c in merged["categories"]]:
            raise InputError(f"{path}: categories differ from those of {paths[0]}")
        base = os.path.dirname(os.path.abspath(path))
        image_ids = {}
        for img in doc["images"]:
            new = dict(img, id=len(merged["images"]) + 1)
            for key in RELATIVE_PATH_KEYS:  # paths relative to the render folder -> to out_path's
                if isinstance(img.get(key), str):
                    new[key] = os.path.relpath(os.path.join(base, img[key]), out_dir)
            image_ids[img["id"]] = new["id"]
            merged["images"].append(new)
        for ann in doc["annotations"]:
            merged["annotations"].append(
                dict(ann, id=len(merged["annotations"]) + 1, image_id=image_ids[ann["image_id"]])
            )
        merged["info"]["sources"].append(os.path.relpath(os.path.abspath(path), out_dir))
    merged["categories"] = merged["categories"] or categories()
    write_json(out_path, merged)
    return merged
