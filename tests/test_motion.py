"""Procedural motion: gait laws, joint angles, arm swing, paths, contact on flat/sloped/uneven
ground, standing activities, metabolic rate and timing."""

from __future__ import annotations

import time

import numpy as np
import pytest

from humv_usd.assets import makehuman_dir

pytestmark = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)

SLOPE = np.radians(5.0)


@pytest.fixture(scope="module")
def rig():
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, 80)
    return body, skeleton_for(body.points, body.groups)


def bumpy_ground(seed=3, amp=0.03, res=0.05, y_range=(-26.0, 4.0), x_range=(-2.5, 2.5)):
    """A smooth random heightfield mesh (+-3 cm, wavelengths ~0.8-2 m), 5 cm grid."""
    import trimesh

    rng = np.random.default_rng(seed)
    xs = np.arange(x_range[0], x_range[1] + res / 2, res)
    ys = np.arange(y_range[0], y_range[1] + res / 2, res)
    X, Y = np.meshgrid(xs, ys)
    Z = np.zeros_like(X)
    for _ in range(10):
        k = 2 * np.pi / rng.uniform(0.8, 2.0)
        a = rng.uniform(0, 2 * np.pi)
        Z += np.sin(k * (np.cos(a) * X + np.sin(a) * Y) + rng.uniform(0, 2 * np.pi))
    Z *= amp / np.abs(Z).max()
    ny, nx = X.shape
    ij = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = (ij[:-1, :-1].ravel(), ij[:-1, 1:].ravel(), ij[1:, 1:].ravel(), ij[1:, :-1].ravel())
    faces = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return trimesh.Trimesh(np.column_stack([X.ravel(), Y.ravel(), Z.ravel()]), faces, process=False)


def uphill(x, y):
    """5 deg slope rising along the walking direction (-Y)."""
    return -np.tan(SLOPE) * np.asarray(y)


def angles(motion, skel):
    from humv_usd.human.gait import sagittal_angles

    rot, pos = motion.world(skel)
    return sagittal_angles(skel, rot, pos)


# ------------------------------------------------------------------------- gait laws
# Published ranges for healthy adults (steps/min, m): self-selected ~1.37 m/s at 113 steps/min
# and 0.71 m steps (Perry & Burnfield 2010); slow/fast walking and the walk ratio
# (Grieve & Gear 1966; Oberg, Karsznia & Oberg 1993; Sekiya & Nagasaki 1998); running
# cadence ~160-180 steps/min nearly independent of speed (Cavanagh & Kram 1989).
WALK_RANGES = {
    0.5: ((55, 85), (0.30, 0.55)),
    1.0: ((85, 110), (0.55, 0.72)),
    1.4: ((100, 125), (0.65, 0.85)),
    2.0: ((125, 150), (0.78, 0.98)),
}
RUN_RANGES = {
    2.5: ((150, 180), (0.80, 1.10)),
    3.5: ((155, 185), (1.10, 1.40)),
    5.0: ((165, 200), (1.45, 1.90)),
}


@pytest.mark.parametrize("mode,table", [("walk", WALK_RANGES), ("run", RUN_RANGES)])
def test_cadence_and_step_length_follow_speed(rig, mode, table):
    from humv_usd.human.motion import make_motion

    _, skel = rig
    cad = []
    for v, ((c_lo, c_hi), (s_lo, s_hi)) in table.items():
        m = make_motion(mode, skel, 30, 240, speed_m_s=v)
        cadence, step = m.gait["cadence_steps_min"], m.gait["step_length_m"]
        assert c_lo <= cadence <= c_hi, (v, cadence)
        assert s_lo <= step <= s_hi, (v, step)
        assert abs(cadence / 60.0 * step - v) < 1e-6 * v  # v = cadence * step
        # the clip really walks at that cadence and speed
        st = m.gait["stance"]["left"]
        ic = np.flatnonzero(st[1:] & ~st[:-1])
        measured = 2 * (len(ic) - 1) / ((ic[-1] - ic[0]) / 30.0) * 60.0
        assert abs(measured - cadence) < 0.05 * cadence, (v, measured, cadence)
        r = m.root_translation
        assert abs(np.linalg.norm(r[-1, :2] - r[0, :2]) / (239 / 30.0) - v) < 0.02 * v
        cad.append(cadence)
        duty = m.gait["duty_factor"]
        assert (duty > 0.5) if mode == "walk" else (duty < 0.5)  # double support vs flight
    assert np.all(np.diff(cad) > 0)


