"""Physical constants and fixed conventions used across HumV-USD (one definition each).

SI units. The CODATA values are exact in the 2019 SI except the Stefan-Boltzmann constant,
which follows from them (CODATA 2018, exact to the digits given).

References
----------
- E. Tiesinga et al., CODATA recommended values of the fundamental physical constants: 2018,
  Rev. Mod. Phys. 93, 025010 (2021).
- IAU 2015 Resolution B3 on recommended nominal conversion constants for selected solar and
  planetary properties (Prsa et al., AJ 152, 41, 2016): nominal solar effective temperature
  5772 K and nominal solar radius 6.957e8 m.
- IAU 2012 Resolution B2: the astronomical unit, 149 597 870 700 m.
"""

from __future__ import annotations

#: Planck constant h [J s] (CODATA 2018, exact).
PLANCK_CONSTANT = 6.62607015e-34
#: Speed of light in vacuum c [m s^-1] (exact).
SPEED_OF_LIGHT = 299792458.0
#: Boltzmann constant k [J K^-1] (CODATA 2018, exact).
BOLTZMANN_CONSTANT = 1.380649e-23
#: Stefan-Boltzmann constant sigma [W m^-2 K^-4] (CODATA 2018).
STEFAN_BOLTZMANN = 5.670374419e-8

#: Nominal effective temperature of the Sun [K] (IAU 2015 Resolution B3).
SUN_TEMPERATURE_K = 5772.0
#: Nominal solar radius [m] (IAU 2015 Resolution B3).
SUN_RADIUS_M = 6.957e8
#: Astronomical unit [m] (IAU 2012 Resolution B2).
ASTRONOMICAL_UNIT_M = 1.495978707e11
#: Angular radius of the Sun seen from 1 au [rad].
SUN_ANGULAR_RADIUS = SUN_RADIUS_M / ASTRONOMICAL_UNIT_M

#: Temperatures a stage may hold for surfaces and the sky [K] (checked by the readers, the
#: render and ``humv-usd check``): a wide sanity range, not a physical limit.
TEMPERATURE_RANGE_K = (1.0, 5000.0)

#: Temperature of the blackbody that weights a spectral emissivity (or transmittance) into a
#: band or sub-band value [K]: a scene near ambient temperature, where the weighting matters.
EMISSIVITY_WEIGHTING_TEMPERATURE_K = 300.0
