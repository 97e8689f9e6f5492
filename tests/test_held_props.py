"""Props held in the right hand (issue 29.3): phone read in front, phone at the ear, handbag by
its handle. The palm on the prop within PALM_GAP (exact box distances, no hand vertex inside),
the arm's IK reaching the grasp, no other body vertex inside the prop over a walk, the phone
off the head by EAR_GAP, the bag clear of the thigh."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from humv_usd.avatar.api import avatar_scenario_dict
from humv_usd.catalog.garments import GARMENTS, HELD_PROPS, garment
from humv_usd.errors import InputError
from humv_usd.human import labels as L
from humv_usd.human.body import build_body
from humv_usd.human.carry import (
    BAG_CLEARANCE,
    EAR_GAP,
    PALM_GAP,
    _hold_pose,
    _rest_parts,
    apply_hold,
    body_regions_of,
    held_rest_transform,
    hold_targets,
    palm_frame,
    prop_signed_distance,
)
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import forward_kinematics, skeleton_for, skin_weights, skinning_matrices
from humv_usd.scenario.load import validate


@functools.lru_cache(maxsize=2)
def _person(sex="male", age=30.0, stature=1.78, mass=80.0):
    body = build_body(sex, age, stature, mass)
    sk = skeleton_for(body.points, body.groups)
    return body, sk, *_rest_parts(body, sk)


def test_catalogue_has_the_held_props():
    assert set(HELD_PROPS) <= set(GARMENTS)
    for name in HELD_PROPS:
        prop = garment(name).prop
        assert prop.joint == "RightHand" and prop.grip is not None


@pytest.mark.parametrize("who", [("male", 30.0, 1.78, 80.0), ("female", 9.0, 1.33, 28.0)])
@pytest.mark.parametrize("name", HELD_PROPS)
def test_palm_on_the_prop_without_penetration(who, name):
    body, sk, _, hand = _person(*who)
    prop = garment(name).prop
    m = held_rest_transform(sk, hand, prop)
    d = prop_signed_distance((hand - m[:3, 3]) @ m[:3, :3], prop)
    assert d.min() == pytest.approx(PALM_GAP, abs=1e-6)  # touching, nothing inside
    palm = palm_frame(sk, hand)
    # the contact is on the palm's side of the hand (the prop's grip point lies along +normal)
    contact = m[:3, :3] @ np.asarray(prop.grip[0]) + m[:3, 3]
    assert (contact - palm.grasp) @ palm.normal > 0.0
    assert (
        abs((contact - palm.grasp) @ palm.fingers) < 1e-9 and abs((contact - palm.grasp) @ palm.across) < 1e-9
    )


def test_phone_at_the_ear_is_off_the_head_by_the_gap():
    body, sk, rest, hand = _person()
    prop = garment("phone_call").prop
    rot, t = _hold_pose(sk, rest, prop, held_rest_transform(sk, hand, prop))
    head = rest[rest[:, 2] > sk.rest_positions[sk.index("Head")][2]]
    assert prop_signed_distance((head - t) @ rot, prop).min() == pytest.approx(EAR_GAP, abs=1e-5)
    assert rot[:, 0] @ np.array([1.0, 0.0, 0.0]) == pytest.approx(1.0)  # the screen faces the head


@pytest.mark.parametrize("name", HELD_PROPS)
def test_hold_over_a_walk(name):
    body, sk, rest, hand = _person()
    prop = garment(name).prop
    rest_m = held_rest_transform(sk, hand, prop)
    motion = apply_hold(
        make_motion("walk", sk, 30.0, 12, speed_m_s=1.3, body_points=body.points), sk, body, prop
    )
    world = forward_kinematics(sk, motion.local_rotations, motion.root_translation)
    # the grasp point reaches its target in the hold's frame (IK)
    frame, grasp, r_h, _ = hold_targets(sk, rest, hand, prop)
    j, fj = sk.index("RightHand"), sk.index(frame)
    want = np.einsum("fij,j->fi", world[:, fj, :3, :3], grasp) + world[:, fj, :3, 3]
    got = (
        np.einsum("fij,j->fi", world[:, j, :3, :3], sk.tail_positions[j] - sk.rest_positions[j])
        + world[:, j, :3, 3]
    )
    assert np.abs(want - got).max() < 1e-3
    # no body vertex other than the right hand and forearm inside the prop (skinned as the avatar)
    mesh, regions = body_regions_of(body, sk)
    idx, w = skin_weights(sk, mesh.vertex_ids, 4)
    counts = np.asarray(mesh.face_counts)
    holding = np.isin(regions, [L.REGION_ID[r] for r in ("rightHand", "rightLowerArm")])
    keep = np.unique(np.asarray(mesh.face_indices)[~holding[np.repeat(np.arange(len(counts)), counts)]])
    skin = skinning_matrices(sk, world)
    to_prop = np.linalg.inv(skin[:, j] @ rest_m)
    dense = np.zeros((len(keep), len(sk.names)))
    np.add.at(dense, (np.repeat(np.arange(len(keep)), 4), idx[keep].ravel()), w[keep].astype(float).ravel())
    pts = np.asarray(mesh.points)[keep]
    for f in range(0, len(skin), 3):
        blend = np.einsum("vj,jab->vab", dense, skin[f])
        posed = np.einsum("vab,vb->va", blend[:, :3, :3], pts) + blend[:, :3, 3]
        d = prop_signed_distance(posed @ to_prop[f, :3, :3].T + to_prop[f, :3, 3], prop)
        bound = (
            EAR_GAP - 1e-4 if name == "phone_call" else (0.5 * BAG_CLEARANCE if name == "handbag" else 0.02)
        )
        assert d.min() > bound


@pytest.mark.parametrize(
    "clothing, line",
    [
        (["rifle", "phone"], "human[0].clothing[1] = 'phone': the right hand already holds 'rifle'"),
        (
            ["phone_call", "tshirt_white", "handbag"],
            "human[0].clothing[2] = 'handbag': the right hand already holds 'phone_call'",
        ),
        (
            ["tshirt_white", "phone"],
            "human[0].clothing[1] = 'phone': the hands carry the box (activity carry)",
        ),
    ],
)
def test_one_thing_in_the_right_hand(clothing, line):
    raw = avatar_scenario_dict(activity="carry" if "carry" in line else "stand")
    raw["human"][0]["clothing"] = clothing
    with pytest.raises(InputError) as info:
        validate(raw)
    assert line in info.value.problems