# ------------------------------------------------------------------------- kinematics
def test_walking_joint_angles_in_normative_ranges(rig):
    """Perry & Burnfield (2010) / Winter (2009): knee ~0-5 deg at contact, ~60-65 deg peak
    in swing; thigh ~20-30 deg flexion and ~10-20 deg extension; ankle ~20 deg plantar
    flexion after toe-off, ~10 deg dorsiflexion in terminal stance."""
    from humv_usd.human.motion import make_motion

    body, skel = rig
    m = make_motion("walk", skel, 30, 150, speed_m_s=1.4, body_points=body.points)
    a = angles(m, skel)
    for side in ("Left", "Right"):
        knee, hip, ankle = a[f"{side}Knee"], a[f"{side}Hip"], a[f"{side}Ankle"]
        assert knee.min() < 8.0 and 55.0 <= knee.max() <= 70.0
        assert 20.0 <= hip.max() <= 40.0 and -25.0 <= hip.min() <= -8.0
        assert 35.0 <= np.ptp(hip) <= 55.0
        assert -30.0 <= ankle.min() <= -10.0 and 5.0 <= ankle.max() <= 20.0
        # loading response: the knee flexes 10-25 deg early in stance
        st = m.gait["stance"][side.lower()]
        first = np.flatnonzero(st[1:] & ~st[:-1])[0] + 1
        assert 10.0 <= knee[first : first + 6].max() <= 25.0


def test_running_kinematics(rig):
    """Novacheck (1998): knee ~40 deg at mid-stance, ~90-105 deg in swing; flight phases."""
    from humv_usd.human.motion import make_motion

    _, skel = rig
    m = make_motion("run", skel, 30, 150, speed_m_s=3.5)
    a = angles(m, skel)
    knee, hip = a["LeftKnee"], a["LeftHip"]
    assert 80.0 <= knee.max() <= 110.0 and knee.min() >= 5.0
    st = m.gait["stance"]["left"]
    assert 25.0 <= knee[st].max() <= 55.0  # stance flexion
    assert 40.0 <= hip.max() <= 65.0 and -35.0 <= hip.min() <= -10.0
    assert m.contact["flight_frames"] > 0.1 * m.frame_count


def test_arm_swing_opposes_the_legs(rig):
    from humv_usd.human.motion import make_motion

    _, skel = rig
    for mode, v in (("walk", 1.4), ("run", 3.5)):
        a = angles(make_motion(mode, skel, 30, 120, speed_m_s=v), skel)
        for side, other in (("Left", "Right"), ("Right", "Left")):
            sh = a[f"{side}Shoulder"]
            assert np.corrcoef(sh, a[f"{side}Hip"])[0, 1] < -0.6  # same side: opposite
            assert np.corrcoef(sh, a[f"{other}Hip"])[0, 1] > 0.6  # other leg: together
            assert 20.0 <= np.ptp(sh) <= 80.0


def test_pelvis_excursions(rig):
    """Vertical CoM excursion ~3-5 cm and mediolateral ~4-6 cm at 1.4 m/s (Orendurff et al.
    2004); the vertical one is not imposed, it follows from legs and ground contact."""
    from humv_usd.human.motion import make_motion

    _, skel = rig
    m = make_motion("walk", skel, 30, 120, speed_m_s=1.4)
    r = m.root_translation
    assert 0.02 <= np.ptp(r[:, 2]) <= 0.06
    assert 0.02 <= np.ptp(r[:, 0]) <= 0.08
    # one vertical oscillation per step, lowest in double support
    z = r[:, 2] - r[:, 2].mean()
    steps = m.gait["cadence_steps_min"] / 60.0 * 4.0  # 120 frames = 4 s
    assert abs(np.sum((z[1:] > 0) & (z[:-1] <= 0)) - steps) <= 1.0
    both = m.gait["stance"]["left"] & m.gait["stance"]["right"]
    assert z[both].mean() < z[~both].mean() - 0.01


