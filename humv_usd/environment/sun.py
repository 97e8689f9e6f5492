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

from humv_usd.environment.weather import Weather, weather_at
from humv_usd.scenario import Scenario
from humv_usd.scenario.times import frame_epoch_s


@dataclass
class SunState:
    """The sun at n times.

    times_s (n,) [s after frame 0]; zenith_deg, azimuth_deg (n,) apparent, compass azimuth;
    direction (n, 3) unit vector toward the sun (x east, y north, z up); dni_w_m2, dhi_w_m2,
    ghi_w_m2 (n,) [W m-2] broadband, cloud-reduced; up (n,) bool (apparent elevation > 0).
    """

    times_s: np.ndarray
    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    direction: np.ndarray
    dni_w_m2: np.ndarray
    dhi_w_m2: np.ndarray
    ghi_w_m2: np.ndarray
    up: np.ndarray


def sun_direction(zenith_deg, azimuth_deg) -> np.ndarray:
    """Unit vector(s) toward the sun in the stage frame (x east, y north, z up), shape (n, 3)."""
    z, a = np.radians(np.atleast_1d(zenith_deg)), np.radians(np.atleast_1d(azimuth_deg))
    return np.stack([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)], axis=-1)


def cloud_reduction(ghi_clear, dhi_clear, zenith_deg, cloud_cover):
    """Global, diffuse and direct-normal irradiance under a cloud cover (Kasten & Czeplak 1980).

    Parameters
    ----------
    ghi_clear, dhi_clear : array-like
        Clear-sky global and diffuse horizontal irradiance [W m-2].
    zenith_deg : array-like
        Solar zenith angle [deg].
    cloud_cover : array-like
        Cloud cover fraction N [0-1] (octas / 8).

    Returns
    -------
    tuple of arrays
        (GHI, DHI, DNI) [W m-2].

    Notes
    -----
    GHI = GHI_clear (1 - 0.75 N^3.4) and the diffuse fraction D/G = 0.3 + 0.7 N^2 (Kasten &
    Czeplak's fits to ten years of Hamburg data). Their clear-sky diffuse fraction 0.3 is replaced
    by the clear-sky model's own D/G, so that N = 0 returns the clear sky unchanged:
    D/G = kd_clear + (1 - kd_clear) N^2, which equals Kasten & Czeplak's law for kd_clear = 0.3.
    DNI = (GHI - DHI) / cos(zenith).

    References
    ----------
    .. [1] Kasten, F., Czeplak, G. (1980). Solar and terrestrial radiation dependent on the
       amount and type of cloud. Solar Energy 24, 177-189.
    """
    ghi_c = np.asarray(ghi_clear, dtype=float)
    n = np.clip(np.asarray(cloud_cover, dtype=float), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        kd_clear = np.where(ghi_c > 0, np.asarray(dhi_clear, dtype=float) / ghi_c, 1.0)
    ghi = ghi_c * (1.0 - 0.75 * n**3.4)
    dhi = ghi * np.clip(kd_clear + (1.0 - kd_clear) * n * n, 0.0, 1.0)
    cosz = np.cos(np.radians(np.asarray(zenith_deg, dtype=float)))
    with np.errstate(divide="ignore", invalid="ignore"):
        dni = np.where(cosz > 1e-6, (ghi - dhi) / cosz, 0.0)
    return ghi, dhi, np.maximum(dni, 0.0)


def utc_times(scenario: Scenario, times_s):
    """pandas DatetimeIndex (UTC) of ``times_s`` seconds after frame 0."""
    import pandas as pd

    t = frame_epoch_s(scenario) + np.atleast_1d(np.asarray(times_s, dtype=float))
    return pd.to_datetime(t, unit="s", utc=True)


def sun_at(scenario: Scenario, times_s, weather: Weather | None = None) -> SunState:
    """Solar position and irradiance at ``times_s`` seconds after frame 0.

    Parameters
    ----------
    scenario : Scenario
        Site (latitude, longitude, elevation), local start time and UTC offset from
        ``[general]``; weather from ``[atmosphere]`` (see :func:`weather_at`).
    times_s : array-like (n,)
        Seconds after frame 0.
    weather : Weather, optional
        Weather at the same times (computed when not given).

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
    import pvlib

    g = scenario["general"]
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    w = weather if weather is not None else weather_at(scenario, t)
    idx = utc_times(scenario, t)
    lat, lon, elev = g["latitude_deg"], g["longitude_deg"], g["elevation_m"]
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
