"""Issue 27 deliverable 3: a person detector trains on a generated dataset and is scored on
held-out variants (``humv-usd bench detector``, :mod:`humv_usd.bench.detector`).

The end-to-end run (sweep -> COCO splits -> HOG + linear SVM -> pycocotools AP per split) is
``extended`` (left out of ``make test``; ``make test-extended``); the box geometry and the sliding
window's feature layout are checked here cheaply."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from humv_usd.bench import detector as D
from humv_usd.cli.main import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "detector"


def test_iou_of_boxes_against_hand_computed_overlaps():
    a = np.array([[0.0, 0.0, 2.0, 2.0]])
    b = np.array([[1.0, 1.0, 2.0, 2.0], [2.0, 0.0, 1.0, 1.0], [0.0, 0.0, 2.0, 2.0], [0.5, 0.5, 1.0, 1.0]])
    # overlap 1 of union 7; edge contact; identical; contained (1 of 4)
    assert np.allclose(D.iou(a, b), [[1 / 7, 0.0, 1.0, 0.25]])


def test_nms_keeps_the_best_of_each_overlapping_group():
    boxes = np.array([[0, 0, 10, 20], [1, 0, 10, 20], [30, 0, 10, 20], [31, 1, 10, 20]], float)
    scores = np.array([0.5, 0.9, 0.3, 0.8])
    assert D.nms(boxes, scores) == [1, 3]


def test_window_features_of_the_pyramid_equal_hog_of_the_crop():
    """The sliding window reads its features out of one HOG of the whole image: they must be
    those of the window cut out with its padding, as training computes them (the order hog()
    ravels blocks in; gradients at the window's edge see the pixels beyond it)."""
    skimage_feature = pytest.importorskip("skimage.feature")
    hog = skimage_feature.hog
    rng = np.random.default_rng(0)
    image = rng.random((48, 40)).astype(np.float32)
    ww, wh = D.WINDOW
    det = D.Detector.__new__(D.Detector)  # no SVM needed: a linear model of known weights
    det._hog, det.heights = hog, [float(wh)]  # scale 1: windows on the cell grid, no resampling
    w = rng.normal(size=D._features(hog, D._crop(image, (0, 0, ww, wh))).size)
    det.model = type("Linear", (), {"coef_": w[None, :], "intercept_": np.array([0.5])})()
    boxes, scores, feats = det._scan(image, keep_features=True)
    assert len(boxes) == (48 // 4 - wh // 4 + 1) * (40 // 4 - ww // 4 + 1)
    inside = [
        k
        for k, (x, y, bw, bh) in enumerate(boxes)
        if x >= D.CELL and y >= D.CELL and x + bw <= 40 - D.CELL and y + bh <= 48 - D.CELL
    ]
    assert len(inside) >= 10
    for k in inside:
        x, y = (int(round(v)) for v in boxes[k][:2])
        padded = image[y - D.CELL : y + wh + D.CELL, x - D.CELL : x + ww + D.CELL]
        assert np.allclose(feats[k], D._features(hog, padded), atol=1e-6)
        assert np.allclose(D._crop(image, boxes[k]), padded, atol=1e-6)
        assert scores[k] == pytest.approx(float(D._features(hog, padded) @ w + 0.5), rel=1e-5)


def test_without_the_extra_one_line_and_exit_2(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "sklearn", None)  # import sklearn -> ImportError
    monkeypatch.setitem(sys.modules, "sklearn.svm", None)
    result = CliRunner().invoke(main, ["bench", "detector", str(tmp_path)])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "pip install -e '.[detector]'" in lines[0]
    assert not list(tmp_path.iterdir())


@pytest.mark.extended
def test_a_detector_trains_on_a_generated_dataset_and_finds_people_in_held_out_variants(tmp_path):
    """12 variants of examples/detector (6 train, 3 val, 3 test: 9 held-out test images),
    swept, trained and scored; a detector that learnt nothing scores AP50 near 0."""
    pytest.importorskip("skimage")
    pytest.importorskip("sklearn")
    folder = tmp_path / "detector"
    shutil.copytree(EXAMPLE, folder)
    sweep = folder / "sweep.toml"
    sweep.write_text(sweep.read_text().replace("count = 32", "count = 12"))
    report_file = tmp_path / "report.json"
    result = CliRunner().invoke(
        main, ["bench", "detector", str(sweep), "-o", str(tmp_path / "dataset"), "--json", str(report_file)]
    )
    assert result.exit_code == 0, result.output
    report = json.loads(report_file.read_text())
    splits = report["splits"]
    assert set(splits) == {"train", "val", "test"}
    # splits by variant: no variant in two splits, every image has its person
    variants = [set(s["variants"]) for s in splits.values()]
    assert not (variants[0] & variants[1] or variants[0] & variants[2] or variants[1] & variants[2])
    assert [len(v) for v in variants] == [6, 3, 3]
    assert all(s["people"] == s["images"] for s in splits.values())
    assert splits["test"]["AP50"] > 0.5, report
    assert splits["train"]["AP50"] > 0.5, report
