"""One dataset out of a sweep's finished render tasks.

Written into DATASET/ (rebuilt from ``renders/`` on every run, so it always lists exactly the
finished tasks, in variant and frame order; a local folder or an fsspec URL, read and written
through :class:`humv_usd.sweep.where.Location`):

* splits by variant (``[dataset] split``, ``split_seed``, ``stratify``: :func:`assign_splits`;
  a variant's frames are near-duplicates, so a split by frame would measure training-set
  accuracy), the same in every export; one training image per record (``[dataset] image``:
  the sensor chain's 8-bit image by default) used by COCO, YOLO and the index alike;
* ``coco/<sensor>.json`` and ``coco/<sensor>_<split>.json`` -- COCO files per sensor over
  every variant / per split: image and annotation ids unique and sequential (a split file keeps
  the full file's ids), ``file_name`` = ``images/<sensor>/<variant>_<frame>.png`` under
  ``coco/`` (hard links to the training images; COCO tools and FiftyOne join it to that
  folder), ``humv_exr`` / ``humv_camera`` relative to ``coco/``, ``humv_variant`` and
  ``humv_split`` on each image, ``num_keypoints`` on every annotation;
* ``index.parquet`` (and ``index_<split>.parquet``) and ``dataset.json`` -- one row per
  variant, frame and sensor: the variant's split and parameters (``param_<axis>`` columns;
  vectors as lists), frame, sensor, band, paths (relative to DATASET/; :func:`humv_usd.sweep.check.load_index`
  loads them absolute from anywhere),
  run time per image [s], Monte Carlo error (IR: mean and 99th percentile of the standard error
  in K away from geometric edges, the render's NETD/3 criterion; EO: of Y relative to mean Y);
* ``README.md`` -- the dataset card: counts, parameter distributions (``card/params.png``),
  contact sheets (``card/contact_<sensor>.png``) and a Hugging Face ``datasets`` header (the
  index as the ``train`` split, for the Hub); locally ``datasets.load_dataset("parquet",
  data_files="DATASET/index.parquet", split="train")`` loads the index (``load_dataset("DATASET")``
  reads the header too, but datasets 4.0 caches a folder with a header by its name and header
  only: a resumed sweep's new rows, or another folder of the same name, come back stale);
* ``yolo/detect/<sensor>/`` and ``yolo/pose/<sensor>/`` -- Ultralytics YOLO exports (images are
  hard links to the training images, copies on an object store, under ``images/<split>/``,
  labels under ``labels/<split>/``; detect: the ``[dataset] detect_classes`` (objects: person,
  prop, panel, vehicle, other, animal, lamp, hvac, fire by default; ground, building and vegetation are in the masks
  only) numbered from 0 in that order, normalised ``class cx cy w h``; pose: persons with the
  17 COCO keypoints ``x y v``; ``data.yaml`` names train/val/test and has no ``path``, so the
  root is its folder).

``humv-usd dataset check DATASET`` reads it as pycocotools, Hugging Face datasets and
Ultralytics do (:mod:`humv_usd.sweep.check`).
"""

from __future__ import annotations

import json
import math
import posixpath
from collections import Counter, defaultdict

import numpy as np

from humv_usd import images
from humv_usd.fileio import jsonable
from humv_usd.groundtruth.coco import RELATIVE_PATH_KEYS, categories
from humv_usd.groundtruth.labels import CLASSES
from humv_usd.sweep.spec import SPLITS
from humv_usd.sweep.where import Location

#: COCO-17 keypoint order mirrored left/right (YOLO pose ``flip_idx``)
COCO_FLIP = [0, 2, 1, 4, 3, 6, 5, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15]
CONTACT_TILES = 16
#: data.yaml has no ``path``: Ultralytics then takes the YAML's folder as the dataset root
#: (``check_det_dataset``); a relative ``path: .`` would resolve against the working directory
#: (or, in older releases, Ultralytics' ``datasets_dir``), not this folder
YOLO_ROOT_NOTE = "# Ultralytics YOLO dataset: the root is this file's folder (no 'path' key)\n"


