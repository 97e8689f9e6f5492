"""The scenario's atmosphere: spectral sky, slant paths and direct sun, LOWTRAN7 or analytic.

:func:`atmosphere_for` builds an :class:`Atmosphere` with only what the scenario needs:

- wavelengths: the union of the sensors' bands (LOWTRAN's 20 cm-1 sampling beyond 2.5 um,
  100 cm-1 below), nothing when there is no sensor;
- LOWTRAN7 only when an infrared sensor (band beyond 3 um) or a NIR/SWIR sensor (its paths
  cross the 0.94, 1.14, 1.38 and 1.87 um water bands) needs it and ``[atmosphere] model``
  is ``lowtran7`` (the default); with EO sensors only, or ``model = "analytic"``, the analytic
  model; when LOWTRAN7 cannot be loaded or fails, the analytic model with a warning on stderr;
- the solar terms only at times the sun is up.

Weather and sun are read from the upstream stage's environment layer
(:mod:`humv_usd.usd.environment`); the atmosphere computes neither.

Models (weather of frame 0; when the
air temperature, humidity, pressure or cloud cover change over the frames (an hourly
``weather_csv``), the sky and paths are computed at weather nodes instead, see
:func:`weather_nodes`, and interpolated linearly in time between them):

Sky, LOWTRAN7: two layers. The lowest ``SKY_LAYER_KM`` above the site is a user-defined
(MODEL 7) layer from the weather (air temperature with a 6.5 K/km lapse rate, hydrostatic
pressure, constant relative humidity, fixed trace gases), above it the chosen standard profile
(MODELs 1-6) to space. Thermal emission without scattering adds exactly:
L(theta) = L_low(theta) + tau_low(theta) L_up(theta'), with sin theta' = R sin theta / (R + h)
the zenith angle where the ray leaves the layer. Most of the window emission (water vapour,
scale height ~2 km) comes from the weather layer; ozone and the upper troposphere from the
profile. Below 2.5 um the sky adds the isotropic diffuse skylight of SPCTRL2 (Bird & Riordan
1986) scaled to the environment layer's diffuse irradiance.

Slant paths: the sensors are near the ground (< ~1 km), so a path is a homogeneous horizontal
path of the same length in the weather layer (LOWTRAN7 MODEL 7, ITYPE 1, thermal radiance); the
absorber amount of a path climbing h km is overestimated by about h/8 km. The ``lowtran``
wrapper runs without aerosol, so the aerosol extinction of the visibility (Koschmieder, Kruse;
:func:`humv_usd.physics.sky.aerosol_extinction`) multiplies the transmittance, treated as
absorbing (path radiance (1 - tau_a) tau_m B(T_air) added, Kirchhoff for an isothermal path).

Direct sun: below 2.5 um SPCTRL2's direct normal spectrum scaled to the scenario's DNI; from 2.5 um
LOWTRAN7's directly transmitted solar irradiance (IEMSCT 3, standard profile) times the Sun-Earth
distance factor and the cloud reduction of the DNI (Kasten & Czeplak 1980).

Analytic fallback: sky eps(theta) B(lambda, T_air) with the Berdahl & Martin (1984) emissivity
spread over zenith by the Martin & Berdahl (1984) slab law; path transmittance from the water
continuum of Roberts et al. (1976), aerosol (Koschmieder/Kruse) and Rayleigh extinction
(0.0116 km-1 at 0.55 um, lambda^-4.08; Elterman 1968), path radiance (1 - tau) B(T_air); direct
sun beyond 2.5 um a 5772 K blackbody (IAU 2015 nominal solar temperature) attenuated by the
broadband DNI / extraterrestrial ratio.

Results of LOWTRAN runs are cached on disk (``$HUMV_USD_CACHE/atmosphere`` or
``~/.cache/humv-usd/atmosphere``), keyed by a hash of the runs' inputs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from humv_usd.atmosphere import lowtran as lt
from humv_usd.compat import trapezoid
from humv_usd.constants import STEFAN_BOLTZMANN, SUN_ANGULAR_RADIUS, SUN_TEMPERATURE_K
from humv_usd.fileio import atomic_path
from humv_usd.physics import planck
from humv_usd.physics.sky import (
    aerosol_extinction,
    cloudy_sky_emissivity,
    directional_sky_emissivity,
    effective_sky_temperature,
    water_continuum_absorption,
    water_vapour_pressure,
)
from humv_usd.physics.sun import SunState, cloud_dni_factor
from humv_usd.physics.weather import Weather
from humv_usd.scenario import Scenario
from humv_usd.scenario.times import frame_epoch_s, frame_times, utc_times
from humv_usd.scenario.weather_csv import read_weather_csv
from humv_usd.usd.environment import read_sun, read_weather, time_codes

log = logging.getLogger(__name__)

CACHE_ENV = "HUMV_USD_CACHE"
#: bump when the cached quantities or their meaning change
CACHE_VERSION = "humv-atmosphere-1"
#: zenith angles of the sky table [deg] (89 is the last above-horizon sample)
SKY_ZENITH_DEG = np.array([0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 75.0, 80.0, 85.0, 89.0])
#: depth of the weather layer under the standard profile [km]
SKY_LAYER_KM = 1.0
#: ranges of the slant-path table [m]
PATH_RANGES_M = np.geomspace(1.0, 30000.0, 19)
#: longwave band of the broadband sky (thermal) [um]
LONGWAVE_UM = (4.0, 50.0)
#: LOWTRAN sampling [cm-1] beyond / below SOLAR_SPLIT_UM
IR_STEP_CM, VIS_STEP_CM = 20.0, 100.0
#: below this wavelength the sun and skylight come from SPCTRL2, above from LOWTRAN / Planck
SOLAR_SPLIT_UM = 2.5
#: aerosol scale height for the vertical optical depth of the visibility's extinction [m]
AEROSOL_SCALE_HEIGHT_M = 1.2e3
#: LOWTRAN7 Earth radius for the layer-exit angle [km]
EARTH_RADIUS_KM = 6371.23
#: samples of the time-varying quantities: at most this many over the scenario


def cache_dir() -> Path:
    base = os.environ.get(CACHE_ENV)
    root = Path(base) if base else Path.home() / ".cache" / "humv-usd"
    return root / "atmosphere"


#: weather quantities the sky and the paths depend on (cloud cover through the thermal layer)
ATMOSPHERE_WEATHER = ("air_temperature_k", "relative_humidity", "pressure_pa", "cloud_cover")


def weather_varies(weather: Weather) -> bool:
    """True when a quantity of :data:`ATMOSPHERE_WEATHER` changes over the samples (wind alone
    leaves the atmosphere as it is)."""
    return any(np.ptp(getattr(weather, k)) > 0 for k in ATMOSPHERE_WEATHER if len(getattr(weather, k)))


def weather_nodes(scenario: Scenario) -> np.ndarray:
    """Times [s after frame 0] of the weather nodes: frame 0, the last frame and the hours of
    ``[atmosphere] weather_csv`` in between, each snapped to the nearest frame.

    Between the series' rows the weather is linear in time, so linear interpolation of the sky
    and path tables between these nodes follows it (to first order in the weather change)."""

    fps = float(scenario["general"]["fps"])
    last = scenario.frame_count - 1
    frames = [0.0, float(last)]
    path = (scenario["atmosphere"] or {}).get("weather_csv")
    if path:
        ts, _ = read_weather_csv(path, scenario)
        rel = (np.asarray(ts, float) - frame_epoch_s(scenario)) * fps
        frames += [float(f) for f in np.round(rel[(rel > 0) & (rel < last)])]
    return np.unique(frames) / fps


def sensor_bands(scenario: Scenario) -> list[tuple[float, float]]:
    """Merged [lo, hi] um bands of the scenario's sensors (overlapping ones joined)."""
    bands = sorted((float(s["wavelength_um"][0]), float(s["wavelength_um"][1])) for s in scenario["sensor"])
    merged: list[list[float]] = []
    for lo, hi in bands:
        if merged and lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return [(lo, hi) for lo, hi in merged]


