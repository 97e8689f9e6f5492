"""The rifle carry: both hands on the rifle in every frame of a walk, legs untouched."""
from __future__ import annotations

import numpy as np
import pytest

from humv_usd.avatar.body import build_body
from humv_usd.avatar.carry import (ARM_JOINTS, RIFLE_GRIP, RIFLE_HANDGUARD_Z, apply_rifle_carry,
                                   carry_rest_transform)
from humv_usd.avatar.motion import make_motion
from humv_usd.avatar.skeleton import forward_kinematics, linear_blend_skinning, skinning_matrices
from humv_usd.clothing.fit import fit_garment, prepare, prop_mesh
from humv_usd.clothing.geometry import RayCaster, Surface

BODIES = {"female_160_55": ("female", 1.60, 55.0), "male_178_80": ("male", 1.78, 80.0),
          "male_190_105": ("male", 1.90, 105.0)}


@pytest.fixture(scope="module")
def carried():
    out = {}
    for key, (sex, h, m) in BODIES.items():
        rig = prepare(build_body(sex, 30, h, m))
        walk = make_motion("walk", rig.skeleton, 30.0, 45)
        out[key] = rig, walk, apply_rifle_carry(walk, rig.skeleton), fit_garment(rig, "rifle")
    return out


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(np.einsum("fi,fi->f", p - a, ab) / np.einsum("fi,fi->f", ab, ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def test_hands_hold_the_rifle_every_frame_of_a_walk(carried):
    print("\nbody: max distance [cm] right hand -> grip axis, left hand -> handguard axis")
    for key, (rig, walk, carry, rifle) in carried.items():
        sk = rig.skeleton
        world = forward_kinematics(sk, carry.local_rotations, carry.root_translation)
        skin = skinning_matrices(sk, world)
        hand = sk.index("RightHand")
        # the rifle's grip and handguard axes (own frame), in the rest pose via its placement
        own = {"grip": (RIFLE_GRIP + [0.005, 0, -0.06], RIFLE_GRIP + [0.005, 0, 0.06]),
               "guard": (np.array([0.22, 0.0, RIFLE_HANDGUARD_Z]),
                         np.array([0.42, 0.0, RIFLE_HANDGUARD_Z]))}
        m = carry_rest_transform(sk)
        to_rest = {k: [m[:3, :3] @ p + m[:3, 3] for p in v] for k, v in own.items()}

        def posed(p):                       # rigid with the right hand, every frame
            return np.einsum("fij,j->fi", skin[:, hand, :3, :3], p) + skin[:, hand, :3, 3]

        # the fitted rifle is that placement
        own_points = prop_mesh(rifle.garment.prop)[0]
        assert np.abs(rifle.points - (own_points @ m[:3, :3].T + m[:3, 3])).max() < 1e-12
        right = world[:, hand, :3, 3]
        left = world[:, sk.index("LeftHand"), :3, 3]
        d_right = _segment_distance(right, *(posed(p) for p in to_rest["grip"]))
        d_left = _segment_distance(left, *(posed(p) for p in to_rest["guard"]))
        print(f"  {key}: {d_right.max() * 100:.1f}  {d_left.max() * 100:.1f}")
        assert d_right.max() < 0.06 and d_left.max() < 0.06
        # hands 0.35-0.45 m apart, left ahead/left/above the right, both in front of the hips
        hips_r, hips_p = world[:, 0, :3, :3], world[:, 0, :3, 3]
        rel_r = np.einsum("fji,fj->fi", hips_r, right - hips_p)
        rel_l = np.einsum("fji,fj->fi", hips_r, left - hips_p)
        span = np.linalg.norm(left - right, axis=1)
        assert np.all((span > 0.3) & (span < 0.45))
        assert np.all(rel_r[:, 0] < 0) and np.all(rel_l[:, 0] > rel_r[:, 0])
        assert np.all(rel_l[:, 1] < rel_r[:, 1]) and np.all(rel_l[:, 2] > rel_r[:, 2])
        assert np.all(np.abs(rel_r[:, 2]) < 0.15)


def test_only_the_arms_change(carried):
    for rig, walk, carry, _ in carried.values():
        sk = rig.skeleton
        arms = [sk.index(n) for n in ARM_JOINTS]
        keep = [j for j in range(len(sk.names)) if j not in arms and not any(
            sk.names[j].startswith(p) for p in ("LThumb", "RThumb", "LeftFinger", "RightFinger",
                                                "LeftHandFinger", "RightHandFinger"))]
        assert np.array_equal(carry.local_rotations[:, keep], walk.local_rotations[:, keep])
        legs = [sk.index(n) for n in sk.names if "Leg" in n or "Foot" in n or "Toe" in n]
        assert np.array_equal(carry.local_rotations[:, legs], walk.local_rotations[:, legs])
        assert np.array_equal(carry.root_translation, walk.root_translation)
        assert np.allclose(np.linalg.norm(carry.local_rotations, axis=-1), 1.0)
        assert not np.allclose(carry.local_rotations[:, arms], walk.local_rotations[:, arms])


def test_rifle_does_not_penetrate_the_torso(carried):
    """No rifle vertex inside the body except where the gripping hands hold it, and every
    rifle vertex on the outer side of the torso/legs surface (signed distance >= 0)."""
    print("\nbody: rifle vertices inside the body (all inside the arms/hands); min signed "
          "distance to the torso and legs [cm] (frame 0 of the walk)")
    for key, (rig, walk, carry, rifle) in carried.items():
        sk = rig.skeleton
        arm_joints = {j for j, n in enumerate(sk.names)
                      if n.startswith(("Right", "Left", "LThumb", "RThumb"))
                      and not any(k in n for k in ("Leg", "Foot", "Toe"))}
        world = forward_kinematics(sk, carry.local_rotations[:1], carry.root_translation[:1])
        skin = skinning_matrices(sk, world)[0]
        body = linear_blend_skinning(rig.mesh.points, rig.joint_indices, rig.joint_weights, skin)
        gun = linear_blend_skinning(rifle.points, rifle.joint_indices, rifle.joint_weights, skin)
        on_arm = np.isin(rig.joint_indices[:, 0], list(arm_joints))
        inside = RayCaster(body, rig.triangles).inside(gun)
        near = Surface(body, rig.triangles).closest(gun)
        assert np.all(on_arm[rig.triangles[near.triangle[inside], 0]])
        torso = rig.triangles[~on_arm[rig.triangles].any(axis=1)]
        signed = Surface(body, torso).closest(gun).signed
        print(f"  {key}: {int(inside.sum())}  {signed.min() * 100:.1f}")
        assert signed.min() >= 0.0
