"""The sun at the frame times: position (NREL SPA through pvlib) and broadband irradiance.

Position: pvlib's NREL Solar Position Algorithm (Reda & Andreas 2004, ±0.0003 deg), apparent
(refraction-corrected with the weather's pressure and air temperature). Clear-sky irradiance:
Ineichen & Perez (2002) with the monthly Linke turbidity climatology of Remund et al. (2003) for
the site (pvlib ``lookup_linke_turbidity``). Clouds: Kasten & Czeplak (1980).

Stage frame: x east, y north, z up; azimuth is a compass angle (0 = north, 90 = east).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.environment.weather import scenario_weather
from humv_usd.physics.sun import SunState, cloud_reduction, sun_direction
from humv_usd.physics.weather import Weather
from humv_usd.scenario import Scenario
from humv_usd.scenario.times import frame_epoch_s


@dataclass(frozen=True)
class Site:
    """Where the scene is: latitude and longitude [deg] (north and east positive) and
    elevation above sea level [m]."""

    latitude_deg: float
    longitude_deg: float
    elevation_m: float


def site_of(scenario: Scenario) -> Site:
    """The scenario's site (``[general]`` latitude_deg, longitude_deg, elevation_m)."""
    g = scenario["general"]
    return Site(float(g["latitude_deg"]), float(g["longitude_deg"]), float(g["elevation_m"]))


def scenario_sun(scenario: Scenario, times_s, weather: Weather | None = None) -> SunState:
    """:func:`sun_at` for a scenario (the tools' thin build step): its site, frame 0 from
    ``[general]`` (local start and UTC offset), and its weather (:func:`humv_usd.environment.
    weather.scenario_weather`) when ``weather`` is not given."""
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    w = weather if weather is not None else scenario_weather(scenario, t)
    return sun_at(site_of(scenario), frame_epoch_s(scenario), t, w)


def sun_at(site: Site, epoch_s: float, times_s, weather: Weather) -> SunState:
    """Solar position and irradiance at a site and times.

    Parameters
    ----------
    site : Site
        Latitude, longitude [deg] and elevation [m].
    epoch_s : float
        UTC POSIX time of frame 0 [s].
    times_s : array-like (n,)
        Seconds after frame 0.
    weather : Weather
        Weather at the same times (pressure, air temperature, cloud cover).

    Returns
    -------
    SunState
        Apparent position from the NREL SPA (pvlib ``spa_python``; refraction with the weather's
        pressure and temperature); Ineichen-Perez clear sky with the Remund et al. (2003) Linke
        turbidity of the site and month, absolute air mass of Kasten & Young (1989) at the site
        pressure, reduced by the cloud cover (:func:`cloud_reduction`). Zero irradiance with
        the sun below the horizon.

    References
    ----------
    .. [1] Reda, I., Andreas, A. (2004). Solar position algorithm for solar radiation
       applications. Solar Energy 76(5), 577-589.
    .. [2] Ineichen, P., Perez, R. (2002). A new airmass independent formulation for the Linke
       turbidity coefficient. Solar Energy 73(3), 151-157.
    .. [3] Remund, J., Wald, L., Lefevre, M., Ranchin, T., Page, J. (2003). Worldwide Linke
       turbidity information. ISES Solar World Congress, Göteborg.
    .. [4] Kasten, F., Young, A. T. (1989). Revised optical air mass tables and approximation
       formula. Applied Optics 28(22), 4735-4738.
    """
    import pandas as pd
    import pvlib

    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    w = weather
    idx = pd.to_datetime(float(epoch_s) + t, unit="s", utc=True)
    lat, lon, elev = site.latitude_deg, site.longitude_deg, site.elevation_m
    sp = pvlib.solarposition.spa_python(
        idx, lat, lon, altitude=elev, pressure=w.pressure_pa, temperature=w.air_temperature_k - 273.15
    )
    zen = sp["apparent_zenith"].to_numpy(dtype=float)
    azi = sp["azimuth"].to_numpy(dtype=float) % 360.0
    up = sp["apparent_elevation"].to_numpy(dtype=float) > 0.0
    ghi = np.zeros_like(zen)
    dhi = np.zeros_like(zen)
    dni = np.zeros_like(zen)
    if up.any():
        u = np.flatnonzero(up)
        am_rel = pvlib.atmosphere.get_relative_airmass(zen[u], model="kastenyoung1989")
        am_abs = pvlib.atmosphere.get_absolute_airmass(am_rel, w.pressure_pa[u])
        tl = pvlib.clearsky.lookup_linke_turbidity(idx[u], lat, lon).to_numpy(dtype=float)
        dni_extra = np.asarray(pvlib.irradiance.get_extra_radiation(idx[u]), dtype=float)
        cs = pvlib.clearsky.ineichen(zen[u], am_abs, tl, altitude=elev, dni_extra=dni_extra)
        cg, cd = (np.nan_to_num(np.asarray(cs[k], dtype=float)) for k in ("ghi", "dhi"))
        ghi[u], dhi[u], dni[u] = cloud_reduction(cg, cd, zen[u], w.cloud_cover[u])
    return SunState(
        times_s=t,
        zenith_deg=zen,
        azimuth_deg=azi,
        direction=sun_direction(zen, azi),
        dni_w_m2=dni,
        dhi_w_m2=dhi,
        ghi_w_m2=ghi,
        up=up,
    )
