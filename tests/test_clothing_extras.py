"""Clothing extras: the vest under the clothing and the rifle prop (issue 4 item 1)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from conftest import quat_x, ramp_pose
from pxr import Usd, UsdGeom, UsdShade

from humv_usd.atmosphere import layer as atmosphere_layer
from humv_usd.avatar import layer as avatar_layer
from humv_usd.catalog.garments import GARMENTS, fabrics, garment
from humv_usd.catalog.materials import LIBRARY
from humv_usd.clothing import layer as clothing_layer
from humv_usd.clothing.collide import LAYER_RADIUS, SHELL_COS, apply, blend_transforms, dress, simulate
from humv_usd.clothing.fit import prepare
from humv_usd.environment import layer as environment_layer
from humv_usd.geometry.mesh import Surface
from humv_usd.geometry.raycast import RayCaster
from humv_usd.human.body import build_body
from humv_usd.human.skeleton import forward_kinematics, skinning_matrices
from humv_usd.human.usdskel import skinned_points
from humv_usd.materials import layer as materials_layer
from humv_usd.pipeline.compose import compose_in_memory
from humv_usd.render.export import StageExport
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.load import validate
from humv_usd.sensors import layer as sensors_layer
from humv_usd.thermal import layer as thermal_layer
from humv_usd.usd import schemas as S
from humv_usd.usd.check import rule_sensors_and_labels
from humv_usd.usd.mesh import signed_volume

BODIES = {
    "female_160_55": ("female", 1.60, 55.0),
    "male_178_80": ("male", 1.78, 80.0),
    "male_190_105": ("male", 1.90, 105.0),
}
TOL = 1e-6
OUTFIT = ["vest", "tshirt_white", "rifle"]


@pytest.fixture(scope="module")
def rigs():
    return {k: prepare(build_body(sex, 30, h, m)) for k, (sex, h, m) in BODIES.items()}


def _world(skeleton, bends: dict[str, float]) -> np.ndarray:
    """(2, J, 4, 4) joint transforms: frame 0 rest, frame 1 ``bends`` [deg about X]."""
    q = np.zeros((2, len(skeleton.names), 4))
    q[..., 0] = 1.0
    for joint, deg in bends.items():
        q[1, skeleton.index(joint)] = quat_x(deg)
    return forward_kinematics(skeleton, q, np.repeat(skeleton.rest_positions[:1], 2, axis=0))


def _over(vest_anim, near, points) -> np.ndarray:
    """Vertices over the vest: within LAYER_RADIUS, offset along the face normal (not beside
    its border)."""
    tri = vest_anim.fitted.triangles
    p = vest_anim.posed[0]
    n = np.cross(
        p[tri[near.triangle, 1]] - p[tri[near.triangle, 0]],
        p[tri[near.triangle, 2]] - p[tri[near.triangle, 0]],
    )
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    off = points - near.point
    dist = np.linalg.norm(off, axis=1)
    return (dist < LAYER_RADIUS) & (np.abs(np.einsum("ij,ij->i", off, n)) >= SHELL_COS * dist)


def test_catalogue_entries_and_materials():
    vest, rifle = garment("vest"), garment("rifle")
    assert vest.layer <= 1 < garment("tshirt_white").layer and not vest.is_prop
    assert 0 < vest.ease <= 0.006 and vest.fabric == "kevlar_vest"
    assert rifle.is_prop and rifle.prop.joint == "RightHand" and rifle.ease == 0.0
    assert rifle.layer > max(g.layer for g in GARMENTS.values() if not g.is_prop)
    assert fabrics(OUTFIT) == ["cotton_white", "kevlar_vest", "polymer_black"]
    for name in ("kevlar_vest", "polymer_black"):
        m = LIBRARY[name]
        assert len(m.source) > 200 and 0.85 <= min(m.emissivity[-3:]) <= 0.96
    assert LIBRARY["polymer_black"].label_class == "prop"


def test_scenario_selects_vest_and_rifle(raw):
    raw["human"][0]["clothing"] = list(OUTFIT)
    assert validate(raw)["human"][0]["clothing"] == OUTFIT
    raw["human"][0]["clothing"] = ["vest", "bazooka"]
    with pytest.raises(Exception, match="bazooka"):
        validate(raw)


def test_vest_fits_three_bodies_and_tshirt_stays_outside_it(rigs):
    """Rest pose: the vest is off the skin; a T-shirt over it keeps the vest's distance +
    its thickness + the minimum gap (the vest is part of the body for it): 0 vertices inside
    the vest after the fix (checked against the vest mesh itself), many before."""
    vest = garment("vest")
    print(
        "\n(body: vest min/median air gap [mm]; tshirt vertices inside the vest's outer "
        "face before -> after the fix; rifle min skin distance [mm])"
    )
    for key, rig in rigs.items():
        sk = rig.skeleton
        skin = skinning_matrices(sk, _world(sk, {})[:1])
        caster = RayCaster(rig.mesh.points, rig.triangles)
        sim = simulate(dress(rig, OUTFIT), skin)
        by = {a.name: a for a in sim.garments}
        assert [a.name for a in sim.garments] == OUTFIT  # inner first, props last
        v = by["vest"]
        assert v.counts[0].inside_after == 0 and v.counts[0].close_after == 0
        assert not caster.inside(v.posed[0]).any()
        assert v.air_gap.min() >= vest.minimum_gap - TOL
        assert 0.003 < np.median(v.air_gap) < 0.012
        # T-shirt against the vest mesh: signed distance to the vest surface (outward normal)
        t = by["tshirt_white"]
        vest_surface = Surface(v.posed[0], v.fitted.triangles)
        near = vest_surface.closest(t.posed[0])
        over = _over(v, near, t.posed[0])
        unfixed = apply(
            blend_transforms(t.fitted.joint_indices, t.fitted.joint_weights, skin[0]), t.fitted.points
        )
        near_before = vest_surface.closest(unfixed)
        before = near_before.signed
        over_before = _over(v, near_before, unfixed)
        after = near.signed
        need = vest.thickness + t.fitted.garment.minimum_gap - 1e-4
        inside_before = int(np.sum(over_before & (before < vest.thickness)))
        inside_after = int(np.sum(over & (after < vest.thickness)))
        assert inside_before > 100, key
        assert inside_after == 0, (key, np.sort(after[over])[:5])
        assert np.quantile(after[over], 0.01) >= need - 0.002
        assert t.counts[0].layered_after == 0 and t.counts[0].inside_after == 0
        r = by["rifle"]  # in the A-pose rest the carried rifle hangs off the right hand
        print(
            f"{key:14s} vest {v.air_gap.min() * 1e3:4.1f}/{np.median(v.air_gap) * 1e3:4.1f}"
            f"  tshirt in vest {inside_before:4d} -> {inside_after}"
            f"  rifle {r.counts[0].min_distance_m * 1e3:5.1f}"
        )


def test_rifle_is_a_closed_rigid_prop_that_follows_the_right_hand(rigs):
    rig = rigs["male_178_80"]
    sk = rig.skeleton
    world = _world(sk, {"RightArm": -60.0, "RightForeArm": -30.0})
    skin = skinning_matrices(sk, world)
    sim = simulate(dress(rig, ["rifle"]), skin)
    r = sim.garments[0]
    f = r.fitted
    # closed, outward, 0.9 m along its main axis (placed for the carry pose: between the hands
    # there, see tests/test_carry.py)
    assert signed_volume(f.points, f.face_counts, f.face_indices) > 0.002
    centred = f.points - f.points.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    assert np.ptp(centred @ axis) == pytest.approx(0.90, abs=0.01)  # parts off the axis
    assert np.all(f.joint_indices[:, 0] == sk.index("RightHand"))
    assert np.all(f.joint_weights[:, 0] == 1.0)
    # rigid motion with the right hand (FK): same transform as the hand joint
    hand = sk.index("RightHand")
    expected = f.points @ skin[1, hand, :3, :3].T + skin[1, hand, :3, 3]
    assert np.abs(r.posed[1] - expected).max() < 1e-9
    assert np.abs(r.posed[0] - f.points).max() < 1e-12  # not moved at rest
    moved = np.linalg.norm(r.posed[1] - r.posed[0], axis=1)
    assert moved.min() > 0.1
    d_rest = np.linalg.norm(r.posed[0] - sk.rest_positions[hand], axis=1)
    d_pose = np.linalg.norm(r.posed[1] - world[1, hand, :3, 3], axis=1)
    assert np.abs(d_rest - d_pose).max() < 1e-9
    # the left arm alone does not move it
    still = simulate(dress(rig, ["rifle"]), skinning_matrices(sk, _world(sk, {"LeftArm": -60.0})))
    assert np.abs(still.garments[0].posed[1] - f.points).max() < 1e-12


# ---------------------------------------------------------------------------- USD + render
@pytest.fixture(scope="module")
def stage_with_outfit(humvvex_raw):
    raw = copy.deepcopy(humvvex_raw)
    raw["general"] = dict(raw["general"], duration_s=0.1)  # 3 frames at 30 fps
    raw["human"][0]["clothing"] = list(OUTFIT)
    scenario = validate(raw)
    human = scenario["human"][0]
    frames = scenario.frame_count
    sk, pose = ramp_pose(scenario, human, {"RightArm": -50.0})  # raise the right arm forward
    avatar = avatar_layer.build_one(scenario, human, motion=pose)
    upstream = compose_in_memory([avatar], scenario["general"]["fps"])
    clothing = clothing_layer.build_one(scenario, human, upstream)
    materials = materials_layer.build(scenario)
    environment = environment_layer.build(scenario)  # the weather the thermal tool reads
    sensors = sensors_layer.build(scenario)
    atmosphere = atmosphere_layer.build(
        scenario, compose_in_memory([environment, sensors], scenario["general"]["fps"])
    )
    layers = [environment, materials, atmosphere, avatar, clothing]
    thermal = thermal_layer.build(scenario, compose_in_memory(layers, scenario["general"]["fps"]))
    stage = compose_in_memory(layers + [thermal], scenario["general"]["fps"])
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)  # as compose's stage.usda (the layers': m)
    return stage, clothing, frames, sk, scenario


@pytest.mark.slow
def test_outfit_layer_opens_and_renders(stage_with_outfit):
    stage, layer, frames, sk, scenario = stage_with_outfit
    assert stage.GetPrimAtPath("/World/Humans/p1/Clothing/vest").HasAPI(S.CLOTHING_API)
    assert stage.GetPrimAtPath("/World/Humans/p1/Clothing/tshirt_white").HasAPI(S.CLOTHING_API)
    assert not stage.GetPrimAtPath("/World/Humans/p1/Clothing/rifle")
    rifle = stage.GetPrimAtPath("/World/Humans/p1/Props/rifle")
    assert rifle.IsA(UsdGeom.Mesh) and not rifle.HasAPI(S.CLOTHING_API)
    assert rifle.GetAttribute(S.LABEL_CLASS).Get() == "prop"
    # its own instance id: after the people, the ground and the scene objects
    assert rifle.HasAPI(S.LABEL_API)
    prop_id = rifle.GetAttribute(S.LABEL_INSTANCE_ID).Get()
    assert prop_id == instance_ids(scenario)["prop:p1:rifle"] == len(instance_ids(scenario))
    person_id = stage.GetPrimAtPath("/World/Humans/p1").GetAttribute(S.LABEL_INSTANCE_ID).Get()
    assert prop_id != person_id
    material, _ = UsdShade.MaterialBindingAPI(rifle).ComputeBoundMaterial()
    assert material.GetPath().name == "polymer_black"
    info = rifle.GetCustomDataByKey("humv:prop")
    # carried: the grip sits inside the gripping hand, a few vertices at most
    assert info["joint"] == "RightHand" and info["insideMax"] <= 5
    assert rule_sensors_and_labels(stage) == []  # instance ids still unique
    for name in ("vest", "tshirt_white"):
        fix = stage.GetPrimAtPath(f"/World/Humans/p1/Clothing/{name}").GetCustomDataByKey("humv:clothing:fix")
        assert fix["insideAfterMax"] == 0 and fix["layeredAfterMax"] == 0, (name, fix)
    # UsdSkel moves the rifle rigidly with the raised right arm
    p0 = skinned_points(stage, "/World/Humans/p1/Props/rifle", Usd.TimeCode(0))
    p2 = skinned_points(stage, "/World/Humans/p1/Props/rifle", Usd.TimeCode(frames - 1))
    assert np.linalg.norm(p2 - p0, axis=1).min() > 0.05
    e0 = np.linalg.norm(p0[:, None] - p0[None], axis=2)
    e2 = np.linalg.norm(p2[:, None] - p2[None], axis=2)
    assert np.abs(e0 - e2).max() < 1e-4
    # render export reads every mesh (rifle: fixed temperature from the thermal tool)
    export = StageExport(stage)
    for f in range(frames):
        state = export.frame_state(f, [])
        paths = {m.path: m for m in state.meshes}
        assert {
            "/World/Humans/p1/Props/rifle",
            "/World/Humans/p1/Clothing/vest",
            "/World/Humans/p1/Clothing/tshirt_white",
        } <= set(paths)
        assert {p.instance_id for p in paths["/World/Humans/p1/Props/rifle"].parts} == {prop_id}
        assert {p.instance_id for p in paths["/World/Humans/p1/Clothing/vest"].parts} == {person_id}
        assert np.all(np.isfinite(state.temperatures["/World/Humans/p1/Props/rifle"]))
    print(f"\nrifle moved {np.linalg.norm(p2 - p0, axis=1).mean():.3f} m (mean) with the arm")


def test_render_rays_show_the_rifle_with_its_own_instance_id(stage_with_outfit, tmp_path):
    """Pixel-centre rays of a small camera 1.2 m in front of the rifle (the render's own
    label pass): rifle pixels carry the prop's id, the person's pixels the person's."""
    from humv_usd.geometry.camera import CameraPose
    from humv_usd.render.ir import IRScene, SensorSetup

    stage, _, _, _, scenario = stage_with_outfit
    ids = instance_ids(scenario)
    state = StageExport(stage).frame_state(0, [])
    rifle = state.points["/World/Humans/p1/Props/rifle"]
    centre = rifle.mean(axis=0)
    origin = centre + np.array([0.0, -1.2, 0.0])  # the person faces -y (heading 180)
    pose = CameraPose(
        origin=origin, forward=np.array([0.0, 1.0, 0.0]), up=np.array([0.0, 0.0, 1.0]), fov_x_deg=40.0
    )
    parts = [
        (part, state.points[m.path][part.vertex_ids], state.flip[m.path])
        for m in state.meshes
        for part in m.parts
    ]
    scene = IRScene(parts, [SensorSetup("cam", 48, 48, pose)], spp=1, max_depth=2, workdir=tmp_path)
    hits = scene.hits("cam")
    on_rifle = np.zeros(hits.part.shape, dtype=bool)
    for k, part in enumerate(scene.parts):
        if part.mesh_path == "/World/Humans/p1/Props/rifle":
            on_rifle |= hits.part == k
    assert on_rifle.sum() > 30
    assert np.all(hits.instance[on_rifle] == ids["prop:p1:rifle"])
    assert np.all(hits.instance[(hits.part >= 0) & ~on_rifle] == ids["human:p1"])
    assert set(np.unique(hits.instance).tolist()) == {0, ids["human:p1"], ids["prop:p1:rifle"]}
