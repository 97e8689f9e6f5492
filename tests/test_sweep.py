"""humv-usd sweep: variants and their validation, the layer keys compose shares, the lock and
staging records, the dataset (COCO per sensor read by pycocotools, parquet index read by
Hugging Face datasets, YOLO), retries, and resuming after kill -9 at random moments."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import ROOT

from humv_usd import images
from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.sweep import store
from humv_usd.sweep.plan import compose_dependencies, layer_keys, render_tasks
from humv_usd.sweep.spec import load_sweep

TINY = """
[general]
name = "tiny"
start = 2018-10-24T14:05:00
utc_offset_h = -4.0
latitude_deg = 39.8
longitude_deg = -84.03
fps = 4.0
duration_s = 0.25
seed = 0

[scene.ground]
material = "concrete"
size_m = [20.0, 20.0]
temperature_k = 297.0

[[scene.object]]
id = "box"
kind = "box"
class = "building"
material = "painted_metal"
center_m = [0.0, 3.0, 0.0]
size_m = [1.0, 0.5, 1.0]
temperature_k = 310.0

[[sensor]]
id = "cam"
band = "LWIR"
resolution = [32, 24]
focal_length_mm = 10.0
position_m = [0.0, -8.0, 1.6]
look_at_m = [0.0, 0.0, 1.0]

[thermal]
model = "fixed"

[atmosphere]
model = "analytic"
"""

SWEEP = """
[sweep]
name = "tiny"
base = "tiny.toml"
count = 2
seed = 3

[grid]
"scene.object.0.temperature_k" = [300.0, 320.0]

[random]
"sensor.0.position_m.0" = { uniform = [-1.0, 1.0] }

[render]
spp = 2
frames_per_task = 1
"""


def _write(tmp_path: Path, sweep: str = SWEEP, base: str = TINY) -> Path:
    (tmp_path / "tiny.toml").write_text(base)
    path = tmp_path / "sweep.toml"
    path.write_text(sweep)
    return path


def _problems(tmp_path, text) -> list[str]:
    with pytest.raises(InputError) as info:
        load_sweep(_write(tmp_path, text))
    return info.value.problems


# ----------------------------------------------------------------------- variants
def test_grid_times_count_with_reproducible_draws(tmp_path):
    sw = load_sweep(_write(tmp_path))
    assert [v.id for v in sw.variants] == ["v0000", "v0001", "v0002", "v0003"]
    temps = [v.scenario["scene"]["object"][0]["temperature_k"] for v in sw.variants]
    assert temps == [300.0, 300.0, 320.0, 320.0]
    xs = [v.scenario["sensor"][0]["position_m"][0] for v in sw.variants]
    assert all(-1.0 <= x <= 1.0 for x in xs) and len(set(xs)) == 4
    assert [v.params["sensor.0.position_m.0"] for v in sw.variants] == xs
    again = load_sweep(_write(tmp_path))
    assert [v.raw for v in again.variants] == [v.raw for v in sw.variants]
    assert sw.digest() == again.digest()
    # the base's other values are untouched
    assert all(v.scenario["sensor"][0]["position_m"][1:] == [-8.0, 1.6] for v in sw.variants)


def test_named_options_append_after_sets_whatever_the_axis_order(tmp_path):
    text = """
