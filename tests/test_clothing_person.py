"""The clothing tool takes the person from the avatar layer (issue 11): body parameters, body
mesh, skinning and skeleton are read from the stage (humv_usd.usd.avatar), not the scenario."""

from __future__ import annotations

import copy
import logging

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, Vt

from humv_usd.avatar import layer as avatar_layer
from humv_usd.clothing import layer as clothing_layer
from humv_usd.clothing.person import MATCH_TOLERANCE_M, read_person, transfer_to_body
from humv_usd.errors import InputError
from humv_usd.human import labels as L
from humv_usd.human.body import build_body
from humv_usd.human.skeleton import skeleton_for, skin_weights
from humv_usd.pipeline.compose import compose_in_memory
from humv_usd.scenario.load import validate
from humv_usd.usd import avatar as UA
from humv_usd.usd import schemas as S
from humv_usd.usd.avatar import read_avatar, read_body_mesh, read_joint_transforms, read_skeleton_rest

GARMENTS = ["leggings"]
BODY = "/World/Humans/p1/Body"


def scenario_with(raw: dict, **person):
    raw = copy.deepcopy(raw)
    raw["human"][0].update(person)
    return validate(raw)


def stage_of(*layers) -> Usd.Stage:
    return compose_in_memory(list(layers), 30.0)


def garment_points(scenario, upstream) -> np.ndarray:
    layer = clothing_layer.build_one(scenario, scenario["human"][0], upstream, garments=GARMENTS)
    stage = Usd.Stage.Open(layer)
    prim = stage.GetPrimAtPath("/World/Humans/p1/Clothing/leggings")
    return np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=np.float64)


@pytest.fixture(scope="module")
def people(humvvex_raw):
    """The humvvex person (1.75 m, 75 kg, one standing frame) and a taller, heavier, slim one."""
    base = validate(humvvex_raw)
    tall = scenario_with(humvvex_raw, stature_m=1.95, mass_kg=95.0, build="slim")
    base_avatar = avatar_layer.build_one(base, base["human"][0])
    tall_avatar = avatar_layer.build_one(tall, tall["human"][0])
    return base, tall, base_avatar, tall_avatar


@pytest.fixture(scope="module")
def base_garment(people):
    base, _, base_avatar, _ = people
    return garment_points(base, stage_of(base_avatar))


# ---------------------------------------------------------------------------- readers
def test_readers_give_what_the_avatar_tool_wrote(people):
    _, tall, _, tall_avatar = people
    stage = stage_of(tall_avatar)
    p = read_avatar(stage, "p1")
    assert (p.sex, p.stature_m, p.mass_kg, p.build) == (
        "male",
        pytest.approx(1.95),
        pytest.approx(95.0),
        0.25,
    )
    body = build_body("male", p.age_yr, 1.95, 95.0, "slim")
    mesh, sk = body.body_mesh(), skeleton_for(body.points, body.groups)
    stage_mesh = read_body_mesh(stage, "p1")
    np.testing.assert_allclose(stage_mesh.points, mesh.points, atol=1e-6)  # float32 in the layer
    np.testing.assert_array_equal(stage_mesh.face_indices, mesh.face_indices)
    idx, w = skin_weights(sk, mesh.vertex_ids, 4)
    np.testing.assert_array_equal(stage_mesh.joint_indices, idx)
    np.testing.assert_allclose(stage_mesh.joint_weights, w)
    np.testing.assert_array_equal(stage_mesh.face_regions, L.body_regions(mesh, sk, idx, w))
    rest = read_skeleton_rest(stage, "p1")
    assert rest.joints == sk.paths
    np.testing.assert_allclose(rest.bind_positions, sk.rest_positions, atol=1e-9)
    np.testing.assert_allclose(rest.bind_rotations, np.tile(np.eye(3), (len(sk.names), 1, 1)))


def test_transfer_to_body_moves_helpers_with_the_body():
    """A translated body carries every helper and joint vertex by the same translation; an
    unchanged body leaves them where they are."""
    body = build_body("female", 30.0, 1.65, 60.0)
    mesh = body.body_mesh()
    shift = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(
        transfer_to_body(body, mesh.points + shift).points, body.points + shift, atol=1e-12
    )
    np.testing.assert_allclose(transfer_to_body(body, mesh.points).points, body.points, atol=1e-15)


# ---------------------------------------------------------------------------- the tool
def test_garments_follow_a_replaced_avatar_layer(people, base_garment):
    """The scenario says 1.75 m / 75 kg, but the avatar layer on the stage is of a 1.95 m,
    95 kg person: the garments are exactly those of that person, not the scenario's."""
    base, tall, _, tall_avatar = people
    from_stage = garment_points(base, stage_of(tall_avatar))
    reference = garment_points(tall, stage_of(tall_avatar))
    np.testing.assert_allclose(from_stage, reference, atol=1e-6)
    height = np.ptp(from_stage[:, 2]) / np.ptp(base_garment[:, 2])
    assert height == pytest.approx(1.95 / 1.75, rel=0.03)  # the leggings' length follows the body
    assert from_stage[:, 2].max() > base_garment[:, 2].max() + 0.08


