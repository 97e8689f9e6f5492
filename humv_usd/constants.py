"""Physical constants and modelling conventions shared by the tools (one definition each)."""

from __future__ import annotations

#: Stefan-Boltzmann constant [W m^-2 K^-4] (CODATA 2018).
STEFAN_BOLTZMANN = 5.670374419e-8

#: Temperature of the blackbody that weights a spectral emissivity over a band [K]: the band
#: emissivity of :func:`humv_usd.usd.materials.band_emissivity`, used alike by the thermal solve
#: and the render (Kirchhoff: one number per material and band).
WEIGHTING_TEMPERATURE_K = 300.0