[sweep]
base = "tiny.toml"
[grid.extra]
none = {}
panel = { "scene.object+" = [{ id = "panel", kind = "panel", class = "panel", material = "blackbody", center_m = [2.0, 3.0, 0.0], size_m = [1.0, 0.05, 1.0], temperature_k = 330.0 }] }
[grid.objects]
one = { "scene.object" = [{ id = "box2", material = "wood", center_m = [0.0, 4.0, 0.0], size_m = [1.0, 1.0, 1.0] }] }
"""
    sw = load_sweep(_write(tmp_path, text))
    ids = [[o["id"] for o in v.scenario["scene"]["object"]] for v in sw.variants]
    assert ids == [["box2"], ["box2", "panel"]]
    assert [v.params["extra"] for v in sw.variants] == ["none", "panel"]


def test_normal_draws_stay_in_the_allowed_range(tmp_path):
    text = SWEEP.replace(
        '"sensor.0.position_m.0" = { uniform = [-1.0, 1.0] }',
        '"atmosphere.relative_humidity" = { normal = [0.95, 0.3] }\n'
        '"general.start" = { uniform = [2018-10-24T06:00:00, 2018-10-24T18:00:00] }',
    ).replace("count = 2", "count = 200")
    sw = load_sweep(_write(tmp_path, text))
    rh = np.array([v.scenario["atmosphere"]["relative_humidity"] for v in sw.variants])
    assert rh.max() <= 1.0 and rh.min() >= 0.0 and (rh > 0.95).any() and (rh < 0.9).any()
    hours = {v.scenario["general"]["start"].hour for v in sw.variants}
    assert min(hours) >= 6 and max(hours) <= 18 and len(hours) > 6


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ('"scene.object.0.temperatur_k" = [300.0]', "grid axis 'scene.object.0.temperatur_k' key"),
        ('"scene.object.3.temperature_k" = [300.0]', "the base scenario has 1 [[scene.object]]"),
        (
            '"scene.object.0.temperature_k" = [300.0, 5000.0]',
            "grid axis 'scene.object.0.temperature_k' = 5000.0",
        ),
        ('"sensor.0.agc" = ["linear", "loud"]', "grid axis 'sensor.0.agc' = loud"),
    ],
)
def test_a_bad_axis_is_one_line_naming_it(tmp_path, change, expected):
    text = SWEEP.replace('"scene.object.0.temperature_k" = [300.0, 320.0]', change)
    problems = _problems(tmp_path, text)
    assert len(problems) == 1, problems
    assert expected in problems[0]


@pytest.mark.parametrize(
    ("draw", "expected"),
    [
        ("{ uniform = [-10.0, 400.0] }", "outside the key's allowed range -360..360"),
        ("{ normal = [500.0, 1.0] }", "normal mean"),
        ("{ gauss = [0.0, 1.0] }", "expected one of"),
    ],
)
def test_a_bad_random_range_is_checked_against_the_spec(tmp_path, draw, expected):
    text = SWEEP.replace(
        '"sensor.0.position_m.0" = { uniform = [-1.0, 1.0] }', f'"scene.object.0.heading_deg" = {draw}'
    )
    problems = _problems(tmp_path, text)
    assert len(problems) == 1 and expected in problems[0] and "scene.object.0.heading_deg" in problems[0]


def test_bad_axis_on_the_command_line_exit_2_nothing_written(tmp_path):
    path = _write(tmp_path, SWEEP.replace('"scene.object.0.temperature_k"', '"scene.object.0.temperature"'))
    out = tmp_path / "dataset"
    r = CliRunner().invoke(main, ["sweep", str(path), "-o", str(out)])
    assert r.exit_code == 2
    lines = [x for x in r.output.splitlines() if x.strip()]
    assert len(lines) == 1 and "grid axis 'scene.object.0.temperature'" in lines[0]
    assert not out.exists()


def test_dry_run_prints_variants_and_cost(tmp_path):
    out = tmp_path / "dataset"
    r = CliRunner().invoke(
        main, ["sweep", str(_write(tmp_path)), "-o", str(out), "--dry-run", "--workers", "2"]
    )
    assert r.exit_code == 0, r.output
    assert r.output.count("\nv000") + r.output.startswith("v000") == 4
    assert "4 variants, 8 render tasks, 8 frames, 8 images" in r.output
    assert "estimated cost" in r.output and not out.exists() and "already in" not in r.output
    assert "estimated disk: 0.0 GB (" in r.output and " free at " in r.output


def test_dry_run_disk_estimate_and_warning_when_it_does_not_fit(tmp_path, monkeypatch):
    import shutil as shutil_mod
    from collections import namedtuple

    from humv_usd.sweep.plan import DISK_BYTES_PER_PIXEL, DISK_BYTES_PER_VARIANT_FRAME, estimate, layer_keys

    sw = load_sweep(_write(tmp_path))
    est = estimate(sw, {v.id: layer_keys(v.scenario) for v in sw.variants}, 2)
    # 8 images of 32 x 24 IR pixels, 4 variants of 2 frames
    want = 8 * 32 * 24 * DISK_BYTES_PER_PIXEL["ir"] + 4 * 2 * DISK_BYTES_PER_VARIANT_FRAME
    assert est["disk_bytes"] == pytest.approx(want) and est["disk_gb"] == round(want / 1e9, 1)
    # what a dataset holds is not counted again: 2 tasks done (variant v0000), v0000 composed
    v0 = {(t.variant, t.chunk) for t in render_tasks(sw) if t.variant == "v0000"}
    left = estimate(sw, {v.id: layer_keys(v.scenario) for v in sw.variants}, 2, v0, {"v0000"})
    want_left = 6 * 32 * 24 * DISK_BYTES_PER_PIXEL["ir"] + 3 * 2 * DISK_BYTES_PER_VARIANT_FRAME
    assert left["disk_bytes"] == pytest.approx(want_left) and left["images_todo"] == 6
    assert (left["tasks_done"], left["frames_done"], left["images"]) == (2, 2, 8)
    assert left["render_s"] == pytest.approx(est["render_s"] * 6 / 8)
    assert left["layers_to_build"] < est["layers_to_build"]
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil_mod, "disk_usage", lambda p: usage(1, 1, 1000))  # 1 kB free
    r = CliRunner().invoke(main, ["sweep", str(_write(tmp_path)), "-o", str(tmp_path / "d"), "--dry-run"])
    assert r.exit_code == 0 and "WARNING: more than is free" in r.output
    # the run refuses it: one line, nothing written
    r = CliRunner().invoke(
        main, ["sweep", str(_write(tmp_path)), "-o", str(tmp_path / "d"), "--workers", "0"]
    )
    assert r.exit_code == 2 and "pass --yes" in r.output and len(r.output.strip().splitlines()) == 1
    assert "4.88 MB left to write (8 images, 4 variants to compose), 1 kB free at " in r.output
    assert not (tmp_path / "d").exists()


def test_layer_keys_are_compose_keys_and_shared_layers_are_found(tmp_path):
    from humv_usd.pipeline.compose import compose

    sw = load_sweep(_write(tmp_path))
    v = sw.variants[0]
    compose(v.scenario, tmp_path / "c")
    report = json.loads((tmp_path / "c" / "compose.json").read_text())
    assert layer_keys(v.scenario) == {e["name"]: e["key"] for e in report["layers"] if "key" in e}
    keys = {x.id: layer_keys(x.scenario) for x in sw.variants}
    # camera moves only: v0001 shares everything but sensors, atmosphere_paths and thermal with
    # v0000 (thermal refines the ground's shadow edges to the closest camera's pixel footprint)
    same = {n for n in keys["v0000"] if keys["v0000"][n] == keys["v0001"][n]}
    assert same == {"environment", "atmosphere", "materials", "scene"}
    deps = compose_dependencies(keys)
    assert deps["v0000"] == [] and deps["v0001"] == ["v0000"] and deps["v0003"] == ["v0000", "v0002"]
    tasks = render_tasks(sw)
    assert [t.name for t in tasks][:2] == ["v0000/f0000-0000", "v0000/f0001-0001"] and len(tasks) == 8


def test_examples_table1_and_random(tmp_path):
    t1 = load_sweep(ROOT / "examples" / "table1.toml")
    assert len(t1.variants) >= 80
    combos = {tuple(sorted(v.params.items())) for v in t1.variants}
    assert len(combos) == len(t1.variants)
    assert {v.scenario["human"][0]["activity"] for v in t1.variants} == {"standTurn", "walk", "postExercise"}
    assert {v.scenario["human"][0]["sex"] for v in t1.variants} == {"male", "female"}
    rnd = load_sweep(ROOT / "examples" / "random_sweep.toml")
    assert len(rnd.variants) >= 10 and len({v.scenario["general"]["start"] for v in rnd.variants}) > 1


def _table1_variant(t1, **params):
    return next(v for v in t1.variants if all(v.params[k] == x for k, x in params.items()))


def test_outfits_share_one_avatar_layer_and_it_is_the_same_layer():
    from humv_usd.avatar.layer import build_one
    from humv_usd.usd.layers import layer_text

    t1 = load_sweep(ROOT / "examples" / "table1.toml")
    same = {"illumination": "full_sun", "human.0.activity": "walk", "weapon": "none", "gender": "male"}
    shorts = _table1_variant(t1, clothing="bare_upper_body_shorts", **same)
    robe = _table1_variant(t1, clothing="robe", **same)
    a, b = layer_keys(shorts.scenario), layer_keys(robe.scenario)
    assert a["avatar_p1"] == b["avatar_p1"] and a["clothing_p1"] != b["clothing_p1"]
    # equal keys must mean equal layers: the avatar reads nothing else of the clothing
    built = [layer_text(build_one(v.scenario, v.scenario["human"][0])) for v in (shorts, robe)]
    assert built[0] == built[1]
    # the rifle changes the arms' pose, so it changes the avatar; so do the sex and the activity
    rifle = _table1_variant(t1, clothing="robe", **{**same, "weapon": "rifle"})
    female = _table1_variant(t1, clothing="robe", **{**same, "gender": "female"})
    stand = _table1_variant(t1, clothing="robe", **{**same, "human.0.activity": "standTurn"})
    for other in (rifle, female, stand):
        assert layer_keys(other.scenario)["avatar_p1"] != b["avatar_p1"]


def test_table1_composes_one_avatar_per_body_motion_and_carry():
    t1 = load_sweep(ROOT / "examples" / "table1.toml")
    keys = {v.id: layer_keys(v.scenario) for v in t1.variants}
    avatars = {k["avatar_p1"] for k in keys.values()}
    assert len(avatars) == 2 * 3 * 2  # gender x activity x weapon (not x 7 outfits x 2 illuminations)
    unique = {(n, k) for lk in keys.values() for n, k in lk.items()}
    # 543 before; 387 until the women wore tied hair (s8): the materials layer reads the garment
    # names, so hair_short / hair_tied split its 28 keys by gender (56)
    assert len(unique) == 415 and sum(len(lk) for lk in keys.values()) == 1512


# ----------------------------------------------------------------------- lock and records
def test_a_live_sweep_holds_the_folder_a_dead_ones_lock_is_taken_over(tmp_path):
    lock = tmp_path / store.SWEEP_DIR / store.LOCK_NAME
    lock.parent.mkdir(parents=True)
    import socket

    lock.write_text(json.dumps({"pid": os.getppid(), "host": socket.gethostname()}))
    with pytest.raises(InputError, match=f"another sweep \\(pid {os.getppid()}"):
        with store.dataset_lock(tmp_path):
            pass
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    lock.write_text(json.dumps({"pid": dead.pid, "host": socket.gethostname()}))
    with store.dataset_lock(tmp_path):
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    assert not lock.exists()


def test_cli_refuses_a_folder_another_sweep_is_writing(tmp_path):
    import socket

    out = tmp_path / "dataset"
    (out / store.SWEEP_DIR).mkdir(parents=True)
    (out / store.SWEEP_DIR / store.LOCK_NAME).write_text(
        json.dumps({"pid": os.getppid(), "host": socket.gethostname()})
    )
    r = CliRunner().invoke(
        main, ["sweep", str(_write(tmp_path)), "-o", str(out), "--workers", "0", "--quiet"]
    )
    assert r.exit_code == 2 and "another sweep" in r.output
    assert sorted(p.name for p in (out / store.SWEEP_DIR).iterdir()) == [store.LOCK_NAME]


def test_a_chunk_lands_once(tmp_path):
    final = store.render_folder(tmp_path, "v0", "f0000-0000")
    for i in range(2):
        staging = store.staging_folder(tmp_path, "v0/f0000-0000")
        (staging / store.TASK_RECORD).write_text(json.dumps({"try": i}))
        assert store.commit(staging, final) == (i == 0)
        assert not staging.exists()
    assert json.loads((final / store.TASK_RECORD).read_text()) == {"try": 0}


# ----------------------------------------------------------------------- end to end
def _files(dataset: Path, suffix: str) -> dict[str, bytes]:
    return {
        p.relative_to(dataset).as_posix(): p.read_bytes()
        for p in sorted((dataset / "renders").rglob(f"*{suffix}"))
    }


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny sweep run uninterrupted, in this process."""
    tmp = tmp_path_factory.mktemp("sweep_ref")
    path = _write(tmp)
    from humv_usd.sweep.run import run_sweep

    result = run_sweep(load_sweep(path), tmp / "dataset", workers=0)
    return tmp, path, tmp / "dataset", result