def _intervals(bands) -> list[tuple[float, float, float]]:
    """LOWTRAN intervals (lo, hi, step cm-1), split at SOLAR_SPLIT_UM, padded by one sample."""
    out = []
    for lo, hi in bands:
        for a, b, step in (
            (lo, min(hi, SOLAR_SPLIT_UM), VIS_STEP_CM),
            (max(lo, SOLAR_SPLIT_UM), hi, IR_STEP_CM),
        ):
            if b <= a:
                continue
            # one sample beyond each edge: LOWTRAN rounds the wavenumbers to its 5 cm-1 grid
            a_pad = 1e4 / (1e4 / a + step)
            b_pad = 1e4 / max(1e4 / b - step, 1.0)
            out.append((round(a_pad, 6), round(b_pad, 6), step))
    return out


def _grid(bands) -> np.ndarray:
    """Analytic wavelength grid: the same sampling as LOWTRAN's, without running it."""
    parts = []
    for lo, hi, step in _intervals(bands):
        nu = np.arange(1e4 / hi, 1e4 / lo + step, step)
        parts.append(1e4 / nu[::-1])
    return np.unique(np.concatenate(parts)) if parts else np.zeros(0)


# --- LOWTRAN runs with a disk cache --------------------------------------------------------------
def _key(cases) -> str:
    text = json.dumps([CACHE_VERSION, cases], sort_keys=True, default=float)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def run_cached(cases: list[dict], ran: dict | None = None, what: str = "") -> list[lt.Run]:
    """LOWTRAN runs for ``cases``, from the disk cache when the same cases ran before.

    Raises :class:`humv_usd.atmosphere.lowtran.LowtranError` when LOWTRAN is needed and fails.
    """
    path = cache_dir() / f"{_key(cases)}.npz"
    fields = ("wavelengths_um", "transmittance", "radiance", "solar", "solar_toa")
    if path.is_file():
        try:
            with np.load(path) as z:
                stacked = [z[f] for f in fields]
            runs = [lt.Run(*(a[i] for a in stacked)) for i in range(len(cases))]
            if ran is not None:
                ran.setdefault("cache", []).append(f"{what}: hit")
            return runs
        except Exception:  # a damaged cache entry is recomputed
            pass
    runs = [lt.run(c) for c in cases]
    try:
        arrays = {f: np.stack([getattr(r, f) for r in runs]) for f in fields}
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)
    except (OSError, ValueError) as e:  # no cache is not an error
        log.warning("atmosphere cache not written (%s)", e)
    if ran is not None:
        ran.setdefault("cache", []).append(f"{what}: miss ({len(cases)} LOWTRAN7 runs)")
    return runs


