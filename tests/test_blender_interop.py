"""Blender (bpy 5.0.1) against our stages and outputs (issue 12, deliverables 4, 5 and 6).

- Garments: Blender's USD import poses the garments (a point cache) and the body (armature)
  where the render puts them, within 1 mm at every frame.
- Round trip: a composed stage imported into Blender (``wm.usd_import``), exported
  (``wm.usd_export``) unedited and after a user's edits (the person moved 1 m, a new cube with a
  new material named like a library material and custom properties ``humv_class`` and
  ``humv_temperature_k``), adopted by ``humv-usd adopt --from`` and rendered: unedited, the
  labels agree with the original render's and the radiance matches; edited, the person's
  pixels move by the projected metre, the cube has its own instance id, class, material and
  temperature.
- EXRs: Blender's compositor (an Image node reading our EXR, no Render Layers node; File Output
  nodes write what it read) reads ``Z`` as Depth and ``R,G,B`` as the colour (Combined) of the
  EO and IR files.

Blender runs in a subprocess of the venv's Python (``import bpy``) with its user folders in a
temporary folder (as tests/test_blender_addon.py).
"""

from __future__ import annotations

import copy
import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import tomllib

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner
from conftest import ROOT
from numpy.testing import assert_allclose
from pxr import Usd, UsdGeom

from humv_usd import images
from humv_usd.catalog.materials import LIBRARY
from humv_usd.cli.main import main
from humv_usd.groundtruth.labels import CLASS_ID
from humv_usd.pipeline.compose import compose
from humv_usd.pipeline.render import render_stage
from humv_usd.render.scene_export import SceneMeshes
from humv_usd.scenario.load import validate
from humv_usd.usd import schemas as S
from humv_usd.usd.check import check_stage

pytestmark = [
    pytest.mark.skipif(
        importlib.util.find_spec("bpy") is None, reason="needs Blender as a Python module (bpy)"
    ),
    pytest.mark.slow,
]

BLENDER_USER_VARS = (
    "BLENDER_USER_RESOURCES",
    "BLENDER_USER_SCRIPTS",
    "BLENDER_USER_CONFIG",
    "BLENDER_USER_DATAFILES",
    "BLENDER_USER_EXTENSIONS",
)
FOCAL_M, PITCH_M, DISTANCE_M = 18e-3, 100e-6, 15.0  # the small camera; the person walks 15 m away
MOVE_M = 1.0  # the user's edit: the person 1 m to the east (+x, to the right in the image)
CUBE_K = 320.0
MESHES = (
    "/World/Humans/p1/Body",
    "/World/Humans/p1/Clothing/tshirt_black",
    "/World/Humans/p1/Clothing/leggings",
)


def run_blender(script: str, args, tmp) -> dict:
    user = tmp / "blender_user"
    env = dict(os.environ, **{v: str(user / v.rsplit("_", 1)[-1].lower()) for v in BLENDER_USER_VARS})
    proc = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script), *map(str, args)],
        env=env,
        cwd=tmp,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    return json.loads(line.removeprefix("RESULT "))


@pytest.fixture(scope="module")
def walk(tmp_path_factory):
    """examples/walk.toml for 3 frames on a 160 x 120 camera (18 mm, 100 um pixels), composed
    and rendered (LWIR, 4 spp)."""
    tmp = tmp_path_factory.mktemp("blender")
    raw = copy.deepcopy(tomllib.loads((ROOT / "examples" / "walk.toml").read_text()))
    raw["general"]["duration_s"] = 2 / 15
    raw["sensor"][0].update(
        resolution=[160, 120], pixel_pitch_um=PITCH_M * 1e6, focal_length_mm=FOCAL_M * 1e3
    )
    compose(validate(raw), tmp / "out")
    render_stage(tmp / "out" / "stage.usda", tmp / "render", spp=4)
    return tmp