@pytest.mark.slow
def test_one_dataset_out(reference):
    from pycocotools.coco import COCO

    tmp, path, dataset, result = reference
    assert result.failures == [] and result.ran == 8 and result.images_rendered == 8
    coco = COCO(str(dataset / "coco" / "cam.json"))
    ids = [img["id"] for img in coco.dataset["images"]]
    assert ids == list(range(1, 9))
    assert len({a["id"] for a in coco.dataset["annotations"]}) == len(coco.dataset["annotations"]) > 0
    assert [img["humv_variant"] for img in coco.dataset["images"]] == [f"v000{i // 2}" for i in range(8)]
    for img in coco.dataset["images"]:  # relinked paths resolve from coco/
        assert (dataset / "coco" / img["file_name"]).is_file() and (
            dataset / "coco" / img["humv_exr"]
        ).is_file()
    ann = coco.dataset["annotations"][0]
    assert coco.annToMask(ann).sum() == ann["area"]

    import datasets

    ds = datasets.load_dataset("parquet", data_files=str(dataset / "index.parquet"), split="train")
    assert ds.num_rows == 8
    assert set(ds.column_names) >= {"variant", "frame", "sensor", "image", "exr", "mc_error_k", "seconds"}
    assert sorted(ds["param_scene_object_0_temperature_k"]) == [300.0] * 4 + [320.0] * 4
    for row in ds:
        assert (dataset / row["image"]).is_file() and row["mc_error_k"] > 0
        # the error column is the render's NETD/3 metric (away from edges), not the all-pixel mean
        manifest = json.loads((dataset / Path(row["exr"]).parents[1] / "manifest.json").read_text())
        (fr,) = [f for s in manifest["sensors"] for f in s["frames"] if f["frame"] == row["frame"]]
        assert row["mc_error_k"] == fr["monte_carlo_error_k"]["mean_k"]
        assert row["mc_error_p99_k"] == fr["monte_carlo_error_k"]["p99_k"] > 0
        assert row["quality_met"] == fr["quality"]["met"]  # issue 25: targets met, or stopped at the cap
        assert row["mc_error_relative"] is None
        assert 0 < row["task_peak_rss_mb"] <= row["peak_rss_mb"]  # the task's own, the worker's so far
    summary = json.loads((dataset / "dataset.json").read_text())
    assert summary["images"] == 8 and summary["images_per_sensor"] == {"cam": 8}
    card = (dataset / "README.md").read_text()
    median_mk = np.median(ds["mc_error_k"]) * 1e3
    assert (
        "| cam | 8 |" in card
        and f"| {median_mk:.1f} mK" in card
        and (dataset / "card" / "contact_cam.png").is_file()
    )
    sheet = images.read_exr(dataset / "card" / "contact_cam.png")
    assert sheet["R"].shape == (2 * 26, 4 * 34)
    labels = sorted((dataset / "yolo" / "detect" / "cam" / "labels").rglob("*.txt"))
    assert len(labels) == 8
    n_lines = sum(len(p.read_text().splitlines()) for p in labels)
    # detection is of objects (person, prop, panel, vehicle, other): the tiny scene's ground and
    # building box are stuff, in the masks only (they were 72 of 113 boxes, often image-wide)
    assert n_lines == 0 and {a["category_id"] for a in coco.dataset["annotations"]} == {2, 3}