# --- the atmosphere ----------------------------------------------------------------------------
@dataclass
class Atmosphere:
    """Spectral atmosphere of a scenario (see the module doc). Build with :func:`atmosphere_for`.

    Arrays: ``wavelengths_um`` (W,) ascending; ``sky_zenith_deg`` (Z,); ``sky_radiance`` (Z, W)
    thermal sky [W m-2 sr-1 um-1]; ``diffuse_radiance`` (n, W) isotropic skylight at
    ``times_s``; ``path_ranges_m`` (R,), ``path_transmittance``, ``path_radiance`` (R, W);
    ``solar`` (n, W) direct normal [W m-2 um-1] at ``times_s``; broadband longwave sky
    ``longwave_radiance`` (Z,) [W m-2 sr-1], ``sky_emissivity``, ``sky_temperature_k``.
    """

    source: str
    wavelengths_um: np.ndarray
    sky_zenith_deg: np.ndarray
    sky_radiance: np.ndarray
    times_s: np.ndarray
    diffuse_radiance: np.ndarray
    path_ranges_m: np.ndarray
    path_transmittance: np.ndarray
    path_radiance: np.ndarray
    solar: np.ndarray
    longwave_radiance: np.ndarray
    sky_emissivity: float
    sky_temperature_k: float
    air_temperature_k: float
    profile: str
    ran: dict = field(default_factory=dict)
    #: weather nodes (None for constant weather): times [s] (K,), and per node the thermal sky
    #: (K, Z, W), path tables (K, R, W) twice, longwave (K, Z), emissivity, sky and air
    #: temperature, cloud cover (K,); the unsuffixed fields above hold node 0
    node_times_s: np.ndarray | None = None
    node_sky_radiance: np.ndarray | None = None
    node_path_transmittance: np.ndarray | None = None
    node_path_radiance: np.ndarray | None = None
    node_longwave_radiance: np.ndarray | None = None
    node_sky_emissivity: np.ndarray | None = None
    node_sky_temperature_k: np.ndarray | None = None
    node_air_temperature_k: np.ndarray | None = None
    node_cloud_cover: np.ndarray | None = None

    def _node_mix(self, table, fallback, t):
        """Linear interpolation over the weather nodes of ``table`` at time t (``fallback``
        for constant weather)."""
        if self.node_times_s is None:
            return fallback
        return lerp_nodes(self.node_times_s, table, t)

    def at_node(self, k: int) -> Atmosphere:
        """The atmosphere with the weather of node k (no nodes: itself)."""
        if self.node_times_s is None:
            return self
        return dataclasses.replace(
            self,
            sky_radiance=self.node_sky_radiance[k],
            path_transmittance=self.node_path_transmittance[k],
            path_radiance=self.node_path_radiance[k],
            longwave_radiance=self.node_longwave_radiance[k],
            sky_emissivity=float(self.node_sky_emissivity[k]),
            sky_temperature_k=float(self.node_sky_temperature_k[k]),
            air_temperature_k=float(self.node_air_temperature_k[k]),
            node_times_s=None,
            node_sky_radiance=None,
            node_path_transmittance=None,
            node_path_radiance=None,
            node_longwave_radiance=None,
            node_sky_emissivity=None,
            node_sky_temperature_k=None,
            node_air_temperature_k=None,
            node_cloud_cover=None,
        )

    def diffuse_at(self, time_s: float) -> np.ndarray:
        """Isotropic diffuse skylight (W,) [W m-2 sr-1 um-1] at ``time_s``."""
        a, b, f = self._time_index(time_s)
        return (1 - f) * self.diffuse_radiance[a] + f * self.diffuse_radiance[b]

    def _time_index(self, t):
        """Linear-interpolation weights of time t over ``times_s``."""
        ts = self.times_s
        if ts.size == 1:
            return 0, 0, 0.0
        t = float(np.clip(t, ts[0], ts[-1]))
        j = int(np.clip(np.searchsorted(ts, t) - 1, 0, ts.size - 2))
        f = (t - ts[j]) / (ts[j + 1] - ts[j])
        return j, j + 1, f

    def sky_spectral_radiance(self, zenith_deg, time_s: float = 0.0) -> np.ndarray:
        """Downwelling sky radiance (len(zenith), W) [W m-2 sr-1 um-1] at ``time_s``.

        Linear in zenith between the table's angles; beyond its last angle (89 deg) the last
        row (callers handle the ground below the horizon).
        """
        z = np.atleast_1d(np.asarray(zenith_deg, dtype=float))
        if self.wavelengths_um.size == 0:
            return np.zeros((z.size, 0))
        zt = self.sky_zenith_deg
        sky = self._node_mix(self.node_sky_radiance, self.sky_radiance, time_s)
        out = np.stack([np.interp(z, zt, sky[:, k]) for k in range(self.wavelengths_um.size)], axis=-1)
        return out + self.diffuse_at(time_s)[None, :]

    def path(
        self, sensor_position_m=None, ranges_m=None, time_s: float = 0.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """(transmittance (R, W), path radiance (R, W) [W m-2 sr-1 um-1]) at ``ranges_m``.

        Homogeneous near-ground paths: the sensor position does not change them (see the module
        doc). Log-linear interpolation in range over the table; ``ranges_m`` None gives the
        table's own ranges. Range 0 gives transmittance 1 and no path radiance. ``time_s``
        matters only with weather nodes (tables linear in time between them).
        """
        if self.node_times_s is not None:
            now = dataclasses.replace(
                self.at_node(0),
                path_transmittance=lerp_nodes(self.node_times_s, self.node_path_transmittance, time_s),
                path_radiance=lerp_nodes(self.node_times_s, self.node_path_radiance, time_s),
            )
            return now.path(sensor_position_m, ranges_m)
        if ranges_m is None:
            return self.path_transmittance.copy(), self.path_radiance.copy()
        r = np.atleast_1d(np.asarray(ranges_m, dtype=float))
        if self.wavelengths_um.size == 0:
            return np.ones((r.size, 0)), np.zeros((r.size, 0))
        rt = np.concatenate([[0.0], self.path_ranges_m])
        tau = np.vstack([np.ones(self.wavelengths_um.size), self.path_transmittance])
        rad = np.vstack([np.zeros(self.wavelengths_um.size), self.path_radiance])
        # interpolate optical depth (linear in range for a homogeneous path) and the radiance
        od = -np.log(np.clip(tau, 1e-300, 1.0))
        x = np.clip(r, 0.0, rt[-1])
        od_r = np.stack([np.interp(x, rt, od[:, k]) for k in range(od.shape[1])], axis=-1)
        rad_r = np.stack([np.interp(x, rt, rad[:, k]) for k in range(od.shape[1])], axis=-1)
        return np.exp(-od_r).reshape(r.size, -1), rad_r.reshape(r.size, -1)

    def solar_spectral_irradiance(self, times_s) -> np.ndarray:
        """Direct solar irradiance at the ground, normal incidence, (n, W) [W m-2 um-1];
        zero when the sun is down. Linear in time between the samples."""
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        out = np.zeros((t.size, self.wavelengths_um.size))
        for i, ti in enumerate(t):
            a, b, f = self._time_index(ti)
            out[i] = (1 - f) * self.solar[a] + f * self.solar[b]
        return out


def with_cloud_cover(atmosphere, cloud_cover: float):
    """The atmosphere's thermal sky with a cloud fraction (Crawford & Duchon 1999).

    Parameters
    ----------
    atmosphere : humv_usd.atmosphere.model.Atmosphere
        Clear-sky atmosphere (LOWTRAN7 or analytic).
    cloud_cover : float
        Cloud fraction c [0-1] (the weather of frame 0, like the atmosphere).

    Returns
    -------
    Atmosphere
        A copy whose thermal sky is L = c B(T_air) + (1 - c) L_clear: spectral rows
        ``sky_radiance`` with the Planck radiance B(lambda, T_air), the broadband
        ``longwave_radiance`` with sigma T_air^4 / pi, ``sky_emissivity`` =
        c + (1 - c) eps_clear and ``sky_temperature_k`` = eps^(1/4) T_air. The isotropic diffuse
        skylight (already reduced by the clouds through the scenario's DHI), the paths and the
        direct sun are unchanged. c = 0 returns the atmosphere itself.

    Notes
    -----
    Clouds as blackbodies at the air temperature (see :func:`cloudy_sky_emissivity`);
    LOWTRAN7 runs without its cloud models, so the clear-sky spectrum is mixed the same way.
    """

    c = float(np.clip(cloud_cover, 0.0, 1.0))
    if c == 0.0:
        return atmosphere
    t_air = float(atmosphere.air_temperature_k)
    wl = np.asarray(atmosphere.wavelengths_um, dtype=float)
    bb = planck.spectral_radiance(wl, t_air) if wl.size else np.zeros(0)
    eps = float(cloudy_sky_emissivity(atmosphere.sky_emissivity, c))
    ran = dict(atmosphere.ran)
    ran["clouds"] = (
        f"cloud cover {c:g}: Crawford & Duchon (1999) mix, clouds as blackbodies "
        f"at the air temperature {t_air:.2f} K (broadband and spectral sky)"
    )
    return dataclasses.replace(
        atmosphere,
        sky_radiance=c * bb[None, :] + (1.0 - c) * np.asarray(atmosphere.sky_radiance),
        longwave_radiance=(
            c * STEFAN_BOLTZMANN * t_air**4 / np.pi + (1.0 - c) * np.asarray(atmosphere.longwave_radiance)
        ),
        sky_emissivity=eps,
        sky_temperature_k=eps**0.25 * t_air,
        ran=ran,
    )


def lerp_nodes(node_times_s, table, t) -> np.ndarray:
    """table (K, ...) at time t, linear between the node times (K,), held beyond them (as USD
    interpolates float-array time samples)."""
    ts = np.asarray(node_times_s, dtype=float)
    table = np.asarray(table)
    if ts.size == 1:
        return table[0]
    t = float(np.clip(t, ts[0], ts[-1]))
    j = int(np.clip(np.searchsorted(ts, t) - 1, 0, ts.size - 2))
    f = (t - ts[j]) / (ts[j + 1] - ts[j])
    return (1 - f) * table[j] + f * table[j + 1]


def _spectrl2(sun: SunState, weather: Weather, scenario: Scenario, grid_um: np.ndarray):
    """SPCTRL2 direct-normal and diffuse-horizontal spectra (n, W) [W m-2 um-1] on ``grid_um``
    (below SOLAR_SPLIT_UM; zero beyond), scaled to the scenario's DNI and DHI."""
    import pvlib

    n = sun.times_s.size
    dni = np.zeros((n, grid_um.size))
    dhi = np.zeros((n, grid_um.size))
    sel = grid_um < SOLAR_SPLIT_UM
    up = np.flatnonzero(sun.up)
    if up.size == 0 or not sel.any():
        return dni, dhi
    import pandas as pd

    zen = sun.zenith_deg[up]
    idx = utc_times(scenario, sun.times_s[up])
    am = pvlib.atmosphere.get_relative_airmass(zen, model="kasten1966")
    pw = pvlib.atmosphere.gueymard94_pw(
        weather.air_temperature_k[up] - 273.15, np.maximum(weather.relative_humidity[up], 0.01) * 100.0
    )
    vis = float(scenario["atmosphere"]["visibility_km"])
    tau500 = float(aerosol_extinction(0.5, vis)) * AEROSOL_SCALE_HEIGHT_M
    spec = pvlib.spectrum.spectrl2(
        apparent_zenith=zen,
        aoi=np.zeros_like(zen),
        surface_tilt=0.0,
        ground_albedo=0.2,
        surface_pressure=weather.pressure_pa[up],
        relative_airmass=am,
        precipitable_water=pw,
        ozone=0.31,
        aerosol_turbidity_500nm=tau500,
        dayofyear=pd.DatetimeIndex(idx).dayofyear.to_numpy(),
    )
    wl = np.asarray(spec["wavelength"], dtype=float) * 1e-3  # [um]
    for key, target, out in (("dni", sun.dni_w_m2, dni), ("dhi", sun.dhi_w_m2, dhi)):
        s = np.nan_to_num(np.asarray(spec[key], dtype=float)) * 1e3  # [W m-2 um-1]
        s = s.reshape(wl.size, -1)
        total = trapezoid(s, wl, axis=0)
        scale = np.where(total > 0, target[up] / np.where(total > 0, total, 1.0), 0.0)
        for j, i in enumerate(up):
            out[i, sel] = np.interp(grid_um[sel], wl, s[:, j]) * scale[j]
    return dni, dhi


def _earth_sun_factor(scenario: Scenario, times_s) -> np.ndarray:
    """(r0 / r)^2: extraterrestrial irradiance over its annual mean (Spencer 1971, pvlib)."""
    import pvlib

    return np.asarray(
        pvlib.irradiance.get_extra_radiation(utc_times(scenario, times_s), solar_constant=1.0), dtype=float
    )


def _cloud_dni_factor(sun: SunState, weather: Weather) -> np.ndarray:
    """DNI / clear-sky DNI of the environment layer's sun (0 where there is no direct sun)."""
    return np.where(sun.dni_w_m2 > 0, cloud_dni_factor(weather.cloud_cover), 0.0)


def _broadband(zenith_deg, lw_spectral, wl_um, t_air) -> tuple[np.ndarray, float, float]:
    """Broadband sky radiance (Z,), hemispherical emissivity and effective temperature from a
    spectral longwave sky on LONGWAVE_UM, with a blackbody at T_air outside it (opaque
    far infrared; the thermal sky below 4 um is negligible at terrestrial temperatures)."""
    inside = trapezoid(lw_spectral, wl_um, axis=-1)
    total_bb = STEFAN_BOLTZMANN * t_air**4 / np.pi
    bb_inside = float(planck.band_radiance(t_air, [wl_um[0], wl_um[-1]]))
    lw = inside + (total_bb - bb_inside)
    mu = np.cos(np.radians(zenith_deg))
    # hemispherical flux 2 pi int L mu dmu, trapezoid in mu with L(mu=0) = L(89 deg)
    mus = np.append(mu, 0.0)
    ls = np.append(lw, lw[-1])
    flux = 2.0 * np.pi * abs(trapezoid(ls * mus, mus))
    eps = flux / (STEFAN_BOLTZMANN * t_air**4)
    return lw, float(eps), float((flux / STEFAN_BOLTZMANN) ** 0.25)


def _mid_layer(t_air, p, rh, h_km):
    """(T, RH, P) at the middle of the weather layer: 6.5 K/km lapse rate, hydrostatic pressure,
    constant relative humidity (US Standard Atmosphere 1976 lapse rate)."""
    t_mid = t_air - 6.5 * h_km / 2
    p_mid = p * (t_mid / t_air) ** (9.80665 * 0.0289644 / (8.3144598 * 6.5e-3))
    return (t_mid, rh, p_mid)


def lowtran_sky(profile: str, z0_km: float, t_air, rh, p, lo_um: float = LONGWAVE_UM[0], ran=None):
    """Thermal sky radiance against zenith (:data:`SKY_ZENITH_DEG`) from LOWTRAN7: the standard
    ``profile`` with its lowest :data:`SKY_LAYER_KM` replaced by the weather (module doc).

    Returns (wavelengths [um] (W,), radiance (Z, W) [W m-2 sr-1 um-1]) over ``lo_um`` to
    ``LONGWAVE_UM[1]``.

    The replacement is a first-order perturbation, L = L_profile + (L_w - L_p) + (tau_w - tau_p)
    L_up, where w and p are homogeneous layers built by the same rule (:func:`_mid_layer`) from
    the weather and from the profile's own state at the site (:func:`profile_state`): when the
    weather equals the profile's state the correction vanishes and the sky is LOWTRAN's own
    standard-profile sky (the identity test); it grows with the weather's departure from the
    profile, which is why ``profile = "auto"`` picks the profile nearest the weather
    (:func:`choose_profile`).
    """
    model = lt.PROFILE_MODEL[profile]
    h = SKY_LAYER_KM
    zen = SKY_ZENITH_DEG
    sin_t = np.sin(np.radians(zen))
    exit_zen = np.degrees(np.arcsin(EARTH_RADIUS_KM * sin_t / (EARTH_RADIUS_KM + z0_km + h)))
    # slant length through the layer on a spherical earth [km]
    r0 = EARTH_RADIUS_KM + z0_km
    length_km = np.sqrt((r0 + h) ** 2 - (r0 * sin_t) ** 2) - r0 * np.cos(np.radians(zen))
    weather_mid = _mid_layer(t_air, p, rh, h)
    t_p, rh_p, p_p = profile_state(profile, z0_km)
    profile_mid = _mid_layer(t_p, p_p, rh_p, h)
    spec = lt.spectral_case(lo_um, LONGWAVE_UM[1], IR_STEP_CM)
    same = np.allclose(weather_mid, profile_mid, rtol=1e-9, atol=0.0)
    states = () if same else (weather_mid, profile_mid)
    cases = (
        [dict(spec, model=model, itype=3, iemsct=1, h1=z0_km, angle=float(t)) for t in zen]
        + (
            []
            if same
            else [dict(spec, model=model, itype=3, iemsct=1, h1=z0_km + h, angle=float(t)) for t in exit_zen]
        )
        + [
            dict(
                lt.layer_case(state[0], state[1], state[2], [z0_km + h / 2]),
                **spec,
                itype=1,
                iemsct=1,
                h1=z0_km + h / 2,
                range_km=float(s),
            )
            for state in states
            for s in length_km
        ]
    )
    runs = run_cached(cases, ran, "sky")
    n = zen.size
    full = runs[:n]
    sky_wl = full[0].wavelengths_um
    if same:
        return sky_wl, np.stack([f.radiance for f in full])
    upper, low_w, low_p = runs[n : 2 * n], runs[2 * n : 3 * n], runs[3 * n :]
    sky_ir = np.stack(
        [
            f.radiance + (w.radiance - q.radiance) + (w.transmittance - q.transmittance) * u.radiance
            for f, u, w, q in zip(full, upper, low_w, low_p)
        ]
    )
    return sky_wl, np.maximum(sky_ir, 0.0)


def profile_state(profile: str, z0_km: float) -> tuple[float, float, float]:
    """(air temperature [K], relative humidity [0-1], pressure [Pa]) of a standard profile at
    the site's elevation z0: its sea-level state (:data:`humv_usd.atmosphere.lowtran.PROFILE_SURFACE`,
    Anderson et al. 1986) with a 6.5 K/km lapse rate, hydrostatic pressure and water vapour
    density falling with a 2 km scale height."""
    t0, p0, rho0 = lt.PROFILE_SURFACE[profile]
    t = t0 - 6.5 * z0_km
    p = p0 * (t / t0) ** (9.80665 * 0.0289644 / (8.3144598 * 6.5e-3))
    e = rho0 * np.exp(-z0_km / 2.0) * 1e-3 * 461.5 * t  # [Pa]
    return (float(t), float(min(e / water_vapour_pressure(t, 1.0), 1.0)), float(p))


#: scales of the profile match [K], [g m-3]: a profile 10 K or 3 g m-3 of water vapour away
#: from the weather counts as 1 (the sky's long wave depends on both about equally:
#: Brutsaert 1975, eps ~ (e/T)^(1/7), d ln eps ~ 0.14 d ln e)
PROFILE_MATCH_SCALES = (10.0, 3.0)


def choose_profile(air_temperature_k, relative_humidity, pressure_pa=101325.0, z0_km: float = 0.0) -> str:
    """The standard profile whose state at the site is nearest the weather.

    Distance: sqrt((dT / 10 K)^2 + (d rho_v / 3 g m-3)^2) between the weather's air
    temperature and water vapour density and the profile's (:func:`profile_state`), so the
    weather layer's perturbation of the profile (:func:`lowtran_sky`) stays small. Ties go to
    the first profile of :data:`humv_usd.atmosphere.lowtran.PROFILE_MODEL`.
    """

    def rho_v(t, rh):
        return water_vapour_pressure(t, rh) / (461.5 * t) * 1e3  # [g m-3]

    rho_w = rho_v(air_temperature_k, relative_humidity)
    best, best_d = "", np.inf
    for name in lt.PROFILE_MODEL:
        t, rh, _ = profile_state(name, z0_km)
        d = np.hypot(
            (t - air_temperature_k) / PROFILE_MATCH_SCALES[0],
            (rho_v(t, rh) - rho_w) / PROFILE_MATCH_SCALES[1],
        )
        if d < best_d:
            best, best_d = name, d
    return best


def resolve_profile(
    profile: str, air_temperature_k, relative_humidity, pressure_pa, z0_km: float = 0.0
) -> str:
    """``profile`` itself, or for "auto" the one :func:`choose_profile` picks."""
    if profile != "auto":
        return profile
    return choose_profile(air_temperature_k, relative_humidity, pressure_pa, z0_km)


def _lowtran_parts(
    scenario, w0: dict, bands, sun: SunState, weather: Weather, ran: dict, sun_too: bool = True, profile=None
):
    """Sky, path and solar tables from LOWTRAN7 (raises LowtranError).

    Runs: one infrared interval (the IR bands' span, extended to LONGWAVE_UM for the
    broadband sky) for the sky: 4 runs per zenith angle; paths: one run per range per interval
    (visible and infrared); direct sun: one run per zenith node per infrared interval.
    """
    g, a = scenario["general"], scenario["atmosphere"]
    z0 = float(g["elevation_m"]) / 1e3
    t_air, rh, p = w0["air_temperature_k"], w0["relative_humidity"], w0["pressure_pa"]
    profile = profile or resolve_profile(a["profile"], t_air, rh, p, z0)
    model = lt.PROFILE_MODEL[profile]
    h = SKY_LAYER_KM
    zen = SKY_ZENITH_DEG
    n = zen.size

    intervals = _intervals(bands)
    vis = [iv for iv in intervals if iv[2] == VIS_STEP_CM]
    ir_parts = [iv for iv in intervals if iv[2] == IR_STEP_CM]
    # no interval beyond SOLAR_SPLIT_UM (NIR/SWIR sensors only): paths in the visible step only
    ir = (min(iv[0] for iv in ir_parts), max(iv[1] for iv in ir_parts), IR_STEP_CM) if ir_parts else None

    # --- sky: full profile + weather-layer perturbation (module doc) ---------------------------
    sky_lo = LONGWAVE_UM[0] if ir is None else min(ir[0], LONGWAVE_UM[0])
    sky_wl, sky_ir = lowtran_sky(profile, z0, t_air, rh, p, sky_lo, ran)
    ran["sky"] = (
        f"LOWTRAN7 thermal sky, {n} zenith angles: profile {profile} "
        f"(MODEL {model}{', chosen for the weather' if a['profile'] == 'auto' else ''}) "
        f"with its lowest {h:g} km replaced by the weather (MODEL 7)"
    )

    # --- wavelength grid: visible samples + infrared samples inside the IR bands ----------------
    in_ir = np.zeros(sky_wl.size, bool)
    for lo, hi, _ in ir_parts:
        in_ir |= (sky_wl >= lo - 1e-9) & (sky_wl <= hi + 1e-9)
    vis_grid = _grid(bands)
    vis_grid = vis_grid[vis_grid < SOLAR_SPLIT_UM]
    grid = np.unique(np.concatenate([vis_grid, sky_wl[in_ir]]))
    sky = np.zeros((n, grid.size))
    sky[:, np.searchsorted(grid, sky_wl[in_ir])] = sky_ir[:, in_ir]

    # --- broadband longwave sky for the thermal layer -----------------------------------------
    sel = (sky_wl >= LONGWAVE_UM[0]) & (sky_wl <= LONGWAVE_UM[1])
    broadband = _broadband(zen, sky_ir[:, sel], sky_wl[sel], t_air)

    # --- paths ------------------------------------------------------------------------------
    tau_m = np.ones((PATH_RANGES_M.size, grid.size))
    rad_m = np.zeros((PATH_RANGES_M.size, grid.size))
    flat = lt.layer_case(t_air, rh, p, [z0])
    for lo, hi, step in vis + ([] if ir is None else [ir]):
        cases = [
            dict(flat, **lt.spectral_case(lo, hi, step), itype=1, iemsct=1, h1=z0, range_km=float(r) / 1e3)
            for r in PATH_RANGES_M
        ]
        runs = run_cached(cases, ran, f"paths {lo:.3g}-{hi:.3g} um")
        wl = runs[0].wavelengths_um
        for j, r in enumerate(runs):
            tau_m[j] = _resample(grid, wl, r.transmittance, tau_m[j])
            rad_m[j] = _resample(grid, wl, r.radiance, rad_m[j])
    ran["paths"] = (
        f"LOWTRAN7 horizontal homogeneous paths (MODEL 7, weather), "
        f"{PATH_RANGES_M.size} ranges {PATH_RANGES_M[0]:g}-{PATH_RANGES_M[-1]:g} m, "
        "times Koschmieder/Kruse aerosol"
    )

    # --- direct sun beyond SOLAR_SPLIT_UM ---------------------------------------------------
    solar = np.zeros((sun.times_s.size, grid.size))
    if sun.up.any() and sun_too and ir is not None:
        zs = sun.zenith_deg[sun.up]
        z_nodes = np.unique(
            np.round(
                np.concatenate(
                    [[zs.min(), zs.max()], np.arange(np.ceil(zs.min()), np.floor(zs.max()) + 0.5, 1.0)]
                ),
                3,
            )
        )
        cases = [
            dict(lt.spectral_case(*ir), model=model, itype=3, iemsct=3, h1=z0, angle=float(zz))
            for zz in z_nodes
        ]
        runs = run_cached(cases, ran, "sun")
        table = np.stack([_resample(grid, r.wavelengths_um, r.solar, np.zeros(grid.size)) for r in runs])
        factor = _earth_sun_factor(scenario, sun.times_s) * _cloud_dni_factor(sun, weather)
        # the wrapper's runs have no aerosol: the vertical aerosol optical depth of the
        # visibility's extinction over a 1.2 km scale height (as the SPCTRL2 branch below
        # SOLAR_SPLIT_UM) times the relative air mass (Kasten 1966), Beer-Lambert
        import pvlib

        tau_aerosol = (
            aerosol_extinction(grid, scenario["atmosphere"]["visibility_km"]) * AEROSOL_SCALE_HEIGHT_M
        )
        airmass = np.asarray(
            pvlib.atmosphere.get_relative_airmass(sun.zenith_deg, model="kasten1966"), dtype=float
        )
        for i in np.flatnonzero(sun.up):
            row = np.array([np.interp(sun.zenith_deg[i], z_nodes, table[:, k]) for k in range(grid.size)])
            row = row * np.exp(-tau_aerosol * np.nan_to_num(airmass[i], nan=38.0))
            solar[i] = np.where(grid >= SOLAR_SPLIT_UM, row * factor[i], 0.0)
        ran["sun"] = (
            f"LOWTRAN7 direct transmitted sun (IEMSCT 3) >= {SOLAR_SPLIT_UM} um, "
            f"{z_nodes.size} zenith nodes, times Koschmieder/Kruse aerosol over "
            f"{AEROSOL_SCALE_HEIGHT_M / 1e3:g} km x air mass"
        )
    return grid, sky, tau_m, rad_m, solar, broadband


def _resample(grid, wl, values, default):
    """values on wl put onto grid where grid lies inside wl's span (linear), else ``default``."""
    inside = (grid >= wl[0] - 1e-9) & (grid <= wl[-1] + 1e-9)
    out = np.array(default, dtype=float, copy=True)
    out[inside] = np.interp(grid[inside], wl, values)
    return out


def _analytic_parts(scenario, w0: dict, bands, sun: SunState, sun_too: bool = True):
    a = scenario["atmosphere"]
    t_air, rh, p = w0["air_temperature_k"], w0["relative_humidity"], w0["pressure_pa"]
    grid = _grid(bands)
    zen = SKY_ZENITH_DEG
    _, eps_sky = effective_sky_temperature(t_air, rh)
    eps_theta = directional_sky_emissivity(zen, float(eps_sky))
    bb = planck.spectral_radiance(grid, t_air) if grid.size else np.zeros(0)
    sky = eps_theta[:, None] * bb[None, :]
    k = (
        water_continuum_absorption(grid, t_air, rh, p)
        + aerosol_extinction(grid, a["visibility_km"])
        + 0.0116e-3 * (grid / 0.55) ** -4.08 * (p / 101325.0)
    )
    tau = np.exp(-np.outer(PATH_RANGES_M, k))
    rad = (1.0 - tau) * bb[None, :]
    lw_bb = STEFAN_BOLTZMANN * t_air**4 / np.pi
    longwave = eps_theta * lw_bb
    broadband = (longwave, float(eps_sky), float(eps_sky) ** 0.25 * t_air)
    solar = np.zeros((sun.times_s.size, grid.size))
    if sun.up.any() and grid.size and sun_too:
        import pvlib

        extra = np.asarray(
            pvlib.irradiance.get_extra_radiation(utc_times(scenario, sun.times_s)), dtype=float
        )
        toa = np.pi * SUN_ANGULAR_RADIUS**2 * planck.spectral_radiance(grid, SUN_TEMPERATURE_K)
        for i in np.flatnonzero(sun.up):
            solar[i] = np.where(
                grid >= SOLAR_SPLIT_UM, toa * extra[i] / 1361.0 * sun.dni_w_m2[i] / extra[i], 0.0
            )
    return grid, sky, tau, rad, solar, broadband


def atmosphere_for(scenario: Scenario, upstream, times_s=None, solar: bool = True) -> Atmosphere:
    """The scenario's :class:`Atmosphere` (see the module doc for what runs when).

    Parameters
    ----------
    scenario : Scenario
    upstream : Usd.Stage
        A stage with the environment layer: weather and sun at the sample times and weather
        nodes (:mod:`humv_usd.usd.environment`).
    times_s : array-like, optional
        Sample times of the sun terms [s after frame 0]; default :func:`frame_times`.
    solar : bool
        Compute the direct sun and the diffuse skylight (False: left zero, for a caller that
        needs only the thermal sky and the paths; it skips SPCTRL2, the LOWTRAN sun runs and
        the pvlib import).

    When the weather's temperature, humidity, pressure or cloud cover vary over the frames
    (:func:`weather_varies`), the sky and the paths are computed at :func:`weather_nodes` (one
    cached LOWTRAN batch per node; the direct sun once) and stored per node.
    """
    a = scenario["atmosphere"]
    t = frame_times(scenario) if times_s is None else np.atleast_1d(np.asarray(times_s, float))
    weather = read_weather(upstream, time_codes(upstream, t))
    w0 = read_weather(upstream, [0.0]).at(0)
    sun = read_sun(upstream, time_codes(upstream, t))
    bands = sensor_bands(scenario)
    ran: dict = {"weather": "frame 0: " + ", ".join(f"{k}={v:g}" for k, v in w0.items())}
    nodes = None
    if bands and weather_varies(weather):
        nodes = weather_nodes(scenario)
        wn = read_weather(upstream, time_codes(upstream, nodes))
        fps = float(scenario["general"]["fps"])
        ran["weather"] = f"{nodes.size} weather nodes (linear between): " + "; ".join(
            f"frame {round(tn * fps)}: T={wn.air_temperature_k[k]:g} K, "
            f"RH={wn.relative_humidity[k]:g}, p={wn.pressure_pa[k]:g} Pa, "
            f"clouds={wn.cloud_cover[k]:g}"
            for k, tn in enumerate(nodes)
        )
        node_weather = [wn.at(k) for k in range(nodes.size)]
    else:
        node_weather = [w0]
    # LOWTRAN7 for the thermal bands and for NIR/SWIR, whose paths cross the water bands
    # (0.94, 1.14, 1.38, 1.87 um) that the analytic model's continuum leaves out
    has_ir = bool(scenario.infrared_sensors) or any(s["band"] in ("NIR", "SWIR") for s in scenario["sensor"])
    z0_km = float(scenario["general"]["elevation_m"]) / 1e3
    # one profile for every weather node (chosen for frame 0's weather with "auto")
    profile = resolve_profile(
        a["profile"], w0["air_temperature_k"], w0["relative_humidity"], w0["pressure_pa"], z0_km
    )
    source = "analytic"
    per_node = None
    if not bands:
        ran["lowtran7"] = "skipped: no sensor"
    elif a["model"] == "analytic":
        ran["lowtran7"] = "skipped: [atmosphere] model = analytic"
    elif not has_ir:
        ran["lowtran7"] = "skipped: no infrared, NIR or SWIR sensor"
    else:
        try:
            per_node = [
                _lowtran_parts(scenario, w, bands, sun, weather, ran, (k == 0 and solar), profile)
                for k, w in enumerate(node_weather)
            ]
            source = "lowtran7"
            ran["lowtran7"] = "ran"
        except lt.LowtranError as e:
            msg = f"{e}; using the analytic atmosphere (Berdahl-Martin sky, Roberts continuum path)"
            warnings.warn(msg, RuntimeWarning, stacklevel=2)
            ran["lowtran7"] = f"failed: {e}"
    if per_node is None:
        per_node = [_analytic_parts(scenario, w, bands, sun, sun_too=solar) for w in node_weather]
        if bands:
            ran["sky"] = "analytic: Berdahl-Martin emissivity, Martin-Berdahl angular law, gray"
            ran["paths"] = "analytic: Roberts water continuum, Kruse aerosol, Rayleigh"
    grid = per_node[0][0]
    skies, taus, rads, lws, epss, t_skies = [], [], [], [], [], []
    for w, (_, sky, tau_m, rad_m, _, (lw, eps, t_sky)) in zip(node_weather, per_node):
        if source == "lowtran7" and grid.size:
            # aerosol (absent from the wrapper's runs) as an absorbing, isothermal extinction
            tau_a = np.exp(-np.outer(PATH_RANGES_M, aerosol_extinction(grid, a["visibility_km"])))
            rad_m = rad_m + tau_m * (1.0 - tau_a) * planck.spectral_radiance(grid, w["air_temperature_k"])
            tau_m = tau_m * tau_a
        skies.append(sky)
        taus.append(tau_m)
        rads.append(rad_m)
        lws.append(np.asarray(lw, float))
        epss.append(eps)
        t_skies.append(t_sky)
    if solar:
        dni_s, dhi_s = _spectrl2(sun, weather, scenario, grid)
        if not sun.up.any():
            ran["sun"] = "skipped: sun below the horizon at every frame"
        elif grid.size and (grid < SOLAR_SPLIT_UM).any():
            ran["skylight"] = f"SPCTRL2 direct and isotropic diffuse < {SOLAR_SPLIT_UM} um"
    else:
        dni_s = dhi_s = np.zeros((sun.times_s.size, grid.size))
        ran["sun"] = "skipped: not asked for (solar=False)"
    direct = per_node[0][4] + dni_s
    diffuse = dhi_s / np.pi
    node_fields = {}
    if nodes is not None:
        node_fields = dict(
            node_times_s=nodes,
            node_sky_radiance=np.stack(skies),
            node_path_transmittance=np.stack(taus),
            node_path_radiance=np.stack(rads),
            node_longwave_radiance=np.stack(lws),
            node_sky_emissivity=np.asarray(epss, float),
            node_sky_temperature_k=np.asarray(t_skies, float),
            node_air_temperature_k=np.array([w["air_temperature_k"] for w in node_weather]),
            node_cloud_cover=np.array([w["cloud_cover"] for w in node_weather]),
        )
    return Atmosphere(
        source=source,
        wavelengths_um=grid,
        sky_zenith_deg=SKY_ZENITH_DEG.copy(),
        sky_radiance=skies[0],
        times_s=t,
        diffuse_radiance=diffuse,
        path_ranges_m=PATH_RANGES_M.copy(),
        path_transmittance=taus[0],
        path_radiance=rads[0],
        solar=direct,
        longwave_radiance=lws[0],
        sky_emissivity=epss[0],
        sky_temperature_k=t_skies[0],
        air_temperature_k=float(w0["air_temperature_k"]),
        profile=profile,
        ran=ran,
        **node_fields,
    )
