"""``humv-usd dataset check``: a sweep dataset read the way its consumers read it (issue 27).

* COCO (``coco/<sensor>[_<split>].json``) through pycocotools: the file loads, every
  ``file_name`` is a file under ``coco/`` without ``..`` (FiftyOne and COCO tools join it to an
  images folder), every annotation carries ``num_keypoints``, and the keypoint and box
  evaluations (``COCOeval``) run on the file with its own annotations as detections and score 1;
* the index through Hugging Face ``datasets`` (``load_dataset("parquet", data_files=...)``):
  it loads, has the ``split`` column, and its paths resolve from the dataset root
  (:func:`load_index` loads it with absolute paths from any working directory);
* the YOLO exports by Ultralytics' rules (``ultralytics/data/utils.py``: ``check_det_dataset``,
  ``img2label_paths``, ``verify_image_label``; re-implemented since Ultralytics needs torch):
  ``train``/``val``/``names`` in ``data.yaml`` (pose: ``kpt_shape`` and a ``flip_idx`` that
  is its own inverse), the root is the YAML's folder, each split folder holds images, each
  image has its label file where ``/images/`` becomes ``/labels/``, rows of 5 (detect) or
  5 + 17 x 3 (pose) columns, classes < len(names), coordinates in [0, 1].

:func:`check_dataset` returns the problems as lines (empty: every consumer reads it).
"""

from __future__ import annotations

import contextlib
import io
import json
import posixpath
from pathlib import Path

import numpy as np

IMAGE_SUFFIXES = {".bmp", ".jpeg", ".jpg", ".png", ".tif", ".tiff", ".webp"}
#: index columns holding paths relative to the dataset root
PATH_COLUMNS = ("image", "preview", "exr", "counts", "objects", "camera")


def load_index(root, split: str | None = None, images: bool = False):
    """The dataset index as a Hugging Face ``datasets.Dataset`` whose path columns are absolute,
    so it loads and opens from any working directory; ``split``: 'train', 'val' or 'test' (all
    rows when None); ``images``: the ``image`` column cast to ``datasets.Image()`` (decoded on
    access)."""
    import datasets

    root = Path(root).resolve()
    ds = datasets.load_dataset("parquet", data_files=str(root / "index.parquet"), split="train")
    if split is not None:
        ds = ds.filter(lambda r: r["split"] == split)
    present = [c for c in PATH_COLUMNS if c in ds.column_names]

    def absolute(row):
        return {c: None if row[c] is None else str(root / row[c]) for c in present}

    ds = ds.map(absolute)
    if images:
        ds = ds.cast_column("image", datasets.Image())
    return ds


def check_dataset(root) -> list[str]:
    """Problems of the dataset at ``root`` as its consumers would meet them (see the module)."""
    root = Path(root)
    if not (root / "index.parquet").is_file():
        return [f"{root}: no index.parquet (not a sweep dataset, or not assembled yet)"]
    problems: list[str] = []
    for path in sorted((root / "coco").glob("*.json")):
        problems += [f"{path.relative_to(root)}: {p}" for p in _check_coco(path)]
    problems += [f"index.parquet: {p}" for p in _check_index(root)]
    for yaml_file in sorted((root / "yolo").glob("*/*/data.yaml")):
        task = yaml_file.parent.parent.name
        problems += [f"{yaml_file.relative_to(root)}: {p}" for p in _check_yolo(yaml_file, task)]
    return problems


