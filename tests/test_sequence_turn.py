"""Motion sequences that turn on the spot, sit on the authored chair and carry the box
(``[[human.segment]]`` activities turn, sitChair, carry; humv_usd.human.sequence)."""

from __future__ import annotations

import numpy as np
import pytest
from test_sequence import _raw

from humv_usd.assets import makehuman_dir
from humv_usd.errors import InputError

needs_rig = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)
FPS = 10.0


@pytest.fixture(scope="module")
def rig():
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, 80.0)
    return body, skeleton_for(body.points, body.groups)


def _world(sk, m):
    from humv_usd.human.gait import fk_matrices
    from humv_usd.human.skeleton import quat_to_matrix

    rot = quat_to_matrix(m.local_rotations)
    return fk_matrices(sk, rot, rot[:, 0], m.root_translation)


def _heading_deg(wrot):
    fwd = -wrot[:, 0][:, :, 1]  # rest facing -Y
    return np.degrees(np.unwrap(np.arctan2(fwd[:, 0], -fwd[:, 1])))


def _sole_points(sk, body, m, side):
    from humv_usd.human import contact as C

    fp = C.foot_points_from_body(sk, body.points)[side]
    wrot, wpos = _world(sk, m)
    return fp.world(wrot, wpos)  # (F, n, 3)


@needs_rig
def test_a_turn_on_the_spot_steps_the_feet_round(rig):
    """Stand, turn 90 deg to the left, stand: the body ends turned by 90 deg where it stood; each
    foot is lifted and set down turned (stepping, not pivoting), and a foot on the ground does
    not move (its sole points' largest displacement between consecutive frames while it is
    down, measured from the posed skeleton, not from the motion's own stance masks)."""
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [
        {"activity": "stand", "duration_s": 0.5},
        {"activity": "turn", "turn_deg": 90.0, "duration_s": 2.5},
        {"activity": "stand"},
    ]
    m = make_sequence_motion(segs, sk, FPS, 41, body_points=body.points)
    wrot, wpos = _world(sk, m)
    psi = _heading_deg(wrot)
    assert abs((psi[-1] - psi[0]) - 90.0) < 2.0
    assert np.linalg.norm(m.root_translation[-1, :2] - m.root_translation[0, :2]) < 0.15
    for side in ("Left", "Right"):
        pts = _sole_points(sk, body, m, side)
        lowest = pts[..., 2].min(axis=1)
        assert lowest.max() > 0.02  # lifted: stepped
        down = lowest < 0.002
        both = down[1:] & down[:-1]
        step = np.linalg.norm(np.diff(pts[..., :2], axis=0), axis=-1).max(axis=1)
        assert step[both].max() < 0.003  # planted: no sliding or pivoting on the ground
        yaw = np.degrees(np.arctan2(*(pts[:, -1, :2] - pts[:, 0, :2]).T[::-1]))
        assert abs(((yaw[-1] - yaw[0]) + 180) % 360 - 180 - 90.0) < 5.0


@needs_rig
def test_a_turn_without_an_angle_turns_back_at_the_path_end(rig):
    """Walk 2 m along the default path (-Y), turn (no angle: 180 deg at the path's end), walk:
    the walk after the turn goes back (+Y)."""
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [
        {"activity": "walk", "distance_m": 2.0},
        {"activity": "turn", "duration_s": 4.0},
        {"activity": "walk"},
    ]
    m = make_sequence_motion(segs, sk, FPS, 101, body_points=body.points)
    y = m.root_translation[:, 1]
    turn_at = int(np.argmin(y))
    assert y[turn_at] < y[0] - 1.5
    assert y[-1] > y[turn_at] + 1.0
    assert m.contact["max_slip_m"] < 0.02 and m.contact["max_penetration_m"] < 0.002