# Ultralytics' reading of a YOLO dataset (ultralytics/data/utils.py: check_det_dataset,
# img2label_paths, verify_image_label; docs.ultralytics.com/datasets/detect and /pose),
# re-implemented here because ultralytics needs torch:
#  1. the YAML needs train, val and names (nc = len(names)); pose also kpt_shape [nkpt, ndim]
#     (ndim 2 or 3) and flip_idx of nkpt entries (a left/right permutation: applied twice, the
#     identity);
#  2. the root is `path`, else the YAML's folder; a relative root that does not exist from the
#     working directory is taken under Ultralytics' datasets_dir; train/val are under the root;
#  3. an image's labels: the last /images/ of its path replaced by /labels/, suffix .txt;
#  4. an image opens and verifies with PIL, both sides > 9 px, a known format;
#  5. a label row has 5 columns (detect) or 5 + nkpt * ndim (pose); coordinates <= 1.01, every
#     value >= -0.01, class < nc; duplicate rows are dropped (we want none).
IMG_FORMATS = {"bmp", "dng", "jpeg", "jpg", "mpo", "png", "tif", "tiff", "webp", "pfm", "heic"}


def _ultralytics_read(yaml_file: str, task: str, datasets_dir: Path) -> list[tuple[str, np.ndarray]]:
    import yaml
    from PIL import Image

    data = yaml.safe_load(Path(yaml_file).read_text())
    assert "train" in data and "val" in data and "names" in data
    names = data["names"]
    nc = len(names)
    assert sorted(names) == list(range(nc)) if isinstance(names, dict) else True
    nkpt, ndim = data["kpt_shape"] if task == "pose" else (0, 0)
    if task == "pose":
        flip = data["flip_idx"]
        assert ndim in (2, 3) and len(flip) == nkpt and [flip[i] for i in flip] == list(range(nkpt))
    root = Path(data.get("path") or Path(yaml_file).parent)
    if not root.exists() and not root.is_absolute():
        root = (datasets_dir / root).resolve()
    out = []
    for split in ("train", "val"):
        folder = (root / data[split]).resolve()
        files = sorted(str(p) for p in folder.rglob("*.*") if p.suffix[1:].lower() in IMG_FORMATS)
        assert files, f"{split}: no images under {folder}"
        for im_file in files:
            sa, sb = f"{os.sep}images{os.sep}", f"{os.sep}labels{os.sep}"
            lb_file = sb.join(im_file.rsplit(sa, 1)).rsplit(".", 1)[0] + ".txt"
            im = Image.open(im_file)
            im.verify()
            assert min(im.size) > 9 and im.format.lower() in IMG_FORMATS
            rows = [x.split() for x in Path(lb_file).read_text().strip().splitlines() if x]
            cols = 5 + nkpt * ndim if task == "pose" else 5
            lb = (
                np.array(rows, dtype=np.float32) if rows else np.zeros((0, cols), np.float32)
            )  # empty: no object
            if len(lb):
                assert lb.ndim == 2 and lb.shape[1] == cols
                points = lb[:, 5:].reshape(-1, ndim)[:, :2] if task == "pose" else lb[:, 1:]
                assert points.max() <= 1.01 and lb.min() >= -0.01 and lb[:, 0].max() < nc
                assert len(np.unique(lb, axis=0)) == len(lb)
            out.append((im_file, lb))
    return out


