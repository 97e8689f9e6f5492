"""Scenario keys that drive the avatar's motion: speed, waypoints, a BVH file."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest
from conftest import ROOT
from pxr import Usd, UsdGeom, UsdSkel

from humv_usd.avatar import layer as avatar_layer
from humv_usd.errors import InputError
from humv_usd.human.usdskel import skinned_points
from humv_usd.scenario import validate

BVH = ROOT / "tests" / "data" / "knee_bend_cmu.bvh"


@pytest.fixture
def walk_raw():
    return tomllib.loads((ROOT / "examples" / "walk.toml").read_text())


def body_centre(stage, frame):
    pts = skinned_points(stage, "/World/Humans/p1/Body", Usd.TimeCode(frame))
    xf = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Humans/p1")).ComputeLocalToWorldTransform(
        Usd.TimeCode(frame)
    )
    return np.asarray(xf.Transform(tuple(float(v) for v in pts.mean(axis=0))))


def test_walk_follows_waypoints(walk_raw):
    raw = copy.deepcopy(walk_raw)
    raw["placement"][0]["waypoints_m"] = [[0.0, 0.0], [0.0, 3.0]]
    raw["general"]["duration_s"] = 4.0
    s = validate(raw)
    stage = Usd.Stage.Open(avatar_layer.build_one(s, s["human"][0]))
    start, turn, later = (body_centre(stage, f) for f in (0, 20, 50))
    assert start[:2] == pytest.approx([-1.4, 0.0], abs=0.15)  # the placement
    assert abs(turn[0]) < 0.3  # rounded the corner at (0, 0)
    assert abs(later[0]) < 0.1 and later[1] > 1.5  # heading north along x = 0
    # 1.4 m/s: the path length covered matches the speed
    assert np.linalg.norm(later[:2] - turn[:2]) == pytest.approx(1.4 * 30 / 15, rel=0.2)


def test_speed_range_depends_on_activity(walk_raw):
    raw = copy.deepcopy(walk_raw)
    raw["human"][0]["speed_m_s"] = 3.0
    with pytest.raises(InputError, match=r"human\[0\].speed_m_s = 3.0: allowed range for walk"):
        validate(raw)
    raw["human"][0]["activity"] = "carry"  # carrying walks a path at its own speed
    with pytest.raises(InputError, match=r"human\[0\].speed_m_s = 3.0: allowed range for carry"):
        validate(raw)
    raw["human"][0]["speed_m_s"] = 1.0
    assert validate(raw)["human"][0]["speed_m_s"] == 1.0
    raw["human"][0]["activity"] = "sit"
    with pytest.raises(InputError, match=r"speed_m_s = 1.0: only for walk, run or carry"):
        validate(raw)


def test_bvh_motion_from_scenario(walk_raw, tmp_path):
    raw = copy.deepcopy(walk_raw)
    del raw["human"][0]["speed_m_s"]
    raw["human"][0]["bvh"] = str(BVH)
    raw["general"]["duration_s"] = 1.0
    s = validate(raw)
    stage = Usd.Stage.Open(avatar_layer.build_one(s, s["human"][0]))
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Humans/p1/Motion"))
    assert len(anim.GetRotationsAttr().GetTimeSamples()) == s.frame_count
    # the knee bend: the hips drop during the clip
    z = [
        skinned_points(stage, "/World/Humans/p1/Body", Usd.TimeCode(f))[:, 2].max()
        for f in (0, s.frame_count // 2)
    ]
    assert z[1] < z[0] - 0.05


def test_bvh_path_errors(walk_raw, tmp_path):
    raw = copy.deepcopy(walk_raw)
    raw["human"][0]["bvh"] = "missing.bvh"
    with pytest.raises(InputError) as info:
        validate(raw, tmp_path / "scenario.toml")
    assert any("human[0].bvh = 'missing.bvh': file not found" in p for p in info.value.problems)
    assert any("human[0].speed_m_s = 1.4: not with bvh" in p for p in info.value.problems)


def test_bvh_path_from_the_home_folder(walk_raw, tmp_path, monkeypatch):
    """``bvh = "~/..."`` (the docs' way to name the set-up's clips) is the home folder's file."""
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    clip = tmp_path / "home" / "clips" / "walk.bvh"
    clip.parent.mkdir(parents=True)
    clip.write_text("HIERARCHY\n")
    raw = copy.deepcopy(walk_raw)
    del raw["human"][0]["speed_m_s"]
    raw["human"][0]["bvh"] = "~/clips/walk.bvh"
    s = validate(raw, tmp_path / "elsewhere" / "scenario.toml")
    assert s["human"][0]["bvh"] == str(clip.resolve())
