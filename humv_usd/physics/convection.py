"""Convective and linearized radiative heat-transfer coefficients of a clothed person.

The seed's h = 10.45 - V + 10 sqrt(V) is Siple & Passel's (1945) wind-chill coefficient in
kcal m^-2 h^-1 K^-1; here it returns W m^-2 K^-1. The modern default is Mitchell's (1974)
forced-convection coefficient of a person, h_c = 8.3 V^0.6 (ASHRAE Fundamentals), with the
ISO 7730 natural-convection floor 2.38 |dT|^0.25.
"""

from __future__ import annotations

import numpy as np

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics.checks import require

KCAL_PER_HOUR_TO_WATT = 1.163  # 1 kcal h^-1 = 1.163 W (international table calorie)

# Siple-Passel polynomial peaks at V = 25 m/s and falls beyond: hold it there
_SIPLE_PASSEL_MAX_WIND = 25.0


def siple_passel(wind_speed):
    """Siple & Passel (1945) wind-chill heat-transfer coefficient (the seed's h).

    Parameters
    ----------
    wind_speed : numeric
        Wind speed [m/s]; clipped to [0, 25].

    Returns
    -------
    numeric
        Combined convective heat-transfer coefficient [W m^-2 K^-1].

    Notes
    -----
    h = 1.163 (10.45 - V + 10 sqrt(V)), the original being in kcal m^-2 h^-1 K^-1. Fitted to the
    cooling of a water-filled plastic cylinder (5.7 cm diameter) at Little America, Antarctica,
    winds about 0-12 m/s; it is commonly used up to about 20 m/s. The polynomial has its maximum
    at V = 25 m/s (35.45 kcal m^-2 h^-1 K^-1 = 41.23 W m^-2 K^-1) and decreases beyond, which
    is unphysical, so V is clipped there. At V = 0 it still gives 12.15 W m^-2 K^-1: it includes
    a still-air (natural convection plus part of radiation) contribution.

    References
    ----------
    .. [1] Siple, P. A., Passel, C. F. (1945). Measurements of dry atmospheric cooling in
       subfreezing temperatures. Proc. Am. Philos. Soc. 89(1), 177-199.
    """
    v = np.clip(require("wind_speed", wind_speed), 0.0, _SIPLE_PASSEL_MAX_WIND)
    return KCAL_PER_HOUR_TO_WATT * (10.45 - v + 10.0 * np.sqrt(v))


def mitchell(wind_speed):
    """Forced-convection coefficient of a person in moving air (Mitchell 1974).

    Parameters
    ----------
    wind_speed : numeric
        Relative air speed [m/s]; negative values are clipped to 0.

    Returns
    -------
    numeric
        Forced-convection heat-transfer coefficient [W m^-2 K^-1].

    Notes
    -----
    h_c = 8.3 V^0.6, listed in ASHRAE Fundamentals (ch. 9, Thermal comfort) for
    0.2 < V < 4 m/s; beyond that it is the standard cylinder-in-crossflow exponent extrapolated.
    It goes to 0 in still air: combine with a natural-convection floor
    (:py:func:`natural_iso7730`), as :py:func:`convective_coefficient` does.

    References
    ----------
    .. [1] Mitchell, D. (1974). Convective heat transfer from man and other animals. In Heat Loss
       from Animals and Man (Monteith, Mount, eds.), Butterworth, London, 59-76.
    .. [2] ASHRAE (2017). ASHRAE Handbook - Fundamentals, ch. 9, Table 6.
    """
    v = np.maximum(require("wind_speed", wind_speed), 0.0)
    return 8.3 * v**0.6


def natural_iso7730(delta_t):
    """Natural-convection coefficient of a clothed person (ISO 7730).

    Parameters
    ----------
    delta_t : numeric
        Clothing surface minus air temperature [K].

    Returns
    -------
    numeric
        Natural-convection heat-transfer coefficient [W m^-2 K^-1].

    Notes
    -----
    h_c = 2.38 |T_cl - T_a|^0.25 (Fanger's PMV model as standardized in ISO 7730).

    References
    ----------
    .. [1] ISO 7730:2005. Ergonomics of the thermal environment - Analytical determination and
       interpretation of thermal comfort using calculation of the PMV and PPD indices.
    """
    return 2.38 * np.abs(require("delta_t", delta_t)) ** 0.25


def iso7730(wind_speed, delta_t=0.0):
    """Convective coefficient of a clothed person, ISO 7730 (Fanger).

    Parameters
    ----------
    wind_speed : numeric
        Relative air speed [m/s].
    delta_t : numeric, default 0
        Clothing surface minus air temperature [K].

    Returns
    -------
    numeric
        Convective heat-transfer coefficient [W m^-2 K^-1].

    Notes
    -----
    h_c = max(2.38 |T_cl - T_a|^0.25, 12.1 sqrt(V)).

    References
    ----------
    .. [1] ISO 7730:2005, Annex D.
    """
    v = np.maximum(require("wind_speed", wind_speed), 0.0)
    return np.maximum(natural_iso7730(delta_t), 12.1 * np.sqrt(v))