PERSON = """
[[human]]
id = "p1"
activity = "walk"
clothing = []

[[placement]]
human = "p1"
position_m = [0.0, 0.0, 0.0]
heading_deg = 90.0
"""


@pytest.fixture(scope="module")
def person_dataset(tmp_path_factory):
    """A tiny sweep with a walking person seen at 96x72 (keypoints for the pose export)."""
    from humv_usd.sweep.run import run_sweep

    tmp = tmp_path_factory.mktemp("sweep_person")
    base = TINY.replace("resolution = [32, 24]", "resolution = [96, 72]") + PERSON
    sweep = SWEEP.replace("count = 2", "count = 1").replace("[300.0, 320.0]", "[300.0]")
    run_sweep(load_sweep(_write(tmp, sweep, base)), tmp / "dataset", workers=0)
    return tmp / "dataset"


@pytest.mark.slow
def test_yolo_export_reads_as_ultralytics_reads_it_from_anywhere(person_dataset, tmp_path, monkeypatch):
    dataset = person_dataset
    coco = json.loads((dataset / "coco" / "cam.json").read_text())
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # neither the dataset nor its parent: the root must be the YAML's folder
    for task in ("detect", "pose"):
        yaml_file = os.path.relpath(dataset / "yolo" / task / "cam" / "data.yaml")
        read = _ultralytics_read(yaml_file, task, datasets_dir=tmp_path / "ultralytics_datasets")
        # one variant: all in train, and val falls back to train (Ultralytics needs a val)
        assert len(read) == 2 * len(coco["images"])
        rows = np.concatenate([lb for _, lb in read[: len(coco["images"])]])
        people = [a for a in coco["annotations"] if a["category_id"] == 1]
        assert people and len(people) < len(coco["annotations"])  # a person, the box and ground
        assert len(rows) == len(people)  # detect: objects only (the box is a building)
        if task == "pose":  # visible keypoints of the people, in pixels again, as in COCO
            w, h = coco["images"][0]["width"], coco["images"][0]["height"]
            kp = rows[:, 5:].reshape(-1, 17, 3)
            ref = np.array([a["keypoints"] for a in people], float).reshape(-1, 17, 3)
            assert ((kp[..., 2] > 0) == (ref[..., 2] > 0)).all()
            seen = ref[..., 2] > 0
            assert np.allclose(kp[seen][:, 0] * w, ref[seen][:, 0], atol=1e-3 * w)
            assert np.allclose(kp[seen][:, 1] * h, ref[seen][:, 1], atol=1e-3 * h)


@pytest.mark.slow
def test_rerun_does_nothing_and_changes_no_label(reference):
    from humv_usd.sweep.run import run_sweep

    tmp, path, dataset, _ = reference
    before = (dataset / "coco" / "cam.json").read_bytes(), _files(dataset, ".json")
    again = run_sweep(load_sweep(path), dataset, workers=0)
    assert again.already_done == 8 and again.ran == 0 and again.composed == 0
    assert (dataset / "coco" / "cam.json").read_bytes() == before[0]
    assert _files(dataset, ".json") == before[1]


