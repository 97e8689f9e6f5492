"""Leaves: boundary-layer conductance and the leaf energy balance (trees, bushes, hedges).

A crown is solved as the outer surface of its foliage (a "big leaf" per face, issue 30.2): the
face absorbs sun and long wave on its outer side, exchanges sensible and latent heat through
both sides of its leaves (boundary-layer conductance of a leaf of characteristic dimension d,
twice the one-sided value) and transpires through a stomatal resistance
(:func:`humv_usd.physics.evaporation.surface_resistance`). This module gives the conductance
and the closed-form (linearized) leaf temperature of Campbell & Norman that the tests compare
the slab solve against.

References
----------
.. [1] Campbell, G. S. & Norman, J. M. (1998). An Introduction to Environmental Biophysics,
   2nd ed., Springer: eq. 7.30 (forced convection of a flat leaf), eq. 14.6 (leaf temperature),
   section 7.9 (a factor 1.4 for outdoor turbulence).
.. [2] Jones, H. G. (2014). Plants and Microclimate, 3rd ed., Cambridge Univ. Press, ch. 9
   (leaves within a few K of the air by day when transpiring, 1-3 K below it on clear nights).
"""

from __future__ import annotations

import numpy as np

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics import evaporation as ev

#: molar heat capacity of air [J mol^-1 K^-1] (Campbell & Norman 1998, Table A.1)
MOLAR_HEAT_CAPACITY_AIR = 29.3
#: outdoor turbulence raises a leaf's forced-convection conductance over the wind tunnel's
#: (Campbell & Norman 1998, section 7.9: factor about 1.4)
OUTDOOR_TURBULENCE = 1.4


def leaf_heat_transfer_coefficient(
    wind_speed_m_s, leaf_dimension_m=0.05, sides=2, pressure_pa=101325.0, air_temperature_k=293.15
):
    """Convective heat transfer coefficient of a leaf [W m^-2 K^-1] (per unit leaf area of one
    side, both sides exchanging for ``sides`` = 2).

    Parameters
    ----------
    wind_speed_m_s : numeric
        Wind speed at the leaf [m s^-1]; floored at 0.1 (free convection keeps some exchange).
    leaf_dimension_m : float, default 0.05
        Characteristic dimension d, 0.72 x leaf width [m] (broad leaves 0.03-0.1).
    sides : int, default 2
        Sides that exchange heat.
    pressure_pa, air_temperature_k : numeric
        For the molar density of air.

    Returns
    -------
    numeric
        h = sides x c_p,molar x rho_molar / rho_molar-at-STP x 1.4 x 0.135 sqrt(u / d):
        Campbell & Norman eq. 7.30, g_Ha = 0.135 sqrt(u/d) mol m^-2 s^-1 (one side, laminar),
        times 1.4 outdoors; c_p g_Ha [W m^-2 K^-1] (about 18 W m^-2 K^-1 per side at 2 m/s
        and d = 5 cm).
    """
    u = np.maximum(np.asarray(wind_speed_m_s, dtype=float), 0.1)
    g = OUTDOOR_TURBULENCE * 0.135 * np.sqrt(u / leaf_dimension_m)  # mol m^-2 s^-1 at 20 degC, 101 kPa
    density = (np.asarray(pressure_pa, dtype=float) / 101325.0) * (
        293.15 / np.asarray(air_temperature_k, dtype=float)
    )
    return sides * MOLAR_HEAT_CAPACITY_AIR * g * density


def leaf_temperature(
    absorbed_w_m2,
    air_temperature_k,
    relative_humidity,
    h_conv,
    surface_resistance_s_m,
    emissivity=0.97,
    pressure_pa=101325.0,
    radiating_sides=1,
):
    """Leaf temperature of the linearized leaf energy balance [K] (Campbell & Norman 1998, eq.
    14.6 in conductance form; Penman-Monteith for one leaf).

    Parameters
    ----------
    absorbed_w_m2 : numeric
        Absorbed short and long wave R_abs [W m^-2].
    air_temperature_k, relative_humidity : numeric
        Air temperature [K], relative humidity [0-1].
    h_conv : numeric
        Convective coefficient of the leaf [W m^-2 K^-1] (:func:`leaf_heat_transfer_coefficient`).
    surface_resistance_s_m : numeric
        Stomatal resistance [s m^-1] in series with the boundary layer (r_a = rho c_p / h).
    emissivity : float
        Leaf emissivity [0-1].
    pressure_pa : numeric
        Air pressure [Pa].
    radiating_sides : int
        Sides that emit long wave (1: the outer surface of a crown).

    Returns
    -------
    numeric
        T_l = T_a + [R_abs - n eps sigma T_a^4 - lambda E(T_a)] / (h_r + h + lambda dE/dT),
        with h_r = 4 n eps sigma T_a^3, lambda E(T_a) = beta h / gamma (e_s(T_a) - e_a) and its
        slope beta h s / gamma: the balance linearized about the air temperature (exact to
        first order in T_l - T_a).
    """
    ta = np.asarray(air_temperature_k, dtype=float)
    beta = ev.evaporation_efficiency(h_conv, surface_resistance_s_m, pressure_pa, ta)
    gamma = ev.psychrometric_constant(pressure_pa, ta)
    vpd = ev.saturation_vapour_pressure(ta) * (1.0 - np.asarray(relative_humidity, dtype=float))
    le0 = beta * h_conv / gamma * vpd
    slope = beta * h_conv / gamma * ev.saturation_slope(ta)
    emitted = radiating_sides * emissivity * STEFAN_BOLTZMANN * ta**4
    h_r = 4.0 * radiating_sides * emissivity * STEFAN_BOLTZMANN * ta**3
    return ta + (absorbed_w_m2 - emitted - le0) / (h_r + h_conv + slope)
