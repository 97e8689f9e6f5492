"""Contact machinery: ground queries, foot contact points, planted stance (rolling without
slipping on a support plane), swing clearance, two-bone leg IK and the contact report."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.assets import makehuman_dir

pytestmark = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)


@pytest.fixture(scope="module")
def rig():
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for

    body = build_body("male", 30, 1.78, 80)
    return body, skeleton_for(body.points, body.groups)


def plane_mesh(slope_deg=5.0, size=4.0):
    import trimesh

    t = np.tan(np.radians(slope_deg))
    v = np.array([[-size, -size, 0], [size, -size, 0], [size, size, 0], [-size, size, 0]], dtype=float)
    v[:, 2] = -t * v[:, 1]
    return trimesh.Trimesh(v, [[0, 1, 2], [0, 2, 3]], process=False)


def test_ground_queries():
    from humv_usd.human.contact import Ground

    xy = np.array([[0.3, -1.2], [-2.0, 3.1], [1.0, 0.0]])
    t = np.tan(np.radians(5.0))
    assert np.allclose(Ground(None).height(xy), 0.0)
    fn = Ground(lambda x, y: -t * y)
    mesh = Ground(plane_mesh())
    assert fn.kind == "function" and mesh.kind == "mesh"
    assert np.allclose(fn.height(xy), -t * xy[:, 1])
    assert np.allclose(mesh.height(xy), -t * xy[:, 1], atol=1e-9)  # ray cast
    assert mesh.height(np.zeros((0, 2))).shape == (0,)
    # outside the mesh: nearest vertex height, no error
    assert np.isfinite(mesh.height(np.array([[10.0, 10.0]]))).all()
    with pytest.raises(TypeError):
        Ground("flat")


def test_foot_points(rig):
    from humv_usd.human.contact import foot_points_from_body, foot_points_from_joints

    body, skel = rig
    eye = np.eye(3)
    for feet in (foot_points_from_joints(skel), foot_points_from_body(skel, body.points)):
        for side, fp in feet.items():
            rest = skel.rest_positions[fp.foot] + fp.relative(eye, eye)
            assert np.abs(rest[:, 2]).max() < 0.011  # on the rest sole plane
            sign = 1 if side == "Left" else -1
            assert np.all(sign * rest[:, 0] > 0.1)  # +x is the person's left
            assert ((fp.toe_weight >= 0) & (fp.toe_weight <= 1)).all()
            assert fp.toe_weight.max() > 0.9 and fp.toe_weight.min() < 0.1  # heel and toes
            span = np.ptp(rest[:, 1])
            assert 0.2 < span < 0.3  # heel to toe tip
    assert len(foot_points_from_body(skel, body.points)["Left"].rest) > 30


def test_plant_stance_rolls_without_slipping_on_a_slope(rig):
    from humv_usd.human.contact import Ground, foot_points_from_joints, plant_stance

    _, skel = rig
    fp = foot_points_from_joints(skel)["Left"]
    t = np.tan(np.radians(5.0))
    ground = Ground(lambda x, y: -t * y)
    n = 30
    pitch = np.radians(np.r_[np.linspace(18, 0, 6), np.zeros(12), np.linspace(0, -50, 12)])
    stance = np.ones(n, bool)
    ankle_xy = np.tile([0.2, 0.13], (n, 1))
    (st,) = plant_stance(ground, fp, stance, ankle_xy, np.zeros(n), pitch)
    # the support plane is the slope
    assert np.allclose(st.plane[:, 2], [0, t / np.hypot(1, t), 1 / np.hypot(1, t)])  # normal
    rel = fp.relative(st.foot_rot, st.toe_rot)
    pts = st.ankle[:, None, :] + rel  # (n, m, 3) world
    h = pts[..., 2] - ground.height(pts[..., :2])
    assert np.abs(h.min(axis=1)).max() < 1e-9  # always touching
    assert h.min() > -1e-9  # never below
    touching = h < 1e-6
    for j in range(rel.shape[1]):  # touching points stay
        sel = pts[touching[:, j], j, :2]
        if len(sel) > 1:
            assert np.linalg.norm(sel - sel[0], axis=1).max() < 1e-4  # 0.1 mm
    # heel first, toes last
    assert touching[0].sum() >= 1 and not touching[0, fp.toe_weight > 0.5].any()
    assert touching[-1, fp.toe_weight > 0.5].all() and not touching[-1, fp.toe_weight < 0.5].any()


def test_swing_clearance_over_a_bump(rig):
    from humv_usd.human.contact import Ground, foot_points_from_joints, swing_targets
    from humv_usd.human.gait import rot_x

    _, skel = rig
    fp = foot_points_from_joints(skel)["Left"]
    n = 20
    ankle = np.column_stack([np.full(n, 0.2), np.linspace(0.3, -0.5, n), np.full(n, 0.09)])
    foot = rot_x(np.full(n, np.radians(10.0)))  # toes slightly down
    bump = Ground(lambda x, y: 0.05 * np.exp(-(((np.asarray(y) + 0.1) / 0.1) ** 2)))
    tg = swing_targets(bump, fp, [], ankle, foot, np.zeros(n))
    pts = tg.ankle[:, None, :] + fp.relative(tg.foot_rot, tg.toe_rot)
    clearance = pts[..., 2] - bump.height(pts[..., :2])
    assert clearance.min() > -1e-3 and tg.lift.max() > 0.0
    flat = swing_targets(Ground(None), fp, [], ankle, foot, np.zeros(n))
    assert flat.lift.max() == 0.0


def test_leg_ik_reaches_targets(rig):
    from humv_usd.human.contact import FootTargets, leg_chain, leg_ik
    from humv_usd.human.gait import fk_matrices, rot_x, rot_y, rot_z

    _, skel = rig
    rng = np.random.default_rng(0)
    n = 50
    chain = leg_chain(skel, "Left")
    root_pos = np.tile(skel.rest_positions[0], (n, 1))
    root_rot = rot_z(rng.uniform(-0.3, 0.3, n)) @ rot_x(rng.uniform(-0.1, 0.1, n))
    hip = root_pos + root_rot @ chain.hip_offset
    d = rng.normal(size=(n, 3)) * [0.15, 0.3, 0.1] + [0, 0, -0.7]
    d *= np.minimum(1.0, 0.95 * chain.reach / np.linalg.norm(d, axis=1))[:, None]
    foot = rot_z(rng.uniform(-0.5, 0.5, n)) @ rot_x(rng.uniform(-0.6, 0.6, n))
    toe = foot @ rot_x(rng.uniform(-0.8, 0.0, n))
    tg = FootTargets(hip + d, foot, toe, np.zeros(n))
    nominal = rot_y(np.full(n, 0.1))
    h, k, a, t = leg_ik(chain, root_pos, root_rot, nominal, tg)
    local = np.tile(np.eye(3), (n, len(skel.names), 1, 1))
    for j, r in ((chain.hip, h), (chain.knee, k), (chain.ankle, a), (chain.toe, t)):
        local[:, j] = r
    wr, wp = fk_matrices(skel, local, root_rot, root_pos)
    assert np.abs(wp[:, chain.ankle] - tg.ankle).max() < 1e-9
    assert np.abs(wr[:, chain.ankle] - foot).max() < 1e-9
    assert np.abs(wr[:, chain.toe] - toe).max() < 1e-9
    # the knee bends forward (hinge about the thigh's x axis, positive flexion only)
    assert np.allclose(k[:, 0], [1, 0, 0])
    assert np.all(np.arctan2(k[:, 2, 1], k[:, 1, 1]) > chain.phi0)
    # out of reach: the leg straightens towards the target
    far = FootTargets(hip + [0.0, 0.0, -1.5], foot, toe, np.zeros(n))
    h, k, a, t = leg_ik(chain, root_pos, root_rot, nominal, far)
    local[:, chain.hip], local[:, chain.knee] = h, k
    _, wp = fk_matrices(skel, local, root_rot, root_pos)
    got = wp[:, chain.ankle] - hip
    assert np.allclose(np.linalg.norm(got, axis=1), chain.reach, rtol=1e-6)
    assert np.allclose(got / np.linalg.norm(got, axis=1)[:, None], [0, 0, -1], atol=1e-9)


def test_contact_report_catches_errors(rig):
    """The report is a real check: sinking, floating and sliding feet are reported."""
    from humv_usd.human.contact import Ground, contact_report, foot_points_from_joints
    from humv_usd.human.motion import make_motion

    _, skel = rig
    m = make_motion("walk", skel, 30, 60)
    feet = foot_points_from_joints(skel)
    rot, pos = m.world(skel)
    stance = {"Left": m.gait["stance"]["left"], "Right": m.gait["stance"]["right"]}
    ok = contact_report(Ground(None), feet, rot, pos, stance)
    assert ok["max_gap_m"] < 1e-6 and ok["max_penetration_m"] < 1e-6 and ok["max_slip_m"] < 0.01
    sunk = contact_report(Ground(None), feet, rot, pos - [0, 0, 0.02], stance)
    assert abs(sunk["max_penetration_m"] - 0.02) < 1e-6
    floating = contact_report(Ground(None), feet, rot, pos + [0, 0, 0.015], stance)
    assert abs(floating["max_gap_m"] - 0.015) < 1e-6
    slide = pos.copy()
    slide[..., 1] -= 0.01 * np.arange(60)[:, None]  # 1 cm per frame forward
    slid = contact_report(Ground(None), feet, rot, slide, stance)
    assert slid["left"]["max_slip_m"] > 0.1 and slid["right"]["max_slip_m"] > 0.1


def test_settle_root(rig):
    from humv_usd.human.contact import Ground, foot_points_from_joints, settle_root
    from humv_usd.human.motion import make_motion

    _, skel = rig
    m = make_motion("stand", skel, 30, 30)
    rot, pos = m.world(skel)
    feet = foot_points_from_joints(skel)
    for dz in (0.03, -0.03):
        off, planted = settle_root(Ground(None), feet, rot, pos + [0, 0, dz], 30)
        assert np.allclose(off, -dz, atol=1e-6) and planted["Left"].all()
    # a lifted, moving foot (flight) is not pulled down, only kept above the ground
    lifted = pos + [0, 0, 0.3]
    lifted[..., 1] += 0.2 * np.arange(30)[:, None]
    off, planted = settle_root(Ground(None), feet, rot, lifted, 30)
    assert not planted["Left"].any() and np.all(off >= -0.3 - 1e-9)
