"""Hands that support the body in imported motion (a crawl) held on the ground
(humv_usd.human.limbs)."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.assets import makehuman_dir, mocap_dir
from humv_usd.human import contact as C
from humv_usd.human import limbs as LB

FPS = 30.0


def test_pivot_offsets_hold_a_sliding_hovering_part_in_place():
    """A two-point part sliding at 0.3 m/s, 6 cm above the ground, supports the body over frames
    10..39: corrected, its lowest point stays where it was (mean place), on the ground; outside
    the run it is never below the ground and leaves it (lifted) rather than sliding on it."""
    frames = 60
    t = np.arange(frames) / FPS
    base = np.column_stack([0.3 * t, np.zeros(frames), np.full(frames, 0.06)])
    pts = np.stack([base, base + [0.05, 0.0, 0.01]], axis=1)  # (F, 2, 3); point 0 lowest
    mask = np.zeros(frames, bool)
    mask[10:40] = True
    off = LB._pivot_offsets(C.Ground(None), pts, mask, FPS)
    moved = pts + off[:, None, :]
    run = moved[10:40, 0]
    assert np.ptp(run[:, 0]) < 1e-9 and np.ptp(run[:, 1]) < 1e-9  # held: no slip
    assert abs(run[0, 0] - np.mean(base[10:40, 0])) < 1e-9  # at the run's mean place
    assert np.allclose(run[:, 2], 0.0)  # on the ground
    assert moved[..., 2].min() > -1e-9  # never below it
    out = ~mask
    assert (moved[out, 0, 2][np.abs(np.arange(frames)[out] - 25) > 18] > 0.03).all()  # lifted clear


needs_crawl = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir() or not (mocap_dir() / "deepmimic_crawl.bvh").is_file(),
    reason="MakeHuman data or the DeepMimic clips not fetched (make setup)",
)


@pytest.fixture(scope="module")
def crawl():
    """The DeepMimic crawl retargeted at 10 fps onto a 1.78 m man: (skeleton, body points, motion,
    posed sample points)."""
    from humv_usd.human import poses as PO
    from humv_usd.human.body import build_body
    from humv_usd.human.bvh import motion_from_bvh
    from humv_usd.human.gait import fk_matrices
    from humv_usd.human.skeleton import quat_to_matrix, skeleton_for

    body = build_body("male", 30, 1.78, 80.0)
    sk = skeleton_for(body.points, body.groups)
    m = motion_from_bvh(
        mocap_dir() / "deepmimic_crawl.bvh", sk, 10.0, body_points=body.points, activity="stand"
    )
    pts = PO.body_points(sk, body.points)
    rot = quat_to_matrix(m.local_rotations)
    wr, wp = fk_matrices(sk, rot, rot[:, 0], m.root_translation)
    return sk, pts, m, pts.posed(wr, wp, sk)


def _pivot_travel(q: np.ndarray, a: int, b: int) -> float:
    """Summed horizontal travel of the lowest point of ``q`` (F, n, 3) from frame to frame over
    [a, b) (the point lowest in the earlier frame followed to the next)."""
    k = np.argmin(q[a:b, :, 2], axis=1)
    piv0 = q[np.arange(a, b - 1), k[:-1], :2]
    piv1 = q[np.arange(a + 1, b), k[:-1], :2]
    return float(np.linalg.norm(piv1 - piv0, axis=1).sum())


@needs_crawl
def test_the_crawl_puts_its_hands_on_the_ground_without_sliding(crawl):
    """The DeepMimic crawl retargeted: before the hand lock its support hands hovered 4-14 cm
    over the ground and slid 157-303 mm per support run; now the hand (with the forearm's end), laid
    flat, touches it in the support frames, its lowest point travels < 12 mm over a run
    (measured 0.0 mm at 30 fps), and no hand point is below it."""
    sk, pts, m, posed = crawl
    for side in C.SIDES:
        sup = m.gait["supports"][f"{side}Hand"]
        assert sup.mean() > 0.3
        q = posed[:, LB.hand_points(sk, pts, side)]
        low = q[..., 2].min(axis=1)
        # on the ground in most support frames (lifted where the forearm would go under it)
        assert np.median(np.abs(low[sup])) < 0.002 and low.min() > -0.002
        for a, b in C.intervals(sup):
            assert _pivot_travel(q, a, b) < 0.012


@needs_crawl
def test_the_crawl_holds_its_supporting_knees_on_the_ground(crawl):
    """s8: before the knee lock the supporting knees (with the thigh and shin next to them) slid
    143-144 mm per support run (s7: 56-169 mm with the knee group alone) and the thighs went up to
    17.6 mm under the ground; now each knee rolls without slipping (< 12 mm per run, as the
    hands; measured 0.3-2.3 mm at 30 fps, more at this test's 10 fps, where the lowest point
    rolls further between frames), on the ground (within 2 mm) in its support frames, the
    trailing feet above it and no body point more than 10 mm under it (7.1 mm: the upper thigh
    at the clip's first frames, where the hips go no lower)."""
    sk, pts, m, posed = crawl
    for side in C.SIDES:
        sup = m.gait["supports"][f"{side}Knee"]
        assert sup.mean() > 0.3
        q = posed[:, LB.knee_points(sk, pts, side)]
        low = q[..., 2].min(axis=1)
        assert np.abs(low[sup]).max() < 0.002
        for a, b in C.intervals(sup):
            assert _pivot_travel(q, a, b) < 0.012
        assert posed[:, pts.groups[f"{side}Foot"], 2].min() > -0.001
    assert posed[..., 2].min() > -0.010


def test_root_shift_reaches_the_thigh_length_by_the_least_move():
    """One supporting knee, equal costs (ROOT_HORIZONTAL_WEIGHT 1): the least shift that puts the
    hip on the sphere of the thigh's length about the knee is along the knee-hip line by the
    difference of lengths (closed form); a knee out of support (weight 0) moves nothing."""
    hips = np.array([[[0.0, 0.0, 0.30]], [[0.0, 0.0, 0.30]]])
    knees = np.array([[[0.25, 0.05, 0.05]], [[0.25, 0.05, 0.05]]])
    length = np.array([0.45])
    d = LB._root_shift(hips, knees, length, np.array([[1.0], [0.0]]))
    v = hips[0, 0] - knees[0, 0]
    dist = np.linalg.norm(v)
    expected = (length[0] - dist) * v / dist
    if LB.ROOT_HORIZONTAL_WEIGHT == 1.0:
        np.testing.assert_allclose(d[0], expected, atol=2e-4)
    assert abs(np.linalg.norm(hips[0, 0] + d[0] - knees[0, 0]) - length[0]) < 2e-4
    np.testing.assert_allclose(d[1], 0.0, atol=1e-12)
