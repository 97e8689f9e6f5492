"""The rifle carry: both hands on the rifle in every frame of a walk, legs untouched."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.clothing.fit import fit_garment, prepare, prop_mesh
from humv_usd.geometry.mesh import Surface
from humv_usd.geometry.raycast import RayCaster
from humv_usd.human.body import build_body
from humv_usd.human.carry import (
    ARM_JOINTS,
    CLEARANCE,
    RIFLE_GRIP,
    RIFLE_HANDGUARD_Z,
    apply_rifle_carry,
    carry_body,
    carry_rest_transform,
    prop_signed_distance,
)
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import forward_kinematics, linear_blend_skinning, skinning_matrices

BODIES = {
    "female_160_55": ("female", 1.60, 55.0),
    "male_178_80": ("male", 1.78, 80.0),
    "male_190_105": ("male", 1.90, 105.0),
}


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
    for key, (rig, _walk, carry, rifle) in carried.items():
        sk = rig.skeleton
        world = forward_kinematics(sk, carry.local_rotations, carry.root_translation)
        skin = skinning_matrices(sk, world)
        hand = sk.index("RightHand")
        # the rifle's grip and handguard axes (own frame), in the rest pose via its placement
        own = {
            "grip": (RIFLE_GRIP + [0.005, 0, -0.06], RIFLE_GRIP + [0.005, 0, 0.06]),
            "guard": (np.array([0.22, 0.0, RIFLE_HANDGUARD_Z]), np.array([0.42, 0.0, RIFLE_HANDGUARD_Z])),
        }
        m = carry_rest_transform(sk)
        to_rest = {k: [m[:3, :3] @ p + m[:3, 3] for p in v] for k, v in own.items()}

        def posed(p):  # rigid with the right hand, every frame
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
        keep = [
            j
            for j in range(len(sk.names))
            if j not in arms
            and not any(
                sk.names[j].startswith(p)
                for p in (
                    "LThumb",
                    "RThumb",
                    "LeftFinger",
                    "RightFinger",
                    "LeftHandFinger",
                    "RightHandFinger",
                )
            )
        ]
        assert np.array_equal(carry.local_rotations[:, keep], walk.local_rotations[:, keep])
        legs = [sk.index(n) for n in sk.names if "Leg" in n or "Foot" in n or "Toe" in n]
        assert np.array_equal(carry.local_rotations[:, legs], walk.local_rotations[:, legs])
        assert np.array_equal(carry.root_translation, walk.root_translation)
        assert np.allclose(np.linalg.norm(carry.local_rotations, axis=-1), 1.0)
        assert not np.allclose(carry.local_rotations[:, arms], walk.local_rotations[:, arms])


def test_rifle_does_not_penetrate_the_torso(carried):
    """No rifle vertex inside the body except where the gripping hands hold it, and every
    rifle vertex on the outer side of the torso/legs surface (signed distance >= 0)."""
    print(
        "\nbody: rifle vertices inside the body (all inside the arms/hands); min signed "
        "distance to the torso and legs [cm] (frame 0 of the walk)"
    )
    for key, (rig, _walk, carry, rifle) in carried.items():
        sk = rig.skeleton
        arm_joints = {
            j
            for j, n in enumerate(sk.names)
            if n.startswith(("Right", "Left", "LThumb", "RThumb"))
            and not any(k in n for k in ("Leg", "Foot", "Toe"))
        }
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


# ---------------------------------------------------------------------------- clearance
def _bow_and_knee_bvh(tmp_path, sk, body):
    """A stand clip with the trunk bowing 60 deg and the right knee raised 95 deg (a pose
    that drives the fixed carry's rifle into the thigh and belly), written and read back as
    BVH (the BVH path of the avatar tool)."""
    from humv_usd.human.bvh import motion_from_bvh, motion_to_bvh, write_bvh
    from humv_usd.human.gait import axis_angle_quat

    frames = 21
    m = make_motion("stand", sk, 30.0, frames, body_points=body.points)
    q = m.local_rotations.copy()
    ramp = np.sin(np.linspace(0, np.pi, frames))
    for joint, deg in (
        ("LowerBack", 25),
        ("Spine", 20),
        ("Spine1", 15),
        ("RightUpLeg", -95),
        ("RightLeg", 100),
    ):
        k = sk.index(joint)
        bend = np.stack([axis_angle_quat((1.0, 0.0, 0.0), np.radians(deg * r)) for r in ramp])
        w1, v1 = q[:, k, :1], q[:, k, 1:]
        w2, v2 = bend[:, :1], bend[:, 1:]
        q[:, k] = np.concatenate(
            [w1 * w2 - np.sum(v1 * v2, 1, keepdims=True), w1 * v2 + w2 * v1 + np.cross(v1, v2)], 1
        )
    path = tmp_path / "bow_knee.bvh"
    write_bvh(path, motion_to_bvh(sk, q, m.root_translation, 30.0))
    return motion_from_bvh(path, sk, 30.0, body_points=body.points, settle=False)


@pytest.fixture(scope="module")
def stressed(tmp_path_factory):
    body = build_body("male", 30, 1.78, 80.0)
    rig = prepare(body)
    sk = rig.skeleton
    motion = _bow_and_knee_bvh(tmp_path_factory.mktemp("bvh"), sk, body)
    report = {}
    carry = apply_rifle_carry(motion, sk, body, report=report)
    return rig, motion, carry, report


def test_prop_signed_distance_matches_the_rifle_mesh():
    """The rifle solid's closed-form distance vs the rifle mesh (closest point on each part's
    closed mesh, inside by ray parity): equal up to the octagons inscribed in the round
    cylinders."""
    from humv_usd.catalog.garments import RIFLE
    from humv_usd.geometry.mesh import fan_triangulate

    rng = np.random.default_rng(1)
    q = rng.uniform([-0.35, -0.12, -0.3], [0.65, 0.12, 0.15], (3000, 3))
    sdf = prop_signed_distance(q)
    d = np.full(len(q), np.inf)
    inside = np.zeros(len(q), dtype=bool)
    for shape in RIFLE.shapes:  # the union: min over the parts
        p, c, i = prop_mesh(type(RIFLE)((shape,), RIFLE.joint, RIFLE.placement))
        t, _ = fan_triangulate(c, i)
        near = Surface(p, t).closest(q, k=len(t))  # all triangles: exact
        d = np.minimum(d, np.linalg.norm(q - near.point, axis=1))
        inside |= RayCaster(p, t).inside(q)
    outside = ~inside
    r = max(s.radius for s in RIFLE.shapes)
    err = sdf[outside] - d[outside]
    print(
        f"\noutside points: {outside.sum()}, SDF - mesh distance in "
        f"[{err.min() * 1e3:.2f}, {err.max() * 1e3:.2f}] mm"
    )
    assert outside.sum() > 1000 and inside.sum() > 10
    assert np.all(err <= 1e-9) and np.all(err >= -0.08 * r)  # round >= octagon
    assert np.all(sdf[inside] <= 1e-9)  # inside the mesh: <= 0


@pytest.mark.slow
def test_carry_clears_the_body_in_a_bvh_bow_with_a_raised_knee(stressed):
    rig, motion, carry, rep = stressed
    sk = rig.skeleton
    before, after = rep["minDistanceBefore_m"], rep["minDistanceAfter_m"]
    print(
        f"\nbow + knee (BVH): min clearance {before.min() * 100:.1f} cm "
        f"({rep['insideBefore'].max()} body vertices inside) -> {after.min() * 100:.1f} cm "
        f"({rep['insideAfter'].max()}); offset max {rep['offset_m'].max() * 100:.1f} cm"
    )
    assert before.min() < 0 and rep["insideBefore"].max() > 0  # the fixed carry fails
    assert after.min() >= CLEARANCE - 1e-6 and rep["insideAfter"].max() == 0
    assert max(rep["graspErrorMax_m"].values()) < 1e-6  # both hands still on it
    step = np.linalg.norm(np.diff(rep["offset_m"]))
    assert np.abs(np.diff(rep["offset_m"])).max() < 0.06, step  # smooth: no popping
    assert np.array_equal(carry.root_translation, motion.root_translation)
    # independent check on the meshes: posed rifle vs posed body, every frame
    rifle = fit_garment(rig, "rifle")
    cb = carry_body(rig.body, sk)
    skin = skinning_matrices(sk, forward_kinematics(sk, carry.local_rotations, carry.root_translation))
    for f in range(0, len(skin), 4):
        gun = linear_blend_skinning(rifle.points, rifle.joint_indices, rifle.joint_weights, skin[f])
        body = linear_blend_skinning(cb.points, cb.joint_indices, cb.joint_weights, skin[f])
        assert not RayCaster(gun, rifle.triangles).inside(body).any()
        gap = np.linalg.norm(body[:, None] - gun[None], axis=2).min()
        assert gap >= CLEARANCE - 1e-6


def test_carry_clearance_in_built_in_motions():
    """Stand, standTurn, walk, run, postExercise: the carry clears the body every frame."""
    body = build_body("female", 30, 1.60, 55.0)
    rig = prepare(body)
    cb = carry_body(body, rig.skeleton)
    print("\nactivity: min clearance before -> after [cm], max offset [cm]")
    for activity in ("stand", "standTurn", "walk", "run", "postExercise"):
        m = make_motion(activity, rig.skeleton, 15.0, 16, body_points=body.points)
        rep = {}
        apply_rifle_carry(m, rig.skeleton, cb, report=rep)
        print(
            f"  {activity:12s} {rep['minDistanceBefore_m'].min() * 100:5.1f} -> "
            f"{rep['minDistanceAfter_m'].min() * 100:5.1f}  {rep['offset_m'].max() * 100:.1f}"
        )
        assert rep["minDistanceAfter_m"].min() >= CLEARANCE - 1e-6
        assert rep["insideAfter"].max() == 0


@pytest.mark.slow
def test_avatar_and_clothing_layers_keep_the_rifle_off_the_body(raw):
    """Through the tools: a running person with the rifle (where the fixed carry comes within
    2.3 cm of the thigh): the avatar layer's carry clears it, the clothing layer measures it
    per frame on the composed motion (customData humv:prop) and labels the rifle as a prop."""
    from humv_usd.avatar import layer as avatar_layer
    from humv_usd.clothing import layer as clothing_layer
    from humv_usd.pipeline.compose import compose_in_memory
    from humv_usd.scenario.ids import instance_ids
    from humv_usd.scenario.load import validate
    from humv_usd.usd import schemas as S

    raw["general"] = dict(raw["general"], fps=15.0, duration_s=1.0)
    raw["human"][0].update(sex="female", stature_m=1.60, mass_kg=55.0, activity="run", clothing=["rifle"])
    scenario = validate(raw)
    human = scenario["human"][0]
    avatar = avatar_layer.build_one(scenario, human)
    upstream = compose_in_memory([avatar], 15.0)
    layer = clothing_layer.build_one(scenario, human, upstream)
    stage = compose_in_memory([avatar, layer], 15.0)
    rifle = stage.GetPrimAtPath("/World/Humans/p1/Props/rifle")
    info = rifle.GetCustomDataByKey("humv:prop")
    print(
        f"\nrun with the rifle: body clearance min {info['bodyClearanceMin_m'] * 100:.2f} cm "
        f"over {info['frames']} frames"
    )
    assert info["frames"] == scenario.frame_count == len(info["bodyClearance_m"])
    assert info["bodyClearanceMin_m"] >= CLEARANCE - 1e-4
    assert info["bodyVerticesInsideMax"] == 0
    assert rifle.GetAttribute(S.LABEL_INSTANCE_ID).Get() == instance_ids(scenario)["prop:p1:rifle"]
    assert rifle.GetAttribute(S.LABEL_CLASS).Get() == "prop"


def test_garment_vertices_are_pushed_off_the_carried_rifle():
    """push_off_prop: points inside the rifle's solid (or nearer than the gap) end the gap
    off it, moved along the distance gradient by the deficit; the others do not move."""
    from humv_usd.clothing.collide import push_off_prop

    rng = np.random.default_rng(3)
    to_world = np.eye(4)
    to_world[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0] * [1, 1, 1]
    if np.linalg.det(to_world[:3, :3]) < 0:
        to_world[:3, 0] *= -1
    to_world[:3, 3] = [0.2, -0.3, 1.0]
    local = rng.uniform([-0.3, -0.06, -0.25], [0.6, 0.06, 0.1], (2000, 3))
    world = local @ to_world[:3, :3].T + to_world[:3, 3]
    gap = 0.002
    out, before, after = push_off_prop(world, to_world, None, gap)
    d0 = prop_signed_distance(local)
    back = (out - to_world[:3, 3]) @ to_world[:3, :3]
    d1 = prop_signed_distance(back)
    assert before == int(np.sum(d0 < gap)) > 100 and after == 0
    assert d1.min() >= gap - 1e-9
    still = d0 >= gap
    assert np.array_equal(out[still], world[still])
    # outside but too close: moved by the deficit (+ the float margin) along the gradient,
    # where the distance is exact
    close = (d0 < gap) & (d0 >= 0)
    moved = np.linalg.norm(out - world, axis=1)
    assert close.sum() > 20
    assert np.all(moved[close] <= (gap - d0[close]) + 5e-4)  # creases between parts
