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
from humv_usd.physics.weather import COLUMNS, Weather
from humv_usd.scenario import Scenario
from humv_usd.scenario.spec import ATMOSPHERE
from humv_usd.scenario.times import frame_epoch_s
from humv_usd.scenario.weather_csv import read_weather_csv


def weather_at(scenario: Scenario, times_s) -> Weather:
    """Weather at ``times_s`` seconds after frame 0.

    Parameters
    ----------
    scenario : Scenario
        Reads ``[atmosphere]`` (constants and ``weather_csv``) and ``[general]`` (start, offset).
    times_s : array-like (n,)
        Seconds after frame 0.

    Returns
    -------
    Weather
        (n,) arrays. Linear interpolation in time; wind direction via its components.
    """
    a = scenario["atmosphere"] or {}
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    const = {k: float(a.get(k, ATMOSPHERE.keys[k].default)) for k in COLUMNS}
    out = {k: np.full(t.shape, v) for k, v in const.items()}
    path = a.get("weather_csv")
    if path:
        ts, series = read_weather_csv(path, scenario)
        abs_t = frame_epoch_s(scenario) + t
        if len(t) and (abs_t.min() < ts[0] - 1e-6 or abs_t.max() > ts[-1] + 1e-6):
            first = dt.datetime.fromtimestamp(ts[0], dt.UTC).isoformat()
            last = dt.datetime.fromtimestamp(ts[-1], dt.UTC).isoformat()
            raise InputError(
                bad_value(
                    "atmosphere.weather_csv",
                    str(path),
                    f"series covers {first} .. {last} UTC, not every frame",
                )
            )
        for k, v in series.items():
            if k == "wind_direction_deg":
                rad = np.radians(v)
                e, n = np.interp(abs_t, ts, np.sin(rad)), np.interp(abs_t, ts, np.cos(rad))
                out[k] = np.degrees(np.arctan2(e, n)) % 360.0
            else:
                out[k] = np.interp(abs_t, ts, v)
    return Weather(**out)
