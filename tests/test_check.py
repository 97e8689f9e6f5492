"""check: USD validators and HumV layer rules find what is broken."""

from __future__ import annotations

import shutil

import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade, Vt

from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.usd.check import check_stage


@pytest.fixture
def out(tmp_path, raw):
    compose(validate(raw), tmp_path / "o")
    return tmp_path / "o"


def edit_layer(path, fn):
    layer = Sdf.Layer.FindOrOpen(str(path))
    stage = Usd.Stage.Open(layer)
    fn(stage)
    layer.Save()
    Sdf.Layer.Find(str(path)).Reload()


def test_clean(out):
    assert check_stage(out / "stage.usda") == []


def test_wrong_temperature_count_and_range(out):
    def broken(stage):
        prim = stage.GetPrimAtPath("/World/Scene/Ground")
        UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:thermal:temperature").Set(Vt.FloatArray([300.0] * 3))
        prim = stage.GetPrimAtPath("/World/Scene/warehouse")
        UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:thermal:temperature").Set(
            Vt.FloatArray([300.0] * 5 + [float("nan")])
        )

    edit_layer(out / "layers" / "thermal.usda", broken)
    found = check_stage(out / "stage.usda")
    # the thermal layer re-tessellates the ground along shadows: its composed face count
    thermal = Sdf.Layer.FindOrOpen(str(out / "layers" / "thermal.usda"))
    faces = len(thermal.GetAttributeAtPath("/World/Scene/Ground.faceVertexCounts").default)
    assert any(f"/World/Scene/Ground: 3 values for {faces} faces" in f for f in found)
    assert any("/World/Scene/warehouse: values" in f for f in found)


def test_missing_material_and_root_prims(out):
    (out / "layers" / "materials.usda").write_text("#usda 1.0\n")
    root = Sdf.Layer.FindOrOpen(str(out / "stage.usda"))
    Sdf.CreatePrimInLayer(root, "/Extra").specifier = Sdf.SpecifierDef
    root.Save()
    found = check_stage(out / "stage.usda")
    assert any(f.startswith("humv:rootLayer:") for f in found)
    assert any("/World/Scene/Ground: no bound material" in f for f in found)
    assert any(f.startswith("usd:") for f in found)  # USD's own binding validator fires too


def test_conventions(out):
    bad = out / "bad.usda"
    shutil.copy(out / "stage.usda", bad)
    layer = Sdf.Layer.FindOrOpen(str(bad))
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("metersPerUnit", 0.01)
    layer.Save()
    found = check_stage(bad)
    assert any("upAxis is Y" in f for f in found)
    assert any("metersPerUnit is 0.01" in f for f in found)


def _time_sampled_mesh_stage(samples: dict[float, list[float]]) -> Usd.Stage:
    """One triangle with a HumvMaterialAPI material and time-sampled per-face temperatures."""
    from humv_usd.usd import schemas as S
    from humv_usd.usd.mesh import define_mesh

    stage = Usd.Stage.CreateInMemory()
    material = UsdShade.Material.Define(stage, "/World/Materials/m").GetPrim()
    material.ApplyAPI(S.MATERIAL_API)
    material.GetAttribute(S.MATERIAL_WAVELENGTHS).Set(Vt.FloatArray([8.0, 12.0]))
    material.GetAttribute(S.MATERIAL_EMISSIVITY).Set(Vt.FloatArray([0.9, 0.9]))
    mesh = define_mesh(
        stage, "/World/Tri", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [3], [0, 1, 2], material.GetPath()
    )
    primvar = UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
        S.TEMPERATURE_PRIMVAR.removeprefix("primvars:"), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform
    )
    for time, values in samples.items():
        primvar.Set(Vt.FloatArray(values), time)
    return stage


