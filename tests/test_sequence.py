"""Motion sequences (issue 29.4, ``[[human.segment]]``, humv_usd.human.sequence): a person who
walks, stops, stands, sits down, gets up and walks on, with blended transitions, planted feet
and the metabolic rate following the segments."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.assets import makehuman_dir
from humv_usd.errors import InputError

needs_rig = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)
FPS = 10.0
MASS = 80.0
STAND_S = 1.5
SEGMENTS = [
    {"activity": "walk", "distance_m": 2.0, "speed_m_s": 1.4},
    {"activity": "stand", "duration_s": STAND_S},
    {"activity": "sit", "duration_s": 6.0},
    {"activity": "walk", "speed_m_s": 1.4},
]


@pytest.fixture(scope="module")
def rig():
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, MASS)
    return body, skeleton_for(body.points, body.groups)


@pytest.fixture(scope="module")
def seq(rig):
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    return make_sequence_motion(SEGMENTS, sk, FPS, int(12 * FPS) + 1, mass_kg=MASS, body_points=body.points)


def _angles_deg(q):
    return np.degrees(2 * np.arccos(np.clip(np.abs(np.sum(q[1:] * q[:-1], -1)), 0.0, 1.0)))


@needs_rig
def test_segments_follow_one_another_along_the_path(seq):
    """Walk 2 m (along -Y, the default path), stop, stand, sit where they stopped, get up and
    walk on along the same line; the root never jumps."""
    from humv_usd.human.poses import SEQUENCES

    r = seq.root_translation
    t = np.arange(len(r)) / FPS
    kinds = [k for k, _, _ in seq.gait["windows"]]
    assert kinds == ["stop", "start"]
    stop0 = seq.gait["windows"][0][1] / FPS
    assert abs(stop0 - 2.0 / 1.4) < 0.45  # the heel strike nearest the segment's end
    stand = (t > seq.gait["windows"][0][2] / FPS + 0.1) & (t < 2.0 / 1.4 + STAND_S)
    assert np.ptp(r[stand, :2], axis=0).max() < 0.005  # standing still
    travelled = -(r[stand][0, 1] - r[0, 1])
    assert 1.8 < travelled < 2.7
    # sitting (after stand -> crouch -> sit) on the ground, within half a metre of the stop
    sat = int(round((2.0 / 1.4 + STAND_S + sum(d for _, d in SEQUENCES["sit"]) + 0.3) * FPS))
    assert r[sat, 2] < 0.3 and np.linalg.norm(r[sat, :2] - r[stand][0, :2]) < 0.6
    # on again along -Y at about the walking speed, and no step of the root is a jump
    assert r[-1, 1] < r[stand][0, 1] - 1.0 and abs(r[-1, 0] - r[0, 0]) < 0.3
    assert np.linalg.norm(np.diff(r, axis=0), axis=1).max() * FPS < 2.5


@needs_rig
def test_transitions_blend_joints_without_jumps(rig, seq):
    """Per-frame joint rotation changes stay within the plain walk's own (toes aside: their
    flick at toe-off is the gait's), so the blends add no pops."""
    from humv_usd.human.motion import make_motion

    body, sk = rig
    walk = make_motion("walk", sk, FPS, 60, 1.4, mass_kg=MASS, body_points=body.points)
    toes = [sk.index("LeftToeBase"), sk.index("RightToeBase")]

    def worst(q):
        a = _angles_deg(q)
        a[:, toes] = 0.0
        return a.max()

    assert worst(seq.local_rotations) <= 1.1 * worst(walk.local_rotations)


