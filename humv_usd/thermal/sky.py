"""Analytic clear-sky radiance by direction, in broadband shortwave and longwave "bands".

Stand-in for the atmosphere tool until LOWTRAN7 sky radiance by zenith lands: the longwave sky is
the Berdahl & Martin (1984) effective emissivity (``humv_usd.physics.sky``) spread over zenith
angle with an angular model, the shortwave sky is an isotropic diffuse sky, the sun is a separate
directional term, and below the horizon an infinite flat ground reflects and emits.

Directions are unit vectors in the stage frame (Z up). Radiance [W m^-2 sr^-1], irradiance
[W m^-2]. Band 0 is shortwave (solar, 0.3-3 um), band 1 longwave (thermal, 3-100 um).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.physics.sky import STEFAN_BOLTZMANN, effective_sky_temperature

BANDS = ("shortwave", "longwave")
SHORTWAVE, LONGWAVE = 0, 1

# Unsworth & Monteith (1975): eps(theta) = a + b ln(sec theta), b from their Table 2 (clear sky)
_UNSWORTH_MONTEITH_B = 0.09


def _martin_berdahl(zenith_emissivity, mu):
    # mu -> 0 makes the exponent blow up; (1-eps_z)^inf = 0 -> eps = 1 at the horizon
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        out = 1.0 - np.power(1.0 - zenith_emissivity, 1.0 / np.maximum(mu, 1e-12))
    return np.where(mu > 0, out, 1.0)


_GAUSS = {}


def _hemispherical_martin_berdahl(zenith_emissivity, n=400):
    """2 int_0^1 eps(mu) mu dmu by Gauss-Legendre in mu (bounded, smooth on (0, 1])."""
    if n not in _GAUSS:
        _GAUSS[n] = np.polynomial.legendre.leggauss(n)
    x, w = _GAUSS[n]
    mu = 0.5 * (x + 1.0)
    eps = _martin_berdahl(np.asarray(zenith_emissivity, dtype=float)[..., None], mu)
    return np.sum(eps * mu * w, axis=-1)  # 2 * 0.5 * sum(...)


def zenith_emissivity_martin_berdahl(sky_emissivity):
    """Zenith emissivity eps_z whose Martin-Berdahl angular law has hemispherical value eps_sky.

    Parameters
    ----------
    sky_emissivity : numeric
        Hemispherical (flux) clear-sky emissivity [0-1].

    Returns
    -------
    numeric
        Zenith emissivity eps_z [0-1] with 2 int eps(theta) cos sin dtheta = eps_sky.

    Notes
    -----
    Solved by bisection (the hemispherical value is monotonic in eps_z). Martin & Berdahl (1984)
    fit eps_z ~ 1 - (1 - eps_sky)^(1/1.8); solving keeps the downwelling flux identical to the
    Berdahl & Martin hemispherical emissivity the rest of the code uses.
    """
    target = np.clip(np.asarray(sky_emissivity, dtype=float), 0.0, 1.0)
    lo, hi = np.zeros_like(target), np.array(target, copy=True)  # eps_z <= eps_sky
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        too_low = _hemispherical_martin_berdahl(mid) < target
        lo, hi = np.where(too_low, mid, lo), np.where(too_low, hi, mid)
    return 0.5 * (lo + hi)


def angular_sky_emissivity(zenith_rad, sky_emissivity, model="martin_berdahl"):
    """Directional clear-sky emissivity eps(theta) with a given hemispherical value.

    Parameters
    ----------
    zenith_rad : numeric
        Zenith angle of the viewing direction [rad], 0 = straight up; >= pi/2 gives 1.
    sky_emissivity : float
        Hemispherical clear-sky emissivity eps_sky [0-1] (e.g. Berdahl & Martin 1984).
    model : {'martin_berdahl', 'unsworth_monteith', 'isotropic'}

    Returns
    -------
    numeric
        eps(theta) [0-1]; for every model 2 int_0^(pi/2) eps cos sin dtheta = eps_sky (the
        Unsworth-Monteith line is clipped at 1 near the horizon, which adds < 0.2 %).

    Notes
    -----
    martin_berdahl: eps(theta) = 1 - (1 - eps_z)^(1/cos theta), the slab-atmosphere law of
    Martin & Berdahl (1984), with eps_z from :func:`zenith_emissivity_martin_berdahl`.
    unsworth_monteith: eps(theta) = a + b ln(sec theta), b = 0.09, a = eps_sky - b/2 (since
    2 int_0^1 mu ln(1/mu) dmu = 1/2).
    isotropic: eps(theta) = eps_sky.

    References
    ----------
    .. [1] Martin, M., Berdahl, P. (1984). Characteristics of infrared sky radiation in the
       United States. Solar Energy 33(3/4), 321-336.
    .. [2] Unsworth, M. H., Monteith, J. L. (1975). Long-wave radiation at the ground I.
       Angular distribution of incoming radiation. Q. J. R. Meteorol. Soc. 101, 13-24.
    """
    mu = np.cos(np.asarray(zenith_rad, dtype=float))
    eps_sky = float(sky_emissivity)
    if model == "martin_berdahl":
        eps = _martin_berdahl(float(zenith_emissivity_martin_berdahl(eps_sky)), mu)
    elif model == "unsworth_monteith":
        b = _UNSWORTH_MONTEITH_B
        with np.errstate(divide="ignore"):
            eps = eps_sky - 0.5 * b + b * np.log(1.0 / np.maximum(mu, 1e-300))
        eps = np.clip(eps, 0.0, 1.0)
    elif model == "isotropic":
        eps = np.full_like(mu, eps_sky)
    else:
        raise ValueError(f"invalid model selection {model}")
    return np.where(mu > 0, eps, 1.0)


@dataclass(frozen=True)
class ClearSky:
    """Analytic clear sky over an infinite flat ground, with the sun as a directional term.

    Parameters
    ----------
    air_temperature_k : float
        Screen-level air temperature [K].
    relative_humidity : float
        [0-1]; sets eps_sky via Berdahl & Martin (1984).
    sun_direction : array-like (3,) or None
        Unit vector towards the sun; None or z <= 0 means no sun.
    direct_normal_irradiance : float
        Beam irradiance on a plane normal to the sun [W m^-2].
    diffuse_horizontal_irradiance : float
        Isotropic diffuse sky irradiance on a horizontal plane [W m^-2] (radiance DHI/pi).
    ground_temperature_k : float or None
        Ground surface temperature [K]; None -> air temperature.
    ground_emissivity : float
        Longwave emissivity of the ground [0-1].
    ground_solar_reflectance : float
        Broadband shortwave albedo of the ground [0-1].
    model : str
        Angular sky emissivity model (see :func:`angular_sky_emissivity`).
    sky_emissivity : float or None
        Override eps_sky (e.g. from the atmosphere layer); None -> Berdahl & Martin.
    """

    air_temperature_k: float
    relative_humidity: float = 0.5
    sun_direction: tuple | None = None
    direct_normal_irradiance: float = 0.0
    diffuse_horizontal_irradiance: float = 0.0
    ground_temperature_k: float | None = None
    ground_emissivity: float = 0.95
    ground_solar_reflectance: float = 0.2
    model: str = "martin_berdahl"
    sky_emissivity: float | None = None

    bands = BANDS

    @property
    def emissivity(self) -> float:
        """Hemispherical clear-sky emissivity eps_sky [0-1]."""
        if self.sky_emissivity is not None:
            return float(self.sky_emissivity)
        return float(effective_sky_temperature(self.air_temperature_k, self.relative_humidity)[1])

    @property
    def sun(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(unit direction towards the sun, per-band normal irradiance [W m^-2]) or None."""
        if self.sun_direction is None or self.direct_normal_irradiance <= 0:
            return None
        s = np.asarray(self.sun_direction, dtype=float)
        s = s / np.linalg.norm(s)
        if s[2] <= 0:  # below the horizon
            return None
        return s, np.array([float(self.direct_normal_irradiance), 0.0])

    def downwelling_irradiance(self) -> np.ndarray:
        """Per-band irradiance on an unshaded horizontal plane from sky + sun [W m^-2]."""
        sw = float(self.diffuse_horizontal_irradiance)
        sun = self.sun
        if sun is not None:
            sw += sun[1][0] * sun[0][2]
        lw = self.emissivity * STEFAN_BOLTZMANN * float(self.air_temperature_k) ** 4
        return np.array([sw, lw])

    def ground_radiance(self) -> np.ndarray:
        """Per-band radiance leaving the (Lambertian) ground [W m^-2 sr^-1]."""
        t_g = self.air_temperature_k if self.ground_temperature_k is None else self.ground_temperature_k
        e_down = self.downwelling_irradiance()
        sw = self.ground_solar_reflectance * e_down[0] / np.pi
        lw = (self.ground_emissivity * STEFAN_BOLTZMANN * float(t_g) ** 4
              + (1.0 - self.ground_emissivity) * e_down[1]) / np.pi
        return np.array([sw, lw])

    def radiance(self, directions) -> np.ndarray:
        """Per-band radiance arriving from each direction, sun excluded [W m^-2 sr^-1].

        Parameters
        ----------
        directions : array (N, 3)
            Unit vectors (direction the light comes from).

        Returns
        -------
        array (2, N)
            Shortwave and longwave radiance; z > 0 sky, z <= 0 ground.
        """
        d = np.asarray(directions, dtype=float)
        up = d[:, 2] > 0
        zen = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
        sky_lw = (angular_sky_emissivity(zen, self.emissivity, self.model)
                  * STEFAN_BOLTZMANN * float(self.air_temperature_k) ** 4 / np.pi)
        sky_sw = np.full(len(d), float(self.diffuse_horizontal_irradiance) / np.pi)
        ground = self.ground_radiance()
        return np.stack([np.where(up, sky_sw, ground[0]), np.where(up, sky_lw, ground[1])])


@dataclass(frozen=True)
class UniformSky:
    """Same radiance from every direction (per band), no sun: the closed-form test case."""

    radiance_per_band: tuple = (0.0, 100.0)
    bands = BANDS
    sun = None

    def downwelling_irradiance(self) -> np.ndarray:
        return np.pi * np.asarray(self.radiance_per_band, dtype=float)

    def radiance(self, directions) -> np.ndarray:
        n = len(np.asarray(directions))
        return np.repeat(np.asarray(self.radiance_per_band, dtype=float)[:, None], n, axis=1)
