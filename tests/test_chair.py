"""The chair a person sits on (issue 29.4, humv_usd.human.chair): the seat's top at the pose's
seat box, no body vertex inside the chair over the whole sitChair motion, the backrest behind
the sitting body, a closed mesh; the instance id and the material follow the scenario."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from humv_usd.catalog.garments import garment
from humv_usd.human.body import build_body
from humv_usd.human.carry import _rest_parts, hold_targets
from humv_usd.human.chair import (
    BACK_CLEARANCE,
    CHAIR_MATERIAL,
    chair_mesh,
    chair_parts,
    inside_chair,
    posed_body_points,
)
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import skeleton_for
from humv_usd.scenario.ids import sits_on_chair
from humv_usd.usd.avatar import read_joint_transforms


@functools.lru_cache(maxsize=1)
def _sitting():
    body = build_body("female", 40.0, 1.64, 70.0)
    sk = skeleton_for(body.points, body.groups)
    motion = make_motion("sitChair", sk, 10.0, 30, body_points=body.points)
    return body, sk, motion


def test_seat_top_is_the_poses_seat_box_and_the_chair_is_closed():
    body, sk, motion = _sitting()
    chair = motion.gait["chair"]
    last = posed_body_points(body, sk, motion)
    pts, counts, idx = chair_mesh(chair, last)
    top = chair["center_m"][2] + chair["size_m"][2] / 2
    seat_base, seat_size = chair_parts(chair, last)[0]
    assert seat_base[2] + seat_size[2] == pytest.approx(chair["size_m"][2])
    assert pts[:, 2].min() == pytest.approx(chair["center_m"][2] - chair["size_m"][2] / 2)
    # every edge of the closed boxes is used twice, in opposite directions
    faces = np.split(idx, np.cumsum(counts)[:-1])
    edges = [(f[k], f[(k + 1) % len(f)]) for f in faces for k in range(len(f))]
    assert sorted(edges) == sorted((b, a) for a, b in edges)
    # the sitting body rests on the seat (within 5 mm) and nothing of it is inside the chair
    d = inside_chair(chair, last, last)
    assert 0.0 <= d.min() < 0.005
    assert abs(last[:, 2].min()) < 0.01  # the feet on the ground
    assert 0.30 < top < 0.55  # a chair-like seat height (the pose puts it at the thighs: 0.33 m here)


def test_no_body_vertex_inside_the_chair_while_sitting_down():
    body, sk, motion = _sitting()
    chair = motion.gait["chair"]
    last = posed_body_points(body, sk, motion)
    for f in range(0, motion.frame_count, 3):
        assert inside_chair(chair, posed_body_points(body, sk, motion, f), last).min() >= -1e-6


def test_backrest_stands_behind_the_body():
    body, sk, motion = _sitting()
    chair = motion.gait["chair"]
    last = posed_body_points(body, sk, motion)
    parts = chair_parts(chair, last)
    back = parts[-1]
    w, d, h = chair["size_m"]
    c, s = np.cos(chair["yaw_rad"]), np.sin(chair["yaw_rad"])
    local = last - np.array(chair["center_m"])
    local = local @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]).T
    local[:, 2] += h / 2
    band = (np.abs(local[:, 0]) < w / 2) & (local[:, 2] > h) & (local[:, 2] < h + 0.42)
    front_of_back = back[0][1] - back[1][1] / 2
    assert front_of_back - local[band, 1].max() >= BACK_CLEARANCE - 1e-9


def test_who_sits_on_a_chair():
    assert sits_on_chair({"activity": "sitChair"})
    assert not sits_on_chair({"activity": "sit"})
    assert sits_on_chair({"activity": "walk", "segment": [{"activity": "walk"}, {"activity": "sitChair"}]})
    assert CHAIR_MATERIAL == "wood"


def test_the_avatar_tool_authors_the_chair_and_holds_the_phone():
    """End to end through the avatar tool (2 fps, 4 s): a seated person with a phone gets the
    chair (wood, class prop, its own instance id, the body on it and not inside it) and the
    right hand where the hold puts the phone."""
    from pxr import Usd, UsdShade

    from humv_usd.avatar.api import avatar_scenario_dict
    from humv_usd.avatar.layer import build_one
    from humv_usd.scenario.ids import instance_ids
    from humv_usd.scenario.load import validate
    from humv_usd.usd.paths import props_path

    raw = avatar_scenario_dict(activity="sitChair", fps=2.0, duration_s=4.0)
    raw["human"][0]["clothing"] = ["phone"]
    scenario = validate(raw)
    layer = build_one(scenario, scenario["human"][0])
    stage = Usd.Stage.Open(layer)
    chair = stage.GetPrimAtPath(props_path("p1").AppendChild("chair"))
    assert chair.IsValid()
    target = UsdShade.MaterialBindingAPI(chair).GetDirectBindingRel().GetTargets()[0]
    assert target.name == CHAIR_MATERIAL
    assert chair.GetAttribute("humv:label:class").Get() == "prop"
    assert chair.GetAttribute("humv:label:instanceId").Get() == instance_ids(scenario)["prop:p1:chair"]
    info = chair.GetCustomDataByKey("humv:chair")
    assert 0.0 <= info["bodyMinDistance_m"] < 0.005
    # the authored animation holds the phone: the right grasp point where apply_hold puts it
    body = build_body("male", 30.0, 1.75, 75.0)
    sk = skeleton_for(body.points, body.groups)
    world = read_joint_transforms(stage, "p1", 9, 2.0)
    rest, hand = _rest_parts(body, sk)
    frame, grasp, _, _ = hold_targets(sk, rest, hand, garment("phone").prop)
    j, fj = sk.index("RightHand"), sk.index(frame)
    for f in (0, 8):
        want = world[f, fj, :3, :3] @ grasp + world[f, fj, :3, 3]
        got = world[f, j, :3, :3] @ (sk.tail_positions[j] - sk.rest_positions[j]) + world[f, j, :3, 3]
        assert np.linalg.norm(want - got) < 0.005


def test_the_avatar_tool_authors_the_carried_box_between_the_palms():
    """activity = "carry": the box is authored (wood, class prop, its own id, bound to the Hips)
    and in the authored animation both palms touch its sides (closest hand vertex 2 mm off,
    PALM_GAP) in every frame; nothing else of the body is inside it."""
    from pxr import Usd, UsdShade

    from humv_usd.avatar.api import avatar_scenario_dict
    from humv_usd.avatar.layer import build_one
    from humv_usd.human import labels as L
    from humv_usd.human.carry import PALM_GAP, body_regions_of
    from humv_usd.human.skeleton import skin_weights, skinning_matrices
    from humv_usd.scenario.ids import instance_ids
    from humv_usd.scenario.load import validate
    from humv_usd.usd.paths import props_path

    raw = avatar_scenario_dict(activity="carry", fps=2.0, duration_s=2.0)
    scenario = validate(raw)
    stage = Usd.Stage.Open(build_one(scenario, scenario["human"][0]))
    box = stage.GetPrimAtPath(props_path("p1").AppendChild("box"))
    assert UsdShade.MaterialBindingAPI(box).GetDirectBindingRel().GetTargets()[0].name == CHAIR_MATERIAL
    assert box.GetAttribute("humv:label:instanceId").Get() == instance_ids(scenario)["prop:p1:box"]
    body = build_body("male", 30.0, 1.75, 75.0)
    sk = skeleton_for(body.points, body.groups)
    assert set(box.GetAttribute("primvars:skel:jointIndices").Get()) == {sk.index("Hips")}
    rest_box = np.asarray(box.GetAttribute("points").Get(), float)
    lo, hi = rest_box.min(0), rest_box.max(0)
    world = read_joint_transforms(stage, "p1", 5, 2.0)
    skin = skinning_matrices(sk, world)
    mesh, regions = body_regions_of(body, sk)
    idx, w = skin_weights(sk, mesh.vertex_ids, 4)
    counts = np.asarray(mesh.face_counts)
    face_of = np.repeat(np.arange(len(counts)), counts)
    for f in range(len(skin)):
        to_rest = np.linalg.inv(skin[f, sk.index("Hips")])  # the box's frame
        blend = np.einsum("vk,vkab->vab", w.astype(float), skin[f][idx])
        posed = np.einsum("vab,vb->va", blend[:, :3, :3], np.asarray(mesh.points)) + blend[:, :3, 3]
        local = posed @ to_rest[:3, :3].T + to_rest[:3, 3]
        q = np.abs(local - (lo + hi) / 2) - (hi - lo) / 2
        d = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
        for side in ("rightHand", "leftHand"):
            hand = np.unique(np.asarray(mesh.face_indices)[(regions == L.REGION_ID[side])[face_of]])
            assert d[hand].min() == pytest.approx(PALM_GAP, abs=1e-3)
        assert d.min() > 0.0
    # every USD consumer skins it (UsdSkel prunes untyped parents: the box stood still)
    from pxr import UsdGeom, UsdSkel

    assert stage.GetPrimAtPath(props_path("p1")).IsA(UsdGeom.Scope)
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/World/Humans/p1")), Usd.PrimDefaultPredicate)
    query = cache.GetSkinningQuery(box)
    assert query and query.HasJointInfluences()
    skel = cache.GetSkelQuery(UsdSkel.BindingAPI(box).GetInheritedSkeleton())
    for f in (0, len(skin) - 1):
        pts = box.GetAttribute("points").Get()
        assert query.ComputeSkinnedPoints(
            skel.ComputeSkinningTransforms(Usd.TimeCode(f)), pts, Usd.TimeCode(f)
        )
        want = rest_box @ skin[f, sk.index("Hips"), :3, :3].T + skin[f, sk.index("Hips"), :3, 3]
        np.testing.assert_allclose(np.asarray(pts, float), want, atol=1e-4)