@pytest.mark.slow
def test_failed_tasks_are_retried_then_reported_without_stopping_the_others(tmp_path, monkeypatch):
    from humv_usd.sweep import run as run_mod

    real = run_mod.render_chunk
    calls: dict[str, int] = {}

    def flaky(dataset, variant, chunk, frames, settings):
        calls[f"{variant}/{chunk}"] = calls.get(f"{variant}/{chunk}", 0) + 1
        if variant == "v0001" and chunk == "f0000-0000" and calls[f"{variant}/{chunk}"] == 1:
            raise RuntimeError("transient")
        if variant == "v0002" and chunk == "f0001-0001":
            raise RuntimeError("always broken")
        return real(dataset, variant, chunk, frames, settings)

    monkeypatch.setattr(run_mod, "render_chunk", flaky)
    text = SWEEP.replace("frames_per_task = 1", "frames_per_task = 1\nretries = 1")
    result = run_mod.run_sweep(load_sweep(_write(tmp_path, text)), tmp_path / "dataset", workers=0)
    assert result.retries == 2 and calls["v0002/f0001-0001"] == 2 and calls["v0001/f0000-0000"] == 2
    assert [f["task"] for f in result.failures] == ["render v0002/f0001-0001"]
    assert "always broken" in result.failures[0]["error"]
    assert result.ran == 7 and result.dataset_summary["images"] == 7
    assert (tmp_path / "dataset" / ".sweep" / "failed" / "render-v0002_f0001-0001.json").is_file()


def _workers(pid: int) -> list[int]:
    """Dask worker processes the local cluster of client ``pid`` spawned."""
    out = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                ppid = int((p / "stat").read_text().rsplit(")", 1)[1].split()[1])
                cmdline = (p / "cmdline").read_bytes().decode(errors="replace")
            except (OSError, IndexError, ValueError):
                continue
            if ppid == pid and "spawn_main" in cmdline:
                out.append(int(p.name))
    return out


#: the kill test's sweep: 4 variants x 6 frames, one frame per task (24 chunks of 160 x 120,
#: long enough to be killed in: the tiny sweep's 8 chunks of 32 x 24 pixels land in bursts of
#: 2-3 after a restart, and 16 chunks of 96 x 72 all landed within a second on the idle machine)
KILL_BASE = TINY.replace("duration_s = 0.25", "duration_s = 1.25").replace("[32, 24]", "[160, 120]")