IMPORT_EXPORT = """
    import json, sys
    import bpy
    import numpy as np

    stage, plain, edited, move, kelvin = sys.argv[1:6]
    meshes = sys.argv[6:]
    result = {}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=stage)
    scene = bpy.context.scene
    result["modifiers"] = {o.name: [m.type for m in o.modifiers] for o in bpy.data.objects if o.type == "MESH"}
    points = {}
    for frame in range(scene.frame_start, scene.frame_end + 1):
        scene.frame_set(frame)
        graph = bpy.context.evaluated_depsgraph_get()
        for name in meshes:
            obj = bpy.data.objects[name].evaluated_get(graph)
            mesh = obj.to_mesh()
            co = np.empty(len(mesh.vertices) * 3)
            mesh.vertices.foreach_get("co", co)
            m = np.array(obj.matrix_world)
            points[f"{name}/{frame}"] = (co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]).tolist()
            obj.to_mesh_clear()
    result["points"] = points
    scene.frame_set(scene.frame_start)
    bpy.ops.wm.usd_export(filepath=plain, export_animation=True)
    # a user's edits: move the person, add a cube with a new material named like a library one
    bpy.data.objects["p1"].location.x += float(move)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(3.0, 0.0, 0.5))
    cube = bpy.context.active_object
    cube.name = "crate"
    cube.data.materials.append(bpy.data.materials.new("wood"))
    cube["humv_class"] = "vehicle"
    cube["humv_temperature_k"] = float(kelvin)
    bpy.ops.wm.usd_export(filepath=edited, export_animation=True)
    print("RESULT " + json.dumps(result))
"""


@pytest.fixture(scope="module")
def blender(walk):
    """Blender imports the stage, reads the posed meshes per frame and exports it twice."""
    names = [p.rsplit("/", 1)[-1] for p in MESHES]
    result = run_blender(
        IMPORT_EXPORT,
        [walk / "out" / "stage.usda", walk / "plain.usda", walk / "edited.usda", MOVE_M, CUBE_K, *names],
        walk,
    )
    return result


def _render_points(stage: Usd.Stage, path: str, frame: int) -> np.ndarray:
    meshes = SceneMeshes(stage)
    pts, m = meshes.points(stage.GetPrimAtPath(path), path, Usd.TimeCode(frame), UsdGeom.XformCache(frame))
    return pts @ m[:3, :3] + m[3, :3]


def test_blender_poses_garments_where_the_render_does(walk, blender):
    """Garments come in as a mesh-sequence cache (no armature), the body with its armature (and,
    since walk.toml's physiology makes the skin temperature primvar time-varying, a cache for that
    attribute before it); at every frame each vertex is within 1 mm of the render's."""
    assert blender["modifiers"]["leggings"] == ["MESH_SEQUENCE_CACHE"]
    assert blender["modifiers"]["Body"][-1] == "ARMATURE"
    assert "ARMATURE" not in blender["modifiers"]["leggings"]
    stage = Usd.Stage.Open(str(walk / "out" / "stage.usda"))
    worst = {}
    for path in MESHES:
        name = path.rsplit("/", 1)[-1]
        for frame in range(3):
            theirs = np.array(blender["points"][f"{name}/{frame}"])
            d = np.linalg.norm(theirs - _render_points(stage, path, frame), axis=1).max()
            worst[name] = max(worst.get(name, 0.0), float(d))
    print("Blender vs render, max vertex distance [mm]:", {k: round(v * 1e3, 4) for k, v in worst.items()})
    assert max(worst.values()) < 1e-3


def _adopt(walk, export: str, out: str):
    result = CliRunner().invoke(
        main, ["adopt", str(walk / export), "-o", str(walk / out), "--from", str(walk / "out" / "stage.usda")]
    )
    assert result.exit_code == 0, result.output
    assert "no animation" not in result.output  # exported with export_animation=True
    return result.output


def test_round_trip_without_edits_renders_the_same(walk, blender):
    output = _adopt(walk, "plain.usda", "plain")
    assert "fps 15 from the original stage" in output
    stage_path = walk / "plain" / "stage.usda"
    assert check_stage(stage_path) == []
    stage = Usd.Stage.Open(str(stage_path))
    assert stage.GetTimeCodesPerSecond() == 15.0
    assert stage.GetPrimAtPath("/World/Sensors/atom1024_lwir").HasAPI(S.SENSOR_API)
    assert stage.GetPrimAtPath("/World/Materials/nylon").HasAPI(S.MATERIAL_API)
    render_stage(stage_path, walk / "plain_render", spp=4)
    for frame in range(3):
        ours = images.read_exr(walk / "render" / "atom1024_lwir" / f"{frame:04d}.exr")
        theirs = images.read_exr(walk / "plain_render" / "atom1024_lwir" / f"{frame:04d}.exr")
        agree = {k: float(np.mean(ours[k] == theirs[k])) for k in ("instance_id", "class_id", "body_region")}
        diff = np.abs(ours["radiance"] - theirs["radiance"])
        print(
            f"frame {frame}: label agreement {agree}; radiance |diff| mean {diff.mean():.3g}, "
            f"max {diff.max():.3g} W m-2 sr-1 (mean radiance {ours['radiance'].mean():.4g})"
        )
        assert min(agree.values()) > 0.999
        assert diff.mean() < 1e-4 * ours["radiance"].mean()