def assign_splits(variants, fractions: dict, seed: int = 0, stratify=()) -> dict[str, str]:
    """{variant id: split} for train/val/test fractions (issue 27: splits by variant, since a
    variant's frames are near-duplicates).

    The variants are shuffled (``numpy.random.default_rng(seed)``) and grouped by their options
    on the ``stratify`` axes; walking the groups in turn, each variant goes to the split with
    the largest deficit against its fraction so far (a Bresenham-like quota), so every stratum is
    shared out in proportion and the totals are exact to one variant. Splits with a non-zero
    fraction get at least one variant while there are variants to spare (train first, then
    val, then test): Ultralytics needs a non-empty val."""
    ids = [v.id for v in variants]
    if not ids:
        return {}
    rng = np.random.default_rng(seed)
    order = list(rng.permutation(len(ids)))
    key = {v.id: tuple(str(v.params.get(a)) for a in stratify) for v in variants}
    groups: dict[tuple, list[str]] = defaultdict(list)
    for i in order:
        groups[key[ids[i]]].append(ids[i])
    names = [s for s in ("train", "val", "test") if fractions.get(s, 0.0) > 0]
    count = dict.fromkeys(names, 0)
    out: dict[str, str] = {}
    n = 0
    for group in sorted(groups, key=str):
        for vid in groups[group]:
            n += 1
            best = max(names, key=lambda s: (fractions[s] * n - count[s], -names.index(s)))
            out[vid] = best
            count[best] += 1
    for need in names:  # a split with a fraction but no variant takes one from the largest
        if count[need] == 0:
            donor = max(names, key=lambda s: count[s])
            if count[donor] < 2:
                break
            vid = next(v for v in reversed(list(out)) if out[v] == donor)
            out[vid] = need
            count[donor] -= 1
            count[need] += 1
    return out


def _chunks(loc: Location, tasks) -> list[tuple[object, str]]:
    """The finished tasks (those with a done record), each with its folder relative to the root."""
    done = set(loc.glob("renders/*/*/task.json"))
    out = []
    for t in tasks:
        folder = f"renders/{t.variant}/{t.chunk}"
        if f"{folder}/task.json" in done:
            out.append((t, folder))
    return out


def _param_columns(variants) -> dict[str, dict[str, object]]:
    """``param_<name>`` -> {variant id: value}; vectors stay lists of numbers; a column of mixed
    types becomes text."""
    columns: dict[str, dict[str, object]] = defaultdict(dict)
    for v in variants:
        for name, value in v.params.items():
            columns["param_" + name.replace(".", "_").replace("+", "")][v.id] = value
    for name, values in columns.items():
        kinds = {type(x) for x in values.values() if x is not None}
        numeric = kinds <= {int, float} and kinds
        vectors = kinds == {list} and all(
            all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
            for v in values.values()
            if v is not None
        )
        if vectors:
            columns[name] = {k: None if v is None else [float(x) for x in v] for k, v in values.items()}
        elif not numeric and kinds != {str} and kinds != {bool}:
            columns[name] = {
                k: json.dumps(x) if not isinstance(x, str) and x is not None else x for k, x in values.items()
            }
    return columns


def _training_image(fr: dict, choice: str) -> str:
    """The frame's image file (relative to its render folder) for ``[dataset] image``: the sensor
    chain's 8-bit image, its 16-bit counts (infrared) or the render's preview; the preview where
    the chosen one was not written (EO has no counts image)."""
    chain = fr.get("sensor_chain") or {}
    if choice == "counts16" and chain.get("counts_png"):
        return chain["counts_png"]
    if choice != "preview" and chain.get("image8_png"):
        return chain["image8_png"]
    return fr["png"]


