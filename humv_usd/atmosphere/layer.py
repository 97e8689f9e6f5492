"""Atmosphere tool: sky model → layers/atmosphere.usda.

Foundation placeholder: the analytic clear sky of Berdahl & Martin (1984) gives one effective
sky temperature; LOWTRAN7 band radiance by zenith angle comes with the atmosphere issue.
"""
from __future__ import annotations

from pxr import Sdf, UsdGeom

from humv_usd.physics.sky import effective_sky_temperature
from humv_usd.scenario import Scenario
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage

NAME = "atmosphere"
READS = ("general", "atmosphere")


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g, a = scenario["general"], scenario["atmosphere"]
    stage = new_layer_stage(g["fps"], scenario.frame_count,
                            "HumV-USD atmosphere layer: analytic clear sky (Berdahl-Martin 1984)")
    prim = UsdGeom.Scope.Define(stage, SCOPES["atmosphere"]).GetPrim()
    prim.ApplyAPI(S.ATMOSPHERE_API)
    t_sky, eps = effective_sky_temperature(a["air_temperature_k"], a["relative_humidity"])
    prim.GetAttribute(S.ATMOSPHERE_MODEL).Set(a["model"])
    prim.GetAttribute(S.ATMOSPHERE_PROFILE).Set(a["profile"])
    prim.GetAttribute(S.ATMOSPHERE_VISIBILITY).Set(a["visibility_km"] * 1000.0)
    prim.GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY).Set(round(float(eps), 6))
    prim.GetAttribute(S.ATMOSPHERE_SKY_TEMPERATURE).Set(round(float(t_sky), 4))
    return finish(stage)
