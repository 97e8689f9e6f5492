"""The render's read of a stage (render.export, render.scene_export, render.frame) and the sensor
list reader (usd.sensor.stage_sensors), on small in-memory stages with closed-form answers."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

from humv_usd.errors import InputError
from humv_usd.render.export import StageExport
from humv_usd.render.scene_export import BACK_SIDE_OFFSET_M
from humv_usd.usd import schemas as S
from humv_usd.usd.sensor import stage_sensors


def _stage() -> Usd.Stage:
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.Xform.Define(stage, "/World")
    sky = UsdGeom.Scope.Define(stage, "/World/Atmosphere").GetPrim()
    sky.CreateAttribute(S.ATMOSPHERE_SKY_TEMPERATURE, Sdf.ValueTypeNames.Float).Set(250.0)
    return stage


def _camera(stage, path, api=False, sensor=True):
    prim = UsdGeom.Camera.Define(stage, path).GetPrim()
    if api:
        prim.ApplyAPI(S.SENSOR_API)
    if sensor:
        prim.CreateAttribute(S.SENSOR_WAVELENGTH_RANGE, Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(8.0, 12.0))
        prim.CreateAttribute(S.SENSOR_RESOLUTION, Sdf.ValueTypeNames.Int2).Set(Gf.Vec2i(8, 6))
    return prim


def _material(stage, name, eps):
    material = UsdShade.Material.Define(stage, f"/World/Materials/{name}")
    prim = material.GetPrim()
    prim.CreateAttribute(S.MATERIAL_WAVELENGTHS, Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray([1.0, 20.0])
    )
    prim.CreateAttribute(S.MATERIAL_EMISSIVITY, Sdf.ValueTypeNames.FloatArray).Set(Vt.FloatArray([eps, eps]))
    return material


def _plate(stage, path, points, counts, indices, material):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in points]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(indices))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)
    return mesh


SQUARE = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]  # counter-clockwise seen from +Z


def test_stage_sensors_are_the_cameras_with_sensor_attributes_in_stage_order():
    stage = _stage()
    _camera(stage, "/World/Sensors/a")  # attributes authored, no API applied
    _camera(stage, "/World/Sensors/plain", sensor=False)  # a camera, not a sensor
    _camera(stage, "/World/Sensors/b", api=True)
    assert [(s.name, s.path) for s in stage_sensors(stage)] == [
        ("a", "/World/Sensors/a"),
        ("b", "/World/Sensors/b"),
    ]
    assert [s.name for s in StageExport(stage).sensors] == ["a", "b"]
    _camera(stage, "/World/Other/a")
    with pytest.raises(InputError, match=r"/World/Other/a.*must be unique; /World/Sensors/a has it"):
        stage_sensors(stage)


def test_mirrored_double_sided_plate_gets_flipped_winding_and_a_back_copy_behind_its_front():
    """Scale x by -1 and lift by 2 m: the world points are the mirrored square at z = 2, the
    winding flips, and the back copy lies BACK_SIDE_OFFSET_M below (the front still faces +Z)."""
    stage = _stage()
    xf = UsdGeom.Xform.Define(stage, "/World/Scene/M")
    xf.AddTranslateOp().Set(Gf.Vec3d(0, 0, 2))
    xf.AddScaleOp().Set(Gf.Vec3f(-1, 1, 1))
    mesh = _plate(stage, "/World/Scene/M/Plate", SQUARE, [4], [0, 1, 2, 3], _material(stage, "a", 0.9))
    mesh.CreateDoubleSidedAttr(True)
    UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "humv:thermal:temperature", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.constant
    ).Set(Vt.FloatArray([310.0]))
    state = StageExport(stage).frame_state(0, [])
    path = "/World/Scene/M/Plate"
    front = np.array(SQUARE, float) * [-1, 1, 1] + [0, 0, 2]
    assert state.flip[path] is True
    assert_allclose(
        state.points[path], np.concatenate([front, front - [0, 0, BACK_SIDE_OFFSET_M]]), atol=1e-7
    )
    [info] = state.meshes
    assert info.double_sided and info.point_count == 4 and info.face_count == 1
    tris = info.parts[0].triangles
    assert tris.shape == (4, 3)  # 2 front + 2 back triangles
    assert_allclose(state.temperatures[path], [310.0])  # constant primvar: one per face
    assert np.isnan(state.sky_temperature_k)  # no infrared sensor asked for


def test_one_part_per_bound_material_subsets_first_with_the_ancestors_instance_id():
    stage = _stage()
    group = UsdGeom.Xform.Define(stage, "/World/Scene/G").GetPrim()
    group.CreateAttribute(S.LABEL_INSTANCE_ID, Sdf.ValueTypeNames.Int).Set(7)
    pts = SQUARE + [(2, 0, 0), (2, 1, 0)]
    mesh = _plate(
        stage, "/World/Scene/G/Two", pts, [4, 4], [0, 1, 2, 3, 1, 4, 5, 2], _material(stage, "a", 0.9)
    )
    binding = UsdShade.MaterialBindingAPI(mesh.GetPrim())
    subset = binding.CreateMaterialBindSubset("right", Vt.IntArray([1]), UsdGeom.Tokens.face)
    UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(_material(stage, "b", 0.5))
    info = StageExport(stage).frame_state(0, []).meshes[0]
    assert [p.material.path for p in info.parts] == ["/World/Materials/b", "/World/Materials/a"]
    assert [p.triangle_face.tolist() for p in info.parts] == [[1, 1], [0, 0]]
    assert [p.instance_id for p in info.parts] == [7, 7]
    assert info.parts[0].vertex_ids.tolist() == [1, 2, 4, 5]


def test_face_temperatures_are_required_only_for_infrared_sensors():
    stage = _stage()
    _plate(stage, "/World/Scene/P", SQUARE, [4], [0, 1, 2, 3], _material(stage, "a", 0.9))
    _camera(stage, "/World/Sensors/lwir")
    export = StageExport(stage)
    assert np.isnan(export.frame_state(0, []).temperatures["/World/Scene/P"]).all()
    with pytest.raises(InputError, match=r"/World/Scene/P\.primvars:humv:thermal:temperature"):
        export.frame_state(0, export.sensors)


def test_sky_temperature_out_of_range_names_the_attribute():
    stage = _stage()
    stage.GetPrimAtPath("/World/Atmosphere").GetAttribute(S.ATMOSPHERE_SKY_TEMPERATURE).Set(6000.0)
    _camera(stage, "/World/Sensors/lwir")
    export = StageExport(stage)
    assert np.isnan(export.frame_state(0, []).sky_temperature_k)  # EO only: not read
    with pytest.raises(InputError, match=r"/World/Atmosphere\.humv:atmosphere:skyTemperature.*1-5000 K"):
        export.frame_state(0, export.sensors)


@pytest.mark.parametrize("bad", [-1, 2**24])
def test_instance_id_out_of_range_names_the_prim_that_carries_it(bad):
    stage = _stage()
    group = UsdGeom.Xform.Define(stage, "/World/Scene/G").GetPrim()
    group.CreateAttribute(S.LABEL_INSTANCE_ID, Sdf.ValueTypeNames.Int).Set(bad)
    _plate(stage, "/World/Scene/G/P", SQUARE, [4], [0, 1, 2, 3], _material(stage, "a", 0.9))
    with pytest.raises(InputError, match=r"/World/Scene/G\.humv:label:instanceId.*0\.\.16777215"):
        StageExport(stage).frame_state(0, [])
