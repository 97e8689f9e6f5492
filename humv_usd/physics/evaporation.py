"""Evaporation and transpiration from surfaces: vapour pressure, the latent heat flux of a
surface with a surface (stomatal) resistance, Penman-Monteith, the wet-bulb temperature, a
Jarvis-type surface resistance of vegetation and the interception reservoir of a wetted
surface (rain, dew).

The latent flux is written in its surface-temperature ("big leaf") form with the same
aerodynamic conductance as the sensible heat (Lewis / Reynolds analogy, r_a = rho c_p / h):

    LE = (rho c_p / gamma) (e_s(T_s) - e_a) / (r_a + r_s)
       = (h / gamma) (e_s(T_s) - e_a) beta,  beta = 1 / (1 + h r_s / (rho c_p)),

so that a surface with r_s = 0 (free water, a wet film) under no radiation settles at the
psychrometric (wet-bulb) temperature, and Penman-Monteith is this balance with the emission
and e_s linearized about the air temperature (Monteith & Unsworth 2013, ch. 13).

References
----------
.. [1] Allen, R. G., Pereira, L. S., Raes, D. & Smith, M. (1998). Crop evapotranspiration,
   FAO Irrigation and Drainage Paper 56, ch. 2-3 (eqs. 3, 5, 8, 11, 13).
.. [2] Monteith, J. L. & Unsworth, M. H. (2013). Principles of Environmental Physics, 4th ed.,
   Academic Press, ch. 13 (the big-leaf Penman-Monteith equation, the psychrometer).
.. [3] Noilhan, J. & Planton, S. (1989). A simple parameterization of land surface processes for
   meteorological models. Mon. Wea. Rev. 117:536-549 (eqs. 30-34: interception reservoir,
   Jarvis-type surface resistance).
.. [4] Stull, R. (2011). Wet-bulb temperature from relative humidity and air temperature.
   J. Appl. Meteor. Climatol. 50:2267-2269.
"""

from __future__ import annotations

import numpy as np

#: specific heat of air at constant pressure [J kg^-1 K^-1] (FAO-56, eq. 8)
AIR_SPECIFIC_HEAT = 1013.0
#: specific gas constant of dry air [J kg^-1 K^-1]
DRY_AIR_GAS_CONSTANT = 287.05
#: ratio of the molecular weights of water vapour and dry air [-]
MOLECULAR_WEIGHT_RATIO = 0.622
#: largest surface resistance of vegetation (stomata closed, night) [s m^-1] (Noilhan & Planton
#: 1989, r_s,max)
MAX_SURFACE_RESISTANCE_S_M = 5000.0


def saturation_vapour_pressure(temperature_k):
    """Saturation vapour pressure over water [Pa] (Tetens form, FAO-56 eq. 11).

    Parameters
    ----------
    temperature_k : numeric
        Temperature [K]; valid about -40 to +60 degC (over water, also below 0 degC).

    Returns
    -------
    numeric
        e_s = 610.8 exp(17.27 T / (T + 237.3)) with T in degC [Pa].
    """
    t = np.asarray(temperature_k, dtype=float) - 273.15
    return 610.8 * np.exp(17.27 * t / (t + 237.3))


def saturation_slope(temperature_k):
    """Slope d e_s / dT of :func:`saturation_vapour_pressure` [Pa K^-1] (FAO-56 eq. 13)."""
    t = np.asarray(temperature_k, dtype=float) - 273.15
    return saturation_vapour_pressure(temperature_k) * 17.27 * 237.3 / (t + 237.3) ** 2


def latent_heat_of_vaporization(temperature_k):
    """Latent heat of vaporization of water [J kg^-1]: 2.501e6 - 2361 T[degC] (linear fit of
    the steam tables over 0-40 degC; Henderson-Sellers 1984, Q. J. R. Meteorol. Soc. 110:1186)."""
    return 2.501e6 - 2361.0 * (np.asarray(temperature_k, dtype=float) - 273.15)


def psychrometric_constant(pressure_pa, temperature_k=293.15):
    """Psychrometric constant gamma = c_p P / (0.622 lambda) [Pa K^-1] (FAO-56 eq. 8; 66.5 Pa
    K^-1 at sea level and 20 degC)."""
    return (
        AIR_SPECIFIC_HEAT
        * np.asarray(pressure_pa, dtype=float)
        / (MOLECULAR_WEIGHT_RATIO * latent_heat_of_vaporization(temperature_k))
    )


def air_heat_capacity(pressure_pa, air_temperature_k):
    """Volumetric heat capacity of air rho c_p [J m^-3 K^-1] (ideal gas, dry air)."""
    p, t = np.asarray(pressure_pa, dtype=float), np.asarray(air_temperature_k, dtype=float)
    return p / (DRY_AIR_GAS_CONSTANT * t) * AIR_SPECIFIC_HEAT


