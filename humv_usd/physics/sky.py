"""Clear-sky thermal radiation near the ground: dew point and effective sky temperature.

Placeholder sky of the foundation: one effective (broadband, hemispherical) sky temperature.
The atmosphere issue replaces it with LOWTRAN7 band radiance against zenith angle.
"""
from __future__ import annotations

import numpy as np

STEFAN_BOLTZMANN = 5.670374419e-8  # [W m^-2 K^-4], CODATA 2018

# Magnus coefficients over water, Alduchov & Eskridge (1996): a [-], b [degC]
_MAGNUS_A = 17.625
_MAGNUS_B = 243.04


def dew_point(air_temperature_k, relative_humidity):
    """Dew-point temperature from air temperature and relative humidity (Magnus formula).

    Parameters
    ----------
    air_temperature_k : numeric
        Air temperature [K].
    relative_humidity : numeric
        Relative humidity over water [0-1]; values are clipped to [1e-6, 1].

    Returns
    -------
    numeric
        Dew-point temperature [K].

    Notes
    -----
    With t the air temperature in degC, a = 17.625 and b = 243.04 degC,
    gamma = ln(RH) + a t / (b + t) and T_dp = b gamma / (a - gamma).
    Accurate to about 0.35 K between -40 and +50 degC.

    References
    ----------
    .. [1] Alduchov, O. A., Eskridge, R. E. (1996). Improved Magnus form approximation of
       saturation vapor pressure. J. Appl. Meteor. 35, 601-609.
    """
    t_c = np.asarray(air_temperature_k, dtype=float) - 273.15
    rh = np.clip(np.asarray(relative_humidity, dtype=float), 1e-6, 1.0)
    gamma = np.log(rh) + _MAGNUS_A * t_c / (_MAGNUS_B + t_c)
    return _MAGNUS_B * gamma / (_MAGNUS_A - gamma) + 273.15


def berdahl_martin_emissivity(dew_point_k):
    """Clear-sky effective emissivity from the dew point (Berdahl & Martin 1984).

    Parameters
    ----------
    dew_point_k : numeric
        Dew-point temperature [K].

    Returns
    -------
    numeric
        Hemispherical broadband clear-sky emissivity [0-1], clipped to [0.3, 1].

    Notes
    -----
    eps = 0.711 + 0.56 (T_dp/100) + 0.73 (T_dp/100)^2 with T_dp in degC; fitted to nighttime
    and daytime pyrgeometer data in six US cities, T_dp from -20 to +30 degC. The daytime
    correction (+0.013 cos(2 pi hour/24)) and the pressure correction are below 1.5 % and left out.

    References
    ----------
    .. [1] Berdahl, P., Martin, M. (1984). Emissivity of clear skies. Solar Energy 32(5),
       663-664.
    """
    tdp = (np.asarray(dew_point_k, dtype=float) - 273.15) / 100.0
    return np.clip(0.711 + 0.56 * tdp + 0.73 * tdp * tdp, 0.3, 1.0)


def effective_sky_temperature(air_temperature_k, relative_humidity):
    """Effective sky temperature T_sky = eps_sky^(1/4) T_air (clear sky, Berdahl & Martin).

    Parameters
    ----------
    air_temperature_k : numeric
        Air temperature near the ground [K].
    relative_humidity : numeric
        Relative humidity [0-1].

    Returns
    -------
    tuple of numeric
        (sky temperature [K], sky emissivity [0-1]); sigma T_sky^4 is the downwelling
        longwave irradiance of a blackbody sky with the same total flux.

    References
    ----------
    .. [1] Berdahl, P., Martin, M. (1984). Emissivity of clear skies. Solar Energy 32(5), 663.
    """
    eps = berdahl_martin_emissivity(dew_point(air_temperature_k, relative_humidity))
    return eps ** 0.25 * np.asarray(air_temperature_k, dtype=float), eps
