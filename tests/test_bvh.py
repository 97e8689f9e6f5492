"""BVH: parsing (channel orders, End Sites, errors with line numbers), writing, retargeting
(names, axes, units, T-pose -> A-pose) and resampling."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from humv_usd.assets import makehuman_dir
from humv_usd.errors import InputError

DATA = Path(__file__).resolve().parent / "data"
needs_rig = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)


@pytest.fixture(scope="module")
def skel():
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, 80)
    return skeleton_for(body.points, body.groups)


def quat_angle_deg(a, b):
    d = np.abs(np.sum(a * b, axis=-1))
    return np.degrees(2 * np.arccos(np.clip(d, -1.0, 1.0)))


# ------------------------------------------------------------------------- parsing
def test_parse_two_joint_chain():
    from humv_usd.human.bvh import read_bvh

    b = read_bvh(DATA / "chain2.bvh")
    assert b.names == ["Thigh", "Shin"] and b.frame_count == 4
    assert abs(b.frame_time - 0.1) < 1e-12 and b.values.shape == (4, 9)
    assert b.joints[1].parent == 0 and np.allclose(b.joints[1].end_site, [0, -40, 0])
    assert b.joints[1].channels == ["Zrotation", "Xrotation", "Yrotation"]
    rot, trans = b.local()
    assert np.allclose(trans[:, 0], [0.0, 80.0, 0.0]) and np.allclose(trans[:, 1], [0, -40, 0])
    for f, deg in enumerate((0, 30, 60, 90)):  # the Shin's Xrotation column
        a = np.radians(deg)
        rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
        assert np.allclose(rot[f, 1], rx)


def test_channel_order_composes_left_to_right():
    """``CHANNELS 3 Zrotation Xrotation Yrotation`` means R = Rz Rx Ry (column vectors)."""
    from humv_usd.human.bvh import parse_bvh

    z, x, y = 20.0, 35.0, -50.0
    orders = {"Zrotation Xrotation Yrotation": (z, x, y), "Yrotation Zrotation Xrotation": None}
    r_zxy = Rotation.from_euler("ZXY", [z, x, y], degrees=True).as_matrix()
    yzx = Rotation.from_matrix(r_zxy).as_euler("YZX", degrees=True)
    orders["Yrotation Zrotation Xrotation"] = tuple(yzx)
    mats = []
    for chans, vals in orders.items():
        text = (
            f"HIERARCHY\nROOT A\n{{\n OFFSET 0 0 0\n CHANNELS 3 {chans}\n End Site\n {{\n"
            f"  OFFSET 0 1 0\n }}\n}}\nMOTION\nFrames: 1\nFrame Time: 0.01\n"
            f"{vals[0]} {vals[1]} {vals[2]}\n"
        )
        rot, _ = parse_bvh(text).local()
        mats.append(rot[0, 0])
    rz = Rotation.from_euler("z", z, degrees=True).as_matrix()
    rx = Rotation.from_euler("x", x, degrees=True).as_matrix()
    ry = Rotation.from_euler("y", y, degrees=True).as_matrix()
    assert np.allclose(mats[0], rz @ rx @ ry) and np.allclose(mats[1], mats[0])
    assert not np.allclose(mats[0], ry @ rx @ rz)


BAD = {
    "no hierarchy": ("ROOT A\n{\n}\n", 1, "'HIERARCHY'"),
    "bad channel": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrot Zrotation\n"
        "}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n",
        5,
        "channel name",
    ),
    "short channels": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation\n"
        "}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0\n",
        6,
        "channel name",
    ),
    "offset text": ("HIERARCHY\nROOT A\n{\n OFFSET 0 zero 0\n}\nMOTION\n", 4, "a number"),
    "no motion": ("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n}\n", 5, "'MOTION'"),
    "frames": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\n"
        "Frames: two\nFrame Time: 0.1\n0\n",
        8,
        "Frames: N",
    ),
    "frame time": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\n"
        "Frames: 1\nFrame Time: -1\n0\n",
        9,
        "Frame Time",
    ),
    "values": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 2 Xrotation Yrotation\n}\n"
        "MOTION\nFrames: 2\nFrame Time: 0.1\n0 0\n0 0 0\n",
        11,
        "2 channel values",
    ),
    "number": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 2 Xrotation Yrotation\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.1\n0 x\n",
        10,
        "a number",
    ),
    "missing frames": (
        "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\n"
        "MOTION\nFrames: 3\nFrame Time: 0.1\n0\n0\n",
        11,
        "3 frame lines",
    ),
    "brace": ("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n JOINT B\n OFFSET 0 1 0\n}\n", 6, "'{'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_bvh_names_file_and_line(tmp_path, case):
    from humv_usd.human.bvh import read_bvh

    text, line, expected = BAD[case]
    path = tmp_path / f"{case.replace(' ', '_')}.bvh"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_bvh(path)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}:{line}: expected"), msg
    assert expected in msg, msg


def test_missing_file_is_input_error(tmp_path):
    from humv_usd.human.bvh import read_bvh

    with pytest.raises(InputError, match="nothere.bvh"):
        read_bvh(tmp_path / "nothere.bvh")


def test_axis_matrix():
    from humv_usd.human.bvh import axis_matrix

    A = axis_matrix("Y", "Z")  # CMU: Y up, facing +Z, left +X
    assert np.allclose(A @ [0, 1, 0], [0, 0, 1]) and np.allclose(A @ [0, 0, 1], [0, -1, 0])
    assert np.allclose(A @ [1, 0, 0], [1, 0, 0]) and abs(np.linalg.det(A) - 1) < 1e-12
    assert np.allclose(axis_matrix("Z", "-Y"), np.eye(3))  # our own convention
    with pytest.raises(InputError):
        axis_matrix("Y", "Y")
    with pytest.raises(InputError):
        axis_matrix("W", "Z")


# ------------------------------------------------------------------------- retargeting
@needs_rig
@pytest.mark.parametrize(
    "order,up,forward,scale", [("ZXY", "Y", "Z", 0.01), ("XYZ", "Z", "-Y", 1.0), ("ZYX", "Y", "-X", 0.0254)]
)
def test_round_trip(tmp_path, skel, order, up, forward, scale):
    """Our motion written as BVH (any channel order, axes, units) reads back unchanged."""
    from humv_usd.human.bvh import motion_from_bvh, motion_to_bvh, write_bvh
    from humv_usd.human.motion import make_motion

    m = make_motion("walk", skel, 30, 45, speed_m_s=1.4)
    b = motion_to_bvh(skel, m.local_rotations, m.root_translation, 30, order, up, forward, scale)
    path = tmp_path / "rt.bvh"
    write_bvh(path, b)
    back = motion_from_bvh(
        path, skel, 30, up_axis=up, forward_axis=forward, recenter=False, settle=False, lock_feet=False
    )
    assert back.frame_count == 45
    assert abs(back.gait["scale_m_per_unit"] - scale) < 1e-6 * scale  # from hip heights
    assert quat_angle_deg(back.local_rotations, m.local_rotations).max() < 1e-3
    assert np.abs(back.root_translation - m.root_translation).max() < 1e-5


@needs_rig
def test_name_map_drives_mapped_joints_only(skel):
    from humv_usd.human.bvh import motion_from_bvh

    m = motion_from_bvh(
        DATA / "chain2.bvh",
        skel,
        10,
        settle=False,
        name_map={"Thigh": "LeftUpLeg", "Shin": "LeftLeg"},
        lock_feet=False,  # the retargeted angles as they are (the lock is tested below)
    )
    assert set(m.gait["mapped"]) == {"LeftUpLeg", "LeftLeg"}
    rot, pos = m.world(skel)
    ix = skel.index
    knee, ankle = pos[:, ix("LeftLeg")], pos[:, ix("LeftFoot")]
    hip = pos[:, ix("LeftUpLeg")]
    for f, deg in enumerate((0, 30, 60, 90)):
        # BVH: shin rotated about X by deg; Y up, facing +Z -> ours: from -Z towards +Y (back)
        a = np.radians(deg)
        want = np.array([0.0, np.sin(a), -np.cos(a)])
        got = (ankle[f] - knee[f]) / np.linalg.norm(ankle[f] - knee[f])
        assert np.allclose(got, want, atol=1e-9)
        thigh = (knee[f] - hip[f]) / np.linalg.norm(knee[f] - hip[f])
        assert np.allclose(thigh, [0, 0, -1], atol=1e-9)  # aligned to the BVH's thigh
    # unmapped joints stay at rest: identity local rotations, Hips at its rest position
    others = [j for j, n in enumerate(skel.names) if n not in ("LeftUpLeg", "LeftLeg")]
    assert np.allclose(np.abs(m.local_rotations[:, others, 0]), 1.0)
    assert np.allclose(m.root_translation, skel.rest_positions[0])
    with pytest.raises(InputError, match="name_map"):
        motion_from_bvh(DATA / "chain2.bvh", skel, 10)  # no name matches the rig


@needs_rig
def test_cmu_knee_bend_retargets_from_t_pose(skel):
    """CMU-named subset (Y up, +Z facing, inch-like units, T-pose rest, per-joint channel
    orders): the knee bend's joint angles come through exactly; the T-pose arms, rotated
    75 deg down in the file, hang 15 deg from the vertical on our A-pose rig."""
    from humv_usd.human.bvh import motion_from_bvh, read_bvh
    from humv_usd.human.gait import sagittal_angles

    src = read_bvh(DATA / "knee_bend_cmu.bvh")
    assert src.joints[src.names.index("LeftArm")].channels[0] == "Xrotation"
    assert src.joints[src.names.index("LeftLeg")].channels[0] == "Zrotation"
    m = motion_from_bvh(DATA / "knee_bend_cmu.bvh", skel, 120, lock_feet=False)
    assert m.frame_count == 121
    rot, pos = m.world(skel)
    a = sagittal_angles(skel, rot, pos)
    s = 0.5 * (1 - np.cos(2 * np.pi * np.arange(121) / 120.0))
    for side in ("Left", "Right"):
        assert np.allclose(a[f"{side}Hip"], 70 * s, atol=0.05)
        assert np.allclose(a[f"{side}Knee"], 110 * s, atol=0.05)
        assert np.allclose(a[f"{side}Ankle"], 40 * s, atol=0.05)
    ix = skel.index
    # world flexion of the arm = its own 60 s minus the trunk's 30 s forward lean
    for f, flex in ((0, 0.0), (30, 15.0), (60, 30.0)):
        d = pos[f, ix("LeftForeArm")] - pos[f, ix("LeftArm")]
        d /= np.linalg.norm(d)
        want = np.array([np.sin(np.radians(15)), 0.0, -np.cos(np.radians(15))])
        fl = np.radians(flex)  # then flexed forward (-Y) about X
        want = np.array([want[0], -np.sin(fl) * -want[2], want[2] * np.cos(fl)])
        assert np.allclose(d, want, atol=1e-6), (f, d, want)
        r = pos[f, ix("RightForeArm")] - pos[f, ix("RightArm")]
        assert np.allclose(r / np.linalg.norm(r), want * [-1, 1, 1], atol=1e-6)
    # the squat goes down ~0.37 m and back; the settled feet stay on the ground
    z = m.root_translation[:, 2]
    assert 0.3 < z[0] - z[60] < 0.45 and abs(z[0] - z[-1]) < 1e-6
    assert m.contact["max_penetration_m"] <= 0.01 and m.contact["max_gap_m"] <= 0.01
    assert m.contact["max_slip_m"] <= 0.02
    assert 0.02 < m.gait["scale_m_per_unit"] < 0.03  # inch-like units


@needs_rig
def test_resampling_120_to_30_fps(skel):
    from humv_usd.human.bvh import motion_from_bvh
    from humv_usd.human.gait import quat_slerp

    full = motion_from_bvh(DATA / "knee_bend_cmu.bvh", skel, 120, settle=False, lock_feet=False)
    m30 = motion_from_bvh(DATA / "knee_bend_cmu.bvh", skel, 30, settle=False, lock_feet=False)
    assert m30.frame_count == 31 and m30.fps == 30.0
    assert quat_angle_deg(m30.local_rotations, full.local_rotations[::4]).max() < 1e-4
    assert np.allclose(m30.root_translation, full.root_translation[::4])
    # off-grid: 24 fps frame 1 (t = 1/24 s = 5 source frames) and frame 3 (15 frames)
    m24 = motion_from_bvh(DATA / "knee_bend_cmu.bvh", skel, 24, frame_count=30, settle=False, lock_feet=False)
    assert quat_angle_deg(m24.local_rotations[3], full.local_rotations[15]).max() < 1e-4
    # 25 fps frame 1: t = 0.04 s = 4.8 source frames -> slerp between frames 4 and 5
    m25 = motion_from_bvh(DATA / "knee_bend_cmu.bvh", skel, 25, settle=False, lock_feet=False)
    want = quat_slerp(full.local_rotations[4], full.local_rotations[5], np.full(31, 0.8))
    assert quat_angle_deg(m25.local_rotations[1], want).max() < 1e-4
    assert np.allclose(
        m25.root_translation[1], 0.2 * full.root_translation[4] + 0.8 * full.root_translation[5]
    )
    assert m30.frame_count == 31 and m24.frame_count == 30
    # beyond the clip the last frame is held
    long = motion_from_bvh(
        DATA / "knee_bend_cmu.bvh", skel, 30, frame_count=40, settle=False, lock_feet=False
    )
    assert np.allclose(long.local_rotations[35], full.local_rotations[-1])


# ------------------------------------------------------------------------- foot locking
def test_clean_stance_fills_flicker_and_drops_blips():
    from humv_usd.human.contact import clean_stance

    m = np.zeros(30, bool)
    m[2:10] = True
    m[11:20] = True  # a one-frame gap (33 ms at 30 fps): filled
    m[25:27] = True  # a two-frame blip (67 ms): dropped
    got = clean_stance(m, 30.0)
    want = np.zeros(30, bool)
    want[2:20] = True
    assert np.array_equal(got, want)


def _standing_slide(skel, slide_m: float, frames: int = 60):
    """The rest pose, both feet down, the whole body carried ``slide_m`` along +X between
    frames 10 and 40 (as a retargeted clip whose feet skate)."""
    from humv_usd.human.gait import fk_matrices

    local = np.tile(np.eye(3), (frames, len(skel.names), 1, 1))
    root = np.tile(skel.rest_positions[0], (frames, 1))
    root[:, 0] += slide_m * np.clip((np.arange(frames) - 10) / 30.0, 0.0, 1.0)
    return local, root, fk_matrices


@needs_rig
def test_lock_feet_plants_a_skating_foot(skel):
    """Feet that skate 3 cm with the body (0.03 m/s, detected as planted) stay where they
    touched down: slip < 0.5 mm, none under the ground, the legs reach them (the root drops
    at most MAX_LOCK_DROP_M)."""
    from humv_usd.human import contact as C

    local, root, fk = _standing_slide(skel, 0.03)
    feet = C.foot_points_from_joints(skel)
    ground = C.Ground(None)
    stance = {s: np.ones(len(root), bool) for s in C.SIDES}
    wr, wp = fk(skel, local, local[:, 0], root)
    before = C.contact_report(ground, feet, wr, wp, stance)
    assert before["max_slip_m"] > 0.029  # the feet move with the body
    out, r2, kept = C.lock_feet(skel, ground, feet, local, local[:, 0], root, stance, 30.0)
    wr, wp = fk(skel, out, out[:, 0], r2)
    after = C.contact_report(ground, feet, wr, wp, kept)
    assert all(m.all() for m in kept.values())
    assert after["max_slip_m"] < 5e-4 and after["max_penetration_m"] < 5e-4
    assert np.abs(r2 - root).max() <= C.MAX_LOCK_DROP_M + 1e-9
    # the ankles stay at their first-frame positions (closed form: nothing moves)
    for s in C.SIDES:
        a = wp[:, skel.index(f"{s}Foot")]
        assert np.abs(a - a[0]).max() < 5e-4


@needs_rig
def test_lock_feet_releases_a_dragged_foot(skel):
    """A 40 cm skate cannot be planted (the legs would not reach): released, legs untouched."""
    from humv_usd.human import contact as C

    local, root, _ = _standing_slide(skel, 0.40)
    feet = C.foot_points_from_joints(skel)
    stance = {s: np.ones(len(root), bool) for s in C.SIDES}
    out, r2, kept = C.lock_feet(skel, C.Ground(None), feet, local, local[:, 0], root, stance, 30.0)
    assert not any(m.any() for m in kept.values())
    assert np.allclose(out, local, atol=1e-9) and np.allclose(r2, root)
