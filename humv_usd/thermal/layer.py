"""Thermal tool → layers/thermal.usda: per-face temperature [K] on every mesh of the stage.

Foundation placeholder (model "fixed"): skin at the scenario's uniform skin temperature, ground
and objects at their fixed temperatures, any other mesh (e.g. from a hand-made layer) at the air
temperature. The thermal issue replaces this with physiology, garment balance and slab models.
"""
from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from humv_usd.avatar.layer import body_path
from humv_usd.scenario import Scenario
from humv_usd.scene.layer import GROUND, object_path
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import finish, new_layer_stage

NAME = "thermal"
READS = ("general", "human", "scene", "thermal", "atmosphere")


def fixed_temperatures(scenario: Scenario) -> dict[Sdf.Path, float]:
    th = scenario["thermal"]
    temps = {body_path(h["id"]): th["skin_temperature_k"] for h in scenario["human"]}
    if scenario["scene"]:
        temps[GROUND] = scenario["scene"]["ground"]["temperature_k"]
        for o in scenario["scene"]["object"]:
            temps[object_path(o["id"])] = o["temperature_k"]
    return temps


def build(scenario: Scenario, upstream: Usd.Stage) -> Sdf.Layer:
    """Read the meshes of the composed ``upstream`` stage; write one temperature per face."""
    g = scenario["general"]
    air = (scenario["atmosphere"] or {}).get("air_temperature_k", 293.15)
    temps = fixed_temperatures(scenario)
    stage = new_layer_stage(g["fps"], scenario.frame_count,
                            "HumV-USD thermal layer: per-face temperatures (fixed model)")
    stage.RemovePrim("/World")  # this layer only adds opinions: overs, no defs
    for prim in upstream.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        faces = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [])
        over = stage.OverridePrim(prim.GetPath())
        over.ApplyAPI(S.THERMAL_API)
        over.GetAttribute(S.THERMAL_MODEL).Set("fixed")
        primvar = UsdGeom.PrimvarsAPI(over).CreatePrimvar(
            S.TEMPERATURE_PRIMVAR.removeprefix("primvars:"), Sdf.ValueTypeNames.FloatArray,
            UsdGeom.Tokens.uniform)
        value = temps.get(prim.GetPath(), air)
        primvar.Set(Vt.FloatArray.FromNumpy(np.full(faces, value, dtype=np.float32)))
    return finish(stage)