def test_round_trip_with_edits(walk, blender):
    output = _adopt(walk, "edited.usda", "edited")
    assert "new mesh /World/Scene/crate" in output and "1 library (wood)" in output
    stage_path = walk / "edited" / "stage.usda"
    assert check_stage(stage_path) == []
    stage = Usd.Stage.Open(str(stage_path))
    crate = stage.GetPrimAtPath("/World/Scene/crate")
    assert crate.GetAttribute(S.LABEL_CLASS).Get() == "vehicle"
    wood = stage.GetPrimAtPath("/World/Materials/wood")
    assert wood.GetAttribute(S.MATERIAL_SOURCE).Get() == LIBRARY["wood"].source
    render_stage(stage_path, walk / "edited_render", spp=4, frames=[0])
    before = images.read_exr(walk / "render" / "atom1024_lwir" / "0000.exr")
    after = images.read_exr(walk / "edited_render" / "atom1024_lwir" / "0000.exr")
    person = [np.nonzero(x["instance_id"] == 1)[1].mean() for x in (before, after)]
    expected = MOVE_M * FOCAL_M / (DISTANCE_M * PITCH_M)
    print(f"person moved {person[1] - person[0]:.2f} px (expected {expected:.2f})")
    assert person[1] - person[0] == pytest.approx(expected, abs=1.0)
    # the restored keypoints (SkelRoot space) moved with the person
    keypoints = []
    for folder in ("render", "edited_render"):
        objects = json.loads((walk / folder / "atom1024_lwir" / "0000.objects.json").read_text())["objects"]
        keypoints.append(
            np.array([o for o in objects if o["class"] == "person"][0]["keypoints"]).reshape(17, 3)
        )
    assert_allclose(keypoints[1][:, 0] - keypoints[0][:, 0], expected, atol=0.5)
    assert_allclose(keypoints[1][:, 1], keypoints[0][:, 1], atol=1e-3)
    new_id = crate.GetAttribute(S.LABEL_INSTANCE_ID).Get()
    assert new_id > before["instance_id"].max()
    cube = after["instance_id"] == new_id
    assert cube.sum() > 20
    assert set(np.unique(after["class_id"][cube]).tolist()) == {CLASS_ID["vehicle"]}
    assert_allclose(after["surface_temperature"][cube], CUBE_K, atol=1e-3)
    # elsewhere (not the person before or after, not the cube) nothing changed
    rest = ~(cube | (before["instance_id"] == 1) | (after["instance_id"] == 1))
    agree = {k: float(np.mean(before[k][rest] == after[k][rest])) for k in ("instance_id", "class_id")}
    diff = np.abs(before["radiance"] - after["radiance"])[rest]
    print(f"edited, outside the edits: label agreement {agree}; radiance |diff| mean {diff.mean():.3g}")
    assert min(agree.values()) > 0.99


COMPOSITOR = """
    import json, sys
    import bpy

    result = {}
    for k in range(1, len(sys.argv), 2):
        src, out = sys.argv[k], sys.argv[k + 1]
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        image = bpy.data.images.load(src)
        tree = bpy.data.node_groups.new("read", "CompositorNodeTree")
        scene.compositing_node_group = tree
        node = tree.nodes.new("CompositorNodeImage")
        node.image = image
        result[src] = [s.name for s in node.outputs]
        # one File Output per pass (a File Output node here writes only its first input)
        for name in ("Combined", "Depth"):
            for old in [n for n in tree.nodes if n.bl_idname == "CompositorNodeOutputFile"]:
                tree.nodes.remove(old)
            file_out = tree.nodes.new("CompositorNodeOutputFile")
            file_out.directory, file_out.file_name = out, name
            file_out.format.file_format = "OPEN_EXR_MULTILAYER"
            file_out.format.color_depth = "32"
            file_out.file_output_items.new("RGBA", name)
            tree.links.new(node.outputs[name], file_out.inputs[name])
            bpy.ops.render.render()
    print("RESULT " + json.dumps(result))
"""


