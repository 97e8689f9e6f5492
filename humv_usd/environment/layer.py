"""Environment tool: scenario/site metadata, weather, the sun and the moon → layers/environment.usda.

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

The sun and the sky are also UsdLux lights (a DistantLight and a DomeLight) for other USD tools;
the moon is a DistantLight /World/Environment/Moon (beam-normal illuminance [lx], PyEphem position
and phase per frame as ``humv:moon:*`` attributes, :func:`humv_usd.usd.environment.write_moon`),
which the render's night light reads (:mod:`humv_usd.render.nightlight`).
"""

from __future__ import annotations

import datetime as dt

import numpy as np
from pxr import Sdf

from humv_usd.environment.moon import MoonState, moon_at
from humv_usd.environment.sun import scenario_sun
from humv_usd.environment.weather import scenario_weather, with_diurnal_cycle
from humv_usd.physics import nightsky
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
    "atmosphere.cloud_size_m",  # broken clouds: the render's cloud shadows read it here
    "thermal.surface_spin_up_s",  # the spin-up window before frame 0 (negative time codes)
)
UPSTREAM = ()
VERSION = "7"  # 5: the sun and sky as UsdLux lights; 6: the moon (UsdLux + humv:moon:*); 7: cloudSize


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


def frame_moon(general: dict, frames_t: np.ndarray) -> tuple[MoonState, np.ndarray]:
    """The moon at the frame times ``frames_t`` [s after frame 0] and its clear-sky beam-normal
    illuminance [lx] (:func:`humv_usd.physics.nightsky.moon_illuminance_lux`). The UTC times
    are frame 0's local ISO time plus each offset, as the render's clock reads them from the
    stage (:func:`humv_usd.render.nightlight.frame_utc`); the refraction of the apparent
    altitude is PyEphem's standard atmosphere (1013.25 hPa, 15 degC)."""
    start = dt.datetime.fromisoformat(local_start_iso(general))
    utc = [(start + dt.timedelta(seconds=float(t))).astimezone(dt.UTC) for t in frames_t]
    moon = moon_at(general["latitude_deg"], general["longitude_deg"], general["elevation_m"], utc)
    lux = nightsky.moon_illuminance_lux(moon.elevation_deg, moon.phase_angle_deg, moon.distance_km)
    return moon, np.asarray(lux, dtype=float)


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
    E.write_cloud_size(env, float(scenario["atmosphere"].get("cloud_size_m") or 0.0))
    sun = scenario_sun(scenario, times, weather)
    if scenario.frame_count > 1 or spin_t.size:
        E.write_sun(env, sun, codes)
    else:
        E.write_sun(env, sun, codes[:1])
    # the same sun and sky as UsdLux lights for other USD tools (frames only, not the spin-up)
    E.write_lights(stage, sun, codes, range(spin_t.size, codes.size))
    # the moon at the frames (the render's night light reads it; not the spin-up)
    moon, moon_lux = frame_moon(g, frames_t)
    E.write_moon(stage, moon, moon_lux, codes[spin_t.size :])
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
        "moon": (
            "PyEphem (ELP 2000-82 as in Meeus 1998), illuminance USNO Circular 171 x Allen's phase "
            f"law x inverse square; above the horizon at {int((moon.elevation_deg > 0).sum())} of "
            f"{frames_t.size} samples, phase angle {float(moon.phase_angle_deg[0]):.1f} deg at frame 0"
        ),
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