@pytest.mark.slow
def test_kill_9_at_random_moments_loses_nothing(tmp_path):
    """Kill the sweep (client and its local cluster: the whole process group, as a crash would;
    or one worker process) with SIGKILL at 5 random moments while chunks render, re-run the same
    command each time, and compare with the uninterrupted sweep: no frame lost, duplicated or
    different."""
    from humv_usd.sweep.run import run_sweep

    (tmp_path / "ref").mkdir()
    ref = tmp_path / "ref" / "dataset"
    run_sweep(load_sweep(_write(tmp_path / "ref", base=KILL_BASE)), ref, workers=0)
    n_chunks = len(list((ref / "renders").glob("*/*/task.json")))
    assert n_chunks == 24
    path = _write(tmp_path, base=KILL_BASE)
    dataset = tmp_path / "dataset"
    cmd = [sys.executable, "-m", "humv_usd.cli.main", "sweep", str(path), "-o", str(dataset), "--quiet"]
    cmd += ["--workers", "2"]
    rng = random.Random(16)
    kills = []

    def done() -> int:
        return len(list((dataset / "renders").glob("*/*/task.json")))

    for k in range(5):
        proc = subprocess.Popen(
            cmd, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        # a random moment while chunks are rendering: after the next chunk has landed, plus 0-0.5 s
        target, t0 = min(n_chunks - 1, done() + 1), time.monotonic()
        while done() < target and proc.poll() is None and time.monotonic() - t0 < 180:
            time.sleep(0.05)
        time.sleep(rng.uniform(0.0, 0.5))
        target_kind = "group"
        if proc.poll() is None:
            workers = _workers(proc.pid) if k % 2 else []
            if workers:  # a worker process (its nanny starts a new one; Dask reschedules the task)
                target_kind = "worker"
                os.kill(rng.choice(workers), signal.SIGKILL)
                time.sleep(rng.uniform(0.2, 0.8))
            os.killpg(proc.pid, signal.SIGKILL)  # then the client and its cluster, as a crash
            proc.wait()
        kills.append((round(time.monotonic() - t0, 1), target_kind, done()))
    print("kills (delay s, target, chunks done):", kills)
    assert sum(n < n_chunks for *_, n in kills) >= 4  # mid-sweep, not after the last chunk
    final = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    assert final.returncode == 0, final.stderr
    assert not any((dataset / ".sweep" / "staging").iterdir())
    assert not (dataset / ".sweep" / "lock").exists()
    # every frame once: the index, the merged COCO and the per-frame labels equal the reference
    idx = json.loads((dataset / "dataset.json").read_text())["index"]
    keys = [(r["variant"], r["frame"], r["sensor"]) for r in idx]
    assert len(keys) == len(set(keys)) == n_chunks
    assert (dataset / "coco" / "cam.json").read_bytes() == (ref / "coco" / "cam.json").read_bytes()
    assert _files(dataset, ".objects.json") == _files(ref, ".objects.json")
    # a chunk's own coco.json differs only in its info (the stage's absolute path)
    strip = lambda files: {k: {**json.loads(v), "info": None} for k, v in files.items()}  # noqa: E731
    assert strip(_files(dataset, "coco.json")) == strip(_files(ref, "coco.json"))
    exrs = sorted((ref / "renders").rglob("*.exr"))
    assert len(exrs) == n_chunks
    for p in exrs:
        a, b = images.read_exr(p), images.read_exr(dataset / p.relative_to(ref))
        assert a.keys() == b.keys()
        for name in a:
            np.testing.assert_array_equal(a[name], b[name], err_msg=f"{p}: {name}")


@pytest.mark.slow
def test_limit_runs_the_first_variants_and_a_later_run_adds_the_rest(tmp_path):
    from humv_usd.sweep.run import run_sweep

    sw = load_sweep(_write(tmp_path))
    first = run_sweep(sw, tmp_path / "dataset", workers=0, limit=1)
    assert first.ran == 2 and first.dataset_summary["variants_with_images"] == 1
    # the dry run of the same sweep counts only what is left
    r = CliRunner().invoke(main, ["sweep", str(sw.path), "-o", str(tmp_path / "dataset"), "--dry-run"])
    assert r.exit_code == 0, r.output
    assert "2 render tasks (2 frames), 1 variants composed; left: 6 images, 3 variants to compose" in r.output
    import datasets

    def rows():  # the documented load line re-reads the index the resumed sweep rewrote
        index = str(tmp_path / "dataset" / "index.parquet")
        return datasets.load_dataset("parquet", data_files=index, split="train").num_rows

    assert rows() == 2
    rest = run_sweep(sw, tmp_path / "dataset", workers=0)
    assert rest.already_done == 2 and rest.ran == 6 and rest.dataset_summary["images"] == 8
    assert rows() == 8


def test_render_threads_share_the_cores_between_local_workers():
    """A task's settings carry the Dr.Jit thread count of its worker's renders; set_render_threads
    applies it (2 workers on 2 cores: 1 thread each rather than 2 each competing)."""
    import drjit as dr

    from humv_usd.sweep import run as sweep_run
    from humv_usd.sweep.tasks import set_render_threads

    assert sweep_run._InProcess.render_threads is None  # in-process: the render's own default
    before = dr.thread_count()
    try:
        set_render_threads(1)
        assert dr.thread_count() == 1
        set_render_threads(before)
        assert dr.thread_count() == before
    finally:
        dr.set_thread_count(before)


def test_progress_prints_status_lines_when_stderr_is_not_a_terminal(capsys, monkeypatch):
    from humv_usd.cli import sweep_cmd

    monkeypatch.setattr(sweep_cmd, "LOG_EVERY_S", 3600.0)
    with sweep_cmd._Progress(quiet=False) as p:
        assert p.lines  # pytest's stderr is not a terminal
        p({"type": "start", "variants": 2, "tasks": 4, "done": 1, "frames": 8, "frames_done": 2})
        p({"type": "compose", "variant": "v0000", "seconds": 1.0, "rebuilt": []})
        p({"type": "render", "task": "v0000/f0000-0001", "frames": 2, "images": 2, "seconds": 1.0})
        monkeypatch.setattr(sweep_cmd, "LOG_EVERY_S", 0.0)
        p({"type": "render", "task": "v0001/f0000-0001", "frames": 2, "images": 2, "seconds": 1.0})
        p({"type": "failed", "task": "render v0001/f0002-0003", "error": "OSError: disk full"})
    err = capsys.readouterr().err
    status = [line for line in err.splitlines() if " min: variants composed " in line]
    # one at the start, none within the interval, one after it
    assert len(status) == 2, err
    assert "render tasks 1/4, frames 2/8" in status[0]
    assert "variants composed 1 (this run), render tasks 3/4, frames 6/8" in status[1]
    assert "images/h, ETA " in status[1] and "failures 0" in status[1]
    assert "failed render v0001/f0002-0003: OSError: disk full" in err
    with sweep_cmd._Progress(quiet=True) as p:  # --quiet: nothing
        p({"type": "start", "variants": 1, "tasks": 1, "done": 0, "frames": 1, "frames_done": 0})
    assert "min: variants composed" not in capsys.readouterr().err


def test_a_local_cluster_does_not_fight_another_for_port_8787():
    """Two sweeps (or a sweep and a bench) on one machine: the second's scheduler must not warn
    that 8787 is taken (its HTTP server goes to a free port; no dashboard)."""
    import socket
    import warnings

    from humv_usd.sweep.run import _Dask

    holder = socket.socket()
    try:
        holder.bind(("127.0.0.1", 8787))  # taken by us, or already by another process: taken
        holder.listen(1)
    except OSError:
        pass
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            ex = _Dask(None, 1)
        try:
            assert ex.workers == 1 and ex.client.submit(sum, [1, 2]).result() == 3
        finally:
            ex.close()
    finally:
        holder.close()


@pytest.mark.slow
def test_splits_by_variant_in_every_export(reference):
    """One split per variant (train 2, val 1, test 1 of 4 variants), the same in the index, the
    COCO split files and the YOLO folders; every export's image is the sensor chain's 8-bit
    image; COCO file names stay under coco/ (FiftyOne joins them to an images folder)."""
    from pycocotools.coco import COCO

    _, _, dataset, _ = reference
    index = json.loads((dataset / "dataset.json").read_text())["index"]
    split_of = {r["variant"]: r["split"] for r in index}
    assert sorted(split_of.values()) == ["test", "train", "train", "val"]
    assert all(r["split"] == split_of[r["variant"]] for r in index)  # never by frame
    assert all(r["image"].endswith("_image8.png") for r in index)
    full = json.loads((dataset / "coco" / "cam.json").read_text())
    for split in ("train", "val", "test"):
        doc = COCO(str(dataset / "coco" / f"cam_{split}.json")).dataset
        variants = {img["humv_variant"] for img in doc["images"]}
        assert variants == {v for v, s in split_of.items() if s == split}
        ids = {img["id"] for img in doc["images"]}
        assert {a["image_id"] for a in doc["annotations"]} <= ids
        assert len(doc["annotations"]) == sum(a["image_id"] in ids for a in full["annotations"])
        yolo = {
            p.stem.split("_")[0]
            for p in (dataset / "yolo" / "detect" / "cam" / "images" / split).glob("*.png")
        }
        assert yolo == variants
    for img in full["images"]:
        assert ".." not in img["file_name"] and img["file_name"].startswith("images/cam/")
        row = next(r for r in index if r["coco_image_id"] == img["id"])
        assert (dataset / "coco" / img["file_name"]).read_bytes() == (dataset / row["image"]).read_bytes()
    data = (dataset / "yolo" / "detect" / "cam" / "data.yaml").read_text()
    assert "train: images/train\nval: images/val\ntest: images/test\n" in data
    # the card's configs header as the Hub reads it: three splits of the index's rows
    import datasets

    hub = datasets.load_dataset(str(dataset))
    assert {k: hub[k].num_rows for k in hub} == {"train": 4, "validation": 2, "test": 2}
    assert set(hub["validation"]["split"]) == {"val"}


@pytest.mark.slow
def test_dataset_check_reads_it_as_the_consumers_do(reference, tmp_path, monkeypatch):
    """pycocotools (keypoint and box COCOeval on the file), Hugging Face datasets from another
    working directory, the YOLO layout rules: no problem; a broken copy is reported."""
    import shutil

    from humv_usd.sweep.check import check_dataset, load_index

    _, _, dataset, _ = reference
    monkeypatch.chdir(tmp_path)
    assert check_dataset(dataset) == []
    ds = load_index(os.path.relpath(dataset), split="train", images=True)
    assert ds.num_rows == 4 and set(ds["split"]) == {"train"}
    assert ds[0]["image"].size == (32, 24)  # decoded by datasets.Image() from another folder
    result = CliRunner().invoke(main, ["dataset", "check", str(dataset)])
    assert result.exit_code == 0, result.output
    broken = tmp_path / "broken"
    shutil.copytree(dataset, broken, symlinks=True)
    doc = json.loads((broken / "coco" / "cam.json").read_text())
    for a in doc["annotations"]:
        a.pop("num_keypoints")
    doc["images"][0]["file_name"] = "../renders/x.png"
    (broken / "coco" / "cam.json").write_text(json.dumps(doc))
    (broken / "yolo" / "detect" / "cam" / "data.yaml").write_text("names: {0: person}\n")
    problems = check_dataset(broken)
    assert any("leaves the COCO folder" in p for p in problems)
    assert any("without num_keypoints" in p for p in problems)
    assert any("data.yaml: no 'train'" in p for p in problems)
    result = CliRunner().invoke(main, ["dataset", "check", str(broken)])
    assert result.exit_code == 1


@pytest.mark.slow
def test_keypoint_evaluation_runs_on_the_exported_coco(person_dataset):
    """COCOeval(..., 'keypoints') on the export (it raised KeyError: 'num_keypoints' on the
    ground and building annotations): the people's own keypoints score OKS AP 1."""
    import contextlib
    import io

    from pycocotools.coco import COCO
    from pycocotools.cocoeval import COCOeval

    gt = COCO(str(person_dataset / "coco" / "cam.json"))
    people = [dict(a, score=1.0) for a in gt.dataset["annotations"] if a["category_id"] == 1]
    assert people and all("num_keypoints" in a for a in gt.dataset["annotations"])
    with contextlib.redirect_stdout(io.StringIO()):
        ev = COCOeval(gt, gt.loadRes(people), "keypoints")
        ev.evaluate()
        ev.accumulate()
        ev.summarize()
    assert ev.stats[0] == pytest.approx(1.0)


def test_dataset_section_is_checked(tmp_path):
    bad = SWEEP + '\n[dataset]\nsplit = { train = 0.5, val = 0.6 }\nimage = "jpeg"\nstratify = ["nope"]\n'
    problems = _problems(tmp_path, bad)
    assert any("dataset.split" in p and "summing to 1" in p for p in problems)
    assert any("dataset.image" in p and "image8" in p for p in problems)
    good = SWEEP + '\n[dataset]\nsplit = { train = 0.5, val = 0.5 }\nimage = "counts16"\n'
    sweep = load_sweep(_write(tmp_path, good))
    assert sweep.dataset["split"] == {"train": 0.5, "val": 0.5, "test": 0.0}
    assert sweep.dataset["image"] == "counts16"


def test_vector_parameters_are_lists_in_the_index():
    from types import SimpleNamespace

    from humv_usd.sweep.dataset import _param_columns

    variants = [
        SimpleNamespace(id=f"v{i}", params={"sensor.0.position_m": [0.0, -8.0 + i, 1.6]}) for i in range(2)
    ]
    col = _param_columns(variants)["param_sensor_0_position_m"]
    assert col == {"v0": [0.0, -8.0, 1.6], "v1": [0.0, -7.0, 1.6]}
