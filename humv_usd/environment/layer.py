"""Environment tool: scenario/site metadata and weather → layers/environment.usda."""
from __future__ import annotations

import datetime as dt

from pxr import Sdf, UsdGeom

from humv_usd.scenario import Scenario
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, WORLD, finish, new_layer_stage

NAME = "environment"
READS = ("general", "atmosphere")


def local_start_iso(general: dict) -> str:
    """Frame 0 as an ISO 8601 local date-time with its UTC offset."""
    tz = dt.timezone(dt.timedelta(hours=general["utc_offset_h"]))
    return general["start"].replace(tzinfo=tz).isoformat()


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g, a = scenario["general"], scenario["atmosphere"] or {}
    stage = new_layer_stage(g["fps"], scenario.frame_count,
                            "HumV-USD environment layer: scenario, site, date/time, weather")
    world = stage.GetPrimAtPath(WORLD)
    world.ApplyAPI(S.SCENARIO_API)
    for attr, value in ((S.SCENARIO_NAME, g["name"]), (S.SCENARIO_DESCRIPTION, g["description"]),
                        (S.SCENARIO_START_TIME, local_start_iso(g)),
                        (S.SCENARIO_TIME_ZONE, g["time_zone"]),
                        (S.SCENARIO_LATITUDE, g["latitude_deg"]),
                        (S.SCENARIO_LONGITUDE, g["longitude_deg"]),
                        (S.SCENARIO_ELEVATION, g["elevation_m"]), (S.SCENARIO_SEED, g["seed"])):
        world.GetAttribute(attr).Set(value)
    env = UsdGeom.Scope.Define(stage, SCOPES["environment"]).GetPrim()
    env.ApplyAPI(S.ENVIRONMENT_API)
    if a:
        for attr, key in ((S.ENVIRONMENT_AIR_TEMPERATURE, "air_temperature_k"),
                          (S.ENVIRONMENT_RELATIVE_HUMIDITY, "relative_humidity"),
                          (S.ENVIRONMENT_WIND_SPEED, "wind_speed_m_s"),
                          (S.ENVIRONMENT_WIND_DIRECTION, "wind_direction_deg"),
                          (S.ENVIRONMENT_PRESSURE, "pressure_pa"),
                          (S.ENVIRONMENT_CLOUD_COVER, "cloud_cover")):
            env.GetAttribute(attr).Set(a[key])
    return finish(stage)
