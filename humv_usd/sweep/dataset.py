"""One dataset out of a sweep's finished render tasks.

Written into DATASET/ (rebuilt from ``renders/`` on every run, so it always lists exactly the
finished tasks, in variant and frame order; a local folder or an fsspec URL, read and written
through :class:`humv_usd.sweep.where.Location`):

* ``coco/<sensor>.json`` -- one COCO file per sensor over every variant: image and annotation
  ids unique and sequential, ``file_name`` / ``humv_exr`` / ``humv_camera`` relative to
  ``coco/``, ``humv_variant`` on each image (labels only: byte-identical between an interrupted
  and an uninterrupted sweep);
* ``index.parquet`` and ``dataset.json`` -- one row per variant, frame and sensor: the variant's
  parameters (``param_<axis>`` columns), frame, sensor, band, paths (relative to DATASET/),
  run time per image [s], Monte Carlo error (IR: mean and 99th percentile of the standard error
  in K away from geometric edges, the render's NETD/3 criterion; EO: of Y relative to mean Y);
* ``README.md`` -- the dataset card: counts, parameter distributions (``card/params.png``),
  contact sheets (``card/contact_<sensor>.png``) and a Hugging Face ``datasets`` header (the
  index as the ``train`` split, for the Hub); locally ``datasets.load_dataset("parquet",
  data_files="DATASET/index.parquet", split="train")`` loads the index (``load_dataset("DATASET")``
  reads the header too, but datasets 4.0 caches a folder with a header by its name and header
  only: a resumed sweep's new rows, or another folder of the same name, come back stale);
* ``yolo/detect/<sensor>/`` and ``yolo/pose/<sensor>/`` -- Ultralytics YOLO exports (images are
  hard links to the 8-bit sensor images, copies on an object store; labels normalised ``class cx cy w h`` and, for pose,
  the 17 COCO keypoints ``x y v``; ``data.yaml`` without ``path``, so the root is its folder).
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
from humv_usd.sweep.where import Location

#: COCO-17 keypoint order mirrored left/right (YOLO pose ``flip_idx``)
COCO_FLIP = [0, 2, 1, 4, 3, 6, 5, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15]
CONTACT_TILES = 16
#: data.yaml has no ``path``: Ultralytics then takes the YAML's folder as the dataset root
#: (``check_det_dataset``); a relative ``path: .`` would resolve against the working directory
#: (or, in older releases, Ultralytics' ``datasets_dir``), not this folder
YOLO_ROOT_NOTE = "# Ultralytics YOLO dataset: the root is this file's folder (no 'path' key)\n"


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
    """``param_<name>`` -> {variant id: value}; a column of mixed types becomes text."""
    columns: dict[str, dict[str, object]] = defaultdict(dict)
    for v in variants:
        for name, value in v.params.items():
            columns["param_" + name.replace(".", "_").replace("+", "")][v.id] = value
    for name, values in columns.items():
        kinds = {type(x) for x in values.values() if x is not None}
        numeric = kinds <= {int, float} and kinds
        if not numeric and kinds != {str} and kinds != {bool}:
            columns[name] = {
                k: json.dumps(x) if not isinstance(x, str) and x is not None else x for k, x in values.items()
            }
    return columns


def assemble(dataset, sweep, tasks) -> dict:
    """Write the merged COCO files, index, card and YOLO exports; return the summary.
    ``dataset``: a folder, an fsspec URL or a :class:`~humv_usd.sweep.where.Location`."""
    loc = dataset if isinstance(dataset, Location) else Location(dataset)
    by_id = {v.id: v for v in sweep.variants}
    params = _param_columns(sweep.variants)
    rows: list[dict] = []
    coco: dict[str, dict] = {}
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
                row = {
                    "variant": task.variant,
                    "variant_index": by_id[task.variant].index,
                    "frame": fr["frame"],
                    "sensor": s["name"],
                    "band": s["band"],
                    "image": f"{rel}/{chain.get('image8_png') or fr['png']}",
                    "preview": f"{rel}/{fr['png']}",
                    "exr": f"{rel}/{fr['exr']}",
                    "counts": f"{rel}/{chain['counts_png']}" if chain.get("counts_png") else None,
                    "objects": f"{rel}/{stem}.objects.json",
                    "camera": f"{rel}/{s['camera']}" if s.get("camera") else None,
                    "coco_image_id": coco_ids.get((s["name"], fr["frame"])),
                    "render_seed": by_id[task.variant].render_seed,
                    "seconds": per_image_s,
                    "mc_error_k": err_k.get("mean_k"),
                    "mc_error_p99_k": err_k.get("p99_k"),
                    "mc_error_edge_k": err_k.get("edge_mean_k"),
                    "mc_error_relative": err_rel.get("mean"),
                    "mc_error": err.get("radiance_stderr_mean", fr.get("Y_stderr_mean")),
                    "peak_rss_mb": record.get("peak_rss_mb"),
                    "task_peak_rss_mb": record.get("task_peak_rss_mb"),
                }
                row.update({name: values.get(task.variant) for name, values in params.items()})
                rows.append(row)
    for sensor, doc in coco.items():
        loc.write_json(f"coco/{sensor}.json", doc)
    _write_index(loc, rows)
    summary = _summary(sweep, rows, coco)
    loc.write_json("dataset.json", {**summary, "index": jsonable(rows)})
    _write_yolo(loc, coco, rows)
    _write_card(loc, sweep, rows, summary, params)
    return summary


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

    table = pa.Table.from_pylist(jsonable(rows)) if rows else pa.table({"variant": pa.array([], pa.string())})
    with loc.writing("index.parquet") as tmp:
        pq.write_table(table, tmp)


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
def _write_yolo(loc: Location, coco: dict, rows: list[dict]) -> None:
    """Detection (every class) and pose (persons, COCO-17 keypoints) exports per sensor."""
    loc.remove("yolo")
    image_of = {(r["sensor"], r["coco_image_id"]): r["image"] for r in rows if r["coco_image_id"]}
    names = list(CLASSES[1:])
    for sensor, doc in coco.items():
        anns = defaultdict(list)
        written = False
        for a in doc["annotations"]:
            anns[a["image_id"]].append(a)
        for img in doc["images"]:
            src = image_of.get((sensor, img["id"]))
            if src is None:
                continue
            stem = f"{img['humv_variant']}_{int(img.get('humv_frame', 0)):04d}"
            w, h = img["width"], img["height"]
            det, pose = [], []
            for a in anns[img["id"]]:
                x, y, bw, bh = a["bbox"]
                box = f"{(x + bw / 2) / w:.6f} {(y + bh / 2) / h:.6f} {bw / w:.6f} {bh / h:.6f}"
                det.append(f"{a['category_id'] - 1} {box}")
                if a.get("keypoints"):
                    kp = a["keypoints"]
                    pts = " ".join(
                        f"{kp[i] / w:.6f} {kp[i + 1] / h:.6f} {int(kp[i + 2])}" if kp[i + 2] > 0 else "0 0 0"
                        for i in range(0, len(kp), 3)
                    )
                    pose.append(f"0 {box} {pts}")
            for kind, lines in (("detect", det), ("pose", pose)):
                base = f"yolo/{kind}/{sensor}"
                loc.copy(src, f"{base}/images/{stem}.png")
                loc.write_text(f"{base}/labels/{stem}.txt", "".join(line + "\n" for line in lines))
            written = True
        det_yaml = (
            YOLO_ROOT_NOTE
            + "train: images\nval: images\nnames:\n"
            + "".join(f"  {i}: {n}\n" for i, n in enumerate(names))
        )
        pose_yaml = (
            YOLO_ROOT_NOTE + "train: images\nval: images\nkpt_shape: [17, 3]\n"
            f"flip_idx: {COCO_FLIP}\nnames:\n  0: person\n"
        )
        if written:
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


def _write_card(loc: Location, sweep, rows: list[dict], summary: dict, params: dict) -> None:
    lines = [
        "---",
        "configs:",
        "- config_name: default",
        "  data_files:",
        "  - split: train",
        "    path: index.parquet",
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
        "over all pixels).",
        "- `coco/<sensor>.json`: COCO with RLE masks, boxes, COCO-17 keypoints (ids unique over the dataset).",
        "- `yolo/detect/<sensor>`, `yolo/pose/<sensor>`: Ultralytics YOLO exports with `data.yaml`.",
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
