"""Collision avoidance between walkers (humv_usd.human.crowd, the social force model of
Helbing & Molnar 1995) and its use by the avatar tool (placement ``avoidance``)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from humv_usd.human import crowd as K

#: hip-to-hip distance two walkers need not to touch [m]: two half shoulder widths (biacromial
#: breadth ~0.40 m for men, ANSUR II 2012) plus a little arm swing
CLEAR_M = 0.5


def test_force_of_a_standing_person_is_the_potentials_gradient():
    # a standing other (no step): b = |r|, V = V0 exp(-|r|/sigma), f = V0/sigma exp(-|r|/sigma) r/|r|
    r = np.array([[0.7, -0.4], [1.5, 0.0], [-0.2, 0.3]])
    f = K.social_force(r, np.zeros_like(r))
    d = np.linalg.norm(r, axis=1, keepdims=True)
    assert_allclose(f, K.V0_M2_S2 / K.SIGMA_M * np.exp(-d / K.SIGMA_M) * r / d, rtol=1e-6)


def test_ellipse_semi_axis():
    # Helbing & Molnar (1995) Eq. 4: 2b = sqrt((|r| + |r - s|)^2 - |s|^2); r along s, beyond it
    r, s = np.array([3.0, 0.0]), np.array([1.0, 0.0])
    assert K._b(r, s) == pytest.approx(0.5 * np.sqrt((3 + 2) ** 2 - 1))
    assert K._b(r, np.zeros(2)) == pytest.approx(3.0)


def straight(starts, goals, speeds, steps):
    t = np.arange(steps) * K.STEP_S
    d = goals - starts
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return starts[:, None, :] + (speeds[:, None] * t)[:, :, None] * d[:, None, :]


def test_head_on_and_crossing_walkers_keep_apart():
    starts = np.array([[-5.0, 0.0], [5.0, 0.05], [0.0, -5.0]])
    goals = np.array([[5.0, 0.0], [-5.0, 0.05], [0.0, 5.0]])
    speeds = np.array([1.3, 1.3, 1.2])
    tracks = K.avoid(starts, [g[None] for g in goals], speeds, 10.0)
    assert K.min_separation(straight(starts, goals, speeds, tracks.shape[1])) < 0.1  # they would collide
    assert K.min_separation(tracks) > CLEAR_M
    # each keeps its speed and gets back on course: past its goal, within 0.5 m of its line
    steps = np.linalg.norm(np.diff(tracks, axis=1), axis=2) / K.STEP_S
    assert_allclose(steps, speeds[:, None] * np.ones_like(steps), rtol=1e-6)
    end = tracks[:, -1]
    assert abs(end[0, 1]) < 0.5 and abs(end[1, 1] - 0.05) < 0.5 and abs(end[2, 0]) < 0.5
    assert end[0, 0] > 5 and end[1, 0] < -5 and end[2, 1] > 5


def test_a_standing_person_is_walked_around():
    starts = np.array([[0.0, -6.0], [0.05, 0.0]])
    tracks = K.avoid(starts, [np.array([[0.0, 6.0]]), np.zeros((0, 2))], np.array([1.4, 0.0]), 10.0)
    assert_allclose(tracks[1], np.broadcast_to(starts[1], tracks[1].shape))  # the obstacle stays
    assert K.min_separation(tracks) > CLEAR_M
    assert tracks[0, -1, 1] > 6.0


def test_scenario_avoidance_reaches_the_motion(tmp_path):
    """Two people walking at each other with placement avoidance = socialForce: their hips'
    ground tracks (avatar motion, in world coordinates) stay apart; without, they meet."""
    from humv_usd.assets import makehuman_dir

    if not (makehuman_dir() / "rigs").is_dir():
        pytest.skip("MakeHuman data not fetched (make setup)")
    from humv_usd.avatar.layer import avoided_waypoints
    from humv_usd.scenario import validate

    raw = {
        "general": {
            "name": "crowd",
            "start": __import__("datetime").datetime(2020, 6, 1, 12),
            "utc_offset_h": 0.0,
            "latitude_deg": 40.0,
            "longitude_deg": 0.0,
            "fps": 10.0,
            "duration_s": 6.0,
        },
        "human": [{"id": "a", "activity": "walk"}, {"id": "b", "activity": "walk"}],
        "placement": [
            {"human": "a", "position_m": [-4.0, 0.0, 0.0], "heading_deg": 90.0, "avoidance": "socialForce"},
            {"human": "b", "position_m": [4.0, 0.1, 0.0], "heading_deg": 270.0, "avoidance": "socialForce"},
        ],
    }
    sc = validate(raw)
    wa, wb = (np.array(avoided_waypoints(sc, h)) for h in ("a", "b"))
    # the tracks bend away from the straight line (y = 0 / 0.1) and come back
    assert np.abs(wa[:, 1]).max() > 0.2 and np.abs(wb[:, 1] - 0.1).max() > 0.2
    assert abs(wa[-1, 1]) < 0.3
    # at equal speeds, points with the same index are passed at the same time
    n = min(len(wa), len(wb))
    assert np.linalg.norm(wa[:n] - wb[:n], axis=1).min() > CLEAR_M
