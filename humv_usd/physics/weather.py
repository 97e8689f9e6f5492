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


def campbell_norman_shape(solar_hour):
    """Shape of the diurnal air-temperature cycle, Gamma(t) in [0, 1] (Campbell & Norman 1998).

    Parameters
    ----------
    solar_hour : numeric
        Local solar time [h]; periodic with 24 h.

    Returns
    -------
    numeric
        Gamma(t) = 0.44 - 0.46 sin(omega t + 0.9) + 0.11 sin(2 omega t + 0.9), omega = pi/12
        h^-1, rescaled to span exactly 0 (its minimum, near 05 h) to 1 (its maximum, near
        14 h); the published form spans 0.03-1.00.

    Notes
    -----
    With the day's minimum T_n and maximum T_x, T(t) = T_n + (T_x - T_n) Gamma(t) (their
    Eq. 2.2, the same minimum and maximum on both sides of the maximum here). A two-harmonic fit to
    the mean clear-sky diurnal course of screen temperatures; it gives the shape, the range
    must come from data (or the scenario).

    References
    ----------
    .. [1] Campbell, G. S., Norman, J. M. (1998). An Introduction to Environmental Biophysics,
       2nd ed., Springer, section 2.3, Eq. 2.2 and Table 2.1.
    """
    w = np.pi / 12.0 * np.asarray(solar_hour, dtype=float)
    g = 0.44 - 0.46 * np.sin(w + 0.9) + 0.11 * np.sin(2.0 * w + 0.9)
    return (g - _GAMMA_MIN) / (_GAMMA_MAX - _GAMMA_MIN)


def _gamma_extremes():
    w = np.pi / 12.0 * np.linspace(0.0, 24.0, 288001)
    g = 0.44 - 0.46 * np.sin(w + 0.9) + 0.11 * np.sin(2.0 * w + 0.9)
    return float(g.min()), float(g.max())


#: extremes of the published Gamma (about 0.03 at 05 h and 1.00 at 14 h); the shape is rescaled
#: to span exactly 0-1 so that the cycle's range is the given daily range
_GAMMA_MIN, _GAMMA_MAX = _gamma_extremes()


def diurnal_air_temperature(solar_hour, anchor_hour, anchor_temperature_k, diurnal_range_k):
    """Air temperature along the diurnal cycle through a known value [K].

    Parameters
    ----------
    solar_hour : numeric
        Local solar times [h] where the temperature is wanted.
    anchor_hour : float
        Local solar time [h] of a known air temperature (the scenario's frame 0).
    anchor_temperature_k : float
        Air temperature at ``anchor_hour`` [K].
    diurnal_range_k : float
        Daily maximum minus minimum [K] (0: constant).

    Returns
    -------
    numeric
        T(t) = T_anchor + R (Gamma(t) - Gamma(t_anchor)) [K], Gamma of
        :func:`campbell_norman_shape`: the cycle of range R that passes through the anchor.
    """
    r = float(diurnal_range_k)
    if not np.isfinite(r) or r < 0.0:
        raise ValueError(f"diurnal_range_k must be finite and >= 0, got {diurnal_range_k!r}")
    g = campbell_norman_shape(solar_hour) - campbell_norman_shape(anchor_hour)
    return float(anchor_temperature_k) + r * g


def relative_humidity_at_constant_vapour_pressure(
    air_temperature_k, anchor_temperature_k, anchor_relative_humidity
):
    """Relative humidity [0-1] at ``air_temperature_k`` when the vapour pressure stays that of
    the anchor (a constant dew point through the day, Campbell & Norman 1998, section 3.3: the
    vapour pressure changes little over a day while the relative humidity follows the
    temperature); capped at 1 (dew). Saturation pressure: Magnus over water (Alduchov &
    Eskridge 1996)."""

    def e_sat(t):
        tc = np.asarray(t, dtype=float) - 273.15
        return 610.94 * np.exp(17.625 * tc / (tc + 243.04))

    e = float(anchor_relative_humidity) * e_sat(anchor_temperature_k)
    return np.minimum(e / e_sat(air_temperature_k), 1.0)