def evaporation_efficiency(h_conv, surface_resistance_s_m, pressure_pa, air_temperature_k, wet_fraction=0.0):
    """beta [0-1]: the share of a free water surface's latent flux that a surface passes.

    Parameters
    ----------
    h_conv : numeric
        Convective coefficient [W m^-2 K^-1] (the aerodynamic conductance, r_a = rho c_p / h).
    surface_resistance_s_m : numeric
        Surface (bulk stomatal) resistance of the dry part [s m^-1]; 0: free water; ``np.inf``:
        no evaporation (a dry, impervious surface).
    pressure_pa, air_temperature_k : numeric
        Air pressure [Pa] and temperature [K] (for rho c_p).
    wet_fraction : numeric, default 0
        Share of the surface covered by a water film (rain, dew) that evaporates with r_s = 0
        [0-1].

    Returns
    -------
    numeric
        beta = w + (1 - w) / (1 + h r_s / (rho c_p)) (Noilhan & Planton 1989, eq. 32:
        r_a / (r_a + r_s) for the dry part, 1 for the wet part).
    """
    rc = air_heat_capacity(pressure_pa, air_temperature_k)
    rs = np.asarray(surface_resistance_s_m, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        dry = np.where(
            np.isinf(rs),
            0.0,
            1.0 / (1.0 + np.asarray(h_conv, dtype=float) * np.where(np.isinf(rs), 0.0, rs) / rc),
        )
    w = np.clip(np.asarray(wet_fraction, dtype=float), 0.0, 1.0)
    return w + (1.0 - w) * dry


def latent_flux(surface_temperature_k, vapour_pressure_pa, h_conv, beta, pressure_pa, air_temperature_k):
    """Latent heat flux leaving a surface and its derivative in the surface temperature.

    Parameters
    ----------
    surface_temperature_k : numeric
        Surface temperature [K].
    vapour_pressure_pa : numeric
        Vapour pressure of the air e_a = RH e_s(T_air) [Pa].
    h_conv : numeric
        Convective coefficient [W m^-2 K^-1].
    beta : numeric
        :func:`evaporation_efficiency` [0-1].
    pressure_pa, air_temperature_k : numeric
        Air pressure [Pa] and temperature [K] (for gamma).

    Returns
    -------
    tuple
        (LE = beta h / gamma (e_s(T_s) - e_a) [W m^-2], positive: evaporation, negative:
        condensation (dew, through the same conductance); dLE/dT_s [W m^-2 K^-1]).
    """
    gamma = psychrometric_constant(pressure_pa, air_temperature_k)
    c = np.asarray(beta, dtype=float) * np.asarray(h_conv, dtype=float) / gamma
    le = c * (saturation_vapour_pressure(surface_temperature_k) - vapour_pressure_pa)
    return le, c * saturation_slope(surface_temperature_k)


def penman_monteith(
    available_energy_w_m2,
    air_temperature_k,
    relative_humidity,
    aerodynamic_resistance_s_m,
    surface_resistance_s_m,
    pressure_pa=101325.0,
):
    """Latent heat flux of the Penman-Monteith equation [W m^-2] (FAO-56 eq. 3).

    Parameters
    ----------
    available_energy_w_m2 : numeric
        R_n - G [W m^-2]; for the comparison with a surface balance, the isothermal net
        radiation (emission at the air temperature).
    air_temperature_k, relative_humidity : numeric
        Air temperature [K] and relative humidity [0-1].
    aerodynamic_resistance_s_m, surface_resistance_s_m : numeric
        r_a (including the radiative conductance for the isothermal form) and r_s [s m^-1].
    pressure_pa : numeric
        Air pressure [Pa].

    Returns
    -------
    numeric
        lambda E = [Delta (R_n - G) + rho c_p (e_s - e_a) / r_a] / [Delta + gamma (1 + r_s / r_a)].
    """
    es = saturation_vapour_pressure(air_temperature_k)
    delta = saturation_slope(air_temperature_k)
    gamma = psychrometric_constant(pressure_pa, air_temperature_k)
    rc = air_heat_capacity(pressure_pa, air_temperature_k)
    ra = np.asarray(aerodynamic_resistance_s_m, dtype=float)
    vpd = es * (1.0 - np.asarray(relative_humidity, dtype=float))
    return (delta * available_energy_w_m2 + rc * vpd / ra) / (
        delta + gamma * (1.0 + np.asarray(surface_resistance_s_m, dtype=float) / ra)
    )


def wet_bulb_temperature(air_temperature_k, relative_humidity, pressure_pa=101325.0):
    """Psychrometric wet-bulb temperature [K]: the root of e_s(T_w) - gamma (T_a - T_w) = e_a
    (a ventilated wet surface without radiation; Monteith & Unsworth 2013, section 13.1),
    by Newton from T_a (the left side is convex and increasing: monotone convergence)."""
    ta = np.asarray(air_temperature_k, dtype=float)
    ea = np.asarray(relative_humidity, dtype=float) * saturation_vapour_pressure(ta)
    gamma = psychrometric_constant(pressure_pa, ta)
    tw = ta.copy()
    for _ in range(50):
        f = saturation_vapour_pressure(tw) - ea - gamma * (ta - tw)
        d = f / (saturation_slope(tw) + gamma)
        tw = tw - d
        if np.max(np.abs(d)) < 1e-10:
            break
    return tw


def stull_wet_bulb(air_temperature_k, relative_humidity):
    """Wet-bulb temperature [K] of Stull's (2011) empirical fit at 101.325 kPa (-20..50 degC,
    RH 5-99 %; within about -1 to +0.65 K of the psychrometric solution): an independent
    reference for :func:`wet_bulb_temperature`."""
    t = np.asarray(air_temperature_k, dtype=float) - 273.15
    rh = 100.0 * np.asarray(relative_humidity, dtype=float)
    tw = (
        t * np.arctan(0.151977 * np.sqrt(rh + 8.313659))
        + np.arctan(t + rh)
        - np.arctan(rh - 1.676331)
        + 0.00391838 * rh**1.5 * np.arctan(0.023101 * rh)
        - 4.686035
    )
    return tw + 273.15


def surface_resistance(
    minimum_s_m, shortwave_w_m2, soil_moisture=1.0, leaf_area_index=2.88, radiation_limit_w_m2=100.0
):
    """Jarvis-type bulk surface resistance of vegetation [s m^-1] (Noilhan & Planton 1989,
    eqs. 31-34, without the vapour-deficit and temperature factors).

    Parameters
    ----------
    minimum_s_m : numeric
        r_s,min = r_l / LAI: the resistance of a well-watered canopy in full light [s m^-1]
        (grass: 100 / 2.88 = 35 s m^-1, the single-leaf r_l = 100 s m^-1 of FAO-56 eq. 5 over
        the reference grass's LAI; noon gives about 45 s m^-1, the ASCE hourly daytime 50).
    shortwave_w_m2 : numeric
        Incoming short wave on the canopy [W m^-2].
    soil_moisture : numeric, default 1
        Relative available soil water (theta - theta_wilt) / (theta_fc - theta_wilt) [0-1]:
        1 at field capacity, 0 at the wilting point (stomata closed).
    leaf_area_index : float, default 2.88
        LAI [m^2 m^-2] (FAO-56 reference grass, 24 h with h = 0.12 m).
    radiation_limit_w_m2 : float, default 100
        R_gl of the light response (100 W m^-2 for crops and grass) [W m^-2].

    Returns
    -------
    numeric
        r_s = r_s,min F1 / F2, capped at :data:`MAX_SURFACE_RESISTANCE_S_M`;
        F1 = (1 + f) / (f + r_s,min / r_s,max), f = 0.55 (S / R_gl)(2 / LAI); F2 = soil_moisture.
        At night (S = 0) r_s = r_s,max: the stomata close.
    """
    f = (
        0.55
        * np.maximum(np.asarray(shortwave_w_m2, dtype=float), 0.0)
        / radiation_limit_w_m2
        * 2.0
        / leaf_area_index
    )
    rmin = np.asarray(minimum_s_m, dtype=float)
    f1 = (1.0 + f) / (f + rmin / MAX_SURFACE_RESISTANCE_S_M)
    f2 = np.clip(np.asarray(soil_moisture, dtype=float), 0.0, 1.0)
    rs = np.where(f2 > 0.0, rmin * f1 / np.maximum(f2, 1e-12), np.inf)
    return np.minimum(rs, MAX_SURFACE_RESISTANCE_S_M)


def wet_fraction(water_kg_m2, capacity_kg_m2):
    """Share of a surface covered by intercepted or ponded water [0-1]: (W / W_max)^(2/3)
    (Deardorff 1978, J. Geophys. Res. 83:1889; Noilhan & Planton 1989, eq. 30); 0 where the
    capacity is 0."""
    w = np.asarray(water_kg_m2, dtype=float)
    cap = np.asarray(capacity_kg_m2, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cap > 0.0, np.clip(w / np.where(cap > 0.0, cap, 1.0), 0.0, 1.0) ** (2.0 / 3.0), 0.0)


def rain_schedule(times_s, rate_mm_h, end_before_s=0.0, duration_s=7200.0):
    """Rain rate [kg m^-2 s^-1] at ``times_s`` [s after frame 0]: ``rate_mm_h`` from
    ``end_before_s + duration_s`` to ``end_before_s`` seconds before frame 0 (1 mm of rain is
    1 kg m^-2); with ``end_before_s`` = 0 it rains on through the frames."""
    t = np.asarray(times_s, dtype=float)
    start, end = -float(end_before_s) - float(duration_s), -float(end_before_s)
    raining = (t > start) & ((t <= end) | (end_before_s <= 0.0))
    return np.where(raining, float(rate_mm_h) / 3600.0, 0.0)
