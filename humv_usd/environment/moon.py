"""The moon at given times and a site: apparent position, phase angle, distance (PyEphem).

PyEphem (``ephem``, the XEphem ``libastro`` C library) computes the Moon from the ELP 2000-82
lunar theory truncated as in Meeus (*Astronomical Algorithms*, 2nd ed., 1998, ch. 47; arc-minute
accuracy) with no data file and no network at run time. Altitude is apparent (refraction with
the given pressure and temperature), topocentric (parallax included).

Stage frame as for the sun (:mod:`humv_usd.environment.sun`): x east, y north, z up; azimuth a
compass angle (0 = north, 90 = east).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

import ephem
import numpy as np

from humv_usd.physics.sun import sun_direction

#: Kilometres per astronomical unit (IAU 2012 Resolution B2).
AU_KM = 149597870.7


@dataclass
class MoonState:
    """The moon at n times: apparent ``elevation_deg`` and compass ``azimuth_deg`` [deg],
    unit ``direction`` (n, 3) toward it (x east, y north, z up), ``phase_angle_deg`` (Sun-Moon-
    Earth angle, 0 = full), ``illuminated_fraction`` of the disk [0-1] and ``distance_km``."""

    elevation_deg: np.ndarray
    azimuth_deg: np.ndarray
    direction: np.ndarray
    phase_angle_deg: np.ndarray
    illuminated_fraction: np.ndarray
    distance_km: np.ndarray


def moon_at(
    latitude_deg: float,
    longitude_deg: float,
    elevation_m: float,
    utc_times,
    pressure_pa: float = 101325.0,
    air_temperature_k: float = 288.15,
) -> MoonState:
    """Moon position and phase seen from a site at ``utc_times``.

    Parameters
    ----------
    latitude_deg, longitude_deg : float
        Site [deg], north and east positive.
    elevation_m : float
        Site elevation [m].
    utc_times : sequence of datetime.datetime
        Times (timezone-aware, or naive in UTC).
    pressure_pa, air_temperature_k : float
        For the refraction of the apparent altitude.

    Returns
    -------
    MoonState

    Notes
    -----
    The phase angle is :math:`\\arccos(2k - 1)` of the illuminated fraction k (the disk of a
    sphere lit at phase angle :math:`\\alpha` is lit over :math:`(1 + \\cos\\alpha)/2`; Meeus
    1998, eq. 48.1).
    """
    obs = ephem.Observer()
    obs.lat, obs.lon = str(float(latitude_deg)), str(float(longitude_deg))
    obs.elevation = float(elevation_m)
    obs.pressure = float(pressure_pa) / 100.0  # [mbar]
    obs.temp = float(air_temperature_k) - 273.15
    moon = ephem.Moon()
    elev, azi, frac, dist = [], [], [], []
    for t in utc_times:
        if isinstance(t, dt.datetime) and t.tzinfo is not None:
            t = t.astimezone(dt.UTC).replace(tzinfo=None)
        obs.date = ephem.Date(t)
        moon.compute(obs)
        elev.append(math.degrees(float(moon.alt)))
        azi.append(math.degrees(float(moon.az)) % 360.0)
        frac.append(float(moon.moon_phase))
        dist.append(float(moon.earth_distance) * AU_KM)
    elev_a, azi_a, frac_a = np.array(elev), np.array(azi), np.clip(np.array(frac), 0.0, 1.0)
    return MoonState(
        elevation_deg=elev_a,
        azimuth_deg=azi_a,
        direction=sun_direction(90.0 - elev_a, azi_a),
        phase_angle_deg=np.degrees(np.arccos(np.clip(2.0 * frac_a - 1.0, -1.0, 1.0))),
        illuminated_fraction=frac_a,
        distance_km=np.array(dist),
    )