def _eo_exr(tmp):
    """The EO plate of tests/test_exr_conventions.py (a white plate 10 m under the camera)."""
    from test_render_eo import eo_camera, reflective
    from test_render_radiometry import atmosphere_tables, plate, sun
    from test_render_radiometry import new_stage as new_eo_stage

    stage = new_eo_stage(tmp / "eo.usda")
    white = reflective(stage, "white", [0.3, 1.0], [0.8, 0.8])
    plate(stage, "/World/p", 1e3, 0.0, white, 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    atmosphere_tables(stage, [0.3, 0.9, 4.0], solar=[1500.0] * 3)
    sun(stage, (0.3, 0.0, 1.0))
    stage.Save()
    render_stage(tmp / "eo.usda", tmp / "eo_render", spp=4)
    return tmp / "eo_render" / "eo" / "0000.exr"


def _read(path):
    buf = oiio.ImageBuf(str(path))
    return list(buf.spec().channelnames), buf.get_pixels(oiio.FLOAT)


def test_blender_compositor_reads_depth_and_previews(walk):
    eo = _eo_exr(walk)
    ir = walk / "render" / "atom1024_lwir" / "0000.exr"
    result = run_blender(COMPOSITOR, [eo, walk / "eo_blender", ir, walk / "ir_blender"], walk)
    for src, out in ((eo, "eo_blender"), (ir, "ir_blender")):
        assert {"Combined", "Depth"} <= set(result[str(src)])
        names, ours = _read(src)
        depth = ours[..., names.index("Z")]
        _, combined = _read(next((walk / out).glob("Combined*.exr")))
        _, read_depth = _read(next((walk / out).glob("Depth*.exr")))
        rgb = np.stack([ours[..., names.index(c)] for c in "RGB"], axis=-1)
        assert_allclose(combined[..., :3], rgb, rtol=1e-6, atol=1e-6)  # R, G, B -> Combined
        finite = np.isfinite(depth)
        assert finite.sum() > 100
        assert_allclose(read_depth[..., 0][finite], depth[finite], rtol=1e-6)  # Z -> Depth
        assert not np.allclose(combined[..., 0][finite], depth[finite])
        if out == "ir_blender":
            assert combined[..., 0].max() > 0.5  # the grey preview, not a black image
        else:
            assert_allclose(depth, 10.0, rtol=1e-5)  # the plate 10 m below the camera


ADDON = """
    import json, sys
    import bpy

    zip_path, stage, out = sys.argv[1:4]
    result = {}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.preferences.addon_install(filepath=zip_path)
    bpy.ops.preferences.addon_enable(module="humv_usd_avatar")
    s = bpy.context.scene.humv_avatar
    s.stage_path = stage
    result["import"] = sorted(bpy.ops.humv.import_stage())
    scene = bpy.context.scene
    result["fps"] = scene.render.fps / scene.render.fps_base
    result["frames"] = [scene.frame_start, scene.frame_end]
    result["materials"] = {
        o.name: [m.name for m in o.data.materials] for o in bpy.data.objects if o.type == "MESH"
    }
    s.export_dir = out
    result["export"] = sorted(bpy.ops.humv.export_stage())
    print("RESULT " + json.dumps(result))
"""


def test_addon_imports_a_stage_and_exports_a_humv_stage(walk):
    """The add-on's Import HumV Stage brings the whole stage (people with skin and garment
    materials, scene, camera) at the stage's frame rate; Export HumV Stage writes a folder that
    passes check and renders the person where the original render has it."""
    zip_path = walk / "humv_usd_avatar.zip"
    subprocess.run(
        [sys.executable, str(ROOT / "tools" / "build_blender_addon.py"), "-o", str(zip_path)],
        check=True,
        capture_output=True,
    )
    result = run_blender(ADDON, [zip_path, walk / "out" / "stage.usda", walk / "addon_out"], walk)
    assert result["import"] == ["FINISHED"] and result["export"] == ["FINISHED"]
    assert result["fps"] == pytest.approx(15.0) and result["frames"] == [0, 2]
    mats = result["materials"]
    assert (
        mats["Body"] == ["skin"]
        and mats["leggings"] == ["nylon"]
        and mats["tshirt_black"] == ["cotton_black"]
    )
    assert {"Ground", "warehouse"} <= set(mats)
    stage_path = walk / "addon_out" / "stage.usda"
    assert check_stage(stage_path) == []
    render_stage(stage_path, walk / "addon_render", spp=4, frames=[0])
    ours = images.read_exr(walk / "render" / "atom1024_lwir" / "0000.exr")
    theirs = images.read_exr(walk / "addon_render" / "atom1024_lwir" / "0000.exr")
    assert np.mean(ours["instance_id"] == theirs["instance_id"]) > 0.999
