"""Issue 27 deliverable 5: edits recompute what they change. A box moved in a user layer, a new
object a user layer references, a box moved and a crate added in a Blender export adopted with
``--scenario``: the ground's cool shadow patch follows (the thermal layer is rebuilt, its key sees
the user layers and the files they reference).

Closed form: on flat ground under the same sun a translated caster's shadow is the same patch
translated by the same vector, and an equal cube casts an equal shadow."""

from __future__ import annotations

import logging
import os
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade

from humv_usd.errors import InputError
from humv_usd.pipeline.adopt import adopt
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate

SCENARIO = """
[general]
name = "shadow"
start = 2018-06-21T12:00:00
utc_offset_h = -4.0
latitude_deg = 39.8
longitude_deg = -84.03
fps = 1.0
duration_s = 0.0
seed = 0

[scene.ground]
material = "concrete"
size_m = [7.0, 7.0]

[[scene.object]]
id = "box"
kind = "box"
class = "prop"
material = "painted_metal"
center_m = [0.0, 0.0, 0.0]
size_m = [1.0, 1.0, 1.0]
temperature_k = 300.0

[[sensor]]
id = "cam"
band = "LWIR"
resolution = [16, 12]
focal_length_mm = 10.0
position_m = [0.0, -10.0, 5.0]
look_at_m = [0.0, 0.0, 0.0]

[thermal]
model = "fixed"
surface_spin_up_s = 1800.0

[atmosphere]
model = "analytic"
"""

MOVE = """#usda 1.0
over "World"
{
    over "Scene"
    {
        over "box"
        {
            double3 xformOp:translate = (2, 0, 0)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }
    }
}
"""

#: a 1 m cube at (x0, 0, 0) (the material is bound where it is used: a reference cannot bind
#: outside itself)
CRATE = """#usda 1.0
(
    defaultPrim = "crate"
)
def Mesh "crate"
{
    int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]
    int[] faceVertexIndices = [0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6, 3, 0, 4, 7]
    point3f[] points = [(%(a)s, -0.5, 0), (%(b)s, -0.5, 0), (%(b)s, 0.5, 0), (%(a)s, 0.5, 0), (%(a)s, -0.5, 1), (%(b)s, -0.5, 1), (%(b)s, 0.5, 1), (%(a)s, 0.5, 1)]
    %(props)s
}
"""

PROPS = """#usda 1.0
over "World"
{
    over "Scene"
    {
        def "crate" (
            prepend apiSchemas = ["MaterialBindingAPI"]
            prepend references = @./crate.usda@
        )
        {
            rel material:binding = </World/Materials/painted_metal>
        }
    }
}
"""


def _crate(x0: float, props: str = "") -> str:
    return CRATE % {"a": x0 - 0.5, "b": x0 + 0.5, "props": props}


def shadows(stage_path) -> tuple[float, list[tuple[float, float, float]]]:
    """(lit ground temperature [K], [(area [m2], centroid x, y) of the cool patch on each side of
    x = 0.75]): ground faces more than 5 K below the lit ground's median."""
    stage = Usd.Stage.Open(str(stage_path))
    g = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Scene/Ground"))
    p = np.asarray(g.GetPointsAttr().Get(0), float)
    counts = np.asarray(g.GetFaceVertexCountsAttr().Get(0))
    idx = np.asarray(g.GetFaceVertexIndicesAttr().Get(0))
    t = np.asarray(g.GetPrim().GetAttribute("primvars:humv:thermal:temperature").Get(0), float)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    centroid = np.array([p[idx[s : s + n]].mean(0) for s, n in zip(starts, counts)])
    area = np.array(  # planar polygons: shoelace
        [
            0.5 * abs(np.dot(q[:, 0], np.roll(q[:, 1], -1)) - np.dot(q[:, 1], np.roll(q[:, 0], -1)))
            for q in (p[idx[s : s + n]] for s, n in zip(starts, counts))
        ]
    )
    lit = float(np.median(t))
    patches = []
    for side in (centroid[:, 0] < 0.75, centroid[:, 0] >= 0.75):
        cool = (t < lit - 5.0) & side
        if cool.any():
            w = area[cool]
            patches.append((float(w.sum()), *np.average(centroid[cool, :2], axis=0, weights=w)))
    return lit, patches


@pytest.fixture(scope="module")
def composed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("edit_thermal")
    (tmp / "shadow.toml").write_text(SCENARIO)
    scenario = validate(tomllib.loads(SCENARIO), tmp / "shadow.toml")
    compose(scenario, tmp / "orig")
    return tmp, scenario


def _with_user_layer(out, name: str) -> None:
    root = Sdf.Layer.FindOrOpen(str(out / "stage.usda"))
    root.subLayerPaths.insert(0, f"./{name}")
    root.Save()