def watmuff(wind_speed):
    """Wind convection coefficient of a flat outdoor surface (ground, walls, panels).

    Parameters
    ----------
    wind_speed : numeric
        Wind speed [m/s] (negative values are clipped to 0).

    Returns
    -------
    numeric
        h = 2.8 + 3.0 V [W m^-2 K^-1].

    Notes
    -----
    Watmuff et al. corrected McAdams' h = 5.7 + 3.8 V for the long-wave radiation that the
    original plate measurement included, so this is convection alone (radiation is a separate
    term in :mod:`humv_usd.physics.slab`). Valid for about 0-7 m/s; used beyond as is.

    References
    ----------
    .. [1] Watmuff, J. H., Charters, W. W. S., Proctor, D. (1977). Solar and wind induced
       external coefficients for solar collectors. COMPLES 2, 56.
    .. [2] Duffie, J. A., Beckman, W. A. (2013). Solar Engineering of Thermal Processes, 4th ed.,
       section 3.15.
    """
    return 2.8 + 3.0 * np.maximum(require("wind_speed", wind_speed), 0.0)


def convective_coefficient(wind_speed, delta_t=0.0, model="mitchell"):
    """Convective heat-transfer coefficient of a clothed surface by model name.

    Parameters
    ----------
    wind_speed : numeric
        Wind speed [m/s].
    delta_t : numeric, default 0
        Surface minus air temperature [K]; used by the natural-convection floor.
    model : str, default 'mitchell'
        'mitchell' (max of 8.3 V^0.6 and 2.38 |dT|^0.25), 'iso7730' (max of 12.1 sqrt(V) and
        2.38 |dT|^0.25) or 'siple_passel' (the seed's coefficient).

    Returns
    -------
    numeric
        Heat-transfer coefficient [W m^-2 K^-1].

    Raises
    ------
    ValueError
        If ``model`` is not one of the above.
    """
    if model == "mitchell":
        return np.maximum(mitchell(wind_speed), natural_iso7730(delta_t))
    if model == "iso7730":
        return iso7730(wind_speed, delta_t)
    if model == "siple_passel":
        return siple_passel(wind_speed) + 0.0 * require("delta_t", delta_t)
    raise ValueError(f"invalid model selection {model}")


def radiative_coefficient(emissivity, mean_temperature_k):
    """Linearized radiative heat-transfer coefficient.

    Parameters
    ----------
    emissivity : numeric
        Effective emissivity (or exchange factor) [0-1].
    mean_temperature_k : numeric
        Mean of the two exchanging surface temperatures [K].

    Returns
    -------
    numeric
        h_r [W m^-2 K^-1].

    Notes
    -----
    h_r = 4 eps sigma T_m^3. Exactly, eps sigma (T1^4 - T2^4) = h_r (T1 - T2) (1 + (dT / 2 T_m)^2),
    so the linearization underestimates the exchange by 0.11 % for dT = 20 K at 300 K. It is the
    seed's Eq. 7 radiation term with T_m = (T_a + T_skin) / 2.

    References
    ----------
    .. [1] Incropera, F. P., DeWitt, D. P. et al. (2007). Fundamentals of Heat and Mass Transfer,
       6th ed., Wiley, Eq. 1.9.
    """
    t = require("mean_temperature_k", mean_temperature_k, 0.0, 1e4)
    return 4.0 * require("emissivity", emissivity, 0.0, 1.0) * STEFAN_BOLTZMANN * t**3


def relative_air_velocity(body_velocity_m_s, wind_speed_m_s, wind_direction_deg=None):
    """Horizontal velocity of the air relative to a moving body [m/s], (..., 2) x east, y north.

    See :func:`relative_air_speed` for the parameters. Without a wind direction the wind is
    taken across the body's motion (perpendicular, to its left).
    """
    v = np.asarray(body_velocity_m_s, dtype=float)[..., :2]
    w = np.asarray(wind_speed_m_s, dtype=float)
    if wind_direction_deg is None:
        speed = np.linalg.norm(v, axis=-1)
        unit = np.where(speed[..., None] > 0, v / np.maximum(speed, 1e-300)[..., None], [1.0, 0.0])
        across = np.stack([-unit[..., 1], unit[..., 0]], axis=-1)
        return w[..., None] * across - v
    theta = np.radians(np.asarray(wind_direction_deg, dtype=float))
    return np.stack([-w * np.sin(theta) - v[..., 0], -w * np.cos(theta) - v[..., 1]], axis=-1)


