"""The chair a person sits on (issue 29.4, humv_usd.human.chair): the seat's top at the pose's
seat box, no body vertex inside the chair over the whole sitChair motion, the backrest behind
the sitting body, a closed mesh; the instance id and the material follow the scenario."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from humv_usd.human.body import build_body
from humv_usd.human.chair import (
    BACK_CLEARANCE,
    CHAIR_MATERIAL,
    chair_mesh,
    chair_parts,
    inside_chair,
    posed_body_points,
)
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import skeleton_for
from humv_usd.scenario.ids import sits_on_chair


@functools.lru_cache(maxsize=1)
def _sitting():
    body = build_body("female", 40.0, 1.64, 70.0)
    sk = skeleton_for(body.points, body.groups)
    motion = make_motion("sitChair", sk, 10.0, 30, body_points=body.points)
    return body, sk, motion


def test_seat_top_is_the_poses_seat_box_and_the_chair_is_closed():
    body, sk, motion = _sitting()
    chair = motion.gait["chair"]
    last = posed_body_points(body, sk, motion)
    pts, counts, idx = chair_mesh(chair, last)
    top = chair["center_m"][2] + chair["size_m"][2] / 2
    seat_base, seat_size = chair_parts(chair, last)[0]
    assert seat_base[2] + seat_size[2] == pytest.approx(chair["size_m"][2])
    assert pts[:, 2].min() == pytest.approx(chair["center_m"][2] - chair["size_m"][2] / 2)
    # every edge of the closed boxes is used twice, in opposite directions
    faces = np.split(idx, np.cumsum(counts)[:-1])
    edges = [(f[k], f[(k + 1) % len(f)]) for f in faces for k in range(len(f))]
    assert sorted(edges) == sorted((b, a) for a, b in edges)
    # the sitting body rests on the seat (within 5 mm) and nothing of it is inside the chair
    d = inside_chair(chair, last, last)
    assert 0.0 <= d.min() < 0.005
    assert abs(last[:, 2].min()) < 0.01  # the feet on the ground
    assert 0.30 < top < 0.55  # a chair-like seat height (the pose puts it at the thighs: 0.33 m here)


def test_no_body_vertex_inside_the_chair_while_sitting_down():
    body, sk, motion = _sitting()
    chair = motion.gait["chair"]
    last = posed_body_points(body, sk, motion)
    for f in range(0, motion.frame_count, 3):
        assert inside_chair(chair, posed_body_points(body, sk, motion, f), last).min() >= -1e-6


def test_backrest_stands_behind_the_body():
    body, sk, motion = _sitting()
    chair = motion.gait["chair"]
    last = posed_body_points(body, sk, motion)
    parts = chair_parts(chair, last)
    back = parts[-1]
    w, d, h = chair["size_m"]
    c, s = np.cos(chair["yaw_rad"]), np.sin(chair["yaw_rad"])
    local = last - np.array(chair["center_m"])
    local = local @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]).T
    local[:, 2] += h / 2
    band = (np.abs(local[:, 0]) < w / 2) & (local[:, 2] > h) & (local[:, 2] < h + 0.42)
    front_of_back = back[0][1] - back[1][1] / 2
    assert front_of_back - local[band, 1].max() >= BACK_CLEARANCE - 1e-9


def test_who_sits_on_a_chair():
    assert sits_on_chair({"activity": "sitChair"})
    assert not sits_on_chair({"activity": "sit"})
    assert sits_on_chair({"activity": "walk", "segment": [{"activity": "walk"}, {"activity": "sitChair"}]})
    assert CHAIR_MATERIAL == "wood"
