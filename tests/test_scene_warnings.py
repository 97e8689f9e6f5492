"""Issue 15: valid but suspicious scenes give one warning line each (compose goes on)."""

from __future__ import annotations

import copy
import logging
from pathlib import Path

import pytest

from humv_usd.scenario import validate
from humv_usd.scenario.warnings import suspicious

DATA = Path(__file__).resolve().parent / "data"


def lines_for(raw, edit) -> list[str]:
    raw = copy.deepcopy(raw)
    edit(raw)
    return suspicious(validate(raw))


def test_the_example_is_not_suspicious(raw):
    assert suspicious(validate(raw)) == []


@pytest.mark.parametrize(
    ("case", "edit", "words"),
    [
        (
            "50 m up",
            lambda r: r["placement"][0].update(position_m=[0.0, 0.0, 50.0]),
            ["+50.00 m from the ground"],
        ),
        (
            "off the ground",
            lambda r: r["placement"][0].update(position_m=[5000.0, 0.0, 0.0]),
            ["off the ground", "+-60"],
        ),
        (
            "in the box",
            lambda r: r["placement"][0].update(position_m=[0.0, 15.0, 0.0]),
            ["intersects", "'warehouse'"],
        ),
        (
            "camera underground",
            lambda r: r["sensor"][0].update(position_m=[0.0, -15.0, -1.0]),
            ["sensor[0]", "below the ground"],
        ),
        (
            "camera in the box",
            lambda r: r["sensor"][1].update(position_m=[0.0, 17.0, 2.0]),
            ["sensor[1]", "inside scene object 'warehouse'"],
        ),
        (
            "camera looks away",
            lambda r: r["sensor"][2].update(look_at_m=[0.0, -30.0, 1.0]),
            ["sensor[2] (mwir_insb)", "no person"],
        ),
        (
            "waypoints while standing",
            lambda r: r["placement"][0].update(waypoints_m=[[1.0, 0.0]]),
            ["waypoints_m", "'stand'"],
        ),
    ],
)
def test_suspicious_scenes_warn_once(raw, case, edit, words):
    found = lines_for(raw, edit)
    hits = [line for line in found if all(w in line for w in words)]
    assert len(hits) == 1, (case, found)
    assert all("\n" not in line for line in found)


def test_compose_logs_the_warnings_and_goes_on(raw, tmp_path, caplog):
    from humv_usd.pipeline.compose import compose

    raw = copy.deepcopy(raw)
    raw["placement"][0]["position_m"] = [0.0, 0.0, 50.0]
    with caplog.at_level(logging.WARNING, logger="humv_usd.pipeline.compose"):
        compose(validate(raw), tmp_path / "o")
    assert any("from the ground" in r.getMessage() for r in caplog.records)
    assert (tmp_path / "o" / "stage.usda").is_file()


def test_unmapped_bvh_joints_are_named(tmp_path, caplog):
    from humv_usd.human.body import build_body
    from humv_usd.human.bvh import motion_from_bvh
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, 80)
    skel = skeleton_for(body.points, body.groups)
    bvh = tmp_path / "pelvis.bvh"
    bvh.write_text((DATA / "knee_bend_cmu.bvh").read_text().replace("ROOT Hips", "ROOT Pelvis"))
    with caplog.at_level(logging.WARNING, logger="humv_usd.human.bvh"):
        motion_from_bvh(bvh, skel, 120)
    [line] = [r.getMessage() for r in caplog.records if "not mapped" in r.getMessage()]
    assert "Pelvis" in line and "1 BVH joint(s)" in line
