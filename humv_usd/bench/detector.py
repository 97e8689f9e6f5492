"""A small person detector trained and scored on a sweep's dataset (issue 27 deliverable 3).

The chain from sweep to trained model, on the CPU, with no deep-learning framework (PyPI's
torchvision is a CUDA build, and no model weights can be fetched): Dalal & Triggs' detector,
histograms of oriented gradients (HOG) of a fixed window and a linear support vector machine,
slid over an image pyramid, with one round of hard-negative mining and greedy non-maximum
suppression. It reads the COCO files of a dataset written by ``humv-usd sweep``
(``coco/<sensor>_<split>.json``, splits by variant: :func:`humv_usd.sweep.dataset.assign_splits`),
trains on ``train``, picks the SVM's ``C`` on ``val`` and reports pycocotools' box AP per split,
so the held-out numbers are ``val`` and ``test``.

References: N. Dalal and B. Triggs, "Histograms of oriented gradients for human detection",
CVPR 2005 (HOG 9 orientations, 2x2-cell blocks, L2-Hys, linear SVM, hard negatives, the
window's 1:2 aspect); P. F. Felzenszwalb et al., "Object detection with discriminatively trained
part-based models", PAMI 2010 (greedy NMS at IoU 0.5 across the pyramid's scales); COCO's
``COCOeval`` for AP (T.-Y. Lin et al., "Microsoft COCO: common objects in context", ECCV 2014).

Needs the ``detector`` extra (``pip install -e .[detector]``: scikit-learn, scikit-image); the
libraries are imported by the functions that use them, so the package imports without them.
"""

from __future__ import annotations

import contextlib
import io
import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image

from humv_usd.errors import InputError

#: the window in pixels (width, height): a standing person's 1:2 box (Dalal & Triggs use 64x128
#: at 6-8 px per cell; ours see people 15-60 px tall, so 4-px cells)
WINDOW = (16, 32)
CELL = 4
ORIENTATIONS = 9
#: the pyramid's window heights grow by this factor (the window slides by one cell)
SCALE_STEP = 1.15
#: jittered copies of each positive (shifts of up to 5 % and scales of up to 7 % of its height,
#: mirrored too): a few dozen people in a small dataset
JITTER = 4
#: negatives per training image (random windows off every person) and hard negatives kept per image
NEGATIVES_PER_IMAGE = 40
HARD_PER_IMAGE = 20
#: the SVM's C chosen on val among these
C_GRID = (0.01, 0.1, 1.0)
NMS_IOU = 0.5
MAX_DETECTIONS = 20
SPLITS = ("train", "val", "test")
EXTRA_HINT = "the detector bench needs scikit-learn and scikit-image: pip install -e '.[detector]'"


def _libraries():
    """(skimage.feature.hog, sklearn.svm.LinearSVC), or one line naming the extra to install."""
    try:
        from skimage.feature import hog
        from sklearn.svm import LinearSVC
    except ImportError as exc:
        raise InputError(f"{EXTRA_HINT} ({exc})") from None
    return hog, LinearSVC


@dataclass
class Split:
    """One split's COCO file: ground truth boxes [x, y, w, h] of the person class per image."""

    name: str
    coco_file: Path
    images: list[dict]
    boxes: dict[int, np.ndarray]
    person_id: int
    variants: list[str] = field(default_factory=list)