#: Kinematic viscosity [m^2 s^-1] and Prandtl number of air at 20 degC, 1 atm (Incropera et al.
#: 2007, Table A.4).
AIR_KINEMATIC_VISCOSITY_M2_S = 1.516e-5
AIR_PRANDTL = 0.713
#: Characteristic diameter of a body segment in cross-flow [m] (limbs 0.08-0.12 m, torso about
#: 0.3 m; a single value: the distribution's shape changes slowly with it).
SEGMENT_DIAMETER_M = 0.15
#: Local over mean Nusselt number at 90 deg from the stagnation line of a cylinder in cross-flow,
#: near the laminar separation (Giedt 1949, Fig. 5; Zukauskas 1972: 0.45-0.6 of the mean for
#: Re 7e4-2e5).
SEPARATION_RATIO = 0.5


def churchill_bernstein(reynolds, prandtl=AIR_PRANDTL):
    """Mean Nusselt number of a cylinder in cross-flow (Churchill & Bernstein 1977; Incropera et
    al. 2007, Eq. 7.54), valid for Re Pr > 0.2."""
    re = np.asarray(reynolds, dtype=float)
    pr = float(prandtl)
    return (
        0.3
        + 0.62
        * re**0.5
        * pr ** (1 / 3)
        / (1 + (0.4 / pr) ** (2 / 3)) ** 0.25
        * (1 + (re / 282000.0) ** 0.625) ** 0.8
    )


def windward_ratio(cos_theta, air_speed_m_s, diameter_m=SEGMENT_DIAMETER_M):
    """Local over mean forced-convection coefficient of a surface element whose outward normal
    makes the angle theta with the direction the air comes from (windward 0, leeward 180 deg).

    Parameters
    ----------
    cos_theta : numeric
        cos(theta) [-1, 1]; a normal facing the oncoming air has +1.
    air_speed_m_s : numeric
        Relative air speed [m/s] (for the Reynolds number).
    diameter_m : float
        Characteristic diameter [m].

    Returns
    -------
    numeric
        h(theta) / h_mean >= 0; its mean over the circumference is 1.

    Notes
    -----
    The cross-flow cylinder's local Nusselt number (Giedt 1949): highest on the stagnation line,
    lowest near the separation at about 90 deg, partly recovering in the wake. Modelled as
    r = 1 + c1 cos(theta) + c2 cos(2 theta), whose circumference mean is 1, with
    r(0) = Nu_0 / Nu_mean: Froessling's stagnation-line Nu_0 = 1.14 Re^0.5 Pr^0.4 (Incropera et
    al. 2007, Eq. 7.51 and Sec. 7.4.1) over Churchill & Bernstein's mean, and
    r(90 deg) = :data:`SEPARATION_RATIO`: c2 = 1 - r(90), c1 = r(0) - 1 - c2. At 3 m/s
    (Re = 3.0e4): windward 1.71, sides 0.5, leeward 1.29 times the mean; at 30 m/s (Re = 3e5,
    past the drag crisis) the wake side takes the larger share, as Giedt measured at 2.2e5. A body is not a cylinder:
    callers renormalise the ratio to a mean of 1 over each segment's facets, so the segment's
    mean coefficient (and the physiology's exchange) is unchanged and only its distribution is
    this model's.
    """
    c = np.clip(np.asarray(cos_theta, dtype=float), -1.0, 1.0)
    re = np.maximum(np.asarray(air_speed_m_s, dtype=float), 1e-6) * diameter_m / AIR_KINEMATIC_VISCOSITY_M2_S
    r0 = 1.14 * re**0.5 * AIR_PRANDTL**0.4 / churchill_bernstein(re)
    c2 = 1.0 - SEPARATION_RATIO
    c1 = r0 - 1.0 - c2
    return np.maximum(1.0 + c1 * c + c2 * (2.0 * c * c - 1.0), 0.0)


def relative_air_speed(body_velocity_m_s, wind_speed_m_s, wind_direction_deg=None):
    """Speed of the air relative to a moving body [m/s] (the speed that forced convection sees).

    Parameters
    ----------
    body_velocity_m_s : array_like
        (..., 2 or 3) velocity of the body over the ground [m/s], x east, y north (z ignored).
    wind_speed_m_s : numeric
        Wind speed over the ground [m/s].
    wind_direction_deg : numeric, optional
        Compass direction the wind blows FROM [deg]. Omitted, the body is taken to move across
        the wind and the two speeds add in quadrature.

    Returns
    -------
    numeric
        |u_wind - u_body| [m/s] in the horizontal.

    Notes
    -----
    A walker at 1.4 m/s in calm air meets 1.4 m/s of air; walking into a 3 m/s head wind, 4.4 m/s;
    with it, 1.6 m/s. The wind blowing from compass direction theta moves the air along
    -(sin theta, cos theta). Body-movement corrections of the same kind are ISO 9920:2007
    Annex E's walking speed in the relative air velocity and ASHRAE Fundamentals (2021) ch. 9.
    """
    return np.linalg.norm(
        relative_air_velocity(body_velocity_m_s, wind_speed_m_s, wind_direction_deg), axis=-1
    )