def test_user_layers_that_move_or_add_objects_move_their_thermal_shadows(composed):
    tmp, scenario = composed
    lit, before = shadows(tmp / "orig" / "stage.usda")
    assert len(before) == 1  # the box's patch (its footprint and its shadow), left of x = 0.75
    area0, x0, y0 = before[0]
    assert 1.0 < area0 < 4.0 and lit > 300.0

    out = tmp / "user"
    shutil.copytree(tmp / "orig", out)
    # one user layer moves the box 2 m east; another references a file with a new 1 m crate
    (out / "move.usda").write_text(MOVE)
    (out / "crate.usda").write_text(_crate(-2.0))
    (out / "props.usda").write_text(PROPS)
    _with_user_layer(out, "move.usda")
    _with_user_layer(out, "props.usda")
    assert "thermal" in compose(scenario, out).rebuilt
    crate, box = shadows(out / "stage.usda")[1]
    assert box[0] == pytest.approx(area0, rel=0.05)
    assert box[1] == pytest.approx(x0 + 2.0, abs=0.05) and box[2] == pytest.approx(y0, abs=0.05)
    assert crate[0] == pytest.approx(area0, rel=0.15)  # an equal cube (a slab, not held: its faces differ)
    assert crate[1] == pytest.approx(x0 - 2.0, abs=0.1) and crate[2] == pytest.approx(y0, abs=0.1)
    # an edit of the referenced file alone (the user layers' text unchanged) rebuilds too
    (out / "crate.usda").write_text(_crate(-2.5))
    assert "thermal" in compose(scenario, out).rebuilt
    crate, _ = shadows(out / "stage.usda")[1]
    assert crate[1] == pytest.approx(x0 - 2.5, abs=0.1)


def _blender_edit(stage_path, export_path) -> None:
    """The composed stage as Blender round-trips it (root_prim_path "", flattened) with the box
    moved 2 m east and a new 1 m crate at x = -2 with a held temperature of 320 K."""
    layer = Usd.Stage.Open(str(stage_path)).Flatten()
    layer.customLayerData = {}
    stage = Usd.Stage.Open(layer)
    UsdGeom.Xformable(stage.GetPrimAtPath("/World/Scene/box")).AddTranslateOp().Set((2.0, 0.0, 0.0))
    crate = Sdf.Layer.CreateAnonymous(".usda")
    crate.ImportFromString(_crate(-2.0, "custom double userProperties:humv_temperature_k = 320"))
    Sdf.CopySpec(crate, "/crate", layer, "/World/Scene/crate")
    binding = UsdShade.MaterialBindingAPI.Apply(stage.GetPrimAtPath("/World/Scene/crate"))
    binding.Bind(UsdShade.Material(stage.GetPrimAtPath("/World/Materials/painted_metal")))
    layer.Export(str(export_path))


def test_adopt_with_the_scenario_recomputes_shadows_of_a_blender_edit(composed, caplog):
    tmp, scenario = composed
    _, ((area0, x0, y0),) = shadows(tmp / "orig" / "stage.usda")
    _blender_edit(tmp / "orig" / "stage.usda", tmp / "export.usda")

    with caplog.at_level(logging.WARNING):  # without the scenario: the stale shadow, with a warning
        stage, _ = adopt(tmp / "export.usda", tmp / "stale", tmp / "orig" / "stage.usda")
    assert "/World/Scene/box" in caplog.text and "/World/Scene/crate" in caplog.text
    assert "--scenario" in caplog.text
    _, stale = shadows(stage)
    assert len(stale) == 1 and stale[0][1] == pytest.approx(x0, abs=0.05)  # the stale patch

    stage, report = adopt(
        tmp / "export.usda", tmp / "adopted", tmp / "orig" / "stage.usda", scenario=scenario
    )
    assert (tmp / "adopted" / "layers" / "thermal.usda").is_file()
    crate, box = shadows(stage)[1]
    assert box[0] == pytest.approx(area0, rel=0.05)
    assert box[1] == pytest.approx(x0 + 2.0, abs=0.05) and box[2] == pytest.approx(y0, abs=0.05)
    assert crate[0] == pytest.approx(area0, rel=0.15) and crate[1] == pytest.approx(x0 - 2.0, abs=0.1)
    adopted = Usd.Stage.Open(str(stage))
    held = adopted.GetPrimAtPath("/World/Scene/crate").GetAttribute("primvars:humv:thermal:temperature")
    assert np.allclose(held.Get(0), 320.0)
    assert report.new_meshes["/World/Scene/crate"]["temperature_k"] == 320.0


def test_adopt_refuses_a_scenario_the_original_was_not_composed_from(composed):
    tmp, _ = composed
    _blender_edit(tmp / "orig" / "stage.usda", tmp / "export2.usda")
    other = validate(tomllib.loads(SCENARIO.replace("temperature_k = 300.0", "temperature_k = 301.0")))
    with pytest.raises(InputError, match=r"^--scenario = .*not the scenario --from was composed from"):
        adopt(tmp / "export2.usda", tmp / "wrong", tmp / "orig" / "stage.usda", scenario=other)
    assert not (tmp / "wrong" / "stage.usda").exists()