def test_garments_fit_a_body_sculpted_in_a_stronger_layer(people, base_garment, caplog):
    """A stronger layer widens the Body mesh by 10 % (same topology, HumvAvatarAPI untouched):
    the garments are fitted on that body (the helpers move with it), with one warning."""
    base, _, base_avatar, _ = people
    sculpt = Sdf.Layer.CreateAnonymous(".usda")
    stage = stage_of(base_avatar)
    stage.GetRootLayer().subLayerPaths.insert(0, sculpt.identifier)  # strongest
    stage.SetEditTarget(sculpt)
    points = read_body_mesh(stage, "p1").points * [1.1, 1.1, 1.0]
    UsdGeom.Mesh(stage.GetPrimAtPath(BODY)).GetPointsAttr().Set(
        Vt.Vec3fArray.FromNumpy(points.astype(np.float32))
    )
    assert read_person(stage, "p1").body_deviation_m > 100 * MATCH_TOLERANCE_M
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="humv_usd.clothing.person"):
        wide = garment_points(base, stage)
    assert [r.getMessage().split(":")[0] for r in caplog.records] == [BODY]
    for axis in (0, 1):  # the bounding box widens with the body
        assert np.ptp(wide[:, axis]) / np.ptp(base_garment[:, axis]) == pytest.approx(1.1, abs=0.01)
    # the ankle cuff is cut square to the tilted shin bone (clothing v5: smooth cuts, not whole
    # faces): the 10 % wider leg tilts and widens it, its lowest point drops ~2.3 mm
    assert np.ptp(wide[:, 2]) == pytest.approx(np.ptp(base_garment[:, 2]), abs=3e-3)


def test_avatar_without_avatar_api_is_one_clear_error(people):
    base, _, base_avatar, _ = people
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(base_avatar)
    spec = layer.GetPrimAtPath("/World/Humans/p1")
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=[S.LABEL_API]))
    with pytest.raises(InputError) as err:
        clothing_layer.build_one(base, base["human"][0], stage_of(layer), garments=GARMENTS)
    assert str(err.value) == "/World/Humans/p1: has no HumvAvatarAPI (sex, age, stature, mass of the person)"
    with pytest.raises(InputError, match=r"^/World/Humans/p1: no avatar on the stage"):
        clothing_layer.build_one(base, base["human"][0], stage_of(), garments=GARMENTS)
    with pytest.raises(InputError, match="needs the composed stage with its avatar layer"):
        clothing_layer.build_one(base, base["human"][0], None, garments=GARMENTS)


def test_body_of_another_topology_is_one_clear_error(people):
    base, _, base_avatar, _ = people
    stage = stage_of(base_avatar)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(BODY))
    mesh.GetFaceVertexCountsAttr().Set(Vt.IntArray([3]))
    mesh.GetFaceVertexIndicesAttr().Set(Vt.IntArray([0, 1, 2]))
    with pytest.raises(InputError, match=rf"^{BODY}: \d+ points and 1 faces, not the MakeHuman body's"):
        read_person(stage, "p1")


def test_garment_regions_follow_the_stage_labels(people):
    """A TD relabels the Body's regions in a stronger layer: the garment faces take the
    stage's region under them (here every body face is the left thigh)."""
    base, _, base_avatar, _ = people
    stage = stage_of(base_avatar)
    body = stage.GetPrimAtPath(BODY)
    faces = len(UsdGeom.Mesh(body).GetFaceVertexCountsAttr().Get())
    thigh = L.REGION_ID["leftUpperLeg"]
    UsdGeom.PrimvarsAPI(body).GetPrimvar("humv:label:bodyRegion").Set(Vt.IntArray([thigh] * faces))
    layer = clothing_layer.build_one(base, base["human"][0], stage, garments=GARMENTS)
    dressed = Usd.Stage.Open(layer)
    garment = dressed.GetPrimAtPath("/World/Humans/p1/Clothing/leggings")
    regions = np.asarray(garment.GetAttribute(UA.BODY_REGION_PRIMVAR).Get())
    assert len(regions) > 100 and set(regions.tolist()) == {thigh}


def test_parameters_overridden_without_a_new_body_keep_garments_on_the_stage_body(
    people, base_garment, caplog
):
    """A stronger layer says 1.95 m / 95 kg but keeps the 1.75 m Body mesh: the garments fit
    the body the render shows (within 1 cm of the 1.75 m garments: helpers of the 1.95 m
    rebuild transferred back onto it), not a 1.95 m body, and a warning names the Body."""
    base, _, base_avatar, _ = people
    stage = stage_of(base_avatar)
    person = stage.GetPrimAtPath("/World/Humans/p1")
    person.GetAttribute(S.AVATAR_STATURE).Set(1.95)
    person.GetAttribute(S.AVATAR_MASS).Set(95.0)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="humv_usd.clothing.person"):
        kept = garment_points(base, stage)
    assert [r.getMessage().split(":")[0] for r in caplog.records] == [BODY]
    assert np.abs(kept - base_garment).max() < 0.01


def test_unchanged_avatar_layer_gives_the_clothing_of_the_scenario_body(people):
    """Reading the person back from an untouched avatar layer changes nothing: the layer text
    equals that of garments fitted on the avatar tool's own body (HumvAvatarAPI's float32
    stature/mass are read as written, 1.78 not 1.7799999713897705)."""
    base, _, base_avatar, _ = people
    human = base["human"][0]
    body = build_body(human["sex"], human["age_yr"], human["stature_m"], human["mass_kg"], human["build"])
    stage = stage_of(base_avatar)
    motion = read_joint_transforms(stage, "p1", base.frame_count, 30.0)  # the same for both
    direct = clothing_layer.build_for_human(human, body, None, motion, GARMENTS, 30.0, base.frame_count)
    from_stage = clothing_layer.build_one(base, human, stage, garments=GARMENTS)
    assert read_avatar(stage_of(base_avatar), "p1").stature_m == human["stature_m"]
    assert from_stage.ExportToString() == direct.ExportToString()