def assemble(dataset, sweep, tasks) -> dict:
    """Write the merged COCO files, index, card and YOLO exports; return the summary.
    ``dataset``: a folder, an fsspec URL or a :class:`~humv_usd.sweep.where.Location`."""
    loc = dataset if isinstance(dataset, Location) else Location(dataset)
    by_id = {v.id: v for v in sweep.variants}
    params = _param_columns(sweep.variants)
    settings = getattr(sweep, "dataset", None) or {}
    split_of = assign_splits(
        sweep.variants,
        settings.get("split", {"train": 0.8, "val": 0.1, "test": 0.1}),
        settings.get("split_seed", 0),
        settings.get("stratify", []),
    )
    choice = settings.get("image", "image8")
    rows: list[dict] = []
    coco: dict[str, dict] = {}
    loc.remove("coco")
    for task, rel in _chunks(loc, tasks):
        manifest = loc.read_json(f"{rel}/manifest.json")
        record = loc.read_json(f"{rel}/task.json")
        doc = loc.read_json(f"{rel}/coco.json") if loc.is_file(f"{rel}/coco.json") else None
        images_in_task = sum(len(s["frames"]) for s in manifest["sensors"] + manifest.get("eo_sensors", []))
        per_image_s = record["seconds"] / max(1, images_in_task)
        coco_ids = _merge_coco(coco, doc, rel, task.variant) if doc else {}
        for s in manifest["sensors"] + manifest.get("eo_sensors", []):
            for fr in s["frames"]:
                chain = fr.get("sensor_chain") or {}
                err = fr.get("monte_carlo_error") or {}
                err_k = fr.get("monte_carlo_error_k") or {}  # infrared, away from edges
                err_rel = fr.get("monte_carlo_error_relative") or {}  # EO, away from edges
                stem = fr["exr"].removesuffix(".exr")
                image = f"{rel}/{_training_image(fr, choice)}"
                coco_id = coco_ids.get((s["name"], fr["frame"]))
                if coco_id:  # COCO's image: the training image, linked under coco/images/<sensor>/
                    name = f"images/{s['name']}/{task.variant}_{int(fr['frame']):04d}.png"
                    loc.copy(image, f"coco/{name}")
                    entry = coco[s["name"]]["images"][coco_id - 1]
                    entry.update(file_name=name, humv_split=split_of[task.variant])
                row = {
                    "variant": task.variant,
                    "variant_index": by_id[task.variant].index,
                    "split": split_of[task.variant],
                    "frame": fr["frame"],
                    "sensor": s["name"],
                    "band": s["band"],
                    "image": image,
                    "preview": f"{rel}/{fr['png']}",
                    "exr": f"{rel}/{fr['exr']}",
                    "counts": f"{rel}/{chain['counts_png']}" if chain.get("counts_png") else None,
                    "objects": f"{rel}/{stem}.objects.json",
                    "camera": f"{rel}/{s['camera']}" if s.get("camera") else None,
                    "coco_image_id": coco_id,
                    "render_seed": by_id[task.variant].render_seed,
                    "seconds": per_image_s,
                    "mc_error_k": err_k.get("mean_k"),
                    "mc_error_p99_k": err_k.get("p99_k"),
                    "mc_error_edge_k": err_k.get("edge_mean_k"),
                    # the automatic quality's targets met on the image and every region (None: not judged)
                    "quality_met": (fr.get("quality") or {}).get("met"),
                    "mc_error_relative": err_rel.get("mean"),
                    "mc_error": err.get("radiance_stderr_mean", fr.get("Y_stderr_mean")),
                    "peak_rss_mb": record.get("peak_rss_mb"),
                    "task_peak_rss_mb": record.get("task_peak_rss_mb"),
                }
                row.update({name: values.get(task.variant) for name, values in params.items()})
                rows.append(row)
    for sensor, doc in coco.items():
        loc.write_json(f"coco/{sensor}.json", doc)
        for split in SPLITS:
            loc.write_json(f"coco/{sensor}_{split}.json", _coco_split(doc, split))
    _write_index(loc, rows)
    summary = _summary(sweep, rows, coco)
    loc.write_json("dataset.json", {**summary, "index": jsonable(rows)})
    _write_yolo(loc, coco, rows, settings.get("detect_classes") or list(CLASSES[1:]))
    _write_card(loc, sweep, rows, summary, params)
    return summary


def _coco_split(doc: dict, split: str) -> dict:
    """The images of one split and their annotations (ids kept: the same as in the full file)."""
    images = [img for img in doc["images"] if img.get("humv_split") == split]
    keep = {img["id"] for img in images}
    info = dict(doc["info"], description=f"{doc['info'].get('description', '')}, {split} split")
    return dict(
        doc, info=info, images=images, annotations=[a for a in doc["annotations"] if a["image_id"] in keep]
    )


