"""Weather at the frame times: constant from ``[atmosphere]`` or an hourly series (CSV).

``[atmosphere] weather_csv`` names a CSV file with a header row. Column ``time`` is a local ISO
8601 date-time (the scenario's ``utc_offset_h`` applies) or one with its own UTC offset; the other
columns are any of :data:`COLUMNS` (the ``[atmosphere]`` key names, same units and ranges). Columns
left out take the constant ``[atmosphere]`` value. Values are interpolated linearly in time (wind
direction through its east/north components, so 350 deg and 10 deg average to 0 deg, not 180);
frame times outside the series are an input error rather than an extrapolation.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from pathlib import Path

import numpy as np

from humv_usd.errors import InputError, bad_value
from humv_usd.physics.weather import COLUMNS, Weather
from humv_usd.scenario import Scenario
from humv_usd.scenario.spec import ATMOSPHERE
from humv_usd.scenario.times import frame_epoch_s


def _parse_time(text: str, tz: dt.timezone) -> float:
    t = dt.datetime.fromisoformat(text.strip())
    if t.tzinfo is None:
        t = t.replace(tzinfo=tz)
    return t.timestamp()


def read_weather_csv(path: str | Path, scenario: Scenario) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Read a weather series: (UTC POSIX times [s] (m,), {column: values (m,)}).

    Raises :class:`InputError` (one line per problem, naming ``atmosphere.weather_csv``, the row
    and column) on unknown columns, unparsable or out-of-range values, or times that do not
    increase.
    """
    where = "atmosphere.weather_csv"
    g = scenario["general"]
    tz = dt.timezone(dt.timedelta(hours=g["utc_offset_h"]))
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        raise InputError(bad_value(where, str(path), f"cannot read ({e.strerror})")) from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if len(rows) < 2:
        raise InputError(bad_value(where, str(path), "expected a header row and at least one data row"))
    header = [c.strip() for c in rows[0]]
    if "time" not in header:
        raise InputError(bad_value(where, str(path), "header needs a 'time' column"))
    problems = [
        bad_value(f"{where} column", c, "allowed columns: time, " + ", ".join(COLUMNS))
        for c in header
        if c != "time" and c not in COLUMNS
    ]
    if len(set(header)) != len(header):
        problems.append(bad_value(f"{where} header", ",".join(header), "columns must be unique"))
    if problems:
        raise InputError(problems[0], problems)
    times, values = [], {c: [] for c in header if c != "time"}
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            problems.append(bad_value(f"{where} line {n}", ",".join(row), f"expected {len(header)} fields"))
            continue
        for c, text in zip(header, row):
            if c == "time":
                try:
                    times.append(_parse_time(text, tz))
                except ValueError:
                    problems.append(
                        bad_value(
                            f"{where} line {n} time",
                            text,
                            "expected an ISO date-time, e.g. 2018-10-24T14:00:00",
                        )
                    )
                    times.append(math.nan)
                continue
            key = ATMOSPHERE.keys[c]
            try:
                v = float(text)
            except ValueError:
                v = math.nan
            if not (math.isfinite(v) and key.lo <= v <= key.hi):
                problems.append(
                    bad_value(f"{where} line {n} {c}", text, f"expected a number in {key.lo}..{key.hi}")
                )
            values[c].append(v)
    t = np.asarray(times, dtype=float)
    if not problems and np.any(np.diff(t) <= 0):
        problems.append(bad_value(f"{where} time", str(path), "times must strictly increase"))
    if problems:
        raise InputError(problems[0], problems)
    return t, {c: np.asarray(v, dtype=float) for c, v in values.items()}


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