# ------------------------------------------------------------------------- contact
GROUNDS = {"flat": lambda: None, "slope5": lambda: uphill, "uneven": bumpy_ground}


@pytest.mark.parametrize("ground", sorted(GROUNDS))
@pytest.mark.parametrize("mode,speed", [("walk", 1.4), ("run", 3.5)])
def test_ground_contact(rig, mode, speed, ground):
    """Contact points: the body's sole vertices (rest height < 1 cm), skinned to the foot and
    toe joints with their MakeHuman weights. Gap and penetration <= 1 cm, slip <= 2 cm."""
    from humv_usd.human.motion import make_motion

    body, skel = rig
    g = GROUNDS[ground]()
    m = make_motion(mode, skel, 30, 180, speed_m_s=speed, ground=g, body_points=body.points)
    c = m.contact
    assert c["contact_points"] == "body"
    assert c["max_gap_m"] <= 0.01, c
    assert c["max_penetration_m"] <= 0.01, c
    for side in ("left", "right"):
        assert c[side]["max_slip_m"] <= 0.02, c
        assert c[side]["stance_frames"] > 0.25 * m.frame_count
    if ground == "slope5":  # the pelvis climbs with the ground
        rise = m.root_translation[-1, 2] - m.root_translation[0, 2]
        run = np.linalg.norm(m.root_translation[-1, :2] - m.root_translation[0, :2])
        assert abs(rise / run - np.tan(SLOPE)) < 0.01


def test_skinned_soles_touch_the_ground(rig):
    """The full skinned mesh (4 influences), not only the contact points, stands on the
    ground: lowest sole vertex within 1 cm in stance frames, nothing deeper than 1 cm."""
    from humv_usd.human.motion import make_motion
    from humv_usd.human.skeleton import (
        forward_kinematics,
        linear_blend_skinning,
        skin_weights,
        skinning_matrices,
    )

    body, skel = rig
    mesh = body.body_mesh()
    low = np.flatnonzero(mesh.points[:, 2] < 0.05)
    idx, w = skin_weights(skel, mesh.vertex_ids[low])
    m = make_motion("walk", skel, 30, 60, speed_m_s=1.4, body_points=body.points)
    S = skinning_matrices(skel, forward_kinematics(skel, m.local_rotations, m.root_translation))
    zmin = np.array([linear_blend_skinning(mesh.points[low], idx, w, s)[:, 2].min() for s in S])
    stance = m.gait["stance"]["left"] | m.gait["stance"]["right"]
    assert zmin.min() >= -0.01 and zmin[stance].max() <= 0.01


def test_path_following(rig):
    from humv_usd.human.gait import yaw_of
    from humv_usd.human.motion import Path, make_motion

    body, skel = rig
    wp = np.array([[0.0, 0.137], [0.0, -4.0], [4.0, -4.0], [4.0, 0.0]])  # 12 m, U-turn
    m = make_motion("walk", skel, 30, 240, speed_m_s=1.4, path=wp, body_points=body.points)
    r = m.root_translation
    track = Path(wp, None)
    dist = [np.min(np.linalg.norm(track.xy - q, axis=1)) for q in r[:, :2]]
    assert max(dist) < 0.06  # on the (corner-rounded) track, +- sway
    arc = np.cumsum(np.linalg.norm(np.diff(track.xy, axis=0), axis=1))
    done = arc[np.argmin(np.linalg.norm(track.xy[1:] - r[-1, :2], axis=1))]
    assert abs(done / (239 / 30.0) - 1.4) < 0.03  # the requested speed along the path
    rot, _ = m.world(skel)
    heading = np.degrees(np.unwrap(yaw_of(rot[:, 0])))  # includes +-pelvis rotation
    assert abs(heading[:20].mean()) < 6.0 and abs(heading[-20:].mean() - 180.0) < 6.0
    assert np.any(np.abs(heading - 90.0) < 5.0)
    assert m.contact["max_slip_m"] <= 0.02 and m.contact["max_penetration_m"] <= 0.01
    # the default path: straight ahead along -Y
    m = make_motion("walk", skel, 30, 60)
    d = m.root_translation[-1] - m.root_translation[0]
    assert d[1] < -2.5 and abs(d[0]) < 0.05


