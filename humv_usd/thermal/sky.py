"""Sky radiance by direction, in broadband shortwave and longwave "bands", with cloud cover.

The longwave sky is either the atmosphere layer's table of broadband radiance against zenith
(``humv:atmosphere:skyLongwaveRadiance`` on ``skyZenithAngles``: LOWTRAN7 when it ran, else the
analytic law below; :func:`stage_longwave_table` reads it) or, without an atmosphere layer, the
analytic sky: the Berdahl & Martin (1984) clear-sky emissivity (``humv_usd.physics.sky``) spread
over zenith angle with an angular model. Cloud cover enters both through the Crawford & Duchon
(1999) mix (:func:`cloudy_sky_emissivity`): the atmosphere layer applies it to the table it
authors (broadband and spectral, so the render sees the same sky), the analytic sky here. The
shortwave sky is an isotropic diffuse sky, the sun is a separate directional term, and below
the horizon an infinite flat ground reflects and emits.

Directions are unit vectors in the stage frame (Z up). Radiance [W m^-2 sr^-1], irradiance
[W m^-2]. Band 0 is shortwave (solar, 0.3-3 um), band 1 longwave (thermal, 3-100 um).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics.sky import (
    cloudy_sky_emissivity,
    effective_sky_temperature,
    hemispherical_irradiance,
    martin_berdahl_law,
    zenith_emissivity_martin_berdahl,
)
from humv_usd.usd.atmosphere import longwave_sky

#: the atmosphere layer's broadband long-wave sky (``stage_longwave_table(stage, time)``)
stage_longwave_table = longwave_sky

BANDS = ("shortwave", "longwave")
SHORTWAVE, LONGWAVE = 0, 1

# Unsworth & Monteith (1975): eps(theta) = a + b ln(sec theta), b from their Table 2 (clear sky)
_UNSWORTH_MONTEITH_B = 0.09


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
        eps = martin_berdahl_law(float(zenith_emissivity_martin_berdahl(eps_sky)), mu)
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
    """Sky (analytic or tabulated longwave, with clouds) over an infinite flat ground, with the
    sun as a directional term.

    Parameters
    ----------
    air_temperature_k : float
        Screen-level air temperature [K].
    relative_humidity : float
        [0-1]; sets the clear-sky eps_sky via Berdahl & Martin (1984).
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
        Angular clear-sky emissivity model (see :func:`angular_sky_emissivity`).
    sky_emissivity : float or None
        Override the clear-sky eps_sky; None -> Berdahl & Martin.
    cloud_cover : float
        Cloud fraction [0-1] of the analytic sky (:func:`cloudy_sky_emissivity`); not applied
        to a table (the atmosphere layer's table already has it).
    longwave_zenith_deg, longwave_radiance : tuple or None
        Longwave sky radiance [W m^-2 sr^-1] tabulated against zenith [deg] (the atmosphere
        layer's ``skyLongwaveRadiance``); when given it replaces the analytic longwave sky, linear
        in zenith between the nodes and constant beyond the last one (89 deg) to the horizon.
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
    cloud_cover: float = 0.0
    longwave_zenith_deg: tuple | None = None
    longwave_radiance: tuple | None = None

    bands = BANDS

    @property
    def tabulated(self) -> bool:
        """True when the longwave sky comes from a table (the atmosphere layer)."""
        return self.longwave_radiance is not None

    @property
    def clear_emissivity(self) -> float:
        """Hemispherical clear-sky emissivity of the analytic sky [0-1]."""
        if self.sky_emissivity is not None:
            return float(self.sky_emissivity)
        return float(effective_sky_temperature(self.air_temperature_k, self.relative_humidity)[1])

    @property
    def emissivity(self) -> float:
        """Hemispherical effective sky emissivity E_sky / (sigma T_air^4) [0-1]: of the table,
        else the analytic clear sky with the cloud mix."""
        if self.tabulated:
            return self.longwave_irradiance() / (STEFAN_BOLTZMANN * float(self.air_temperature_k) ** 4)
        return float(cloudy_sky_emissivity(self.clear_emissivity, self.cloud_cover))

    def longwave_irradiance(self) -> float:
        """Downwelling longwave sky irradiance on a horizontal plane E_sky [W m^-2]: the table's
        :func:`hemispherical_irradiance`, else eps sigma T_air^4."""
        if self.tabulated:
            return hemispherical_irradiance(self.longwave_zenith_deg, self.longwave_radiance)
        return self.emissivity * STEFAN_BOLTZMANN * float(self.air_temperature_k) ** 4

    def longwave_sky_radiance(self, zenith_rad) -> np.ndarray:
        """Longwave sky radiance [W m^-2 sr^-1] at zenith angles [rad] above the horizon."""
        zen = np.asarray(zenith_rad, dtype=float)
        if self.tabulated:
            return np.interp(
                np.degrees(zen),
                np.asarray(self.longwave_zenith_deg, float),
                np.asarray(self.longwave_radiance, float),
            )
        eps = cloudy_sky_emissivity(
            angular_sky_emissivity(zen, self.clear_emissivity, self.model), self.cloud_cover
        )
        return eps * STEFAN_BOLTZMANN * float(self.air_temperature_k) ** 4 / np.pi

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
        return np.array([sw, self.longwave_irradiance()])

    def ground_radiance(self) -> np.ndarray:
        """Per-band radiance leaving the (Lambertian) ground [W m^-2 sr^-1]."""
        t_g = self.air_temperature_k if self.ground_temperature_k is None else self.ground_temperature_k
        e_down = self.downwelling_irradiance()
        sw = self.ground_solar_reflectance * e_down[0] / np.pi
        lw = (
            self.ground_emissivity * STEFAN_BOLTZMANN * float(t_g) ** 4
            + (1.0 - self.ground_emissivity) * e_down[1]
        ) / np.pi
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
        sky_lw = self.longwave_sky_radiance(np.minimum(zen, 0.5 * np.pi))
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
