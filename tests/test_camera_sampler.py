"""The sweep's camera sampler (humv_usd.sweep.cameras) and the dataset viewpoint presets."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from humv_usd.catalog.viewpoints import VIEWPOINTS
from humv_usd.errors import InputError
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.geometry.rig import camera_axes
from humv_usd.scenario import validate
from humv_usd.sweep.cameras import (
    PERSON_RADIUS_M,
    parse_camera,
    person_box_px,
    sample_view,
    with_sensor_keys,
)
from humv_usd.sweep.spec import load_sweep


def _sampler(table):
    problems: list[str] = []
    s = parse_camera(table, problems)
    assert not problems, problems
    return s


def test_person_height_in_pixels_is_the_pinhole_closed_form():
    """A person of stature H at distance d, camera at mid-height looking level: the box is
    f/p (H/(d - r)) tall (the near edge of the cylinder's rings), to the pixel."""
    w, h, f_px = 640, 512, 800.0
    fov = math.degrees(2 * math.atan(w / (2 * f_px)))
    for d in (8.0, 25.0, 60.0):
        fwd, up = camera_axes(0.0, 0.0)
        cam = Camera.from_pose(CameraPose(np.array([0.0, -d, 0.9]), fwd, up, fov), w, h)
        px, width, inside = person_box_px(cam, [0.0, 0.0, 0.0], 1.8)
        assert inside
        assert px == pytest.approx(f_px * 1.8 / (d - PERSON_RADIUS_M), rel=1e-3)
        assert width == pytest.approx(f_px * 2 * PERSON_RADIUS_M / d, rel=0.05)


def test_every_draw_meets_the_constraints(raw):
    """50 KAIST-like draws around the humvvex person: in view, tall enough, the camera outside
    the warehouse and above the ground, the person at the drawn distance (checked afresh)."""
    s = _sampler({"preset": "kaist"})
    scenario = validate(with_sensor_keys(raw, s))
    sensor = scenario["sensor"][0]
    w, h = sensor["resolution"]
    fov = math.degrees(2 * math.atan(w * sensor["pixel_pitch_um"] / (2e3 * sensor["focal_length_mm"])))
    wall = scenario["scene"]["object"][0]
    for k in range(50):
        v = sample_view(s, scenario, np.random.default_rng([0, k, 28]))
        eye = np.asarray(v["position_m"])
        assert 1.8 <= eye[2] <= 2.2 and 5.0 <= v["distance_m"] <= 45.0
        assert np.hypot(eye[0], eye[1] - 0.0) == pytest.approx(v["distance_m"], rel=1e-4)
        # the line of sight to the person's centre misses the warehouse (points along it, brute force)
        line = eye + np.linspace(0.0, 1.0, 2001)[:, None] * (np.array([0.0, 0.0, 0.89]) - eye)
        in_box = (np.abs(line[:, 0] - wall["center_m"][0]) < 20.0) & (
            np.abs(line[:, 1] - wall["center_m"][1]) < 7.5
        )
        assert not np.any(in_box & (line[:, 2] < 8.0))
        fwd = np.asarray(v["look_at_m"]) - eye
        cam = Camera.from_pose(CameraPose(eye, fwd / np.linalg.norm(fwd), camera_axes(0, 0)[1], fov), w, h)
        uv, z = cam.project([0.0, 0.0, 0.89])
        assert z > 0 and 0 <= uv[0] <= w and 0 <= uv[1] <= h
        assert v["person_height_px"] >= 20.0


def test_hit_uav_draws_keep_the_published_altitude_and_angle(raw):
    s = _sampler({"preset": "hit_uav"})
    scenario = validate(with_sensor_keys(raw, s))
    views = [sample_view(s, scenario, np.random.default_rng([1, k, 28])) for k in range(30)]
    assert all(60.0 <= v["height_m"] <= 130.0 and -90.0 <= v["pitch_deg"] <= -30.0 for v in views)
    assert max(v["person_height_px"] for v in views) < 40.0  # small objects from 60-130 m


def test_impossible_constraints_and_bad_keys_are_one_line(raw):
    s = _sampler({"preset": "kaist", "min_height_px": 5000})
    scenario = validate(with_sensor_keys(raw, s))
    with pytest.raises(InputError, match="most often failed: at least 5000 px tall"):
        sample_view(s, scenario, np.random.default_rng(0))
    problems: list[str] = []
    parse_camera({"preset": "nope", "distance_m": {"uniform": [5, 1]}, "colour": 1}, problems)
    assert len(problems) == 3
    assert any("camera.preset" in p and "kaist" in p for p in problems)
    assert any("camera.distance_m" in p for p in problems)


def test_presets_cite_their_sources():
    for p in VIEWPOINTS.values():
        assert p.source and p.published_height_px
        assert "estimated" in p.source or "estimated" in p.published_height_px


def test_a_sweep_draws_one_reproducible_pose_per_variant(tmp_path):
    base = tmp_path / "base.toml"
    base.write_text(
        (__import__("pathlib").Path(__file__).parents[1] / "examples" / "humvvex_fixed.toml").read_text()
    )
    sweep = tmp_path / "s.toml"
    sweep.write_text(
        '[sweep]\nbase = "base.toml"\ncount = 3\nseed = 5\n'
        '[camera]\npreset = "flir_adas"\nazimuth_deg = { uniform = [150.0, 210.0] }\n'
    )
    a, b = load_sweep(sweep), load_sweep(sweep)
    poses = [v.raw["sensor"][0]["position_m"] for v in a.variants]
    assert poses == [v.raw["sensor"][0]["position_m"] for v in b.variants]
    assert len({tuple(p) for p in poses}) == 3
    for v in a.variants:
        assert v.raw["sensor"][0]["preset"] == "tau2_640" and v.scenario is not None
        assert v.params["camera.person_height_px"] >= 10.0
        assert 150.0 <= v.params["camera.azimuth_deg"] <= 210.0
    assert copy.deepcopy(a.variants[0].params) == b.variants[0].params


def test_the_sweep_files_documented_example_loads_and_keeps_the_view(tmp_path):
    """The sweep-file example in ``humv_usd.sweep.spec``'s docstring loads, and its ``[set]``
    pixel count keeps the camera's field of view (issue 28: ``sensor.0.resolution`` there cropped
    38.4 deg to 12.4 deg): every variant's sensor keeps the base's sensor width (pixels x pitch)."""
    from humv_usd.sweep import spec as sweep_spec

    block = sweep_spec.__doc__.split("::\n", 1)[1]
    lines = []
    for line in block.splitlines()[1:]:
        if line and not line.startswith("    "):
            break
        lines.append(line[4:])
    walk = Path(__file__).resolve().parents[1] / "examples" / "walk.toml"
    # walk.toml has one person: the example's draw of a second one ("human.1") is left out
    lines = [line for line in lines if not line.startswith('"human.1"')]
    text = "\n".join(lines).replace('base = "walk.toml"', f'base = "{walk.as_posix()}"')
    assert f'base = "{walk.as_posix()}"' in text
    (tmp_path / "example.toml").write_text(text)
    sweep = sweep_spec.load_sweep(tmp_path / "example.toml")
    base = validate(tomllib.loads(walk.read_text()))["sensor"][0]
    assert sweep.variants
    for v in sweep.variants:
        s = v.scenario["sensor"][0]
        assert s["render_resolution"] == [256, 192]
        assert s["resolution"][0] * s["pixel_pitch_um"] == pytest.approx(
            base["resolution"][0] * base["pixel_pitch_um"]
        )
