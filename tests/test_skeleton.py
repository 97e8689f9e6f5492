"""Skeleton: CMU rig on the fitted body, weights, forward kinematics and skinning."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.assets import makehuman_dir

pytestmark = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)


@pytest.fixture(scope="module")
def rigged():
    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for, skin_weights

    body = build_body("male", 30, 1.78, 80)
    skel = skeleton_for(body.points, body.groups)
    mesh = body.body_mesh()
    idx, w = skin_weights(skel, mesh.vertex_ids)
    return body, skel, mesh, idx, w


def test_hierarchy_and_sides(rigged):
    _, skel, *_ = rigged
    assert len(skel.names) == 31 and skel.names[0] == "Hips" and skel.parents[0] == -1
    assert all(skel.parents[j] < j for j in range(1, 31))  # topological
    left, right = skel.rest_positions[skel.index("LeftUpLeg")], skel.rest_positions[skel.index("RightUpLeg")]
    assert left[0] > 0.05 and right[0] < -0.05  # +x is the person's left
    head = skel.rest_positions[skel.index("Head")]
    foot = skel.rest_positions[skel.index("LeftFoot")]
    assert 1.4 < head[2] < 1.78 and 0.0 < foot[2] < 0.15
    assert skel.paths[skel.index("LeftFoot")] == "Hips/LHipJoint/LeftUpLeg/LeftLeg/LeftFoot"


def test_weights_normalized(rigged):
    _, skel, mesh, idx, w = rigged
    assert idx.shape == (len(mesh.points), 4)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-6)
    assert idx.max() < len(skel.names)


def test_rest_pose_is_identity_and_rotation_is_rigid(rigged):
    from humv_usd.human.skeleton import forward_kinematics, linear_blend_skinning, skinning_matrices

    _, skel, mesh, idx, w = rigged
    q = np.zeros((1, len(skel.names), 4))
    q[..., 0] = 1.0
    world = forward_kinematics(skel, q, skel.rest_positions[:1])
    np.testing.assert_allclose(world[0, :, :3, 3], skel.rest_positions, atol=1e-12)
    pts = linear_blend_skinning(mesh.points, idx, w, skinning_matrices(skel, world)[0])
    np.testing.assert_allclose(pts, mesh.points, atol=1e-9)
    # turning the root 90 deg about z turns every point rigidly about the hips
    half = np.sqrt(0.5)
    q[0, 0] = (half, 0.0, 0.0, half)
    world = forward_kinematics(skel, q, skel.rest_positions[:1])
    pts = linear_blend_skinning(mesh.points, idx, w, skinning_matrices(skel, world)[0])
    rel = mesh.points - skel.rest_positions[0]
    expected = np.stack([-rel[:, 1], rel[:, 0], rel[:, 2]], axis=1) + skel.rest_positions[0]
    np.testing.assert_allclose(pts, expected, atol=1e-9)
    # bending the left knee moves the left foot and not the right one
    q[0, 0] = (1.0, 0.0, 0.0, 0.0)
    k = skel.index("LeftLeg")
    q[0, k] = (np.cos(0.5), np.sin(0.5), 0.0, 0.0)
    world = forward_kinematics(skel, q, skel.rest_positions[:1])
    lf, rf = skel.index("LeftFoot"), skel.index("RightFoot")
    assert np.linalg.norm(world[0, lf, :3, 3] - skel.rest_positions[lf]) > 0.1
    np.testing.assert_allclose(world[0, rf, :3, 3], skel.rest_positions[rf], atol=1e-12)
