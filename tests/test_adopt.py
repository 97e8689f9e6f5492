"""``humv-usd adopt`` on a hand-written export in Blender's conventions (fast; the real Blender
round trip is tests/test_blender_interop.py).

The export mimics what bpy 5.0.1's ``wm.usd_export`` wrote for a composed stage: everything under
``/root``, object Xforms with their data prim as a child (the camera object renamed
``cam.001`` -> ``cam_001`` because another object took ``cam``), ``/root/_materials`` with a
Principled BSDF, ``primvars:humv_thermal_temperature``, ``userProperties:blender:*`` names,
custom properties as ``userProperties:<name>``, 24 time codes per second.
"""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from pxr import Sdf, Usd, UsdGeom, UsdShade

from humv_usd.catalog.materials import LIBRARY
from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.usd import schemas as S
from humv_usd.usd.adopt import BLENDER_PRIMVAR_NAMES, adopt_blender_export
from humv_usd.usd.check import check_stage
from humv_usd.usd.layers import SCOPES, new_layer_stage
from humv_usd.usd.materials import write_material
from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.thermal import write_surface_temperature

AIR_K = 290.0
QUAD = dict(points=[(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], counts=[4], indices=[0, 1, 2, 3])


def _original(path) -> None:
    """A small HumV stage: environment, a labelled box with time-sampled temperatures bound to
    concrete, a camera with HumvSensorAPI; 15 fps, frames 0-2."""
    stage = new_layer_stage(15.0, 3, "original")
    env = UsdGeom.Scope.Define(stage, SCOPES["environment"]).GetPrim()
    env.ApplyAPI(S.ENVIRONMENT_API)
    env.GetAttribute(S.ENVIRONMENT_AIR_TEMPERATURE).Set(AIR_K)
    write_material(stage, SCOPES["materials"].AppendChild("concrete"), LIBRARY["concrete"])
    box = define_mesh(
        stage,
        "/World/Scene/box",
        np.array(QUAD["points"], float),
        QUAD["counts"],
        QUAD["indices"],
        material=SCOPES["materials"].AppendChild("concrete"),
    ).GetPrim()
    label(box, 7, "building")
    write_surface_temperature(box, "slab", np.array([[300.0], [301.0], [302.0]]))
    cam = UsdGeom.Camera.Define(stage, "/World/Sensors/cam")
    cam.CreateHorizontalApertureAttr(1.088)
    cam.CreateVerticalApertureAttr(0.816)
    cam.GetPrim().ApplyAPI(S.SENSOR_API)
    cam.GetPrim().GetAttribute(S.SENSOR_BAND).Set("LWIR")
    stage.GetRootLayer().Export(str(path))


BLENDER_EXPORT = """#usda 1.0
(
    defaultPrim = "root"
    doc = "Blender v5.0.1"
    endTimeCode = 2
    metersPerUnit = 1
    startTimeCode = 0
    timeCodesPerSecond = 24
    upAxis = "Z"
)

def Xform "root"
{
    def Xform "World"
    {
        custom string userProperties:blender:object_name = "World"
        def Xform "Environment"
        {
            custom string userProperties:blender:object_name = "Environment"
        }
        def Xform "Scene"
        {
            def Xform "box"
            {
                custom string userProperties:blender:object_name = "box"
                def Mesh "box" (
                    prepend apiSchemas = ["MaterialBindingAPI"]
                )
                {
                    int[] faceVertexCounts = %(box_counts)s
                    int[] faceVertexIndices = %(box_indices)s
                    rel material:binding = </root/_materials/concrete>
                    point3f[] points = %(box_points)s
                    float[] primvars:humv_thermal_temperature = %(box_temps)s (
                        interpolation = "uniform"
                    )
                    custom string userProperties:blender:data_name = "box"
                }
            }
        }
        def Xform "Sensors"
        {
            def Xform "cam_001"
            {
                float3 xformOp:rotateXYZ = (90, 0, 0)
                double3 xformOp:translate = (0, -10, 1.5)
                uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
                custom string userProperties:blender:object_name = "cam.001"
                def Camera "cam"
                {
                    float focalLength = 0.25
                    float horizontalAperture = 3.6
                    float verticalAperture = 2.025
                    custom string userProperties:blender:data_name = "cam"
                }
            }
        }
    }
    def Xform "crate"
    {
        double3 xformOp:translate = (3, 0, 0.5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
        custom string userProperties:blender:object_name = "crate"
        %(crate_props)s
        def Mesh "Cube" (
            prepend apiSchemas = ["MaterialBindingAPI"]
        )
        {
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            rel material:binding = </root/_materials/%(crate_material)s>
            point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
            custom string userProperties:blender:data_name = "Cube"
        }
    }
    def Scope "_materials"
    {
        def Material "concrete"
        {
            token outputs:surface.connect = </root/_materials/concrete/Principled_BSDF.outputs:surface>
            def Shader "Principled_BSDF"
            {
                uniform token info:id = "UsdPreviewSurface"
                token outputs:surface
            }
        }
        def Material "%(crate_material)s"
        {
            token outputs:surface.connect = </root/_materials/%(crate_material)s/Principled_BSDF.outputs:surface>
            def Shader "Principled_BSDF"
            {
                uniform token info:id = "UsdPreviewSurface"
                token outputs:surface
            }
        }
    }
}
"""


def blender_export(path, crate_material="wood_001", crate_props="", box_quads=1) -> None:
    """The export text; ``box_quads`` > 1: the user subdivided the box (another topology)."""
    points = [(x, y, 0) for y in (0, 1) for x in range(box_quads + 1)]
    n = box_quads + 1
    indices = [i for q in range(box_quads) for i in (q, q + 1, n + q + 1, n + q)]
    path.write_text(
        BLENDER_EXPORT
        % dict(
            box_counts=[4] * box_quads,
            box_indices=indices,
            box_points=points,
            box_temps=[299.0] * box_quads,
            crate_material=crate_material,
            crate_props=crate_props,
        )
    )


@pytest.fixture
def files(tmp_path):
    _original(tmp_path / "original.usda")
    blender_export(
        tmp_path / "export.usda",
        crate_props='custom string userProperties:humv_class = "vehicle"\n'
        "        custom double userProperties:humv_temperature_k = 320",
    )
    return tmp_path


def _adopted(files, export="export.usda", **kw):
    original = Usd.Stage.Open(str(files / "original.usda"))
    layer, report = adopt_blender_export(Sdf.Layer.FindOrOpen(str(files / export)), original, **kw)
    return Usd.Stage.Open(layer), report


def test_blender_namespace_maps_back_to_ours(files):
    stage, report = _adopted(files)
    box = stage.GetPrimAtPath("/World/Scene/box")
    assert box.IsA(UsdGeom.Mesh) and not stage.GetPrimAtPath("/World/Scene/box/box")
    assert not stage.GetPrimAtPath("/root")
    material, _ = UsdShade.MaterialBindingAPI(box).ComputeBoundMaterial()
    assert material.GetPath() == "/World/Materials/concrete"
    source = material.GetSurfaceOutput().GetConnectedSources()[0][0].source.GetPath()
    assert source == "/World/Materials/concrete/Principled_BSDF"
    # the camera object was renamed cam.001 by Blender; the prim keeps the data's name
    cam = stage.GetPrimAtPath("/World/Sensors/cam")
    assert cam.IsA(UsdGeom.Camera)
    assert cam.GetAttribute("xformOp:translate").Get() == (0, -10, 1.5)
    assert UsdGeom.Camera(cam).GetFocalLengthAttr().Get() == pytest.approx(0.25)  # Blender's lens
    # objects at Blender's top level are scene objects
    assert stage.GetPrimAtPath("/World/Scene/crate").IsA(UsdGeom.Mesh)
    assert report.prims == 12  # World, 5 under it, the crate, Materials and 2 x (material, shader)
    assert BLENDER_PRIMVAR_NAMES["primvars:humv_thermal_temperature"] == S.TEMPERATURE_PRIMVAR
    assert not box.GetAttribute("primvars:humv_thermal_temperature")


def test_original_restores_what_blender_drops(files):
    stage, report = _adopted(files)
    box = stage.GetPrimAtPath("/World/Scene/box")
    assert box.HasAPI(S.LABEL_API) and box.GetAttribute(S.LABEL_INSTANCE_ID).Get() == 7
    assert box.GetAttribute(S.LABEL_CLASS).Get() == "building"
    temps = box.GetAttribute(S.TEMPERATURE_PRIMVAR)
    assert [list(temps.Get(f)) for f in range(3)] == [[300.0], [301.0], [302.0]]  # not Blender's 299
    assert box.GetAttribute(S.THERMAL_MODEL).Get() == "slab"
    cam = stage.GetPrimAtPath("/World/Sensors/cam")
    assert cam.HasAPI(S.SENSOR_API) and cam.GetAttribute(S.SENSOR_BAND).Get() == "LWIR"
    camera = UsdGeom.Camera(cam)  # the sensor's filmback, not Blender's 36 mm x 20.25 mm
    assert camera.GetHorizontalApertureAttr().Get() == pytest.approx(1.088)
    assert camera.GetVerticalApertureAttr().Get() == pytest.approx(0.816)
    env = stage.GetPrimAtPath("/World/Environment")
    assert env.GetTypeName() == "Scope" and env.GetAttribute(S.ENVIRONMENT_AIR_TEMPERATURE).Get() == AIR_K
    concrete = stage.GetPrimAtPath("/World/Materials/concrete")
    assert concrete.GetAttribute(S.MATERIAL_SOURCE).Get() == LIBRARY["concrete"].source
    assert report.materials == {"concrete": "original", "wood_001": "library"}
    layer = stage.GetRootLayer()
    assert (layer.timeCodesPerSecond, layer.framesPerSecond) == (15.0, 15.0)
    assert (layer.startTimeCode, layer.endTimeCode) == (0, 2)
    assert report.fps_source == "the original stage"
    assert report.static_export  # the hand-written export has no time samples; the original moves


def test_new_mesh_gets_library_material_label_and_held_temperature(files):
    stage, report = _adopted(files)
    crate = stage.GetPrimAtPath("/World/Scene/crate")
    wood = stage.GetPrimAtPath("/World/Materials/wood_001")  # Blender's wood.001
    assert wood.HasAPI(S.MATERIAL_API)
    assert wood.GetAttribute(S.MATERIAL_SOURCE).Get() == LIBRARY["wood"].source
    assert list(wood.GetAttribute(S.MATERIAL_EMISSIVITY).Get()) == pytest.approx(
        LIBRARY["wood"].spectrum_emissivity
    )
    assert crate.GetAttribute(S.LABEL_INSTANCE_ID).Get() == 8  # after the original's 7
    assert crate.GetAttribute(S.LABEL_CLASS).Get() == "vehicle"  # its custom property
    assert list(crate.GetAttribute(S.TEMPERATURE_PRIMVAR).Get()) == [320.0]
    assert crate.GetAttribute(S.THERMAL_MODEL).Get() == "fixed"
    assert report.new_meshes == {
        "/World/Scene/crate": {"temperature_k": 320.0, "instance_id": 8, "label_class": "vehicle"}
    }


def test_new_mesh_without_properties_takes_the_air_temperature(tmp_path):
    _original(tmp_path / "original.usda")
    blender_export(tmp_path / "export.usda", crate_material="concrete_001")
    stage, report = _adopted(tmp_path, label_class="prop")
    crate = stage.GetPrimAtPath("/World/Scene/crate")
    assert report.materials["concrete_001"] == "original"  # Blender's concrete.001: the original's
    assert list(crate.GetAttribute(S.TEMPERATURE_PRIMVAR).Get()) == [AIR_K]
    assert crate.GetAttribute(S.LABEL_CLASS).Get() == "prop"
    stage, _ = _adopted(tmp_path, temperature_k=280.0)
    assert list(stage.GetPrimAtPath("/World/Scene/crate").GetAttribute(S.TEMPERATURE_PRIMVAR).Get()) == [
        280.0
    ]


def test_changed_topology_keeps_blenders_values(files, caplog):
    blender_export(files / "subdivided.usda", box_quads=3)
    stage, report = _adopted(files, export="subdivided.usda")
    box = stage.GetPrimAtPath("/World/Scene/box")
    assert list(box.GetAttribute(S.TEMPERATURE_PRIMVAR).Get()) == [299.0] * 3
    assert box.GetAttribute(S.LABEL_INSTANCE_ID).Get() == 7  # non-primvar data still restored
    assert report.kept_blender_values == ["/World/Scene/box"]
    assert "faces or points differ" in caplog.text


def test_cli_writes_a_stage_that_passes_check(files):
    result = CliRunner().invoke(
        main,
        [
            "adopt",
            str(files / "export.usda"),
            "-o",
            str(files / "out"),
            "--from",
            str(files / "original.usda"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "1 library (wood_001)" in result.output and "new mesh /World/Scene/crate" in result.output
    root = Sdf.Layer.FindOrOpen(str(files / "out" / "stage.usda"))
    assert list(root.subLayerPaths) == ["./layers/adopted.usda"] and not root.rootPrims
    assert root.customLayerData["humv:adoptedFrom"] == str(files / "export.usda")
    assert check_stage(files / "out" / "stage.usda") == []


@pytest.mark.parametrize(
    ("material", "props", "expected"),
    [
        (
            "unobtainium",
            "",
            "/World/Materials/unobtainium = 'unobtainium': expected the name of a library material",
        ),
        (
            "wood",
            'custom string userProperties:humv_class = "dragon"',
            "userProperties:humv_class = 'dragon'",
        ),
        ("wood", "custom double userProperties:humv_temperature_k = -4", "/World/Scene/crate: temperature"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, material, props, expected):
    _original(tmp_path / "original.usda")
    blender_export(tmp_path / "export.usda", crate_material=material, crate_props=props)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main,
        ["adopt", str(tmp_path / "export.usda"), "-o", str(out), "--from", str(tmp_path / "original.usda")],
    )
    assert result.exit_code == 2
    assert expected in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_without_the_original_the_export_rate_is_kept_with_a_warning(files, caplog):
    layer, report = adopt_blender_export(
        Sdf.Layer.FindOrOpen(str(files / "export.usda")), None, temperature_k=290
    )
    assert report.fps == 24.0 and "frame rate 24 from the Blender export" in caplog.text
    stage = Usd.Stage.Open(layer)
    box = stage.GetPrimAtPath("/World/Scene/box")  # a new object now: id 1
    assert (box.GetAttribute(S.LABEL_INSTANCE_ID).Get(), box.GetAttribute(S.LABEL_CLASS).Get()) == (
        1,
        "other",
    )
    assert list(box.GetAttribute(S.TEMPERATURE_PRIMVAR).Get()) == [299.0]  # Blender's, renamed
    with pytest.raises(InputError, match="expected the name of a library material"):
        blender_export(files / "bad.usda", crate_material="unobtainium")
        adopt_blender_export(Sdf.Layer.FindOrOpen(str(files / "bad.usda")), None, temperature_k=290)


def _reroot(src: Sdf.Layer, root: str) -> Sdf.Layer:
    """The export as Blender writes it with ``root_prim_path=root`` ("" none, "/World")."""
    out = Sdf.Layer.CreateAnonymous("reroot.usda")
    out.timeCodesPerSecond = src.timeCodesPerSecond
    base = Sdf.Path(root) if root else Sdf.Path.absoluteRootPath
    if root:
        Sdf.CreatePrimInLayer(out, base).typeName = "Xform"
    for child in src.GetPrimAtPath("/root").nameChildren:
        Sdf.CreatePrimInLayer(out, base.AppendChild(child.name))
        Sdf.CopySpec(src, child.path, out, base.AppendChild(child.name))

    def fix(path):
        spec = out.GetObjectAtPath(path)
        move = lambda p: p.ReplacePrefix("/root", base)  # noqa: E731
        if isinstance(spec, Sdf.RelationshipSpec):
            spec.targetPathList.ModifyItemEdits(move)
        elif isinstance(spec, Sdf.AttributeSpec):
            spec.connectionPathList.ModifyItemEdits(move)

    out.Traverse(Sdf.Path.absoluteRootPath, fix)
    out.defaultPrim = "World"
    return out


@pytest.mark.parametrize("root", ["", "/World"])
def test_other_root_prim_paths(files, root):
    """Blender's ``root_prim_path`` "" (World and _materials at the top) or "/World" (a World
    root holding the exported World) map to the same stage."""
    original = Usd.Stage.Open(str(files / "original.usda"))
    layer, report = adopt_blender_export(
        _reroot(Sdf.Layer.FindOrOpen(str(files / "export.usda")), root), original
    )
    stage = Usd.Stage.Open(layer)
    assert not stage.GetPrimAtPath("/World/World")
    box = stage.GetPrimAtPath("/World/Scene/box")
    material, _ = UsdShade.MaterialBindingAPI(box).ComputeBoundMaterial()
    assert material.GetPath() == "/World/Materials/concrete" and material.GetPrim().HasAPI(S.MATERIAL_API)
    assert box.GetAttribute(S.LABEL_INSTANCE_ID).Get() == 7
    assert stage.GetPrimAtPath("/World/Scene/crate").GetAttribute(S.LABEL_CLASS).Get() == "vehicle"
    assert report.prims == 12


def test_adopt_never_writes_over_from_or_the_export(files):
    """Issue 26: ``-o`` the folder of ``--from`` overwrote the original stage."""
    orig = files / "orig"
    orig.mkdir()
    (orig / "stage.usda").write_bytes((files / "original.usda").read_bytes())
    before = {p: p.read_bytes() for p in files.rglob("*.usda")}
    (orig / "alias").symlink_to(orig)
    cases = [
        (orig, orig / "stage.usda"),  # OUT = ORIGINAL's folder
        (orig / "alias", orig / "stage.usda"),  # the same folder by another name
        (orig / "sub" / "..", orig / "stage.usda"),
        (files / "o2", files / "o2" / "stage.usda"),  # --from is the stage OUT would write
    ]
    for out, original in cases:
        result = CliRunner().invoke(
            main, ["adopt", str(files / "export.usda"), "-o", str(out), "--from", str(original)]
        )
        assert result.exit_code == 2, (out, result.output)
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and "--out" in lines[0] and "--from" in lines[0], result.output
    result = CliRunner().invoke(main, ["adopt", str(orig / "stage.usda"), "-o", str(orig)])
    assert result.exit_code == 2 and "BLENDER_EXPORT" in result.output
    assert {p: p.read_bytes() for p in files.rglob("*.usda")} == before
    assert not (orig / "layers").exists()


def test_a_humv_stage_as_the_export_is_one_line(files):
    """Issue 26: adopting a composed HumV stage ended in a Tf.ErrorException traceback."""
    stage = files / "humv" / "stage.usda"
    stage.parent.mkdir()
    stage.write_bytes((files / "original.usda").read_bytes())
    layer = Sdf.Layer.FindOrOpen(str(stage))
    layer.customLayerData = {"humv:layerKeys": {"layers/scene.usda": "0"}}
    layer.Save()
    result = CliRunner().invoke(main, ["adopt", str(stage), "-o", str(files / "out")])
    assert result.exit_code == 2 and "Traceback" not in result.output
    (line,) = result.output.strip().splitlines()
    assert "a HumV-USD stage" in line and not (files / "out").exists()


def test_a_temperature_property_that_is_a_string_is_one_line(tmp_path):
    _original(tmp_path / "original.usda")
    blender_export(
        tmp_path / "export.usda", crate_props='custom string userProperties:humv_temperature_k = "hot"'
    )
    result = CliRunner().invoke(
        main,
        [
            "adopt",
            str(tmp_path / "export.usda"),
            "-o",
            str(tmp_path / "out"),
            "--from",
            str(tmp_path / "original.usda"),
        ],
    )
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    (line,) = result.output.strip().splitlines()
    assert "humv_temperature_k" in line and "'hot'" in line
    assert not (tmp_path / "out").exists()
