"""COCO output: loads in pycocotools, annToMask equals our instance masks, merge into a dataset."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner
from numpy.testing import assert_allclose
from test_groundtruth import camera, label, material, mesh, new_stage, read_exr, sphere_mesh, wall

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.groundtruth import coco as C
from humv_usd.groundtruth import labels as GL
from humv_usd.pipeline.render import render_stage


@pytest.fixture(scope="module")
def render_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("coco")
    stage = new_stage(tmp / "stage.usda")
    m = material(stage, "/World/Materials/m", 0.9)
    label(stage.DefinePrim("/World/Humans/p1", "Xform"), 1, "person")
    mesh(stage, "/World/Humans/p1/Body", *sphere_mesh((0.0, 0.0, 1.0), 0.5, 1), m, 305.0)
    mesh(stage, "/World/Scene/wall", *wall(-3.0, 3.0, 0.0, 3.0, 2.0), m, 290.0, instance_id=2, cls="building")
    mesh(stage, "/World/Scene/post", *wall(-0.1, 0.1, 0.0, 2.0, -1.0), m, 295.0, instance_id=3, cls="prop")
    camera(stage, "a", (0.0, -5.0, 1.0), (0.0, 0.0, 1.0), res=(40, 30))
    camera(stage, "b", (2.0, -5.0, 1.5), (0.0, 0.0, 1.0), res=(32, 24))
    stage.Save()
    render_stage(tmp / "stage.usda", tmp / "out", spp=1, annotators=["boxes", "occlusion", "coco"])
    return tmp / "out"


def test_coco_loads_in_pycocotools_and_masks_match(render_dir):
    from pycocotools.coco import COCO

    coco = COCO(str(render_dir / "coco.json"))
    assert len(coco.getImgIds()) == 2
    assert {c["name"] for c in coco.loadCats(coco.getCatIds())} == set(GL.CLASSES[1:])
    assert coco.loadCats([1])[0]["keypoints"][0] == "nose"
    seen = set()
    for img in coco.loadImgs(coco.getImgIds()):
        assert (render_dir / img["file_name"]).is_file()
        ch = read_exr(render_dir / img["humv_exr"])
        anns = coco.loadAnns(coco.getAnnIds(imgIds=[img["id"]]))
        assert {a["humv_instance_id"] for a in anns} == set(
            np.unique(ch["instance_id"]).astype(int).tolist()
        ) - {0}
        for a in anns:
            ours = ch["instance_id"] == a["humv_instance_id"]
            assert np.array_equal(coco.annToMask(a).astype(bool), ours)
            assert a["area"] == ours.sum()
            rows, cols = np.nonzero(ours)
            assert a["bbox"] == [
                cols.min(),
                rows.min(),
                cols.max() - cols.min() + 1,
                rows.max() - rows.min() + 1,
            ]
            assert (
                a["category_id"]
                == GL.CLASS_ID[{1: "person", 2: "building", 3: "prop"}[a["humv_instance_id"]]]
            )
            x, y, w, h = a["bbox_full"]
            # the full box contains every visible pixel centre (the visible box is in whole pixels)
            assert x <= a["bbox"][0] + 0.5 and x + w >= a["bbox"][0] + a["bbox"][2] - 0.5
            assert y <= a["bbox"][1] + 0.5 and y + h >= a["bbox"][1] + a["bbox"][3] - 0.5
            assert 0.0 <= a["occlusion"] <= 1.0
            seen.add(a["humv_instance_id"])
    assert seen == {1, 2, 3}
    # the post stands in front of the sphere in view a: the person is partly occluded there
    person_a = [a for a in coco.loadAnns(coco.getAnnIds(imgIds=[1])) if a["humv_instance_id"] == 1][0]
    assert person_a["occlusion"] > 0.05


def test_merge_renumbers_and_relinks(render_dir, tmp_path):
    from pycocotools.coco import COCO

    second = tmp_path / "second"
    shutil.copytree(render_dir, second)
    out = tmp_path / "dataset" / "all.json"
    result = CliRunner().invoke(
        main, ["coco-merge", str(render_dir), str(second / "coco.json"), "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    doc = json.loads(out.read_text())
    single = json.loads((render_dir / "coco.json").read_text())
    assert len(doc["images"]) == 2 * len(single["images"])
    assert len(doc["annotations"]) == 2 * len(single["annotations"])
    assert len({i["id"] for i in doc["images"]}) == len(doc["images"])
    assert len({a["id"] for a in doc["annotations"]}) == len(doc["annotations"])
    for img in doc["images"]:
        for key in ("file_name", "humv_exr", "humv_camera"):  # relinked to the merged file's folder
            assert (out.parent / img[key]).is_file(), (key, img[key])
    coco = COCO(str(out))
    a = coco.loadAnns(coco.getAnnIds(imgIds=[3]))[0]  # first image of the second render
    exr = out.parent / coco.loadImgs([3])[0]["humv_exr"]
    assert exr.is_relative_to(out.parent.parent) and "second" in exr.parts
    ours = read_exr(exr)["instance_id"] == a["humv_instance_id"]
    assert np.array_equal(coco.annToMask(a).astype(bool), ours)


def test_merge_rejects_non_coco(tmp_path):
    bad = tmp_path / "x.json"
    bad.write_text('{"images": []}')
    with pytest.raises(InputError, match="not a COCO file"):
        C.merge([bad], tmp_path / "m.json")
    result = CliRunner().invoke(main, ["coco-merge", str(bad), "-o", str(tmp_path / "m.json")])
    assert result.exit_code == 2 and "not a COCO file" in result.output


def test_rle_round_trip():
    from pycocotools import mask as mask_util

    rng = np.random.default_rng(0)
    m = rng.random((7, 11)) > 0.6
    rle = C.encode_mask(m)
    back = mask_util.decode({"size": rle["size"], "counts": rle["counts"].encode()})
    assert np.array_equal(back.astype(bool), m)
    assert_allclose(mask_util.area({"size": rle["size"], "counts": rle["counts"].encode()}), m.sum())