def load_splits(dataset: Path, sensor: str | None = None) -> tuple[str, dict[str, Split]]:
    """The sensor (the first with person boxes when None) and its train/val/test COCO files."""
    coco_dir = Path(dataset) / "coco"
    if not coco_dir.is_dir():
        raise InputError(f"dataset = '{dataset}': no coco/ folder (run humv-usd sweep first)")
    sensors = sorted(
        p.stem for p in coco_dir.glob("*.json") if not any(p.stem.endswith("_" + s) for s in SPLITS)
    )
    if sensor is None:
        sensor = next((s for s in sensors if _has_people(coco_dir / f"{s}.json")), None)
        if sensor is None:
            raise InputError(f"dataset = '{dataset}': no sensor's COCO file has a person box")
    elif sensor not in sensors:
        raise InputError(f"--sensor = {sensor!r}: expected one of {', '.join(sensors) or '(none)'}")
    splits = {}
    for name in SPLITS:
        path = coco_dir / f"{sensor}_{name}.json"
        if not path.is_file():
            continue
        doc = json.loads(path.read_text())
        person = next((c["id"] for c in doc["categories"] if c["name"] == "person"), None)
        if person is None:
            raise InputError(f"{path}: no 'person' category")
        boxes: dict[int, list] = {im["id"]: [] for im in doc["images"]}
        for a in doc["annotations"]:
            if (
                a["category_id"] == person
                and not a.get("iscrowd", 0)
                and a["bbox"][2] > 0
                and a["bbox"][3] > 0
            ):
                boxes[a["image_id"]].append(a["bbox"])
        splits[name] = Split(
            name,
            path,
            doc["images"],
            {k: np.asarray(v, float).reshape(-1, 4) for k, v in boxes.items()},
            person,
            sorted({im.get("humv_variant", "") for im in doc["images"]}),
        )
    if "train" not in splits or not splits["train"].images:
        raise InputError(f"dataset = '{dataset}': sensor {sensor!r} has no train split with images")
    return sensor, splits


def _has_people(path: Path) -> bool:
    doc = json.loads(path.read_text())
    person = {c["id"] for c in doc["categories"] if c["name"] == "person"}
    return any(a["category_id"] in person for a in doc["annotations"])


def _gray(split: Split, image: dict) -> np.ndarray:
    """The training image as float grey in [0, 1] (the 8-bit PNG the exports share)."""
    with Image.open(split.coco_file.parent / image["file_name"]) as im:
        return np.asarray(im.convert("L"), np.float32) / 255.0


def _resize(gray: np.ndarray, scale: float) -> np.ndarray:
    h, w = gray.shape
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    return np.asarray(Image.fromarray(gray, mode="F").resize(size, Image.BILINEAR), np.float32)


def _window_box(box, margin: float = 0.15) -> tuple[float, float, float, float]:
    """The 1:2 window [x, y, w, h] around a person box, with a margin (Dalal & Triggs' context)."""
    x, y, w, h = box
    cx, cy = x + w / 2, y + h / 2
    hh = max(h, 2.0 * w) * (1.0 + 2.0 * margin)
    return cx - hh / 4, cy - hh / 2, hh / 2, hh


def _crop(gray: np.ndarray, win) -> np.ndarray:
    """The window resampled to :data:`WINDOW` plus one cell on every side (the scan's gradients
    and blocks at the window's edge see the pixels beyond it; edge pixels repeated outside the
    image)."""
    x, y, w, h = win
    ww, wh = WINDOW
    sx, sy = w / ww, h / wh
    xs = np.clip(x + (np.arange(-CELL, ww + CELL) + 0.5) * sx - 0.5, 0, gray.shape[1] - 1)
    ys = np.clip(y + (np.arange(-CELL, wh + CELL) + 0.5) * sy - 0.5, 0, gray.shape[0] - 1)
    x0, y0 = np.floor(xs).astype(int), np.floor(ys).astype(int)
    x1, y1 = np.minimum(x0 + 1, gray.shape[1] - 1), np.minimum(y0 + 1, gray.shape[0] - 1)
    fx, fy = (xs - x0)[None, :], (ys - y0)[:, None]
    g = gray
    top = g[np.ix_(y0, x0)] * (1 - fx) + g[np.ix_(y0, x1)] * fx
    bottom = g[np.ix_(y1, x0)] * (1 - fx) + g[np.ix_(y1, x1)] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def _blocks(hog, image: np.ndarray) -> np.ndarray:
    """HOG blocks (rows, cols, 2, 2, orientations) of an image: L2-Hys, 2x2-cell blocks."""
    return hog(
        image,
        orientations=ORIENTATIONS,
        pixels_per_cell=(CELL, CELL),
        cells_per_block=(2, 2),
        block_norm="L2-Hys",
        feature_vector=False,
    )