@needs_rig
def test_sit_chair_in_a_sequence_authors_a_chair_off_the_walked_path(rig):
    """Walk, turn round, sit on the chair, walk off: the chair is reported (the avatar tool
    authors it) and no body point is ever inside it, before, while and after sitting."""
    from humv_usd.human import poses as PO
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [
        {"activity": "walk", "distance_m": 2.0},
        {"activity": "turn", "turn_deg": 180.0, "duration_s": 4.0},
        {"activity": "sitChair", "duration_s": 6.0},
        {"activity": "walk"},
    ]
    m = make_sequence_motion(segs, sk, FPS, 141, body_points=body.points)
    box = m.gait["chair"]
    wrot, wpos = _world(sk, m)
    pts = PO.body_points(sk, body.points).posed(wrot, wpos, sk)
    c, s = np.cos(box["yaw_rad"]), np.sin(box["yaw_rad"])
    d = pts - np.asarray(box["center_m"])
    u, v = c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]
    w, dep, h = box["size_m"]
    inside = (np.abs(u) < w / 2) & (np.abs(v) < dep / 2) & (np.abs(d[..., 2]) < h / 2 - 1e-3)
    assert not inside.any()
    seat_top = box["center_m"][2] + h / 2
    assert (pts[..., 2].min(axis=1) < seat_top + 0.02).any()  # sat on it (seat points at its top)


@needs_rig
def test_a_carry_sequence_holds_the_box_through_stop_and_turn(rig):
    """Carry, stop, turn, carry on: the hands stay at the box's grasp points in the Hips' frame
    in every frame (apply_box_carry over the whole sequence)."""
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [
        {"activity": "carry", "distance_m": 2.0},
        {"activity": "turn", "turn_deg": -90.0, "duration_s": 3.0},
        {"activity": "carry"},
    ]
    m = make_sequence_motion(segs, sk, FPS, 81, body_points=body.points)
    wrot, wpos = _world(sk, m)
    hips = sk.index("Hips")
    for side in ("Left", "Right"):
        hand = wpos[:, sk.index(f"{side}Hand")] - wpos[:, hips]
        local = np.einsum("fji,fj->fi", wrot[:, hips], hand)
        spread = np.linalg.norm(local - local.mean(axis=0), axis=1).max()
        assert spread < 0.01, side


def test_carries_box_counts_carry_segments():
    from humv_usd.scenario.ids import carries_box, sits_on_chair

    h = {
        "id": "p",
        "activity": "stand",
        "segment": [{"activity": "carry", "distance_m": 2}, {"activity": "stand"}],
    }
    assert carries_box(h) and not sits_on_chair(h)


@pytest.mark.parametrize(
    "segments,message",
    [
        (
            [{"activity": "carry", "distance_m": 3}, {"activity": "sit"}],
            r"segment\[1\]\.activity = 'sit': the hands hold the box of this sequence's carry: only carry, stand, turn",
        ),
        (
            [{"activity": "stand", "duration_s": 2, "turn_deg": 90}, {"activity": "walk"}],
            r"segment\[0\]\.turn_deg = 90\.0: only for turn \(activity is 'stand'\)",
        ),
        (
            [{"activity": "turn", "turn_deg": 400}],
            r"segment\[0\]\.turn_deg = 400: allowed range -360\.0\.\.360\.0",
        ),
        (
            [
                {"activity": "sitChair", "duration_s": 6},
                {"activity": "stand", "duration_s": 1},
                {"activity": "sitChair"},
            ],
            r"segment\[2\]\.activity = 'sitChair': one sitChair per sequence",
        ),
    ],
)
def test_bad_turn_carry_chair_segments_are_one_line_each(segments, message):
    from humv_usd.scenario.load import validate

    with pytest.raises(InputError, match=message) as err:
        validate(_raw(segments))
    assert len(str(err.value).strip().splitlines()) == 1


@needs_rig
def test_a_turn_too_short_is_one_clear_error(rig):
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [{"activity": "turn", "turn_deg": 180.0, "duration_s": 2.0}, {"activity": "stand"}]
    with pytest.raises(InputError, match=r"segment\[0\]\.duration_s = 2\.0: a turn of 180 deg needs 3\.00 s"):
        make_sequence_motion(segs, sk, FPS, 41, where="human[0].segment")


@needs_rig
def test_a_chair_on_the_walked_path_is_refused(rig):
    """Walk up and sit down on the chair without turning round: the chair (authored for the
    whole clip) would stand where the person has just walked: one clear line."""
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [{"activity": "walk", "distance_m": 2.0}, {"activity": "sitChair"}]
    with pytest.raises(
        InputError, match=r"segment\[1\]\.activity = 'sitChair': its chair .* turn round first"
    ):
        make_sequence_motion(segs, sk, FPS, 81, body_points=body.points, where="human[0].segment")
