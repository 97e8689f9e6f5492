"""Stages that other USD tools show right (issue 27, deliverable 4): the sun and sky as UsdLux
lights, cameras focused where they look, model kinds, typed scopes, SkelRoot and Skeleton
extents, prim names that do not collide in Blender, every layer opening alone; checked with
USD's own validators (UsdValidation, every registered validator) and with Blender's importer
and Cycles."""

from __future__ import annotations

import copy
import importlib.util

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdValidation

from humv_usd.human.usdskel import skinned_points
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.usd import environment as E
from humv_usd.usd import schemas as S

pytestmark = pytest.mark.slow

#: Validator findings allowed on a layer opened alone, by layer-name prefix: the avatar and scene
#: layers bind materials that the materials layer defines (they resolve once it is beside them,
#: which the test checks). Everything else must be clean. A clothing layer alone shows nothing:
#: its garments sit under ``over`` parents that the avatar layer defines (documented, not an error).
ALONE_EXCEPTIONS = {"avatar_": "InvalidResourcePath", "scene": "InvalidResourcePath"}


def _validate(stage) -> list:
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    return list(ctx.Validate(stage))


@pytest.fixture(scope="module")
def stage_dir(tmp_path_factory, humvvex_raw):
    out = tmp_path_factory.mktemp("interop")
    compose(validate(copy.deepcopy(humvvex_raw)), out)
    return out


def test_every_layer_opens_alone_and_the_stage_validates(stage_dir):
    assert _validate(Usd.Stage.Open(str(stage_dir / "stage.usda"))) == []
    layers = sorted((stage_dir / "layers").glob("*.usda"))
    assert {p.stem.split("_")[0] for p in layers} >= {
        "avatar",
        "scene",
        "materials",
        "sensors",
        "environment",
    }
    for path in layers:
        errors = _validate(Usd.Stage.Open(str(path)))
        allowed = next((v for k, v in ALONE_EXCEPTIONS.items() if path.stem.startswith(k)), None)
        assert all(e.GetName() == allowed for e in errors), (path.name, [e.GetMessage() for e in errors])
        if errors:  # the documented exception: material bindings resolve with the materials layer
            root = Sdf.Layer.CreateAnonymous(".usda")
            root.subLayerPaths = [str(path), str(stage_dir / "layers" / "materials.usda")]
            root.defaultPrim = "World"
            both = Usd.Stage.Open(root)
            UsdGeom.SetStageUpAxis(both, UsdGeom.Tokens.z)
            UsdGeom.SetStageMetersPerUnit(both, 1.0)
            assert [e.GetMessage() for e in _validate(both)] == [], path.name


def test_sun_and_sky_lights_follow_the_environment(stage_dir, humvvex_raw, tmp_path):
    stage = Usd.Stage.Open(str(stage_dir / "stage.usda"))
    env = stage.GetPrimAtPath("/World/Environment")
    sun_dir = np.array(env.GetAttribute(S.ENVIRONMENT_SUN_DIRECTION).Get(0), dtype=float)
    dni = env.GetAttribute(S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE).Get(0)
    dhi = env.GetAttribute(S.ENVIRONMENT_DIFFUSE_HORIZONTAL_IRRADIANCE).Get(0)
    sun = UsdLux.DistantLight(stage.GetPrimAtPath("/World/Environment/Sun"))
    m = UsdGeom.Xformable(sun).ComputeLocalToWorldTransform(0)
    travel = np.array(m.TransformDir(Gf.Vec3d(0, 0, -1)))  # a DistantLight shines along its -Z
    assert_allclose(travel / np.linalg.norm(travel), -sun_dir / np.linalg.norm(sun_dir), atol=1e-6)
    assert sun.GetNormalizeAttr().Get() is True  # intensity = illuminance [lx] (UsdLux)
    assert sun.GetIntensityAttr().Get(0) == pytest.approx(dni * E.BEAM_EFFICACY_LM_W, rel=1e-6)
    assert 5e4 < sun.GetIntensityAttr().Get(0) < 1.2e5  # clear afternoon sun: 50-120 klx
    dome = UsdLux.DomeLight(stage.GetPrimAtPath("/World/Environment/Sky"))
    assert dome.GetIntensityAttr().Get(0) == pytest.approx(dhi * E.DIFFUSE_EFFICACY_LM_W / np.pi, rel=1e-6)
    texture = dome.GetTextureFileAttr().Get()  # the sky's colour (tests/test_sky_texture.py)
    assert texture.path.startswith("./") and (stage_dir / "layers" / texture.path[2:]).is_file()
    assert texture.resolvedPath == str(stage_dir / "layers" / texture.path[2:])
    night = copy.deepcopy(humvvex_raw)
    night["general"]["start"] = night["general"]["start"].replace(hour=23)
    compose(validate(night), tmp_path)
    dark = Usd.Stage.Open(str(tmp_path / "stage.usda"))
    assert UsdLux.DistantLight(dark.GetPrimAtPath("/World/Environment/Sun")).GetIntensityAttr().Get(0) == 0.0
    assert UsdLux.DomeLight(dark.GetPrimAtPath("/World/Environment/Sky")).GetIntensityAttr().Get(0) == 0.0