BLENDER_EDIT = """
import sys, bpy
stage, edited = sys.argv[1:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.usd_import(filepath=stage)
bpy.data.objects["p1"].location.x += 1.0
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-4.0, 0.0, 0.5))
cube = bpy.context.active_object
cube.name = "crate"
cube.data.materials.append(bpy.data.materials.new("wood"))
cube["humv_class"] = "prop"
cube["humv_temperature_k"] = 300.0
bpy.ops.wm.usd_export(filepath=edited, export_animation=True)
"""


def _patches(stage_path, cuts=(-3.0, 0.8)) -> dict:
    """{crate, p1, p2: (area [m2], centroid x, y) of the ground's faces more than 2 K below the
    lit ground's median, split at x = cuts}."""
    stage = Usd.Stage.Open(str(stage_path))
    g = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Scene/Ground"))
    p = np.asarray(g.GetPointsAttr().Get(0), float)
    counts = np.asarray(g.GetFaceVertexCountsAttr().Get(0))
    idx = np.asarray(g.GetFaceVertexIndicesAttr().Get(0))
    t = np.asarray(g.GetPrim().GetAttribute("primvars:humv:thermal:temperature").Get(0), float)
    polys = [p[idx[s : s + n]] for s, n in zip(np.r_[0, np.cumsum(counts)[:-1]], counts)]
    centroid = np.array([q.mean(0) for q in polys])
    area = np.array(
        [
            0.5 * abs(np.dot(q[:, 0], np.roll(q[:, 1], -1)) - np.dot(q[:, 1], np.roll(q[:, 0], -1)))
            for q in polys
        ]
    )
    cool = t < np.median(t) - 2.0
    x = centroid[:, 0]
    out = {}
    for name, side in (("crate", x < cuts[0]), ("p1", (x >= cuts[0]) & (x < cuts[1])), ("p2", x >= cuts[1])):
        sel = cool & side
        out[name] = (
            (float(area[sel].sum()), *np.average(centroid[sel, :2], axis=0, weights=area[sel]))
            if sel.any()
            else None
        )
    return out


@pytest.mark.extended
def test_a_real_blender_edit_of_two_people_adopted_with_the_scenario(tmp_path):
    """The issue's edit in bpy 5.0.1 (examples/walk.toml's site with two people standing 30 min,
    a slab ground, p1 moved 1 m east, a 1 m crate added): adopted with --scenario, p1's cool
    patch moves 1 m, p2's stays, the crate casts one; Blender's renames (Body.001, the merged
    scene scope) come back."""
    import copy
    import subprocess
    import sys

    pytest.importorskip("bpy")
    import tomlkit

    root = Path(__file__).resolve().parents[1]
    raw = tomllib.loads((root / "examples" / "walk.toml").read_text())
    raw["general"].update(duration_s=0.0, start=raw["general"]["start"].replace(hour=12, minute=30))
    raw["thermal"] = {"model": "fixed", "surface_spin_up_s": 3600.0}
    raw["atmosphere"] = {"model": "analytic"}
    raw["scene"]["ground"].pop("temperature_k")
    raw["scene"]["ground"]["size_m"] = [12.0, 12.0]
    raw["scene"]["object"] = []
    raw["sensor"][0]["resolution"] = [64, 48]
    p2 = copy.deepcopy(raw["human"][0])
    p2.update(id="p2", sex="female")
    raw["human"].append(p2)
    raw["placement"][0].update(position_m=[-1.5, 0.0, 0.0], standing_before_s=1800.0)
    raw["placement"].append(
        {"human": "p2", "position_m": [2.0, 1.0, 0.0], "heading_deg": 270.0, "standing_before_s": 1800.0}
    )
    (tmp_path / "two.toml").write_text(tomlkit.dumps(raw))
    scenario = validate(raw, tmp_path / "two.toml")
    compose(scenario, tmp_path / "out")
    env = dict(os.environ, BLENDER_USER_CONFIG=str(tmp_path / "bu"))
    run = subprocess.run(
        [
            sys.executable,
            "-c",
            BLENDER_EDIT,
            str(tmp_path / "out" / "stage.usda"),
            str(tmp_path / "edited.usda"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    stage, report = adopt(
        tmp_path / "edited.usda", tmp_path / "adopted", tmp_path / "out" / "stage.usda", scenario=scenario
    )
    before, after = _patches(tmp_path / "out" / "stage.usda"), _patches(stage)
    print("before", before, "after", after)
    assert before["crate"] is None and after["crate"] is not None and after["crate"][0] > 1.0
    assert after["p1"][1] - before["p1"][1] == pytest.approx(1.0, abs=0.1)
    assert after["p1"][2] == pytest.approx(before["p1"][2], abs=0.1)
    assert after["p2"][1:] == pytest.approx(before["p2"][1:], abs=0.02)
    assert after["p1"][0] == pytest.approx(before["p1"][0], rel=0.15)
    adopted = Usd.Stage.Open(str(stage))
    assert adopted.GetPrimAtPath("/World/Humans/p2/Body") and not adopted.GetPrimAtPath(
        "/World/Humans/p2/Body_001"
    )
    assert adopted.GetPrimAtPath("/World/Scene/Ground") and "/World/Scene/crate" in report.new_meshes