def _merge_coco(coco: dict, doc: dict, folder: str, variant: str) -> dict:
    """Add one chunk's COCO images/annotations to the per-sensor documents (ids renumbered);
    ``folder``: the chunk's folder relative to the dataset's root."""
    ids = {}
    new_id = {}
    for img in doc["images"]:
        sensor = img.get("humv_sensor", "all")
        merged = coco.setdefault(
            sensor,
            {
                "info": {"description": f"HumV-USD sweep dataset, sensor {sensor}"},
                "licenses": [],
                "images": [],
                "annotations": [],
                "categories": doc.get("categories") or categories(),
            },
        )
        entry = dict(img, id=len(merged["images"]) + 1, humv_variant=variant)
        for key in RELATIVE_PATH_KEYS:
            if isinstance(img.get(key), str):
                entry[key] = posixpath.relpath(f"{folder}/{img[key]}", "coco")
        merged["images"].append(entry)
        new_id[img["id"]] = (sensor, entry["id"])
        ids[(sensor, img.get("humv_frame"))] = entry["id"]
    for ann in doc["annotations"]:
        sensor, image_id = new_id[ann["image_id"]]
        merged = coco[sensor]
        merged["annotations"].append(dict(ann, id=len(merged["annotations"]) + 1, image_id=image_id))
    return ids