@needs_rig
def test_feet_stay_planted_through_stop_and_start(rig, seq):
    """The planted feet do not slide or sink over the whole sequence, the transitions included
    (the walk's own level: slip <= 2 cm, penetration and gap <= 1 cm), and in the stop the
    leading foot stands still from its foot-flat to the end of the blend."""
    c = seq.contact
    assert c["max_slip_m"] <= 0.02 and c["max_penetration_m"] <= 0.01 and c["max_gap_m"] <= 0.01
    _, sk = rig
    _, pos = seq.world(sk)
    kind, w0, w1 = seq.gait["windows"][0]
    a, b = int(np.ceil(w0)), int(np.floor(w1))
    still = [
        np.ptp(pos[(a + b) // 2 : b + 1, sk.index(f"{s}Foot"), :2], axis=0).max() for s in ("Left", "Right")
    ]
    assert min(still) < 0.003


@needs_rig
def test_metabolic_rate_follows_the_segments(seq):
    """ACSM walking (3.5 + 0.1 v mL/kg/min, v in m/min) while walking; standing and sitting
    quietly the Compendium's 1.3 MET plus the walk's excess decaying from the stop as
    0.9 exp(-t/40 s) + 0.1 exp(-t/600 s) (EPOC); 0.7 MET more (2 MET) while sitting down."""
    t = np.arange(seq.frame_count) / FPS
    per_met = 3.5 * MASS * 20.1 / 60.0
    walking = (3.5 + 0.1 * 1.4 * 60.0) * MASS * 20.1 / 60.0
    rate = seq.metabolic_rate_w
    stop = seq.gait["windows"][0][1] / FPS

    def quiet(tt):
        x = tt - stop
        return 1.3 * per_met + (walking - 1.3 * per_met) * (
            0.9 * np.exp(-x / 40.0) + 0.1 * np.exp(-x / 600.0)
        )

    np.testing.assert_allclose(rate[t < 1.0], walking, rtol=1e-9)
    sit_at = 2.0 / 1.4 + STAND_S  # the sit segment starts (it stands up 2.6 s before its end)
    standing = (t > sit_at - 0.4) & (t < sit_at)
    np.testing.assert_allclose(rate[standing], quiet(t[standing]), rtol=1e-9)
    sitting = (t > sit_at + 2.8) & (t < sit_at + 3.3)
    np.testing.assert_allclose(rate[sitting], quiet(t[sitting]), rtol=1e-9)
    down = (t > sit_at) & (t < sit_at + 2.6)
    assert np.all(rate[down] <= quiet(t[down]) + 0.7 * per_met + 1e-9)
    assert rate[down].max() > quiet(t[down]).max() + 0.6 * per_met
    np.testing.assert_allclose(rate[-5:], walking, rtol=1e-9)


@needs_rig
def test_a_segment_too_short_for_its_transitions_is_one_clear_error(rig):
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [
        {"activity": "stand", "duration_s": 0.5},
        {"activity": "sit", "duration_s": 3.0},
        {"activity": "walk"},
    ]
    with pytest.raises(
        InputError, match=r"human\[0\]\.segment\[1\]\.duration_s = 3\.0: 'sit' here needs at least 5\.2"
    ):
        make_sequence_motion(segs, sk, 10.0, 60, where="human[0].segment")


@pytest.mark.parametrize(
    "segments,message",
    [
        (
            [{"activity": "walk", "distance_m": 3}, {"activity": "run"}],
            r"segment\[1\]\.activity = 'run': follows 'walk'",
        ),
        (
            [{"activity": "sit", "distance_m": 3}],
            r"segment\[0\]\.distance_m = 3\.0: only for walk, run or carry",
        ),
        (
            [{"activity": "walk", "speed_m_s": 2.5}],
            r"segment\[0\]\.speed_m_s = 2\.5: allowed range for walk: 0\.5\.\.2\.0",
        ),
        ([{"activity": "walk"}, {"activity": "stand"}], r"segment\[0\]\.duration_s: missing"),
        (
            [{"activity": "walk", "transition_s": 9}],
            r"segment\[0\]\.transition_s = 9: allowed range 0\.4\.\.3\.0",
        ),
        ([{"activity": "swim"}], r"segment\[0\]\.activity = 'swim': allowed values"),
    ],
)
def test_bad_segments_are_one_line_each(segments, message):
    from humv_usd.scenario.load import validate

    with pytest.raises(InputError, match=message) as err:
        validate(_raw(segments))
    assert len(str(err.value).strip().splitlines()) == 1


def _raw(segments, **placement):
    import datetime

    return {
        "general": {
            "name": "s",
            "start": datetime.datetime(2020, 6, 1, 12),
            "utc_offset_h": 0.0,
            "latitude_deg": 40.0,
            "longitude_deg": 0.0,
        },
        "human": [{"id": "p", "segment": segments}],
        "placement": [{"human": "p", "position_m": [0.0, 0.0, 0.0], **placement}],
    }


def test_avoidance_is_said_to_be_ignored_with_segments():
    from humv_usd.scenario.load import validate
    from humv_usd.scenario.warnings import suspicious

    segs = [{"activity": "walk", "duration_s": 2.0}, {"activity": "sit"}]
    said = suspicious(validate(_raw(segs, avoidance="socialForce", waypoints_m=[[0.0, 5.0]])))
    assert any("avoidance = 'socialForce': ignored with human.segment" in w for w in said), said
    assert not any("waypoints_m: ignored" in w for w in said)  # the walk follows them


@needs_rig
def test_low_frame_rates_sample_the_same_sequence(rig, seq):
    """Below 30 fps the sequence is simulated at k * fps >= 30 and decimated: at 1 fps it is the
    10 fps clip's every tenth frame (both are the 30 fps simulation), feet still planted; the
    contact report is the simulation's (measured on 1 fps frames, a foot's stances a stride
    apart merged into one: metres of slip)."""
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    m1 = make_sequence_motion(SEGMENTS, sk, 1.0, 13, mass_kg=MASS, body_points=body.points)
    np.testing.assert_allclose(m1.root_translation, seq.root_translation[::10], atol=1e-9)
    np.testing.assert_allclose(
        np.abs(np.sum(m1.local_rotations * seq.local_rotations[::10], -1)), 1.0, atol=1e-9
    )
    assert m1.contact["max_penetration_m"] <= 0.01
    assert m1.contact["max_slip_m"] == seq.contact["max_slip_m"] < 0.02


@needs_rig
def test_segments_after_the_clip_are_not_simulated(rig):
    """A clip shorter than its segments keeps the ones that start inside it; the last of those
    lasts to the end (a sit followed by a walk after the clip's end need not get up again)."""
    from humv_usd.human.sequence import make_sequence_motion

    body, sk = rig
    segs = [
        {"activity": "sit", "duration_s": 3.0},
        {"activity": "walk", "distance_m": 4.0},
        {"activity": "lieProne"},
    ]
    m = make_sequence_motion(segs, sk, 10.0, 31, body_points=body.points)
    assert m.gait["windows"] == [] and m.frame_count == 31
    assert m.root_translation[-1, 2] < 0.3  # still seated at 3 s
