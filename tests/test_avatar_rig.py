"""The UsdSkel avatar layer against our own FK/LBS, against Blender's USD import, and rendered.

A non-trivial pose (root turned and moved, left knee bent, right arm raised, spine bent) is
authored through ``avatar.layer.build_one(..., motion=...)``; UsdSkel's skinning of the layer
must reproduce :func:`humv_usd.human.skeleton.linear_blend_skinning` to 1 mm and Blender's
armature (``bpy.ops.wm.usd_import``, in a child process so Blender's state stays out of the
test session) our forward kinematics to 1 cm.
"""

from __future__ import annotations

import copy
import importlib.util
import json
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel

from humv_usd import images
from humv_usd.assets import makehuman_dir
from humv_usd.avatar import layer as avatar_layer
from humv_usd.human import usdskel
from humv_usd.human.body import build_body
from humv_usd.human.gait import axis_angle_quat
from humv_usd.human.skeleton import (
    forward_kinematics,
    linear_blend_skinning,
    skeleton_for,
    skin_weights,
    skinning_matrices,
)
from humv_usd.scenario import validate
from humv_usd.usd import schemas as S

pytestmark = pytest.mark.skipif(
    not (makehuman_dir() / "rigs").is_dir(), reason="MakeHuman data not fetched (make setup)"
)

POSITION = (1.5, -2.0, 0.25)
HEADING_DEG = 120.0


def axis_angle(axis, angle) -> np.ndarray:
    return axis_angle_quat(axis, angle)


def posed_motion(skel, frames=3) -> usdskel.Pose:
    """Frame 0 rest; 1: root turned 35 deg and moved, left knee bent, right arm raised;
    2: spine bent forward, left hip flexed."""
    q = np.zeros((frames, len(skel.names), 4))
    q[..., 0] = 1.0
    root = np.repeat(skel.rest_positions[:1], frames, axis=0)
    q[1, 0] = axis_angle([0, 0, 1], np.radians(35))
    q[1, skel.index("LeftLeg")] = axis_angle([1, 0, 0], 1.1)
    q[1, skel.index("RightArm")] = axis_angle([0, 1, 0.3], -0.9)
    root[1] += (0.3, -0.2, 0.05)
    q[2, skel.index("Spine")] = axis_angle([1, 0.2, 0], -0.4)
    q[2, skel.index("LeftUpLeg")] = axis_angle([1, 0, 0], -0.7)
    return usdskel.Pose(root, q)


@pytest.fixture(scope="module")
def scenario(humvvex_raw):
    raw = copy.deepcopy(humvvex_raw)
    raw["placement"][0]["position_m"] = list(POSITION)
    raw["placement"][0]["heading_deg"] = HEADING_DEG
    raw["general"]["duration_s"] = 2 / 30  # frames 0..2
    return validate(raw)


@pytest.fixture(scope="module")
def rig(scenario):
    h = scenario["human"][0]
    body = build_body(h["sex"], h["age_yr"], h["stature_m"], h["mass_kg"], h["build"])
    skel = skeleton_for(body.points, body.groups)
    mesh = body.body_mesh()
    idx, w = skin_weights(skel, mesh.vertex_ids)
    motion = posed_motion(skel)
    world = forward_kinematics(skel, motion.local_rotations, motion.root_translation)
    skin = skinning_matrices(skel, world)
    ours = np.stack([linear_blend_skinning(mesh.points, idx, w, skin[f]) for f in range(motion.frame_count)])
    layer = avatar_layer.build_one(scenario, h, motion=motion)
    return dict(
        body=body,
        skel=skel,
        mesh=mesh,
        motion=motion,
        world=world,
        ours=ours,
        layer=layer,
        stage=Usd.Stage.Open(layer),
    )


