"""Environment tool: scenario/site metadata, weather and the sun → layers/environment.usda.

Weather (:func:`humv_usd.environment.weather.weather_at`) is authored as default values when it
is constant and time-sampled when an hourly series makes it vary; the sun
(:func:`humv_usd.environment.sun.sun_at`) is time-sampled per frame (strided frames for very
long scenarios, see :func:`humv_usd.atmosphere.model.frame_times`; USD interpolates between).
"""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, UsdGeom

from humv_usd.environment.sun import sun_at
from humv_usd.environment.weather import COLUMNS, weather_at
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import CLOCK
from humv_usd.scenario.times import frame_times, local_start_iso
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, WORLD, finish, new_layer_stage

NAME = "environment"
READS = (
    "general.name",
    "general.description",
    *CLOCK,
    *(f"atmosphere.{k}" for k in COLUMNS),
    "atmosphere.weather_csv",
)
UPSTREAM = ()
VERSION = "1"

_WEATHER_ATTRS = (
    (S.ENVIRONMENT_AIR_TEMPERATURE, "air_temperature_k"),
    (S.ENVIRONMENT_RELATIVE_HUMIDITY, "relative_humidity"),
    (S.ENVIRONMENT_WIND_SPEED, "wind_speed_m_s"),
    (S.ENVIRONMENT_WIND_DIRECTION, "wind_direction_deg"),
    (S.ENVIRONMENT_PRESSURE, "pressure_pa"),
    (S.ENVIRONMENT_CLOUD_COVER, "cloud_cover"),
)


def _set(attr, values, codes, sampled: bool, convert=float):
    if sampled:
        for code, v in zip(codes, values):
            attr.Set(convert(v), float(code))
    else:
        attr.Set(convert(values[0]))


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, "HumV-USD environment layer: scenario, site, date/time, weather, sun"
    )
    world = stage.GetPrimAtPath(WORLD)
    world.ApplyAPI(S.SCENARIO_API)
    for attr, value in (
        (S.SCENARIO_NAME, g["name"]),
        (S.SCENARIO_DESCRIPTION, g["description"]),
        (S.SCENARIO_START_TIME, local_start_iso(g)),
        (S.SCENARIO_TIME_ZONE, g["time_zone"]),
        (S.SCENARIO_LATITUDE, g["latitude_deg"]),
        (S.SCENARIO_LONGITUDE, g["longitude_deg"]),
        (S.SCENARIO_ELEVATION, g["elevation_m"]),
        (S.SCENARIO_SEED, g["seed"]),
    ):
        world.GetAttribute(attr).Set(value)
    env = UsdGeom.Scope.Define(stage, SCOPES["environment"]).GetPrim()
    env.ApplyAPI(S.ENVIRONMENT_API)

    times = frame_times(scenario)
    codes = np.round(times * float(g["fps"]), 6)
    sampled = scenario.frame_count > 1
    weather = weather_at(scenario, times)
    for attr, key in _WEATHER_ATTRS:
        _set(env.GetAttribute(attr), getattr(weather, key), codes, weather.varies)
    sun = sun_at(scenario, times, weather)
    _set(
        env.GetAttribute(S.ENVIRONMENT_SUN_DIRECTION),
        sun.direction,
        codes,
        sampled,
        lambda d: Gf.Vec3f(*map(float, d)),
    )
    for attr, values in (
        (S.ENVIRONMENT_SUN_ZENITH, sun.zenith_deg),
        (S.ENVIRONMENT_SUN_AZIMUTH, sun.azimuth_deg),
        (S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE, sun.dni_w_m2),
        (S.ENVIRONMENT_DIFFUSE_HORIZONTAL_IRRADIANCE, sun.dhi_w_m2),
        (S.ENVIRONMENT_GLOBAL_HORIZONTAL_IRRADIANCE, sun.ghi_w_m2),
    ):
        _set(env.GetAttribute(attr), values, codes, sampled)
    n_up = int(sun.up.sum())
    ran = {
        "weather": (
            "hourly series " + str(scenario["atmosphere"].get("weather_csv"))
            if scenario["atmosphere"].get("weather_csv")
            else "constant [atmosphere]"
        ),
        "sun": (
            "NREL SPA (pvlib), Ineichen-Perez clear sky, Kasten-Czeplak clouds; "
            f"sun up at {n_up} of {sun.up.size} samples"
        ),
        "samples": f"{times.size} of {scenario.frame_count} frames",
    }
    stage.GetRootLayer().customLayerData = {"humv:environment:ran": ran}
    return finish(stage)