def _write_index(loc: Location, rows: list[dict]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    empty = pa.table({"variant": pa.array([], pa.string()), "split": pa.array([], pa.string())})
    table = pa.Table.from_pylist(jsonable(rows)) if rows else empty
    with loc.writing("index.parquet") as tmp:
        pq.write_table(table, tmp)
    for split in SPLITS:  # the Hub's splits (the card's configs header)
        part = [r for r in rows if r["split"] == split]
        with loc.writing(f"index_{split}.parquet") as tmp:
            pq.write_table(
                pa.Table.from_pylist(jsonable(part), schema=table.schema)
                if part
                else table.schema.empty_table(),
                tmp,
            )


def _summary(sweep, rows: list[dict], coco: dict) -> dict:
    per_sensor = Counter(r["sensor"] for r in rows)
    anns = {
        sensor: dict(Counter(CLASSES[a["category_id"]] for a in doc["annotations"]))
        for sensor, doc in coco.items()
    }
    secs = [r["seconds"] for r in rows]
    return {
        "name": sweep.name,
        "sweep_digest": sweep.digest(),
        "variants": len(sweep.variants),
        "variants_with_images": len({r["variant"] for r in rows}),
        "frames": len({(r["variant"], r["frame"]) for r in rows}),
        "images": len(rows),
        "images_per_sensor": dict(per_sensor),
        "annotations_per_sensor": anns,
        "render": sweep.render,
        "seconds_per_image_median": float(np.median(secs)) if secs else None,
        "mc_error_k_median": _median(rows, "mc_error_k"),
        "mc_error_relative_median": _median(rows, "mc_error_relative"),
        "files": {
            "index": "index.parquet",
            "coco": {s: f"coco/{s}.json" for s in coco},
            "yolo": "yolo/",
            "card": "README.md",
        },
    }


# ----------------------------------------------------------------------------- YOLO
def _write_yolo(loc: Location, coco: dict, rows: list[dict], detect_classes: list[str]) -> None:
    """Detection (the ``detect_classes``, renumbered from 0 in that order) and pose (persons,
    COCO-17 keypoints) exports per sensor, with images and labels under ``<split>/`` folders
    and ``data.yaml`` naming each split (val falls back to train where no variant is in val)."""
    loc.remove("yolo")
    image_of = {(r["sensor"], r["coco_image_id"]): r["image"] for r in rows if r["coco_image_id"]}
    det_id = {CLASSES.index(c): i for i, c in enumerate(detect_classes)}
    for sensor, doc in coco.items():
        anns = defaultdict(list)
        splits: set[str] = set()
        for a in doc["annotations"]:
            anns[a["image_id"]].append(a)
        for img in doc["images"]:
            src = image_of.get((sensor, img["id"]))
            if src is None:
                continue
            split = img.get("humv_split", "train")
            stem = f"{img['humv_variant']}_{int(img.get('humv_frame', 0)):04d}"
            w, h = img["width"], img["height"]
            det, pose = [], []
            for a in anns[img["id"]]:
                x, y, bw, bh = a["bbox"]
                box = f"{(x + bw / 2) / w:.6f} {(y + bh / 2) / h:.6f} {bw / w:.6f} {bh / h:.6f}"
                if a["category_id"] in det_id:
                    det.append(f"{det_id[a['category_id']]} {box}")
                if a.get("keypoints"):
                    kp = a["keypoints"]
                    pts = " ".join(
                        f"{kp[i] / w:.6f} {kp[i + 1] / h:.6f} {int(kp[i + 2])}" if kp[i + 2] > 0 else "0 0 0"
                        for i in range(0, len(kp), 3)
                    )
                    pose.append(f"0 {box} {pts}")
            for kind, lines in (("detect", det), ("pose", pose)):
                base = f"yolo/{kind}/{sensor}"
                loc.copy(src, f"{base}/images/{split}/{stem}.png")
                loc.write_text(f"{base}/labels/{split}/{stem}.txt", "".join(line + "\n" for line in lines))
            splits.add(split)
        if not splits:
            continue
        lists = "train: images/train\n" + f"val: images/{'val' if 'val' in splits else 'train'}\n"
        lists += "test: images/test\n" if "test" in splits else ""
        det_yaml = (
            YOLO_ROOT_NOTE
            + lists
            + "names:\n"
            + "".join(f"  {i}: {n}\n" for i, n in enumerate(detect_classes))
        )
        pose_yaml = (
            YOLO_ROOT_NOTE + lists + f"kpt_shape: [17, 3]\nflip_idx: {COCO_FLIP}\nnames:\n  0: person\n"
        )
        loc.write_text(f"yolo/detect/{sensor}/data.yaml", det_yaml)
        loc.write_text(f"yolo/pose/{sensor}/data.yaml", pose_yaml)


# ----------------------------------------------------------------------------- card
def _contact_sheet(loc: Location, paths: list[str], out: str) -> bool:
    """A grid of up to CONTACT_TILES images (evenly spaced over ``paths``) as one PNG."""
    if not paths:
        return False
    step = max(1, len(paths) // CONTACT_TILES)
    tiles = []
    for p in paths[::step][:CONTACT_TILES]:
        with loc.local_copy(p) as local:
            ch = images.read_exr(local)
        if {"R", "G", "B"} <= ch.keys():
            a = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
        else:
            a = np.repeat(next(iter(ch.values()))[..., None], 3, axis=-1)
        tiles.append(np.asarray(a, dtype=np.uint8))
    h, w = tiles[0].shape[:2]
    cols = min(4, len(tiles))
    rows = math.ceil(len(tiles) / cols)
    sheet = np.zeros((rows * (h + 2), cols * (w + 2), 3), np.uint8)
    for i, t in enumerate(tiles):
        yi = (np.arange(h) * t.shape[0] // h)[:, None]
        xi = (np.arange(w) * t.shape[1] // w)[None, :]
        r, c = divmod(i, cols)
        sheet[r * (h + 2) : r * (h + 2) + h, c * (w + 2) : c * (w + 2) + w] = t[yi, xi]
    with loc.writing(out) as tmp:
        images.write_png(tmp, sheet)
    return True


def _param_plots(loc: Location, params: dict, out: str) -> bool:
    if not params:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(params)
    fig, axes = plt.subplots(1, n, figsize=(3.2 * n, 2.6), squeeze=False)
    for ax, (name, values) in zip(axes[0], params.items()):
        vals = list(values.values())
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            ax.hist(vals, bins=min(20, max(3, len(set(vals)))))
        else:
            counts = Counter(str(v) for v in vals)
            ax.bar(range(len(counts)), list(counts.values()))
            ax.set_xticks(range(len(counts)), [k[:14] for k in counts], rotation=60, ha="right", fontsize=6)
        ax.set_title(name.removeprefix("param_"), fontsize=8)
    fig.tight_layout()
    with loc.writing(out) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)
    return True


def _distribution_lines(params: dict) -> list[str]:
    lines = ["| parameter | distribution over variants |", "|---|---|"]
    for name, values in params.items():
        vals = list(values.values())
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            a = np.asarray(vals, float)
            text = f"min {a.min():g}, median {np.median(a):g}, max {a.max():g} ({a.size} values)"
        else:
            text = ", ".join(f"{k}: {c}" for k, c in Counter(str(v) for v in vals).most_common())
        lines.append(f"| {name.removeprefix('param_')} | {text} |")
    return lines


def _median(rows: list[dict], key: str) -> float | None:
    """Median of a column over the rows that have it (None: none has)."""
    values = [r[key] for r in rows if r[key] is not None]
    return float(np.median(values)) if values else None


def _error_text(rows: list[dict]) -> str:
    """A sensor's median Monte Carlo error away from edges: mK (infrared) or % of mean Y (EO)."""
    k, p99, rel = (_median(rows, key) for key in ("mc_error_k", "mc_error_p99_k", "mc_error_relative"))
    if k is not None:
        return f"{k * 1e3:.1f} mK" + (f" (99th percentile {p99 * 1e3:.0f} mK)" if p99 is not None else "")
    if rel is not None:
        return f"{rel * 100:.2f} % of mean Y"
    return "-"


def _split_text(rows: list[dict]) -> str:
    variants = {r["variant"]: r["split"] for r in rows}
    counts = Counter(variants.values())
    return ", ".join(f"{s} {counts.get(s, 0)} variants" for s in SPLITS)


def _write_card(loc: Location, sweep, rows: list[dict], summary: dict, params: dict) -> None:
    lines = [
        "---",
        "configs:",
        "- config_name: default",
        "  data_files:",
        "  - split: train",
        "    path: index_train.parquet",
        "  - split: validation",
        "    path: index_val.parquet",
        "  - split: test",
        "    path: index_test.parquet",
        "---",
        "",
        f"# {sweep.name}: a HumV-USD sweep dataset",
        "",
        f"Made by `humv-usd sweep` from `{sweep.path.name}` (base scenario `{sweep.base_path.name}`): "
        f"{summary['variants']} variants ({summary['variants_with_images']} with images), "
        f"{summary['frames']} frames, {summary['images']} images; render {sweep.render['spp'] or 'automatic'} spp.",
        "",
        "| sensor | images | annotations | Monte Carlo error away from edges (median) |",
        "|---|---|---|---|",
    ]
    for sensor, n in summary["images_per_sensor"].items():
        anns = ", ".join(f"{k} {v}" for k, v in summary["annotations_per_sensor"].get(sensor, {}).items())
        lines.append(
            f"| {sensor} | {n} | {anns or '-'} | {_error_text([r for r in rows if r['sensor'] == sensor])} |"
        )
    present = {r["variant"] for r in rows}  # distributions over the variants with images
    params = {name: {k: v for k, v in values.items() if k in present} for name, values in params.items()}
    lines += ["", "## Parameters (variants with images)", "", *_distribution_lines(params), ""]
    if _param_plots(loc, params, "card/params.png"):
        lines += ["![parameter distributions](card/params.png)", ""]
    lines += ["## Contact sheets", ""]
    for sensor in summary["images_per_sensor"]:
        paths = [r["image"] for r in rows if r["sensor"] == sensor]
        if _contact_sheet(loc, paths, f"card/contact_{sensor}.png"):
            lines += [f"![{sensor}](card/contact_{sensor}.png)", ""]
    lines += [
        "## Files",
        "",
        "- `index.parquet` / `dataset.json`: one row per variant, frame and sensor (parameters as "
        "`param_*` columns, paths relative to this folder, `seconds` per image; Monte Carlo error "
        "of the image: infrared `mc_error_k` / `mc_error_p99_k` the mean / 99th percentile of the "
        "per-pixel standard error [K] over pixels away from geometric edges (the render's NETD/3 "
        "criterion), `mc_error_edge_k` the edge pixels' mean, EO `mc_error_relative` the mean error "
        "of Y over the mean Y away from edges; `mc_error` the mean radiance (EO: Y) standard error "
        "over all pixels; `quality_met` whether the render's automatic quality met its targets on the "
        "image and on every labelled region class, people first: false where it stopped at the sample "
        "cap, null where not judged).",
        "- `coco/<sensor>.json`, `coco/<sensor>_<split>.json`: COCO with RLE masks, boxes, COCO-17 "
        "keypoints (ids unique over the dataset; `file_name` under `coco/images/<sensor>/`).",
        "- `yolo/detect/<sensor>`, `yolo/pose/<sensor>`: Ultralytics YOLO exports with `data.yaml` "
        "(train/val/test folders; detect: the object classes).",
        f"- Splits by variant: {_split_text(rows)}; `split` column in the index, `index_<split>.parquet` per split.",
        "- `renders/<variant>/<chunk>/`: the render outputs (EXR with labels, PNGs, `camera.json`, "
        "`<frame>.objects.json`, manifest); `variants/<variant>/`: each variant's scenario and stage.",
        "",
        "Load the index with Hugging Face `datasets`: "
        '`datasets.load_dataset("parquet", data_files="<this folder>/index.parquet", split="train")` '
        '(it re-reads a changed index; `load_dataset("<this folder>")` caches a local folder by its '
        "name: after a resumed sweep it can return the old rows).",
        "",
    ]
    loc.write_text("README.md", "\n".join(lines))