def test_time_sampled_temperatures_are_checked_per_sample():
    """A multi-frame thermal layer (jos3/twoNode) has time samples: each is checked and named
    by its time (GetTimeSamples gives floats, not time codes: this crashed once)."""
    from humv_usd.usd.check import rule_meshes

    assert rule_meshes(_time_sampled_mesh_stage({0.0: [300.0], 1.0: [301.0], 2.0: [302.0]})) == []
    found = rule_meshes(_time_sampled_mesh_stage({0.0: [300.0], 1.0: [float("nan")], 2.0: [300.0, 1.0]}))
    assert len(found) == 2
    assert "/World/Tri at time 1.0: values nan..nan K outside 1..5000 K" in found[0]
    assert "/World/Tri at time 2.0: 2 values for 1 faces" in found[1]


def _skinned_triangle(points_samples: dict[float, list]) -> Usd.Stage:
    """A SkelRoot with a one-joint Skeleton and a skinned triangle whose points carry
    ``points_samples`` (time -> points) besides their default."""
    from pxr import Gf, UsdSkel

    stage = Usd.Stage.CreateInMemory()
    UsdSkel.Root.Define(stage, "/Rig")
    skel = UsdSkel.Skeleton.Define(stage, "/Rig/Skel")
    skel.CreateJointsAttr(["root"])
    skel.CreateBindTransformsAttr([Gf.Matrix4d(1)])
    skel.CreateRestTransformsAttr([Gf.Matrix4d(1)])
    mesh = UsdGeom.Mesh.Define(stage, "/Rig/Cloth")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2])
    for time, points in points_samples.items():
        mesh.GetPointsAttr().Set(points, time)
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    binding.CreateJointIndicesPrimvar(True, 1).Set([0])
    binding.CreateJointWeightsPrimvar(True, 1).Set([1.0])
    return stage


def test_skinned_mesh_with_time_sampled_points_is_a_finding():
    """Skinning ignores a skinned mesh's point samples: one finding naming the prim and the fix;
    a skinned mesh with rest points only is clean (and so is a composed stage with people and
    garments, plain point caches: test_clean)."""
    from humv_usd.usd.check import rule_skinned_points

    moving = {0.0: [(0, 0, 0), (1, 0, 0), (0, 1, 0)], 1.0: [(0, 0, 0.1), (1, 0, 0.1), (0, 1, 0.1)]}
    found = rule_skinned_points(_skinned_triangle(moving))
    assert len(found) == 1
    assert found[0].startswith("humv:skinnedPoints: /Rig/Cloth: skinned by /Rig/Skel")
    assert "2 samples" in found[0] and "fix:" in found[0]
    assert rule_skinned_points(_skinned_triangle({})) == []
    # without joint influences the samples are the motion (nothing skins it)
    stage = _skinned_triangle(moving)
    from pxr import UsdSkel

    UsdSkel.BindingAPI(stage.GetPrimAtPath("/Rig/Cloth")).GetJointIndicesPrimvar().GetAttr().Clear()
    assert rule_skinned_points(stage) == []


def test_a_layer_rewritten_on_disk_is_read_again_in_the_same_process(tmp_path):
    """A process that opened a folder and then sees it recomposed (tests, the editor's worker)
    checks and renders the files as they are now, not the layers still held in memory."""
    from humv_usd.usd.layers import open_stage

    sub = tmp_path / "sub.usda"
    root = tmp_path / "stage.usda"
    layer = Sdf.Layer.CreateNew(str(sub))
    prim = Sdf.PrimSpec(layer, "P", Sdf.SpecifierDef)
    Sdf.AttributeSpec(prim, "v", Sdf.ValueTypeNames.Int).default = 1
    layer.Save()
    top = Sdf.Layer.CreateNew(str(root))
    top.subLayerPaths.append("sub.usda")
    top.Save()
    held = open_stage(root)  # keeps the layers loaded
    assert held.GetPrimAtPath("/P").GetAttribute("v").Get() == 1
    # another writer replaces the file (compose's atomic rename)
    text = sub.read_text().replace("int v = 1", "int v = 2")
    assert "int v = 2" in text
    tmp = tmp_path / ".sub.tmp"
    tmp.write_text(text)
    tmp.replace(sub)
    assert open_stage(root).GetPrimAtPath("/P").GetAttribute("v").Get() == 2
