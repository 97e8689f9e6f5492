"""Weather at the frame times: constant from ``[atmosphere]`` or an hourly series (CSV).

``[atmosphere] weather_csv`` names a CSV file with a header row. Column ``time`` is a local ISO
8601 date-time (the scenario's ``utc_offset_h`` applies) or one with its own UTC offset; the other
columns are any of :data:`COLUMNS` (the ``[atmosphere]`` key names, same units and ranges). Columns
left out take the constant ``[atmosphere]`` value. Values are interpolated linearly in time (wind
direction through its east/north components, so 350 deg and 10 deg average to 0 deg, not 180);
frame times outside the series are an input error rather than an extrapolation.
"""

from __future__ import annotations

import datetime as dt

import numpy as np

from humv_usd.errors import InputError, bad_value
from humv_usd.physics.weather import (
    COLUMNS,
    Weather,
    diurnal_air_temperature,
    relative_humidity_at_constant_vapour_pressure,
)
from humv_usd.scenario import Scenario
from humv_usd.scenario.spec import ATMOSPHERE
from humv_usd.scenario.times import frame_epoch_s
from humv_usd.scenario.weather_csv import read_weather_csv


def scenario_weather(scenario: Scenario, times_s) -> Weather:
    """:func:`weather_at` for a scenario (the tools' thin build step): ``[atmosphere]``'s
    constants and ``weather_csv`` series (read with the scenario's UTC offset), frame 0 from
    ``[general]``, at ``times_s`` seconds after frame 0."""
    a = scenario["atmosphere"] or {}
    const = {k: float(a.get(k, ATMOSPHERE.keys[k].default)) for k in COLUMNS}
    path = a.get("weather_csv")
    series = read_weather_csv(path, scenario) if path else None
    return weather_at(frame_epoch_s(scenario), times_s, const, series, source=str(path) if path else None)


def weather_at(epoch_s: float, times_s, constants: dict, series=None, source: str | None = None) -> Weather:
    """Weather at times: constants, or a time series where it has a column.

    Parameters
    ----------
    epoch_s : float
        UTC POSIX time of frame 0 [s].
    times_s : array-like (n,)
        Seconds after frame 0.
    constants : dict
        A value per :data:`humv_usd.physics.weather.COLUMNS` name (the ``[atmosphere]`` keys,
        same units).
    series : (times [UTC POSIX s] (m,), {column: (m,) values}), optional
        A measured series (:func:`humv_usd.scenario.weather_csv.read_weather_csv`); its columns
        replace the constants. Times outside it are an InputError naming ``source``.
    source : str, optional
        Where the series comes from, for the error message.

    Returns
    -------
    Weather
        (n,) arrays. Linear interpolation in time; wind direction via its components.
    """
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    out = {k: np.full(t.shape, float(constants[k])) for k in COLUMNS}
    if series is not None:
        ts, columns = series
        abs_t = float(epoch_s) + t
        if len(t) and (abs_t.min() < ts[0] - 1e-6 or abs_t.max() > ts[-1] + 1e-6):
            first = dt.datetime.fromtimestamp(ts[0], dt.UTC).isoformat()
            last = dt.datetime.fromtimestamp(ts[-1], dt.UTC).isoformat()
            raise InputError(
                bad_value(
                    "atmosphere.weather_csv",
                    source,
                    f"series covers {first} .. {last} UTC, not every frame",
                )
            )
        for k, v in columns.items():
            if k == "wind_direction_deg":
                rad = np.radians(v)
                e, n = np.interp(abs_t, ts, np.sin(rad)), np.interp(abs_t, ts, np.cos(rad))
                out[k] = np.degrees(np.arctan2(e, n)) % 360.0
            else:
                out[k] = np.interp(abs_t, ts, v)
    return Weather(**out)


def solar_hours(scenario: Scenario, times_s) -> np.ndarray:
    """Local mean solar time [h, 0-24) at ``times_s`` seconds after frame 0: UTC plus
    longitude / 15 deg h^-1 (the equation of time, under 17 min, is left out)."""
    t = frame_epoch_s(scenario) + np.atleast_1d(np.asarray(times_s, dtype=float))
    lon = float(scenario["general"]["longitude_deg"])
    return ((t / 3600.0) + lon / 15.0) % 24.0


def with_diurnal_cycle(scenario: Scenario, times_s, weather: Weather, covered_from_s: float) -> Weather:
    """``weather`` with the air temperature and humidity of the times before ``covered_from_s``
    (the first time the scenario's data give: frame 0, or the first row of a weather series)
    following a diurnal cycle instead of holding that time's values.

    Temperature: :func:`humv_usd.physics.weather.diurnal_air_temperature` (Campbell & Norman
    1998 shape) of range ``[atmosphere] diurnal_range_k`` through the value at
    ``covered_from_s``; humidity: that time's vapour pressure held (constant dew point), so
    the relative humidity rises at night (capped at 1). Wind, pressure and clouds keep their
    held values. The slabs' spin-up (negative time codes) is the only user: frames are
    covered by the data.
    """
    r = float(
        (scenario["atmosphere"] or {}).get("diurnal_range_k", ATMOSPHERE.keys["diurnal_range_k"].default)
    )
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    before = t < covered_from_s - 1e-9
    if r == 0.0 or not before.any():
        return weather
    anchor = int(np.argmin(np.abs(t - covered_from_s)))
    t_anchor = float(weather.air_temperature_k[anchor])
    rh_anchor = float(weather.relative_humidity[anchor])
    hours = solar_hours(scenario, t[before])
    anchor_hour = float(solar_hours(scenario, [covered_from_s])[0])
    air = weather.air_temperature_k.copy()
    rh = weather.relative_humidity.copy()
    air[before] = diurnal_air_temperature(hours, anchor_hour, t_anchor, r)
    rh[before] = relative_humidity_at_constant_vapour_pressure(air[before], t_anchor, rh_anchor)
    out = {k: getattr(weather, k) for k in COLUMNS}
    out.update(air_temperature_k=air, relative_humidity=rh)
    return Weather(**out)
