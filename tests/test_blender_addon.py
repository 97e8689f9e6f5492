"""The Blender add-on: zip, install, enable, build the avatar layer, import it (bpy, headless).

Blender runs in a separate process of the venv's Python (``import bpy``), so its state does not
leak into the test session, with every Blender user folder (scripts, config, …) in a temporary
folder so that installing the add-on does not touch the machine's Blender set-up.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import time
import zipfile

import pytest
from conftest import ROOT
from pxr import Usd

from humv_usd.usd import schemas as S

# find_spec, not importorskip: bpy is never imported into the test session itself
pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("bpy") is None,
    reason="needs Blender as a Python module: pip install '.[blender]'",
)

SCRIPT = textwrap.dedent("""
    import json, sys
    import bpy

    zip_path, out_path, bad_path, user_dir = sys.argv[1:5]
    result = {}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.preferences.addon_install(filepath=zip_path)
    bpy.ops.preferences.addon_enable(module="humv_usd_avatar")
    import humv_usd_avatar
    result["installed_at"] = humv_usd_avatar.__file__
    result["panel"] = hasattr(bpy.types, "HUMV_PT_avatar")

    s = bpy.context.scene.humv_avatar
    s.sex, s.age_yr, s.stature_m, s.mass_kg = "female", 41.0, 1.62, 58.0
    s.build, s.activity, s.fps, s.duration_s = "slim", "walk", 15.0, 2.0

    def run():
        try:
            return sorted(bpy.ops.humv.build_avatar_layer()), ""
        except RuntimeError as exc:        # an operator's error reports
            return ["ERROR"], str(exc)

    # humv_usd not importable -> a clear error, nothing written
    sys.modules["humv_usd"] = None
    s.output_path = out_path
    result["no_package"] = run()
    del sys.modules["humv_usd"]

    # bad values -> the validator's lines with the panel's labels, nothing written
    s.output_path, s.stature_m = bad_path, 3.0
    result["bad"] = run()
    s.output_path, s.stature_m = out_path, 1.62

    result["objects_before"] = len(bpy.data.objects)
    result["ok"] = run()
    result["objects"] = sorted((o.name, o.type) for o in bpy.data.objects)
    result["frame_range"] = [bpy.context.scene.frame_start, bpy.context.scene.frame_end]
    result["fps"] = bpy.context.scene.render.fps / bpy.context.scene.render.fps_base
    print("RESULT " + json.dumps(result))
""")

BLENDER_USER_VARS = (
    "BLENDER_USER_RESOURCES",
    "BLENDER_USER_SCRIPTS",
    "BLENDER_USER_CONFIG",
    "BLENDER_USER_DATAFILES",
    "BLENDER_USER_EXTENSIONS",
)


@pytest.mark.slow
def test_addon_installs_builds_and_imports_the_avatar(tmp_path):
    start = time.perf_counter()
    zip_path = tmp_path / "dist" / "humv_usd_avatar.zip"
    subprocess.run(
        [sys.executable, str(ROOT / "tools" / "build_blender_addon.py"), "-o", str(zip_path)],
        check=True,
        capture_output=True,
        text=True,
    )
    with zipfile.ZipFile(zip_path) as zf:
        assert "humv_usd_avatar/__init__.py" in zf.namelist()

    user = tmp_path / "blender_user"
    env = dict(os.environ, **{var: str(user / var.rsplit("_", 1)[-1].lower()) for var in BLENDER_USER_VARS})
    out = tmp_path / "layers" / "anna.usda"
    bad = tmp_path / "layers" / "anna.txt"
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(zip_path), str(out), str(bad), str(user)],
        env=env,
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    result = json.loads(line.removeprefix("RESULT "))

    # installed into the temporary user scripts folder, panel registered
    assert result["installed_at"].startswith(str(user))
    assert result["panel"]

    status, message = result["no_package"]
    assert status == ["ERROR"] and "cannot import humv_usd" in message
    status, message = result["bad"]
    assert status == ["ERROR"]
    assert "Stature = 3.0: allowed range 0.7..2.3" in message
    assert "Output Path = " in message and "ending in .usda" in message
    assert not bad.exists()

    # the layer: written, opens with USD, the requested person
    assert result["ok"] == [["FINISHED"], ""]
    stage = Usd.Stage.Open(str(out))
    prim = stage.GetPrimAtPath("/World/Humans/p1")
    assert prim.HasAPI(S.AVATAR_API)
    assert prim.GetAttribute(S.AVATAR_STATURE).Get() == pytest.approx(1.62)
    assert prim.GetAttribute(S.AVATAR_ACTIVITY).Get() == "walk"

    # imported into the Blender scene: a mesh (and, once the avatar is rigged, an armature)
    assert result["objects_before"] == 0
    assert {kind for _, kind in result["objects"]} & {"MESH", "ARMATURE"}
    assert result["frame_range"] == [0, 30]
    assert result["fps"] == pytest.approx(15.0)
    assert time.perf_counter() - start < 60
