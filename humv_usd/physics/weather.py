"""The weather at n times as plain arrays: the shape the environment tool writes and
:mod:`humv_usd.usd.environment` reads back from the stage."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: weather quantities: Weather field = [atmosphere] key = weather CSV column
COLUMNS = (
    "air_temperature_k",
    "relative_humidity",
    "wind_speed_m_s",
    "wind_direction_deg",
    "pressure_pa",
    "cloud_cover",
)


@dataclass
class Weather:
    """Weather at n times; every field is an (n,) float array, SI units.

    air_temperature_k [K], relative_humidity [0-1], wind_speed_m_s [m/s], wind_direction_deg
    [deg, compass, direction the wind blows FROM], pressure_pa [Pa], cloud_cover [0-1].
    """

    air_temperature_k: np.ndarray
    relative_humidity: np.ndarray
    wind_speed_m_s: np.ndarray
    wind_direction_deg: np.ndarray
    pressure_pa: np.ndarray
    cloud_cover: np.ndarray

    def at(self, i: int) -> dict[str, float]:
        """The weather of sample i as a plain dict (keys = :data:`COLUMNS`)."""
        return {k: float(getattr(self, k)[i]) for k in COLUMNS}

    @property
    def varies(self) -> bool:
        """True when any quantity changes over the samples."""
        return any(np.ptp(getattr(self, k)) > 0 for k in COLUMNS if len(getattr(self, k)))
