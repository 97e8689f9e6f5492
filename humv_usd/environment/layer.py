"""Environment tool: scenario/site metadata, weather and the sun → layers/environment.usda.

The one place that computes the weather (:func:`humv_usd.environment.weather.weather_at`) and
the sun (:func:`humv_usd.environment.sun.sun_at`); every other tool and the render read them back
through :mod:`humv_usd.usd.environment`. Weather is authored as default values when it is constant
and time-sampled when an hourly series makes it vary; the sun is time-sampled per frame (strided
frames for very long scenarios, see :func:`humv_usd.scenario.times.frame_times`; USD interpolates
between).

The layer also holds the weather and the sun of the thermal tool's scene-surface spin-up, at
negative time codes (``[thermal] surface_spin_up_s`` before frame 0 in 10-minute steps,
:func:`humv_usd.scenario.times.spin_up_times`). Before the weather data start (frame 0 for a
constant weather, the first row of an hourly series) the spin-up's air temperature follows a
diurnal cycle of range ``[atmosphere] diurnal_range_k`` through the first known value
(Campbell & Norman 1998 shape, dew point held: :func:`humv_usd.environment.weather.with_diurnal_cycle`);
wind, pressure and clouds hold the first known values; the sun follows the clock. Readers at frames >= 0 (the
render) see the same values as without these samples.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf

from humv_usd.environment.sun import scenario_sun
from humv_usd.environment.weather import scenario_weather, with_diurnal_cycle
from humv_usd.physics.weather import COLUMNS
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import CLOCK
from humv_usd.scenario.times import frame_epoch_s, frame_times, local_start_iso, spin_up_times
from humv_usd.scenario.weather_csv import read_weather_csv
from humv_usd.usd import environment as E
from humv_usd.usd.layers import finish, new_layer_stage

NAME = "environment"
READS = (
    "general.name",
    "general.description",
    *CLOCK,
    *(f"atmosphere.{k}" for k in COLUMNS),
    "atmosphere.weather_csv",
    "atmosphere.diurnal_range_k",  # the spin-up's diurnal cycle before the data start
    "thermal.surface_spin_up_s",  # the spin-up window before frame 0 (negative time codes)
)
UPSTREAM = ()
VERSION = "5"  # 5: the sun and sky as UsdLux lights


def _covered_from(scenario: Scenario) -> float:
    """First time [s after frame 0] the scenario's weather data give: frame 0, or the first
    row of an hourly series that starts before it."""
    path = (scenario["atmosphere"] or {}).get("weather_csv")
    if not path:
        return 0.0
    ts, _ = read_weather_csv(path, scenario)
    return min(0.0, float(ts[0] - frame_epoch_s(scenario)))


def _weather_times(scenario: Scenario, times_s: np.ndarray) -> np.ndarray:
    """Times at which to evaluate the weather: spin-up times before an hourly series starts take
    its first row (the series must cover the frames, not the spin-up day)."""
    path = (scenario["atmosphere"] or {}).get("weather_csv")
    if not path:
        return times_s
    ts, _ = read_weather_csv(path, scenario)
    t0 = frame_epoch_s(scenario)
    return np.where(times_s < 0.0, np.clip(times_s, ts[0] - t0, ts[-1] - t0), times_s)


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, "HumV-USD environment layer: scenario, site, date/time, weather, sun"
    )
    E.write_site(
        stage,
        E.Site(
            name=g["name"],
            description=g["description"],
            start_time=local_start_iso(g),
            time_zone=g["time_zone"],
            latitude_deg=g["latitude_deg"],
            longitude_deg=g["longitude_deg"],
            elevation_m=g["elevation_m"],
            seed=g["seed"],
        ),
    )
    env = E.define_environment(stage)

    frames_t = frame_times(scenario)
    spin_t = spin_up_times(scenario)
    times = np.concatenate([spin_t, frames_t])
    codes = np.round(times * float(g["fps"]), 6)
    weather = scenario_weather(scenario, _weather_times(scenario, times))
    covered = _covered_from(scenario)
    weather = with_diurnal_cycle(scenario, times, weather, covered)
    E.write_weather(env, weather, codes)
    sun = scenario_sun(scenario, times, weather)
    if scenario.frame_count > 1 or spin_t.size:
        E.write_sun(env, sun, codes)
    else:
        E.write_sun(env, sun, codes[:1])
    # the same sun and sky as UsdLux lights for other USD tools (frames only, not the spin-up)
    E.write_lights(stage, sun, codes, range(spin_t.size, codes.size))
    n_up = int(sun.up[spin_t.size :].sum())
    ran = {
        "weather": (
            "hourly series " + str(scenario["atmosphere"].get("weather_csv"))
            if scenario["atmosphere"].get("weather_csv")
            else "constant [atmosphere]"
        ),
        "sun": (
            "NREL SPA (pvlib), Ineichen-Perez clear sky, Kasten-Czeplak clouds; "
            f"sun up at {n_up} of {frames_t.size} samples"
        ),
        "samples": f"{frames_t.size} of {scenario.frame_count} frames",
    }
    if spin_t.size:
        ran["spinUp"] = (
            f"{spin_t.size} samples at negative time codes {codes[0]:g} .. {codes[spin_t.size - 1]:g} "
            f"(thermal.surface_spin_up_s = {-spin_t[0]:g} s, 600 s steps)"
        )
        r = float(scenario["atmosphere"].get("diurnal_range_k", 0.0) or 0.0)
        if r > 0 and spin_t[0] < covered - 1e-9:
            ran["spinUpWeather"] = (
                f"diurnal cycle of {r:g} K range (Campbell & Norman 1998) through the weather at "
                f"{covered:g} s, dew point held"
            )
    stage.GetRootLayer().customLayerData = {"humv:environment:ran": ran}
    return finish(stage)
