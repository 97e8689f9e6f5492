"""Issue 26, the cases left after tests/test_hostile_inputs.py: stages and files made by hand or
by other tools. Each is one line naming the key, the value and what is allowed, exit code 2, no
traceback, nothing half-written (an empty output folder at most)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Sdf, Usd
from test_hostile_inputs import _one_line, _tiny_stage

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.human.bvh import MAX_DEPTH, read_bvh
from humv_usd.scene.assets import read_asset
from humv_usd.usd.check import check_stage


def _no_images(out) -> bool:
    return not out.exists() or not any(p.is_file() for p in out.rglob("*"))


@pytest.mark.parametrize("name", ["timeCodesPerSecond", "framesPerSecond"])
def test_zero_time_codes_per_second_is_named_by_check_and_refused_by_render(tmp_path, name):
    """Was: check ok (or a faceVertexIndices error) and render went ahead."""
    path = _tiny_stage(tmp_path)
    root = Sdf.Layer.FindOrOpen(str(path))
    root.timeCodesPerSecond = root.timeCodesPerSecond  # authored: unauthored, it follows fps
    setattr(root, name, 0.0)
    root.Save()
    assert f"humv:timeCodes: stage: {name} = 0, expected > 0" in check_stage(path)
    out = tmp_path / "r"
    line = _one_line(CliRunner().invoke(main, ["render", str(path), "-o", str(out), "--spp", "1"]))
    assert f"{name} = 0.0: expected > 0" in line and str(path) in line
    assert _no_images(out)


def test_a_temperature_primvar_redeclared_as_strings_is_one_line(tmp_path):
    """A user layer declaring the temperature primvar string[]: USD keeps the weakest layer's
    type name (float[]) but the strongest value (strings); was a ValueError traceback in check
    and render."""
    path = _tiny_stage(tmp_path)
    edit = tmp_path / "edit.usda"
    edit.write_text(
        '#usda 1.0\nover "World"\n{\n    over "Scene"\n    {\n        over "ground"\n        {\n'
        '            string[] primvars:humv:thermal:temperature = ["hot", "hot"] (\n'
        '                interpolation = "uniform"\n            )\n        }\n    }\n}\n'
    )
    root = Sdf.Layer.FindOrOpen(str(path))
    stage = Usd.Stage.Open(root)
    faces = len(stage.GetPrimAtPath("/World/Scene/ground").GetAttribute("faceVertexCounts").Get())
    edit.write_text(edit.read_text().replace('["hot", "hot"]', "[" + ", ".join(['"hot"'] * faces) + "]"))
    root.subLayerPaths.insert(0, "./edit.usda")
    root.Save()
    findings = check_stage(path)
    assert any(
        f.startswith("humv:temperature: /World/Scene/ground: declared string[] in ")
        and "expected float[]" in f
        for f in findings
    ), findings
    out = tmp_path / "r"
    line = _one_line(CliRunner().invoke(main, ["render", str(path), "-o", str(out), "--spp", "1"]))
    assert "/World/Scene/ground.primvars:humv:thermal:temperature: declared string[]" in line
    assert _no_images(out)


def test_a_bvh_deeper_than_any_rig_is_one_line(tmp_path):
    """1,200 nested joints: was a RecursionError."""
    depth = 1200
    lines = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    for i in range(1, depth):
        lines += [f"JOINT j{i}", "{", "OFFSET 0 0.1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", "OFFSET 0 0.1 0", "}", *["}"] * depth]
    lines += ["MOTION", "Frames: 1", "Frame Time: 0.0333333", " ".join(["0"] * 3 * depth)]
    path = tmp_path / "deep.bvh"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as info:
        read_bvh(path)
    (line,) = info.value.problems
    assert line.startswith(f"{path}:") and f"at most {MAX_DEPTH} joints deep" in line
    assert f"JOINT j{MAX_DEPTH}" in line


def test_an_obj_coordinate_beyond_usds_float_points_is_one_line(tmp_path):
    """1e39 is a finite double but inf as USD's float point: was inf points and 12 lines of numpy
    warnings."""
    path = tmp_path / "big.obj"
    path.write_text("v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warning on the way
        with pytest.raises(InputError) as info:
            read_asset(str(path))
    (line,) = info.value.problems
    limit = float(np.finfo(np.float32).max)
    assert f"vertex coordinate of 1e+39: allowed range -{limit:.3g}..{limit:.3g}" in line
    path.write_text("v 0 0 0\nv 1e38 0 0\nv 0 1 0\nf 1 2 3\n")  # inside float's range: read
    assert read_asset(str(path)).meshes


def test_ctrl_c_while_the_command_starts_is_one_line(tmp_path):
    """SIGINT during the imports (pxr takes a second or more): was a KeyboardInterrupt traceback
    from inside an import. (The interpreter's own first ~0.2 s, before humv_usd is imported,
    stay Python's.) The signal goes once pxr's libraries are mapped into the process (humv_usd
    imports pxr right after installing its start-up handler), not after a fixed sleep: on a
    loaded machine the interpreter's own start took longer than the sleep (exit -2)."""
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    maps = Path("/proc/self/maps")
    if not maps.is_file():
        pytest.skip("needs /proc/<pid>/maps to see when the imports are under way")
    script = Path(sys.executable).parent / "humv-usd"
    proc = subprocess.Popen(
        [str(script), "check", str(tmp_path / "missing.usda")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    importing = False
    deadline = time.monotonic() + 60
    while proc.poll() is None and time.monotonic() < deadline:
        try:
            importing = "/pxr/" in Path(f"/proc/{proc.pid}/maps").read_text()
        except OSError:  # gone between poll and read
            pass
        if importing:
            break
        time.sleep(0.01)
    if proc.poll() is not None:
        pytest.skip("the command started and finished before the signal")
    assert importing, "pxr was not loaded within 60 s"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("humv-usd:") and "interrupted (Ctrl-C)" in lines[0], err
    assert not list(tmp_path.iterdir())


def test_progress_lines_when_stderr_is_a_log(monkeypatch, capsys):
    """Issue 26: compose printed nothing for 97 s when stderr was not a terminal. Lines come
    after PLAIN_AFTER_S and at most every PLAIN_EVERY_S; a captured stderr (a test runner,
    CliRunner) gets none."""
    from humv_usd.cli import common

    with common.progress_display("compose") as progress:
        assert progress is None  # pytest captures stderr: not the process's own
    clock = iter([0.0, 1.0, 6.0, 7.0, 9.5])
    monkeypatch.setattr(common.time, "monotonic", lambda: next(clock))
    callback = common._plain_lines("compose")  # started at t = 0
    for done in range(4):  # at t = 1 (too early), 6, 7 (too soon after 6), 9.5
        callback(done, 7, f"layer {done}")
    assert capsys.readouterr().err.splitlines() == [
        "humv-usd compose: [1/7] layer 1, 6.0 s",
        "humv-usd compose: [3/7] layer 3, 9.5 s",
    ]


def test_compose_onto_an_immutable_stage_is_one_line_before_any_write(tmp_path):
    """Was: the layers renamed into place, then a PermissionError traceback on stage.usda, a
    journal left behind (half-written)."""
    import shutil
    import subprocess

    out = tmp_path / "out"
    (out / "layers").mkdir(parents=True)
    (out / "stage.usda").write_text("#usda 1.0\n")
    (out / "layers" / "scene.usda").write_text("#usda 1.0\n")
    if not shutil.which("chattr") or subprocess.run(["chattr", "+i", str(out / "stage.usda")]).returncode:
        pytest.skip("no chattr +i on this file system")
    try:
        before = sorted(p.name for p in out.rglob("*"))
        result = CliRunner().invoke(main, ["compose", str(tmp_path / "none.toml"), "-o", str(out)])
        line = _one_line(result)
        assert line == (
            f"humv-usd: error: {out / 'stage.usda'}: read-only or immutable, and compose replaces it; "
            "make it writable (chmod u+w, chattr -i) or compose into another folder"
        )
        assert sorted(p.name for p in out.rglob("*")) == before
    finally:
        subprocess.run(["chattr", "-i", str(out / "stage.usda")])


def test_a_full_disk_during_compose_is_one_line(tmp_path, monkeypatch):
    import errno

    import humv_usd.pipeline.compose as compose_module

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "out" / "layers" / "x.usda"))

    monkeypatch.setattr(compose_module, "compose", full)
    from test_edit_thermal import SCENARIO

    scenario = tmp_path / "s.toml"
    scenario.write_text(SCENARIO)
    result = CliRunner().invoke(main, ["compose", str(scenario), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1 and "Traceback" not in result.output
    (line,) = result.output.strip().splitlines()
    assert line.endswith("x.usda: No space left on device; nothing was changed")


TWO_BODIES = """#usda 1.0
(
    defaultPrim = "root"
    endTimeCode = 0
    metersPerUnit = 1
    startTimeCode = 0
    upAxis = "Z"
)

def Xform "root"
{
    def Xform "World"
    {
        def Xform "Humans"
        {
            def Xform "p1"
            {
                def Xform "Body"
                {
                    custom string userProperties:blender:object_name = "Body"
                    def Mesh "Body"
                    {
                        int[] faceVertexCounts = [4]
                        int[] faceVertexIndices = [0, 1, 2, 3]
                        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]
                        custom string userProperties:blender:data_name = "Body"
                    }
                }
            }
            def Xform "p2"
            {
                def Xform "Body_001"
                {
                    custom string userProperties:blender:object_name = "Body.001"
                    def Mesh "Body_001"
                    {
                        int[] faceVertexCounts = [4]
                        int[] faceVertexIndices = [0, 1, 2, 3]
                        point3f[] points = [(2, 0, 0), (3, 0, 0), (3, 0, 1), (2, 0, 1)]
                        custom string userProperties:blender:data_name = "Body.001"
                    }
                }
            }
        }
    }
}
"""


def test_blenders_body_001_of_a_second_person_gets_its_name_and_labels_back(tmp_path):
    """Blender keeps names unique over the file: the second person's Body came back as Body_001,
    was not matched to the original, and lost its label (1,164 of 1,918 person pixels with the
    wrong material kind in the issue's render)."""
    from humv_usd.usd.adopt import adopt_blender_export
    from humv_usd.usd.layers import new_layer_stage
    from humv_usd.usd.mesh import define_mesh, label

    original = new_layer_stage(1.0, 1, "two people")
    for k, pid in enumerate(("p1", "p2"), start=1):
        quad = np.array([(2 * k - 2, 0, 0), (2 * k - 1, 0, 0), (2 * k - 1, 0, 1), (2 * k - 2, 0, 1)], float)
        label(
            define_mesh(original, f"/World/Humans/{pid}/Body", quad, [4], [0, 1, 2, 3]).GetPrim(),
            10 + k,
            "person",
        )
    export = Sdf.Layer.CreateAnonymous(".usda")
    export.ImportFromString(TWO_BODIES)
    layer, report = adopt_blender_export(export, original, fps=1.0, temperature_k=300.0)
    stage = Usd.Stage.Open(layer)
    assert not stage.GetPrimAtPath("/World/Humans/p2/Body_001")
    for k, pid in enumerate(("p1", "p2"), start=1):
        body = stage.GetPrimAtPath(f"/World/Humans/{pid}/Body")
        assert body and body.GetAttribute("humv:label:instanceId").Get() == 10 + k
        assert body.GetAttribute("humv:label:class").Get() == "person"
    assert report.restored == ["/World/Humans/p1/Body", "/World/Humans/p2/Body"]  # both matched


def _cube(stage, path, centre, size):
    """A closed cube mesh (6 quads)."""
    from humv_usd.usd.mesh import define_mesh

    c, h = np.asarray(centre, float), size / 2.0
    corners = np.array([[x, y, z] for z in (-h, h) for y in (-h, h) for x in (-h, h)]) + c
    quads = [0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5]
    define_mesh(stage, path, corners, [4] * 6, quads)


def test_a_camera_or_person_inside_an_asset_is_a_warning():
    """Boxes were warned about from the scenario; an asset enclosing camera and person was not."""
    from pxr import UsdGeom

    from humv_usd.usd.check import enclosed_in_scene_objects
    from humv_usd.usd.layers import new_layer_stage

    stage = new_layer_stage(1.0, 1, "enclosed")
    _cube(stage, "/World/Scene/hall/shell", (0.0, 0.0, 2.0), 10.0)  # an asset: a closed hall
    _cube(stage, "/World/Scene/crate/crate", (0.0, 0.0, 1.0), 3.0)  # a box: the scenario warns
    _cube(stage, "/World/Scene/kiosk/kiosk", (20.0, 0.0, 1.0), 2.0)  # encloses nothing
    UsdGeom.Xform.Define(stage, "/World/Humans/p1").AddTranslateOp().Set((1.0, 2.0, 0.0))
    cam = UsdGeom.Camera.Define(stage, "/World/Sensors/cam")
    cam.AddTranslateOp().Set((3.0, -4.0, 1.6))
    lines = enclosed_in_scene_objects(stage, skip={"crate"})
    assert [line.split(" is inside ")[0] for line in lines] == ["camera /World/Sensors/cam", "person p1"]
    assert all("scene object 'hall'" in line for line in lines)
    cam.GetPrim().GetAttribute("xformOp:translate").Set((3.0, -12.0, 1.6))  # outside the hall
    assert [line.split(" is inside ")[0] for line in enclosed_in_scene_objects(stage, skip={"crate"})] == [
        "person p1"
    ]


def test_a_scene_scope_blender_merged_away_comes_back():
    """Blender's importer merges an Xform with one child into that child's object: a scene whose
    only object is the ground came back as /World/Ground, and a crate added at the top of the
    outliner sat under an undefined /World/Scene (seen in a real bpy 5.0.1 round trip)."""
    from humv_usd.usd.adopt import adopt_blender_export
    from humv_usd.usd.layers import new_layer_stage
    from humv_usd.usd.mesh import define_mesh, label

    quad = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], float)
    original = new_layer_stage(1.0, 1, "ground only")
    label(define_mesh(original, "/World/Scene/Ground", quad, [4], [0, 1, 2, 3]).GetPrim(), 1, "ground")
    mesh = (
        "int[] faceVertexCounts = [4]\n int[] faceVertexIndices = [0, 1, 2, 3]\n"
        " point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]"
    )
    export = Sdf.Layer.CreateAnonymous(".usda")
    export.ImportFromString(
        '#usda 1.0\n(\n    defaultPrim = "root"\n)\ndef Xform "root"\n{\n'
        '    def Xform "crate"\n    {\n        def Mesh "Cube"\n        {\n' + mesh + "\n"
        '            custom string userProperties:blender:data_name = "Cube"\n        }\n    }\n'
        '    def Xform "World"\n    {\n        def Xform "Ground"\n        {\n'
        '            def Mesh "Ground"\n            {\n' + mesh + "\n            }\n        }\n    }\n}\n"
    )
    layer, report = adopt_blender_export(export, original, fps=1.0, temperature_k=300.0)
    stage = Usd.Stage.Open(layer)
    meshes = sorted(str(p.GetPath()) for p in stage.Traverse() if p.GetTypeName() == "Mesh")
    assert meshes == ["/World/Scene/Ground", "/World/Scene/crate"]
    assert stage.GetPrimAtPath("/World/Scene/Ground").GetAttribute("humv:label:class").Get() == "ground"
    assert "/World/Scene/Ground" in report.restored and "/World/Scene/crate" in report.new_meshes
