"""DeepMimic clips -> CMU BVH (human/deepmimic.py) and their retargeting onto our rig."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from humv_usd.assets import mocap_dir
from humv_usd.errors import InputError
from humv_usd.human import deepmimic as D
from humv_usd.human.bvh import format_bvh, parse_bvh


def _frame(root=(0.0, 0.9, 0.0), right_hip=(1.0, 0.0, 0.0, 0.0), right_knee=0.0, dt=1 / 30):
    f = np.zeros(D.FRAME_VALUES)
    f[0], f[1:4] = dt, root
    for sl in (slice(4, 8), slice(8, 12), slice(12, 16), slice(21, 25), slice(25, 29)):
        f[sl] = (1.0, 0.0, 0.0, 0.0)
    for sl in (slice(30, 34), slice(35, 39), slice(39, 43)):
        f[sl] = (1.0, 0.0, 0.0, 0.0)
    f[16:20], f[20] = right_hip, right_knee
    return f


def _world_positions(bvh, frame: int) -> dict[str, np.ndarray]:
    rot, trans = bvh.local()
    pos, wrot = {}, {}
    for i, j in enumerate(bvh.joints):
        if j.parent < 0:
            wrot[i], pos[i] = rot[frame, i], trans[frame, i]
        else:
            wrot[i] = wrot[j.parent] @ rot[frame, i]
            pos[i] = pos[j.parent] + wrot[j.parent] @ trans[frame, i]
    return {j.name: pos[i] for i, j in enumerate(bvh.joints)}


def test_hip_flexion_puts_the_knee_forward():
    """Right hip +90 deg about DeepMimic's z (its right axis): the thigh swings from down to
    forward (+X there, +Z in CMU's frame); the knee at hip + thigh length 0.25 x 1.686184."""
    q = Rotation.from_euler("z", 90, degrees=True).as_quat()  # xyzw
    frames = np.array([_frame(right_hip=(q[3], q[0], q[1], q[2])), _frame(dt=0.0)])
    bvh = D.clip_to_bvh(frames)
    p = _world_positions(bvh, 0)
    thigh = 0.25 * 1.686184
    hip = np.array([-0.25 * 0.339548, 0.9, 0.0])  # DeepMimic's right (+z) is CMU's -x
    np.testing.assert_allclose(p["RightUpLeg"], hip, atol=1e-9)
    np.testing.assert_allclose(p["RightLeg"], hip + [0.0, 0.0, thigh], atol=1e-5)
    # the other leg hangs: left knee straight below its hip
    np.testing.assert_allclose(p["LeftLeg"] - p["LeftUpLeg"], [0.0, -thigh, 0.0], atol=1e-9)
    assert [j.name for j in bvh.joints][:3] == ["Hips", "Spine", "Neck"]


def test_knee_angle_and_bvh_round_trip():
    frames = np.array([_frame(right_knee=-1.0), _frame(right_knee=-0.5), _frame(dt=0.0)])
    bvh = D.clip_to_bvh(frames)
    back = parse_bvh(format_bvh(bvh, precision=8), "<memory>")
    np.testing.assert_allclose(back.values, bvh.values, atol=1e-6)
    assert back.frame_time == pytest.approx(1 / 30)
    # knee flexion about the right axis: the shank swings backwards (-Z in CMU's frame)
    p = _world_positions(back, 0)
    shank = p["RightFoot"] - p["RightLeg"]
    assert shank[2] == pytest.approx(-0.25 * 1.63948 * np.sin(1.0), abs=1e-5)


def test_wrapping_clip_repeats_with_the_root_moving_on():
    frames = np.array(
        [_frame(root=(0.0, 0.9, 0.0)), _frame(root=(0.5, 0.9, 0.0)), _frame(root=(1.0, 0.9, 0.0), dt=0)]
    )
    bvh = D.clip_to_bvh(frames, wraps=True, cycles=3)
    assert bvh.frame_count == 3 * 2 + 1
    x_dm = [_world_positions(bvh, f)["Hips"] for f in range(bvh.frame_count)]
    # DeepMimic +X (forward) is CMU +Z
    np.testing.assert_allclose([p[2] for p in x_dm], np.arange(7) * 0.5, atol=1e-9)
    with pytest.raises(InputError, match="cycles"):
        D.clip_to_bvh(frames, wraps=False, cycles=2)


def test_bad_clips_are_one_clear_error():
    with pytest.raises(InputError, match="^x.txt: not a DeepMimic clip"):
        D.parse_clip("{nope", "x.txt")
    with pytest.raises(InputError, match="44 values"):
        D.parse_clip(json.dumps({"Loop": "none", "Frames": [[0.1, 1, 2], [0.0, 1, 2]]}), "y.txt")
    frames, wraps = D.parse_clip(json.dumps({"Loop": "wrap", "Frames": [list(_frame()), list(_frame(dt=0))]}))
    assert wraps and frames.shape == (2, 44)


@pytest.mark.extended
def test_fetched_clips_retarget_onto_the_rig():
    """The clips fetched at set-up (tools/fetch_mocap.py): walking at DeepMimic's pace with
    planted feet; the get-up never puts the body under the ground."""
    walk, getup = mocap_dir() / "deepmimic_walk.bvh", mocap_dir() / "deepmimic_getup_faceup.bvh"
    if not walk.is_file():
        pytest.skip("DeepMimic clips not fetched (tools/fetch_mocap.py)")
    from humv_usd.human.body import build_body
    from humv_usd.human.bvh import motion_from_bvh
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, 80.0)
    sk = skeleton_for(body.points, body.groups)
    m = motion_from_bvh(walk, sk, 30.0, body_points=body.points)
    speed = np.linalg.norm(m.root_translation[-1, :2] - m.root_translation[0, :2]) / (m.frame_count / 30.0)
    assert 0.9 < speed < 1.2  # 1.239 m per 1.27 s cycle, scaled by our hip height (x1.06)
    assert m.contact["max_slip_m"] < 0.02 and m.contact["max_penetration_m"] < 1e-3
    g = motion_from_bvh(getup, sk, 30.0, body_points=body.points)
    assert g.contact["max_penetration_m"] < 1e-3
    assert g.root_translation[0, 2] < 0.3 < 0.8 < g.root_translation[-1, 2]  # lying -> standing
