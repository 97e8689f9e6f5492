"""Frame times of a scenario: frame 0's absolute time and the sample times of time-varying
quantities. Every tool that samples in time uses these, so their time samples line up."""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING

import numpy as np

#: most time samples a time-varying quantity gets (longer scenarios are strided)
MAX_TIME_SAMPLES = 500

if TYPE_CHECKING:
    from humv_usd.scenario.load import Scenario


def frame_times(scenario: Scenario) -> np.ndarray:
    """Times [s after frame 0] at which time-varying quantities are sampled: every frame, or
    evenly strided frames plus the last one when there are more than MAX_TIME_SAMPLES."""
    g = scenario["general"]
    n = scenario.frame_count
    stride = max(1, int(np.ceil(n / MAX_TIME_SAMPLES)))
    frames = np.unique(np.append(np.arange(0, n, stride), n - 1))
    return frames / float(g["fps"])


def frame_epoch_s(scenario: Scenario) -> float:
    """UTC POSIX time [s] of frame 0 (local ``general.start`` minus ``utc_offset_h``)."""
    g = scenario["general"]
    tz = dt.timezone(dt.timedelta(hours=g["utc_offset_h"]))
    return g["start"].replace(tzinfo=tz).timestamp()


def utc_times(scenario: Scenario, times_s):
    """pandas DatetimeIndex (UTC) of ``times_s`` seconds after frame 0."""
    import pandas as pd

    t = frame_epoch_s(scenario) + np.atleast_1d(np.asarray(times_s, dtype=float))
    return pd.to_datetime(t, unit="s", utc=True)


def local_start_iso(general: dict) -> str:
    """Frame 0 as an ISO 8601 local date-time with its UTC offset."""
    tz = dt.timezone(dt.timedelta(hours=general["utc_offset_h"]))
    return general["start"].replace(tzinfo=tz).isoformat()


#: step of the scene-surface spin-up before frame 0 [s]
SPIN_UP_STEP_S = 600.0


def spin_up_times(scenario: Scenario) -> np.ndarray:
    """Times [s after frame 0, < 0] of the scene-surface spin-up: ``[thermal] surface_spin_up_s``
    before frame 0 in :data:`SPIN_UP_STEP_S` steps (empty without a spin-up). The environment
    layer holds the weather and the sun at these times, and the thermal tool steps its slabs
    through them."""
    spin = float((scenario["thermal"] or {}).get("surface_spin_up_s", 0.0) or 0.0)
    return np.arange(-spin, 0.0, SPIN_UP_STEP_S) if spin > 0 else np.zeros(0)