def test_kinds_scopes_extents_and_focus(stage_dir, humvvex_raw):
    stage = Usd.Stage.Open(str(stage_dir / "stage.usda"))
    kinds = {
        p: Usd.ModelAPI(stage.GetPrimAtPath(p)).GetKind() for p in ("/World", "/World/Scene", "/World/Humans")
    }
    assert kinds == {"/World": "assembly", "/World/Scene": "group", "/World/Humans": "group"}
    assert Usd.ModelAPI(stage.GetPrimAtPath("/World/Humans/p1")).GetKind() == "component"
    assert Usd.ModelAPI(stage.GetPrimAtPath("/World/Scene/warehouse")).GetKind() == "component"
    assert stage.GetPrimAtPath("/World/Materials").GetTypeName() == "Scope"
    # the SkelRoot's extent (its own space) holds every skinned point of the body
    root = stage.GetPrimAtPath("/World/Humans/p1")
    lo, hi = (np.array(v) for v in root.GetAttribute("extent").Get(0))
    local = np.linalg.inv(np.array(UsdGeom.Xformable(root).ComputeLocalToWorldTransform(0)))
    pts = skinned_points(stage, "/World/Humans/p1/Body", Usd.TimeCode(0), space="world")
    pts = (np.c_[pts, np.ones(len(pts))] @ local)[:, :3]
    assert (pts >= lo - 1e-4).all() and (pts <= hi + 1e-4).all()
    assert stage.GetPrimAtPath("/World/Humans/p1/Skeleton").GetAttribute("extent").Get(0) is not None
    for s in humvvex_raw["sensor"]:
        cam = UsdGeom.Camera(stage.GetPrimAtPath(f"/World/Sensors/{s['id']}"))
        distance = np.linalg.norm(np.subtract(s["look_at_m"], s["position_m"]))
        assert cam.GetFocusDistanceAttr().Get() == pytest.approx(distance, rel=1e-6)
    # the atmosphere's path tables are named apart from the cameras
    names = {p.GetName() for p in stage.GetPrimAtPath("/World/Atmosphere/Paths").GetChildren()}
    assert not names & {s["id"] for s in humvvex_raw["sensor"]}


BLENDER = """
    import json, sys
    import bpy

    stage, image = sys.argv[1:3]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.world = bpy.data.worlds.new("World")  # as in Blender's default scene
    bpy.ops.wm.usd_import(filepath=stage)
    scene = bpy.context.scene
    cam = bpy.data.objects["eo_rgb"]
    bg = [n for n in scene.world.node_tree.nodes if n.type == "BACKGROUND"]
    result = {
        "cameras": sorted(o.name for o in bpy.data.objects if o.type == "CAMERA"),
        "suns": {o.name: o.data.energy for o in bpy.data.objects if o.type == "LIGHT" and o.data.type == "SUN"},
        "world_strength": bg[0].inputs["Strength"].default_value if bg else None,
        "world_images": [
            n.image.filepath for n in scene.world.node_tree.nodes if n.type == "TEX_ENVIRONMENT" and n.image
        ],
        "focus": cam.data.dof.focus_distance,
    }
    scene.camera = cam
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 4
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 96, 72, 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = image
    bpy.ops.render.render(write_still=True)
    print("RESULT " + json.dumps(result))
"""


@pytest.mark.skipif(importlib.util.find_spec("bpy") is None, reason="needs Blender as a Python module (bpy)")
def test_blender_imports_the_stage_lit_focused_and_named(stage_dir, humvvex_raw, tmp_path):
    """Blender 5.0's USD importer: the cameras keep the scenario's names (the path tables took
    them and the cameras became '<sensor>.001'), focus at the look-at distance (fStop without
    focusDistance gave a uniform blur), the sun is a Sun light and the sky the world background
    (the stage rendered black), and Cycles renders the scene lit."""
    import OpenImageIO as oiio
    from test_blender_interop import run_blender

    result = run_blender(BLENDER, [stage_dir / "stage.usda", tmp_path / "eo.exr"], tmp_path)
    assert result["cameras"] == sorted(s["id"] for s in humvvex_raw["sensor"])
    eo = next(s for s in humvvex_raw["sensor"] if s["id"] == "eo_rgb")
    assert result["focus"] == pytest.approx(
        np.linalg.norm(np.subtract(eo["look_at_m"], eo["position_m"])), rel=1e-4
    )
    # the sun and the moon (issue 24.4: below the horizon on this afternoon, intensity 0)
    assert (
        set(result["suns"]) == {"Sun", "Moon"} and result["suns"]["Sun"] > 0 and result["world_strength"] > 0
    )
    # the sky's colour: the dome's lat-long texture from the atmosphere layer (issue 27.4)
    assert [p.replace("\\", "/").rsplit("/", 1)[-1] for p in result["world_images"]] == ["atmosphere_sky.exr"]
    rgb = oiio.ImageBuf(str(tmp_path / "eo.exr")).get_pixels(oiio.FLOAT)[..., :3]
    assert np.isfinite(rgb).all() and rgb.mean() > 1.0  # lit (it was black without UsdLux)
