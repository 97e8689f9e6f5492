"""Dual quaternion skinning against closed forms and UsdSkel; the arm clearance of the avatar
tool against an independent inside test (issue 25, deliverable 2: armpits)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from humv_usd.assets import makehuman_dir

needs_makehuman = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)


def _twist(angle: float) -> np.ndarray:
    """(2, 4, 4): joint 0 identity, joint 1 a rotation by ``angle`` about the x axis through
    (0.1, 0, 0) (a twist of a limb along x)."""
    c, s = np.cos(angle), np.sin(angle)
    m = np.tile(np.eye(4), (2, 1, 1))
    m[1, :3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    m[1, :3, 3] = np.array([0.1, 0.0, 0.0]) - m[1, :3, :3] @ [0.1, 0.0, 0.0]
    return m


def test_dqs_keeps_the_radius_that_linear_blending_collapses():
    """Half/half between an identity and a 120 deg twist: LBS averages two vectors 120 deg
    apart (radius r cos 60 deg = r/2, the candy wrapper); DQS rotates by 60 deg (radius r, the
    point on the bisector) (Kavan et al. 2008, Fig. 2)."""
    from humv_usd.human.skeleton import dual_quaternion_skinning, linear_blend_skinning

    skin = _twist(np.radians(120.0))
    p = np.array([[0.3, 0.04, 0.0]])
    idx, w = np.array([[0, 1]]), np.array([[0.5, 0.5]])
    lbs = linear_blend_skinning(p, idx, w, skin)[0]
    dqs = dual_quaternion_skinning(p, idx, w, skin)[0]
    assert np.hypot(*lbs[1:]) == pytest.approx(0.02, abs=1e-12)
    assert np.hypot(*dqs[1:]) == pytest.approx(0.04, abs=1e-12)
    np.testing.assert_allclose(dqs, [0.3, 0.04 * np.cos(np.pi / 3), 0.04 * np.sin(np.pi / 3)], atol=1e-12)
    # one influence: the rigid transform itself, translation included
    rigid = dual_quaternion_skinning(p, np.array([[1, 0]]), np.array([[1.0, 0.0]]), skin)[0]
    np.testing.assert_allclose(rigid, skin[1, :3, :3] @ p[0] + skin[1, :3, 3], atol=1e-12)


@pytest.fixture(scope="module")
def rigged():
    from humv_usd.geometry.mesh import fan_triangulate
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for, skin_weights

    body = build_body("male", 30, 1.78, 80)
    skel = skeleton_for(body.points, body.groups)
    mesh = body.body_mesh()
    idx, w = skin_weights(skel, mesh.vertex_ids)
    tris, _ = fan_triangulate(mesh.face_counts, mesh.face_indices)
    return body, skel, mesh, tris, idx, w


def _arms_down(skel, frames_down: int, frames_rest: int):
    """Frames with both arms hanging vertically (adducted from the rest A-pose into the trunk),
    then frames at rest; the rest of the body at rest."""
    from humv_usd.human.motion import Motion

    q = np.zeros((frames_down + frames_rest, len(skel.names), 4))
    q[..., 0] = 1.0
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        j = skel.index(f"{side}Arm")
        d = skel.tail_positions[j] - skel.rest_positions[j]
        rest_abd = np.arctan2(abs(d[0]), -d[2])  # from the vertical in the frontal plane
        h = 0.5 * sign * rest_abd
        q[:frames_down, j] = (np.cos(h), 0.0, np.sin(h), 0.0)
    root = np.repeat(skel.rest_positions[:1], len(q), axis=0)
    rate = np.full(len(q), 100.0)
    return Motion(1.0, root, q, "stand", rate, {})


@needs_makehuman
def test_dqs_is_what_usdskel_computes_for_dual_quaternion(rigged):
    """Our DQS and UsdSkel's ``skel:skinningMethod = dualQuaternion`` (SkinningQuery) agree on
    the body in a pose; the classic method is our LBS."""
    from pxr import Usd, UsdSkel

    from humv_usd.human import usdskel
    from humv_usd.human.skeleton import (
        dual_quaternion_skinning,
        forward_kinematics,
        linear_blend_skinning,
        skinning_matrices,
    )
    from humv_usd.usd.mesh import define_mesh

    body, skel, mesh, _, idx, w = rigged
    motion = _arms_down(skel, 1, 0)
    q = motion.local_rotations.copy()
    q[0, skel.index("LeftForeArm")] = (np.cos(0.6), 0.3, 0.0, np.sin(0.6) * 0.9)  # twist + bend
    q[0, skel.index("LeftUpLeg")] = (np.cos(0.5), -np.sin(0.5), 0.0, 0.0)
    pose = usdskel.Pose(motion.root_translation, q / np.linalg.norm(q, axis=-1, keepdims=True))
    stage = Usd.Stage.CreateInMemory()
    usdskel.define_skel_root(stage, "/P")
    usdskel.define_skeleton(stage, "/P/Skeleton", skel)
    usdskel.define_animation(stage, "/P/Motion", skel, pose)
    usdskel.bind_animation(stage.GetPrimAtPath("/P/Skeleton"), "/P/Motion")
    m = define_mesh(stage, "/P/Body", mesh.points, mesh.face_counts, mesh.face_indices)
    binding = usdskel.bind_mesh(m.GetPrim(), "/P/Skeleton", idx, w)
    skin = skinning_matrices(skel, forward_kinematics(skel, pose.local_rotations, pose.root_translation))[0]
    lbs = linear_blend_skinning(mesh.points, idx, w, skin)
    dqs = dual_quaternion_skinning(mesh.points, idx, w, skin)
    assert np.abs(dqs - lbs).max() > 5e-3  # the two methods differ in this pose
    np.testing.assert_allclose(usdskel.skinned_points(stage, "/P/Body", Usd.TimeCode(0)), lbs, atol=2e-6)
    binding.CreateSkinningMethodAttr().Set(UsdSkel.Tokens.dualQuaternion)
    np.testing.assert_allclose(usdskel.skinned_points(stage, "/P/Body", Usd.TimeCode(0)), dqs, atol=2e-6)


@needs_makehuman
def test_clear_arms_takes_the_upper_arm_out_of_the_trunk(rigged):
    """Arms hanging vertically put the upper arm into the trunk; after ``clear_arms`` no upper-arm
    test point below the armpit (skin + 4 mm, > 10 cm from the abduction axis) is inside the
    posed body by an independent test (the signed ray-crossing winding number of the whole
    body), the arm is abducted by 2-30 deg, and
    frames already clear (beyond the one-frame dilation) keep their rotations bit for bit."""
    from humv_usd.bench.skinning import winding_numbers
    from humv_usd.human.clearance import MAX_ABDUCTION, arm_body, clear_arms
    from humv_usd.human.skeleton import forward_kinematics, linear_blend_skinning, skinning_matrices

    body, skel, mesh, tris, idx, w = rigged
    arms = arm_body(skel, mesh.points, tris, idx, w)
    motion = _arms_down(skel, 1, 3)  # 1 fps: every frame is checked
    report = {}
    cleared = clear_arms(motion, skel, arms, report)
    # frame 1 takes frame 0's angle (dilated by one checked frame), frames 2 and 3 are clear
    np.testing.assert_array_equal(cleared.local_rotations[2:], motion.local_rotations[2:])
    assert report["Left"]["frames"] == 2
    for side in ("Left", "Right"):
        assert 2.0 < report[side]["max_deg"] <= np.degrees(MAX_ABDUCTION) + 1e-9

    def inside_counts(m):
        world = forward_kinematics(skel, m.local_rotations[:1], m.root_translation[:1])
        p = linear_blend_skinning(mesh.points, idx, w, skinning_matrices(skel, world)[0])
        from humv_usd.geometry.mesh import vertex_normals

        n = vertex_normals(p, tris)
        out = {}
        for side, sign in (("Left", -1.0), ("Right", 1.0)):
            j = skel.index(f"{side}Arm")
            axis = sign * world[0, skel.parents[j], :3, 1]
            ids = arms.arm[side]
            test = p[ids] + 0.004 * n[ids]
            # the armpit's own crease (7-9 cm from the axis) folds < 2 mm into itself under linear
            # blending at any abduction: the clearance leaves it (see human/clearance.py)
            far = np.linalg.norm(np.cross(axis, test - world[0, j, :3, 3]), axis=1) > 0.10
            out[side] = int(np.sum(winding_numbers(test[far], p, tris) > 0.5))
        return out

    before, after = inside_counts(motion), inside_counts(cleared)
    assert min(before.values()) > 20  # the check can fail: arms down are in the trunk
    assert after == {"Left": 0, "Right": 0}


@needs_makehuman
def test_swivel_keeps_the_hands_and_takes_the_elbows_out_of_the_trunk(rigged):
    """Hands that hold something (arms down, elbows bent 90 deg, hands in front): ``clear_arms``
    in ``swivel`` mode turns each arm about its shoulder-wrist line, so the wrists stay where
    they were (1e-12 m) and the hands keep their world rotation, the elbows move out to the
    side, and the upper-arm test points below the armpit (skin + 4 mm, > 10 cm from the
    shoulder and the elbow, > 4 cm from the line) inside the posed body by the independent
    winding number drop from > 20 to at most 1 per side."""
    from humv_usd.bench.skinning import winding_numbers
    from humv_usd.geometry.mesh import vertex_normals
    from humv_usd.human.clearance import arm_body, clear_arms
    from humv_usd.human.skeleton import forward_kinematics, linear_blend_skinning, skinning_matrices

    body, skel, mesh, tris, idx, w = rigged
    arms = arm_body(skel, mesh.points, tris, idx, w)
    motion = _arms_down(skel, 1, 0)
    q = motion.local_rotations.copy()
    for side in ("Left", "Right"):
        q[0, skel.index(f"{side}ForeArm")] = (np.cos(np.pi / 4), -np.sin(np.pi / 4), 0.0, 0.0)
    motion = dataclasses.replace(motion, local_rotations=q)
    report = {}
    cleared = clear_arms(motion, skel, arms, report, mode="swivel")
    w0 = forward_kinematics(skel, motion.local_rotations, motion.root_translation)[0]
    w1 = forward_kinematics(skel, cleared.local_rotations, cleared.root_translation)[0]

    def inside(world, side):
        """Upper-arm test points below the armpit inside the posed body (independent test)."""
        p = linear_blend_skinning(mesh.points, idx, w, skinning_matrices(skel, world[None])[0])
        n = vertex_normals(p, tris)
        hand, elbow, sh = (skel.index(f"{side}{j}") for j in ("Hand", "ForeArm", "Arm"))
        line = world[hand, :3, 3] - world[sh, :3, 3]
        line /= np.linalg.norm(line)
        ids = arms.arm[side]
        test = p[ids] + 0.004 * n[ids]
        rel = test - world[sh, :3, 3]
        far = (np.linalg.norm(rel, axis=1) > 0.10) & (np.linalg.norm(np.cross(line, rel), axis=1) > 0.04)
        # the upper arm only: the bent elbow's own crease folds into itself (not the trunk)
        far &= np.linalg.norm(test - world[elbow, :3, 3], axis=1) > 0.10
        return int(np.sum(winding_numbers(test[far], p, tris) > 0.5))

    for side, out in (("Left", 1.0), ("Right", -1.0)):
        hand, elbow = skel.index(f"{side}Hand"), skel.index(f"{side}ForeArm")
        assert report[side]["max_deg"] > 1.0
        np.testing.assert_allclose(w1[hand, :3, 3], w0[hand, :3, 3], atol=1e-12)
        np.testing.assert_allclose(w1[hand, :3, :3], w0[hand, :3, :3], atol=1e-12)
        assert out * (w1[elbow, 0, 3] - w0[elbow, 0, 3]) > 0.005  # the elbow moved out
        # one point may stay: the back of the armpit (11 cm from the shoulder), which the swivel
        # moves along the trunk rather than out of it
        assert inside(w0, side) > 20 and inside(w1, side) <= 1
