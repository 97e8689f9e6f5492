"""Sensor tool: cameras with HumvSensorAPI → layers/sensors.usda."""
from __future__ import annotations

from pxr import Gf, Sdf, UsdGeom

from humv_usd.scenario import Scenario
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, look_at_matrix, finish, new_layer_stage

NAME = "sensors"
READS = ("general", "sensor")

# UsdGeom lens and filmback values are in tenths of a scene unit: on a metre stage 1 mm = 0.01.
_MM_TO_TENTHS_OF_M = 0.01


def sensor_path(sensor_id: str) -> Sdf.Path:
    return SCOPES["sensors"].AppendChild(sensor_id)


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    stage = new_layer_stage(g["fps"], scenario.frame_count, "HumV-USD sensors layer")
    UsdGeom.Scope.Define(stage, SCOPES["sensors"])
    for s in scenario["sensor"]:
        cam = UsdGeom.Camera.Define(stage, sensor_path(s["id"]))
        cam.AddTransformOp().Set(look_at_matrix(s["position_m"], s["look_at_m"]))
        width, height = s["resolution"]
        pitch_mm = s["pixel_pitch_um"] * 1e-3
        cam.CreateProjectionAttr(UsdGeom.Tokens.perspective)
        cam.CreateFocalLengthAttr(s["focal_length_mm"] * _MM_TO_TENTHS_OF_M)
        cam.CreateHorizontalApertureAttr(width * pitch_mm * _MM_TO_TENTHS_OF_M)
        cam.CreateVerticalApertureAttr(height * pitch_mm * _MM_TO_TENTHS_OF_M)
        cam.CreateFStopAttr(s["f_number"])
        cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, 1.0e5))
        prim = cam.GetPrim()
        prim.ApplyAPI(S.SENSOR_API)
        for attr, value in ((S.SENSOR_BAND, s["band"]),
                            (S.SENSOR_WAVELENGTH_RANGE, Gf.Vec2f(*s["wavelength_um"])),
                            (S.SENSOR_RESOLUTION, Gf.Vec2i(width, height)),
                            (S.SENSOR_PIXEL_PITCH, s["pixel_pitch_um"] * 1e-6),
                            (S.SENSOR_F_NUMBER, s["f_number"]), (S.SENSOR_NETD, s["netd_k"]),
                            (S.SENSOR_BIT_DEPTH, s["bit_depth"]), (S.SENSOR_GAIN, s["gain"]),
                            (S.SENSOR_OFFSET, s["offset"])):
            prim.GetAttribute(attr).Set(value)
    return finish(stage)
