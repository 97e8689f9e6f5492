"""The hourly weather series of ``[atmosphere] weather_csv``: a CSV file with a header row.

Column ``time`` is a local ISO 8601 date-time (the scenario's ``utc_offset_h`` applies) or one
with its own UTC offset; the other columns are any of
:data:`humv_usd.physics.weather.COLUMNS` (the ``[atmosphere]`` key names, same units and ranges).
Reading and checking it is scenario input; the environment tool interpolates it
(:func:`humv_usd.environment.weather.weather_at`), the atmosphere tool takes its hours as weather
nodes.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from humv_usd.errors import InputError, bad_value
from humv_usd.physics.weather import COLUMNS
from humv_usd.scenario.spec import ATMOSPHERE

if TYPE_CHECKING:
    from humv_usd.scenario.load import Scenario


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
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        raise InputError(bad_value(where, str(path), f"cannot read ({e.strerror})")) from None
    except UnicodeDecodeError as e:
        raise InputError(
            bad_value(where, str(path), f"expected UTF-8 text (byte {e.start} is not UTF-8: {e.reason})")
        ) from None
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