def placement_matrix() -> np.ndarray:
    """The SkelRoot's local-to-world (column-vector): translate, then rotate about z."""
    a = np.radians((180.0 - HEADING_DEG) % 360.0)
    m = np.eye(4)
    m[:3, :3] = [[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
    m[:3, 3] = POSITION
    return m


def to_world(points: np.ndarray) -> np.ndarray:
    m = placement_matrix()
    return points @ m[:3, :3].T + m[:3, 3]


# --------------------------------------------------------------------------------- structure
def test_layer_is_a_usdskel_avatar(rig):
    stage, skel = rig["stage"], rig["skel"]
    root = stage.GetPrimAtPath("/World/Humans/p1")
    assert root.IsA(UsdSkel.Root)
    assert root.HasAPI(S.AVATAR_API) and root.HasAPI(S.LABEL_API)
    assert list(UsdGeom.Xformable(root).GetXformOpOrderAttr().Get()) == [
        "xformOp:translate",
        "xformOp:rotateZ",
    ]
    m = np.asarray(UsdGeom.Xformable(root).ComputeLocalToWorldTransform(Usd.TimeCode(0))).T
    np.testing.assert_allclose(m, placement_matrix(), atol=1e-9)

    sk = UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Humans/p1/Skeleton"))
    assert list(sk.GetJointsAttr().Get()) == skel.paths and len(skel.paths) == 31
    bind = np.asarray(sk.GetBindTransformsAttr().Get())
    rest = np.asarray(sk.GetRestTransformsAttr().Get())
    np.testing.assert_allclose(bind[:, 3, :3], skel.rest_positions, atol=1e-9)
    np.testing.assert_allclose(rest[:, 3, :3], skel.rest_local_translations, atol=1e-9)
    np.testing.assert_allclose(bind[:, :3, :3], np.tile(np.eye(3), (31, 1, 1)))
    assert [str(t) for t in UsdSkel.BindingAPI(sk.GetPrim()).GetAnimationSourceRel().GetTargets()] == [
        "/World/Humans/p1/Motion"
    ]

    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Humans/p1/Motion"))
    assert list(anim.GetJointsAttr().Get()) == skel.paths
    assert anim.GetRotationsAttr().GetTimeSamples() == [0.0, 1.0, 2.0]
    assert anim.GetTranslationsAttr().GetTimeSamples() == [0.0, 1.0, 2.0]
    q = anim.GetRotationsAttr().Get(1)[skel.index("LeftLeg")]
    expected = rig["motion"].local_rotations[1, skel.index("LeftLeg")]
    np.testing.assert_allclose([q.GetReal(), *q.GetImaginary()], expected, atol=1e-6)

    body = stage.GetPrimAtPath("/World/Humans/p1/Body")
    binding = UsdSkel.BindingAPI(body)
    assert [str(t) for t in binding.GetSkeletonRel().GetTargets()] == ["/World/Humans/p1/Skeleton"]
    for pv in (binding.GetJointIndicesPrimvar(), binding.GetJointWeightsPrimvar()):
        assert pv.GetElementSize() == 4 and pv.GetInterpolation() == UsdGeom.Tokens.vertex
        assert len(pv.Get()) == 4 * len(rig["mesh"].points)
    assert binding.GetGeomBindTransformAttr().Get() == Gf.Matrix4d(1.0)
    query = UsdSkel.Cache()
    query.Populate(UsdSkel.Root(root), Usd.PrimDefaultPredicate)
    assert query.GetSkinningQuery(body).HasJointInfluences()


def test_rest_motion_stands_at_rest(scenario, rig):
    layer = avatar_layer.build_one(scenario, scenario["human"][0], motion=usdskel.rest_motion(rig["skel"]))
    stage = Usd.Stage.Open(layer)
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Humans/p1/Motion"))
    assert anim.GetRotationsAttr().GetTimeSamples() == [0.0]  # held for every frame
    for frame in (0, 2):
        pts = usdskel.skinned_points(stage, "/World/Humans/p1/Body", Usd.TimeCode(frame))
        np.testing.assert_allclose(pts, rig["mesh"].points, atol=1e-6)


def test_bad_motion_is_rejected(scenario, rig):
    skel = rig["skel"]
    with pytest.raises(ValueError, match="local_rotations"):
        usdskel.as_pose(usdskel.Pose(np.zeros((2, 3)), np.ones((2, 30, 4))), skel)
    with pytest.raises(ValueError, match="root_translation"):
        usdskel.as_pose(usdskel.Pose(np.zeros((3, 3)), np.ones((2, 31, 4))), skel)
    with pytest.raises(TypeError):
        usdskel.as_pose(object(), skel)


# --------------------------------------------------------------------------------- UsdSkel
def test_usdskel_skinning_matches_ours(rig):
    """UsdSkel (Cache + SkinningQuery.ComputeSkinnedPoints) vs our LBS, < 1 mm every frame."""
    stage, ours = rig["stage"], rig["ours"]
    assert np.abs(ours[1] - rig["mesh"].points).max() > 0.3  # the pose is non-trivial
    worst = 0.0
    for frame in range(len(ours)):
        pts = usdskel.skinned_points(stage, "/World/Humans/p1/Body", Usd.TimeCode(frame))
        worst = max(worst, float(np.linalg.norm(pts - ours[frame], axis=1).max()))
        world = usdskel.skinned_points(stage, "/World/Humans/p1/Body", Usd.TimeCode(frame), space="world")
        np.testing.assert_allclose(world, to_world(ours[frame]), atol=1e-3)
    print(f"UsdSkel vs ours: max {worst * 1e3:.2e} mm")
    assert worst < 1e-3
    # the joints too: UsdSkel's skel-space joint transforms are our FK
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/World/Humans/p1")), Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath("/World/Humans/p1/Skeleton")))
    for frame in range(len(ours)):
        joints = np.asarray(query.ComputeJointSkelTransforms(Usd.TimeCode(frame)))
        np.testing.assert_allclose(np.transpose(joints, (0, 2, 1)), rig["world"][frame], atol=1e-5)


# --------------------------------------------------------------------------------- Blender
BLENDER_SCRIPT = textwrap.dedent("""
    import json, sys
    import bpy
    path, frames = sys.argv[1], [int(f) for f in sys.argv[2].split(",")]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=path)
    arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
    action = arm.animation_data.action
    keys = 0
    for layer in action.layers:
        for strip in layer.strips:
            for slot in action.slots:
                bag = strip.channelbag(slot)
                if bag is not None:
                    keys += sum(len(fc.keyframe_points) for fc in bag.fcurves)
    heads = {}
    for f in frames:
        bpy.context.scene.frame_set(f)
        heads[f] = {b.name: list(arm.matrix_world @ b.head) for b in arm.pose.bones}
    print("RESULT " + json.dumps({"bones": len(arm.data.bones), "keys": keys,
                                  "frame_range": list(action.frame_range), "heads": heads,
                                  "meshes": [o.name for o in bpy.data.objects if o.type == "MESH"]}))
""")


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs bpy")
def test_blender_imports_armature_and_action(rig, tmp_path):
    start = time.perf_counter()
    path = tmp_path / "avatar.usda"
    rig["layer"].Export(str(path))
    proc = subprocess.run(
        [sys.executable, "-c", BLENDER_SCRIPT, str(path), "0,1,2"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    result = json.loads(line.removeprefix("RESULT "))
    assert result["bones"] == 31
    assert result["keys"] > 0 and result["frame_range"] == [0.0, 2.0]
    assert result["meshes"] == ["Body"]
    skel, world = rig["skel"], rig["world"]
    worst = 0.0
    for frame, heads in result["heads"].items():
        ours = to_world(world[int(frame), :, :3, 3])
        theirs = np.array([heads[name] for name in skel.names])
        worst = max(worst, float(np.linalg.norm(theirs - ours, axis=1).max()))
    print(
        f"Blender vs ours: max {worst * 1e3:.2e} mm over 31 bone heads x 3 frames; "
        f"{time.perf_counter() - start:.1f} s"
    )
    assert worst < 0.01


# --------------------------------------------------------------------------------- render
@pytest.mark.slow
def test_render_poses_the_avatar_per_frame(humvvex_raw, tmp_path):
    """The person's instance-id pixels follow the animation (UsdSkel posing in render)."""

    from humv_usd.pipeline.compose import compose
    from humv_usd.pipeline.render import render_stage
    from humv_usd.usd.check import check_stage
    from humv_usd.usd.layers import set_inputs_key

    raw = copy.deepcopy(humvvex_raw)
    raw["general"]["duration_s"] = 1 / 30  # frames 0, 1
    raw["sensor"][0].update(resolution=[96, 64], pixel_pitch_um=100.0)
    scenario = validate(raw)
    out = tmp_path / "out"
    compose(scenario, out)
    h = scenario["human"][0]
    body = build_body(h["sex"], h["age_yr"], h["stature_m"], h["mass_kg"], h["build"])
    skel = skeleton_for(body.points, body.groups)
    motion = usdskel.rest_motion(skel, frames=2)
    shift_m = 0.8
    motion.root_translation[1, 0] += shift_m  # heading 180: avatar x = world x
    # garments are a point cache built on the avatar layer: a hand edit of the avatar layer
    # (same inputs key) is kept by compose, which rebuilds the clothing (and thermal) layers on it
    avatar_file = str(out / "layers/avatar_p1.usda")
    key = Sdf.Layer.OpenAsAnonymous(avatar_file).customLayerData["humv:inputsKey"]
    edited = avatar_layer.build_one(scenario, h, motion=motion)
    set_inputs_key(edited, key)
    edited.Export(avatar_file)
    compose(scenario, out)
    assert check_stage(out / "stage.usda") == []

    render_stage(out / "stage.usda", tmp_path / "render", spp=4, sensors=["atom1024_lwir"])
    columns = []
    for frame in (0, 1):
        ids = images.read_exr(tmp_path / f"render/atom1024_lwir/{frame:04d}.exr")["instance_id"]
        person = ids == 1
        assert person.sum() > 20
        columns.append(np.nonzero(person)[1].mean())
    # 0.8 m at 15 m through a 25 mm lens on 100 um pixels: 13.3 px to the right (+x)
    expected = shift_m * 25e-3 / (15.0 * 100e-6)
    print(f"person's column moved {columns[1] - columns[0]:.2f} px (expected {expected:.2f})")
    assert columns[1] - columns[0] == pytest.approx(expected, abs=1.5)


def test_render_export_rejects_broken_skinning(rig):
    """Joint indices out of range: a one-line InputError naming the mesh, not a crash."""
    from pxr import Sdf, Vt

    from humv_usd.errors import InputError
    from humv_usd.render.export import StageExport

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(rig["layer"])
    stage = Usd.Stage.Open(layer)
    body = stage.GetPrimAtPath("/World/Humans/p1/Body")
    UsdSkel.BindingAPI(body).GetJointIndicesPrimvar().Set(Vt.IntArray([99] * (4 * len(rig["mesh"].points))))
    exporter = StageExport(stage)
    assert list(exporter.meshes.skinned) == ["/World/Humans/p1/Body"]
    with pytest.raises(InputError, match="/World/Humans/p1/Body.primvars:skel:jointIndices"):
        exporter.meshes.points(body, "/World/Humans/p1/Body", Usd.TimeCode(1), UsdGeom.XformCache(1))


def test_without_motion_the_activity_moves_the_avatar(scenario):
    """compose passes no motion: the avatar performs its activity (stand: sway and breathing)
    over every frame, with the metabolic schedule and the contact report on the SkelRoot."""
    layer = avatar_layer.build_one(scenario, scenario["human"][0])
    stage = Usd.Stage.Open(layer)
    anim = UsdSkel.Animation(stage.GetPrimAtPath("/World/Humans/p1/Motion"))
    assert anim.GetRotationsAttr().GetTimeSamples() == [0.0, 1.0, 2.0]
    root = stage.GetPrimAtPath("/World/Humans/p1")
    assert 80.0 < root.GetAttribute(S.AVATAR_METABOLIC_RATE).Get(0) < 250.0  # ~1.3 met
    contact = root.GetCustomDataByKey("humv:contact")
    assert contact["max_gap_m"] <= 0.01 and contact["max_penetration_m"] <= 0.01