def _check_coco(path: Path) -> list[str]:
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    out = []
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            gt = COCO(str(path))
    except Exception as exc:  # noqa: BLE001 - whatever pycocotools raises is the finding
        return [f"pycocotools cannot load it ({type(exc).__name__}: {exc})"]
    for img in gt.dataset["images"]:
        name = img["file_name"]
        if ".." in posixpath.normpath(name).split("/") or posixpath.isabs(name):
            out.append(f"image {img['id']}: file_name {name!r} leaves the COCO folder")
        elif not (path.parent / name).is_file():
            out.append(f"image {img['id']}: file_name {name!r} is not a file under {path.parent.name}/")
    missing = [a["id"] for a in gt.dataset["annotations"] if "num_keypoints" not in a]
    if missing:
        out.append(f"{len(missing)} annotations without num_keypoints (first id {missing[0]})")
    anns = gt.dataset["annotations"]
    if not anns or out:
        return out
    for kind in ("bbox", "keypoints"):
        dts = [
            dict(a, score=1.0)
            for a in anns
            if kind == "bbox" or (a.get("keypoints") and a.get("num_keypoints", 0) > 0)
        ]
        if not dts:
            continue
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                ev = COCOeval(gt, gt.loadRes(json.loads(json.dumps(dts))), kind)
                if kind == "keypoints":
                    ev.params.catIds = [1]
                ev.evaluate()
                ev.accumulate()
                ev.summarize()
        except Exception as exc:  # noqa: BLE001
            out.append(f"COCOeval({kind!r}) fails ({type(exc).__name__}: {exc})")
            continue
        if not ev.stats[0] > 0.99:  # its own annotations must score AP = 1
            out.append(f"COCOeval({kind!r}) of the annotations against themselves: AP {ev.stats[0]:.3f} < 1")
    return out


def _check_index(root: Path) -> list[str]:
    try:
        ds = load_index(root)
    except Exception as exc:  # noqa: BLE001
        return [f"Hugging Face datasets cannot load it ({type(exc).__name__}: {exc})"]
    out = []
    if "split" not in ds.column_names:
        out.append("no split column")
    for c in ("image", "exr"):
        if c not in ds.column_names:
            out.append(f"no {c} column")
            continue
        bad = [p for p in ds[c] if p is not None and not Path(p).is_file()]
        if bad:
            out.append(f"{len(bad)} {c} paths do not resolve from the dataset root (first {bad[0]})")
    return out


def _check_yolo(yaml_file: Path, task: str) -> list[str]:
    import yaml
    from PIL import Image

    data = yaml.safe_load(yaml_file.read_text())
    out = [f"no {k!r}" for k in ("train", "val", "names") if k not in data]
    if out:
        return out
    names = data["names"]
    nc = len(names)
    nkpt = ndim = 0
    if task == "pose":
        nkpt, ndim = data.get("kpt_shape", (0, 0))
        flip = data.get("flip_idx", [])
        if ndim not in (2, 3) or len(flip) != nkpt or [flip[i] for i in flip] != list(range(nkpt)):
            out.append("pose: kpt_shape / flip_idx do not match (flip_idx must be its own inverse)")
            return out
    root = Path(data.get("path") or yaml_file.parent)
    cols = 5 + nkpt * ndim if task == "pose" else 5
    for split in ("train", "val", "test"):
        if split not in data:
            continue
        folder = root / data[split]
        files = sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            out.append(f"{split}: no images under {data[split]}")
            continue
        for im_file in files:
            parts = str(im_file).rsplit("/images/", 1)
            label = Path("/labels/".join(parts)).with_suffix(".txt")
            try:
                with Image.open(im_file) as im:
                    im.verify()
                    small = min(im.size) <= 9
            except Exception as exc:  # noqa: BLE001
                out.append(f"{im_file.name}: not an image PIL reads ({exc})")
                continue
            if small:
                out.append(f"{im_file.name}: a side of 9 px or less (Ultralytics drops it)")
            if not label.is_file():
                out.append(f"{im_file.name}: no label file {label.name}")
                continue
            rows = [r.split() for r in label.read_text().splitlines() if r.strip()]
            if not rows:
                continue
            if any(len(r) != cols for r in rows):
                out.append(f"{label.name}: rows of {sorted({len(r) for r in rows})} values, expected {cols}")
                continue
            a = np.array(rows, dtype=float)
            points = a[:, 5:].reshape(len(a), -1, ndim)[..., :2] if task == "pose" else a[:, 1:]
            if a[:, 0].max() >= nc or (a[:, 0] % 1).any():
                out.append(f"{label.name}: a class id outside 0..{nc - 1}")
            if points.size and (points.max() > 1.01 or a.min() < -0.01):
                out.append(f"{label.name}: coordinates outside [0, 1]")
            if len(np.unique(a, axis=0)) != len(a):
                out.append(f"{label.name}: duplicate rows (Ultralytics drops them)")
    return out