@pytest.mark.parametrize("mode", ["walk", "run"])
def test_low_frame_rates_sample_the_same_motion(rig, mode):
    """A 2 s clip at 2 and 5 fps is the 30 fps clip at the same times (at 2 fps a walking
    swing fell between two frames: the merged stance pinned the foot and the pelvis sat at
    0.08-0.2 m; the run flew to 2 m): pelvis within 5 mm, no foot contact point below the
    ground, the Hips at standing height less at most 10 % (knee flexion, CoM oscillation); the
    contact report is the simulated motion's (measured on 1 fps frames, a foot's stances a
    stride apart merged into one: a walk reported 4.6 m of slip)."""
    from humv_usd.human import contact as C
    from humv_usd.human.motion import make_motion

    _, skel = rig
    feet = C.foot_points_from_joints(skel)
    ref = make_motion(mode, skel, 30, 61)
    for fps in (1, 2, 5):
        m = make_motion(mode, skel, fps, 2 * fps + 1)
        assert m.fps == fps and m.frame_count == 2 * fps + 1
        assert m.contact["max_slip_m"] == ref.contact["max_slip_m"] < 0.02
        same = ref.root_translation[:: 30 // fps]
        assert np.abs(m.root_translation - same).max() < 0.005
        rot, pos = m.world(skel)
        for fp in feet.values():
            assert fp.world(rot, pos)[..., 2].min() > -0.002
        assert m.root_translation[:, 2].min() > 0.9 * skel.rest_positions[0, 2]
        assert len(m.gait["stance"]["left"]) == len(m.metabolic_rate_w) == m.frame_count


# ------------------------------------------------------------------------- standing
def test_quiet_standing(rig):
    from humv_usd.human.motion import make_motion

    body, skel = rig
    m = make_motion("stand", skel, 30, 900, body_points=body.points, seed=2)
    r = m.root_translation
    ap, ml = r[:, 1] - r[:, 1].mean(), r[:, 0] - r[:, 0].mean()
    assert 0.002 <= ap.std() <= 0.008 and 0.001 <= ml.std() <= 0.006
    assert np.abs(ap).max() <= 0.015
    f = np.fft.rfftfreq(len(ap), 1 / 30.0)
    p = np.abs(np.fft.rfft(ap)) ** 2
    band = (f >= 0.08) & (f <= 0.55)
    assert p[band].sum() > 0.9 * p[1:].sum()  # sway at 0.1-0.5 Hz
    assert 12.0 <= 60 * np.mean(m.gait["breath_rate_hz"]) <= 16.5
    c = m.contact
    assert c["max_slip_m"] < 0.002 and c["max_gap_m"] < 0.01 and c["max_penetration_m"] < 0.01
    assert c["left"]["stance_frames"] == c["right"]["stance_frames"] == 900
    # different seeds, different sway
    m2 = make_motion("stand", skel, 30, 900, seed=3)
    assert not np.allclose(m2.root_translation, m.root_translation)


def test_stand_turn(rig):
    from humv_usd.human.gait import yaw_of
    from humv_usd.human.motion import make_motion

    body, skel = rig
    m = make_motion("standTurn", skel, 30, 150, body_points=body.points, ground=uphill)
    rot, _ = m.world(skel)
    heading = np.degrees(np.unwrap(yaw_of(rot[:, 0])))
    assert abs(heading[0]) < 1.0 and abs(heading[-1] - 180.0) < 1.0  # + = to the left
    assert np.all(np.diff(heading) > -0.5)
    for side in ("left", "right"):
        st = m.gait["stance"][side]
        assert 2 <= np.sum(st[1:] & ~st[:-1]) <= 4  # a few steps per foot
    c = m.contact
    assert c["max_slip_m"] <= 0.02 and c["max_gap_m"] <= 0.01 and c["max_penetration_m"] <= 0.01
    assert np.ptp(m.root_translation[:, :2], axis=0).max() < 0.08  # turns in place
    right = make_motion("standTurn", skel, 30, 150, turn_deg=-90)
    rot, _ = right.world(skel)
    assert abs(np.degrees(yaw_of(rot[-1, 0])) + 90.0) < 1.0


def test_post_exercise(rig):
    from humv_usd.human.motion import make_motion

    _, skel = rig
    m = make_motion("postExercise", skel, 30, 600, mass_kg=75, exercise_met=10.0)
    rate = m.metabolic_rate_w
    assert np.all(np.diff(rate) < 0)
    assert 600 < rate[0] < 900 and rate[-1] < 0.75 * rate[0]
    b = m.gait["breath_rate_hz"] * 60
    assert b[0] > 30 and np.all(np.diff(b) <= 0)
    later = make_motion("postExercise", skel, 30, 30, mass_kg=75, time_since_exercise_s=600)
    assert later.metabolic_rate_w[0] < 0.5 * rate[-1]


# ------------------------------------------------------------------------- metabolic rate
def test_metabolic_rates(rig):
    from humv_usd.human.motion import acsm_vo2, make_motion, met_to_watts, metabolic_rate

    _, skel = rig
    t = np.arange(10) / 30.0
    walk = metabolic_rate("walk", 75.0, t, 1.4)
    assert np.allclose(walk, walk[0]) and 250.0 <= walk[0] <= 350.0
    assert abs(acsm_vo2("walk", 1.4) - (3.5 + 0.1 * 84.0)) < 1e-9
    assert abs(acsm_vo2("run", 3.0) - (3.5 + 0.2 * 180.0)) < 1e-9
    assert metabolic_rate("walk", 75.0, t, 1.4, grade=0.05)[0] > walk[0] * 1.5
    assert np.allclose(metabolic_rate("walk", 75.0, t, 1.4, grade=-0.05), walk)
    stand = metabolic_rate("stand", 75.0, t)
    assert 100.0 <= stand[0] <= 130.0 and abs(stand[0] - met_to_watts(1.3, 75.0)) < 1e-9
    # the motion carries it per frame; uphill costs more than level
    level = make_motion("walk", skel, 30, 90, speed_m_s=1.4, mass_kg=75)
    climb = make_motion("walk", skel, 30, 90, speed_m_s=1.4, mass_kg=75, ground=uphill)
    assert level.metabolic_rate_w.shape == (90,)
    assert np.allclose(level.metabolic_rate_w, walk[0])
    g = np.tan(SLOPE)
    expect = float(metabolic_rate("walk", 75.0, t, 1.4, grade=g)[0])
    assert abs(np.median(climb.metabolic_rate_w) - expect) < 0.05 * expect


# ------------------------------------------------------------------------- API
def test_motion_arrays_and_errors(rig):
    from humv_usd.errors import InputError
    from humv_usd.human.motion import ACTIVITIES, make_motion

    _, skel = rig
    for act in ACTIVITIES:
        m = make_motion(act, skel, 24, 48)
        assert m.activity == act and m.fps == 24.0 and m.frame_count == 48
        assert m.root_translation.shape == (48, 3)
        assert m.local_rotations.shape == (48, len(skel.names), 4)
        assert np.allclose(np.linalg.norm(m.local_rotations, axis=-1), 1.0)
        dots = np.sum(m.local_rotations[1:] * m.local_rotations[:-1], axis=-1)
        assert dots.min() > 0.9  # continuous signs, smooth
        assert m.metabolic_rate_w.shape == (48,)
        for key in ("max_gap_m", "max_penetration_m", "max_slip_m", "left", "right"):
            assert key in m.contact
    with pytest.raises(InputError, match="activity"):
        make_motion("crawl", skel, 30, 10)
    with pytest.raises(InputError, match="speed_m_s"):
        make_motion("walk", skel, 30, 10, speed_m_s=4.0)
    with pytest.raises(InputError, match="speed_m_s"):
        make_motion("run", skel, 30, 10, speed_m_s=0.5)
    with pytest.raises(InputError, match="path"):
        make_motion("walk", skel, 30, 10, path=[[0.0, 0.0]])


def test_ten_second_walk_is_fast(rig):
    """Goal: <= 2 s for a 10 s, 30 fps walk (the avatar layer's budget is 10 s in total)."""
    from humv_usd.human.motion import make_motion

    body, skel = rig
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        make_motion("walk", skel, 30, 300, speed_m_s=1.4, body_points=body.points)
        times.append(time.perf_counter() - t0)
    assert np.median(times) <= 2.0, times