def _features(hog, padded: np.ndarray) -> np.ndarray:
    """The window's feature vector from its padded crop (:func:`_crop`): the blocks inside the
    window, as the scan reads them out of the whole image's blocks."""
    bh, bw = WINDOW[1] // CELL - 1, WINDOW[0] // CELL - 1
    return _blocks(hog, padded)[1 : 1 + bh, 1 : 1 + bw].ravel()


def iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of boxes a (N, 4) and b (M, 4) as [x, y, w, h] -> (N, M)."""
    a, b = np.asarray(a, float).reshape(-1, 4), np.asarray(b, float).reshape(-1, 4)
    x0 = np.maximum(a[:, None, 0], b[None, :, 0])
    y0 = np.maximum(a[:, None, 1], b[None, :, 1])
    x1 = np.minimum(a[:, None, 0] + a[:, None, 2], b[None, :, 0] + b[None, :, 2])
    y1 = np.minimum(a[:, None, 1] + a[:, None, 3], b[None, :, 1] + b[None, :, 3])
    inter = np.clip(x1 - x0, 0, None) * np.clip(y1 - y0, 0, None)
    union = (a[:, 2] * a[:, 3])[:, None] + (b[:, 2] * b[:, 3])[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def nms(boxes: np.ndarray, scores: np.ndarray, threshold: float = NMS_IOU) -> list[int]:
    """Greedy non-maximum suppression: indices kept, best score first."""
    order = list(np.argsort(-np.asarray(scores), kind="stable"))
    keep: list[int] = []
    while order:
        i = order.pop(0)
        keep.append(i)
        if order:
            overlap = iou(boxes[[i]], boxes[order])[0]
            order = [j for j, o in zip(order, overlap) if o <= threshold]
    return keep


def _random_negatives(gray, people: np.ndarray, heights, rng, count: int) -> list:
    """Windows of the people's heights anywhere in the image that overlap no person (IoU < 0.2)."""
    out = []
    h_img, w_img = gray.shape
    for _ in range(count * 4):
        if len(out) >= count:
            break
        h = float(rng.choice(heights)) * float(rng.uniform(0.8, 1.25))
        win = (rng.uniform(-h / 4, w_img - h / 4), rng.uniform(-h / 4, h_img - 3 * h / 4), h / 2, h)
        if len(people) == 0 or iou(np.array([win]), people).max() < 0.2:
            out.append(win)
    return out


class Detector:
    """HOG + linear SVM sliding-window person detector (see the module doc)."""

    def __init__(self, heights: np.ndarray, C: float = 0.1, seed: int = 0):
        hog, svc = _libraries()
        self._hog, self._svc = hog, svc
        self.C, self.seed = C, seed
        lo, hi = float(np.min(heights)), float(np.max(heights))
        # window heights of the pyramid: the training people's box heights with margins, x0.8..x1.25
        self.heights = [w for w in _geometric(lo * 1.3 * 0.8, hi * 1.3 * 1.25, SCALE_STEP)]
        self.train_heights = np.asarray(heights, float) * 1.3
        self.model = None

    def fit(self, samples: list[tuple[np.ndarray, np.ndarray]]) -> dict:
        """Train on (grey image, person boxes) pairs: positives (and their mirror images), random
        negatives, then one round of hard negatives (the false positives of the first model)."""
        rng = np.random.default_rng(self.seed)
        pos, neg = [], []
        for gray, people in samples:
            for box in people:
                x, y, w, h = _window_box(box)
                for k in range(JITTER + 1):
                    dx, dy, ds = rng.uniform(-0.05, 0.05, 3) * (k > 0) * np.array([h, h, 1.4])
                    win = (x + dx - w * ds / 2, y + dy - h * ds / 2, w * (1 + ds), h * (1 + ds))
                    patch = _crop(gray, win)
                    pos += [_features(self._hog, patch), _features(self._hog, patch[:, ::-1])]
            neg += [
                _features(self._hog, _crop(gray, w))
                for w in _random_negatives(gray, people, self.train_heights, rng, NEGATIVES_PER_IMAGE)
            ]
        if not pos:
            raise InputError("the train split has no person box to learn from")
        self._train(pos, neg)
        hard = []
        for gray, people in samples:
            boxes, scores, feats = self._scan(gray, keep_features=True)
            false = [
                f
                for b, s, f in sorted(zip(boxes, scores, feats), key=lambda t: -t[1])
                if s > -1.0 and (len(people) == 0 or iou(np.array([b]), people).max() < 0.3)
            ]
            hard += false[:HARD_PER_IMAGE]
        self._train(pos, neg + hard)
        return {"positives": len(pos), "negatives": len(neg), "hard_negatives": len(hard)}

    def _train(self, pos, neg) -> None:
        x = np.vstack(pos + neg)
        y = np.r_[np.ones(len(pos)), np.zeros(len(neg))]
        self.model = self._svc(C=self.C, class_weight="balanced", max_iter=20000, random_state=self.seed)
        self.model.fit(x, y)

    def _scan(self, gray: np.ndarray, keep_features: bool = False):
        """Every window of the pyramid: boxes [x, y, w, h] in image pixels, SVM scores (and features)."""
        ww, wh = WINDOW
        boxes, scores, feats = [], [], []
        w_vec, b = self.model.coef_.ravel(), float(self.model.intercept_[0])
        cells_w, cells_h = ww // CELL, wh // CELL
        for height in self.heights:
            scale = wh / height
            img = _resize(gray, scale)
            if img.shape[0] < wh or img.shape[1] < ww:
                continue
            blocks = _blocks(self._hog, img)
            bh, bw = cells_h - 1, cells_w - 1  # blocks per window
            rows, cols = blocks.shape[0] - bh + 1, blocks.shape[1] - bw + 1
            if rows < 1 or cols < 1:
                continue
            view = np.lib.stride_tricks.sliding_window_view(blocks, (bh, bw), axis=(0, 1))
            # (rows, cols, 2, 2, orient, bh, bw) -> the window's feature vector in hog()'s order
            f = np.moveaxis(view, (5, 6), (2, 3)).reshape(rows, cols, -1)
            s = f @ w_vec + b
            r, c = np.meshgrid(np.arange(s.shape[0]), np.arange(s.shape[1]), indexing="ij")
            x = c * CELL / scale
            y = r * CELL / scale
            bx = np.stack([x, y, np.full_like(x, ww / scale), np.full_like(y, wh / scale)], -1).reshape(-1, 4)
            boxes.append(bx)
            scores.append(s.ravel())
            if keep_features:
                feats.append(f.reshape(-1, f.shape[-1]))
        if not boxes:
            empty = np.zeros((0, 4))
            return (empty, np.zeros(0), np.zeros((0, 1))) if keep_features else (empty, np.zeros(0))
        boxes, scores = np.vstack(boxes), np.concatenate(scores)
        return (boxes, scores, np.vstack(feats)) if keep_features else (boxes, scores)

    def detect(self, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Person boxes [x, y, w, h] (the window shrunk back by its margin) and scores, after NMS."""
        boxes, scores = self._scan(gray)
        if not len(boxes):
            return boxes, scores
        top = np.argsort(-scores)[:2000]
        boxes, scores = boxes[top], scores[top]
        keep = nms(boxes, scores)[:MAX_DETECTIONS]
        boxes, scores = boxes[keep], scores[keep]
        return _unmargin(boxes), scores


def _unmargin(windows: np.ndarray, margin: float = 0.15) -> np.ndarray:
    """Person boxes inside the windows: the window's height less its margins, a person's width
    of 0.4 of that height (the median training box's aspect is near it)."""
    x, y, w, h = windows.T
    ph = h / (1.0 + 2.0 * margin)
    pw = 0.4 * ph
    cx, cy = x + w / 2, y + h / 2
    return np.stack([cx - pw / 2, cy - ph / 2, pw, ph], -1)


def _geometric(lo: float, hi: float, step: float) -> list[float]:
    out, h = [], lo
    while h <= hi * 1.0001:
        out.append(h)
        h *= step
    return out or [lo]


def coco_ap(split: Split, detections: list[dict]) -> dict:
    """pycocotools' box AP of the person class on ``split``: AP50, AP (0.5:0.95), AR@100."""
    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    with contextlib.redirect_stdout(io.StringIO()):  # pycocotools prints its tables
        gt = COCO(str(split.coco_file))
        if not detections:
            return {"AP50": 0.0, "AP": 0.0, "AR100": 0.0}
        dt = gt.loadRes(detections)
        ev = COCOeval(gt, dt, "bbox")
        ev.params.catIds = [split.person_id]
        ev.params.imgIds = [im["id"] for im in split.images]
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    stats = [max(0.0, float(v)) for v in ev.stats]  # -1: no ground truth of that size
    return {"AP50": stats[1], "AP": stats[0], "AR100": stats[8]}


def _detections(det: Detector, split: Split) -> list[dict]:
    out = []
    for image in split.images:
        boxes, scores = det.detect(_gray(split, image))
        out += [
            {
                "image_id": image["id"],
                "category_id": split.person_id,
                "bbox": [round(float(v), 3) for v in b],
                "score": float(s),
            }
            for b, s in zip(boxes, scores)
        ]
    return out


def bench_detector(dataset: Path, sensor: str | None = None, seed: int = 0, on_line=None) -> dict:
    """Train on the train split (C chosen on val by AP50 when val has people), evaluate on every
    split with pycocotools; the report (also the caller's to write as JSON)."""
    say = on_line or (lambda text: None)
    sensor, splits = load_splits(dataset, sensor)
    train = splits["train"]
    samples = [(_gray(train, im), train.boxes[im["id"]]) for im in train.images]
    heights = (
        np.concatenate([b[:, 3] for _, b in samples if len(b)]) if any(len(b) for _, b in samples) else []
    )
    if not len(heights):
        raise InputError(f"the train split of sensor {sensor!r} has no person box to learn from")
    val = splits.get("val")
    tuning = val is not None and any(len(b) for b in val.boxes.values())
    candidates = C_GRID if tuning else (0.1,)
    best = None
    t0 = time.perf_counter()
    for c in candidates:
        det = Detector(heights, C=c, seed=seed)
        counts = det.fit(samples)
        score = coco_ap(val, _detections(det, val))["AP50"] if tuning else 0.0
        say(
            f"C = {c:g}: {counts['positives']} positives, {counts['negatives']} + {counts['hard_negatives']} negatives; val AP50 {score:.3f}"
        )
        if best is None or score > best[0]:
            best = (score, c, det, counts)
    train_s = time.perf_counter() - t0
    _, c, det, counts = best
    report = {
        "detector": "HOG + linear SVM (Dalal & Triggs 2005), sliding window over an image pyramid",
        "dataset": str(dataset),
        "sensor": sensor,
        "window_px": list(WINDOW),
        "C": c,
        "C_chosen_on": "val AP50" if tuning else "default (val has no person)",
        "training": counts,
        "train_seconds": round(train_s, 2),
        "splits": {},
    }
    for name, split in splits.items():
        t1 = time.perf_counter()
        metrics = coco_ap(split, _detections(det, split))
        report["splits"][name] = {
            "images": len(split.images),
            "people": int(sum(len(b) for b in split.boxes.values())),
            "variants": split.variants,
            **{k: round(v, 4) for k, v in metrics.items()},
            "seconds_per_image": round((time.perf_counter() - t1) / max(1, len(split.images)), 3),
        }
    return report
