"""Diffuse reflectance of a head of hair from its melanin: eumelanin and pheomelanin.

Hair colour is set by two pigments in the keratin fibre: brown-black eumelanin and red-yellow
pheomelanin. Their absorption coefficients, per unit concentration and per fibre diameter, are

    sigma_eu(lambda) = 0.419 (lambda / 0.65 µm)^-3.33
    sigma_ph(lambda) = 0.187 (lambda / 0.65 µm)^-4.75

with the spectral exponents of Donner & Jensen (2006) "A spectral BSSRDF for shading human
skin", EGSR, Eq. 4-5 (eumelanin lambda^-3.33, pheomelanin lambda^-4.75) and the values at the red
end from Chiang, Bitterli, Tappan & Burley (2016) "A practical and controllable hair and fur
model for production path tracing", Computer Graphics Forum 35(2):275, Eq. 9 (their RGB
coefficients (0.419, 0.697, 1.37) and (0.187, 0.4, 1.05); the power laws above reproduce the
green and blue ones to 5 %). ``sigma_a = C_eu sigma_eu + C_ph sigma_ph``; Chiang et al. and pbrt-v3
(Pharr, Jakob & Humphreys 2016, section 9.9) give eumelanin concentrations of about 0.3 for
blond, 1.3 for brown and 8 for black hair.

A fibre, crossed at its mean chord (pi/4 of the diameter for rays across a cylinder), reflects
the Fresnel part ``r_f`` at its keratin surface (n = 1.55: Marschner et al. 2003 "Light
scattering from human hair fibers", ACM TOG 22:780) and passes the rest, attenuated, on: its
single-scattering albedo is

    omega = r_f + (1 - r_f) exp(-sigma_a pi/4)

with ``r_f`` the diffuse (hemispherical) Fresnel reflectance of n = 1.55 (0.099). A head of hair is
many fibres deep; its diffuse reflectance is that of an optically thick layer of isotropic
scatterers, ``R = (1 - gamma) / (1 + gamma)``, ``gamma = sqrt(1 - omega)`` (Hapke 1981, J.
Geophys. Res. 86:3039, Eq. 16). The smooth melanin power laws hold where melanin dominates
(0.4-1.1 µm); the fibre's other absorption (keratin's C-H/N-H bands and its water in the SWIR)
is taken from a measured spectrum of dark hair by inverting the same model
(:func:`other_absorption`: what the measured reflectance needs beyond the dark hair's melanin,
>= 0) and added to every colour, so the colours share the measured SWIR bands and black hair
keeps the measured spectrum (:mod:`humv_usd.catalog.hair`). Grey hair is a mixture of pigmented
and unpigmented fibres: its albedo is the fibre-number-weighted mean.
"""

from __future__ import annotations

import numpy as np

from humv_usd.compat import trapezoid

#: per unit concentration, per fibre diameter, at 0.65 µm (Chiang et al. 2016, red channel)
EUMELANIN_AT_650 = 0.419
PHEOMELANIN_AT_650 = 0.187
#: spectral exponents (Donner & Jensen 2006)
EUMELANIN_EXPONENT = 3.33
PHEOMELANIN_EXPONENT = 4.75
#: keratin's refractive index (Marschner et al. 2003)
KERATIN_INDEX = 1.55
MEAN_CHORD = np.pi / 4.0  # per diameter, rays across a cylinder
WAVELENGTH_RANGE_UM = (0.38, 1.1)

#: hair colour -> (eumelanin, pheomelanin, fraction of unpigmented fibres). Black, brown and
#: blond from Chiang et al. (2016) / pbrt-v3; dark brown between them; red a pheomelanin-rich
#: mix; grey = brown hair with half its fibres white. Concentrations other than 0.3 / 1.3 / 8
#: and the grey fraction are design choices, not measurements.
HAIR_COLOURS = {
    "black": (8.0, 0.0, 0.0),
    "dark_brown": (3.0, 0.0, 0.0),
    "brown": (1.3, 0.0, 0.0),
    "blond": (0.3, 0.0, 0.0),
    "red": (0.4, 2.0, 0.0),
    "grey": (1.3, 0.0, 0.5),
}


def diffuse_fresnel(n: float = KERATIN_INDEX) -> float:
    """Hemispherical reflectance of a smooth dielectric surface lit diffusely from outside
    (unpolarised Fresnel averaged with weight 2 cos(theta) sin(theta)) [-]."""
    theta = np.linspace(0.0, np.pi / 2, 2001)[:-1]
    c = np.cos(theta)
    s = np.sqrt(np.maximum(0.0, 1.0 - (np.sin(theta) / n) ** 2))
    rs = ((c - n * s) / (c + n * s)) ** 2
    rp = ((s - n * c) / (s + n * c)) ** 2
    f = 0.5 * (rs + rp) * 2.0 * c * np.sin(theta)
    return float(trapezoid(f, theta))


def melanin_absorption(wavelength_um, eumelanin: float, pheomelanin: float = 0.0) -> np.ndarray:
    """Absorption coefficient per fibre diameter [-] at ``wavelength_um`` [µm]."""
    w = np.asarray(wavelength_um, dtype=float) / 0.65
    eu = eumelanin * EUMELANIN_AT_650 * w**-EUMELANIN_EXPONENT
    return eu + pheomelanin * PHEOMELANIN_AT_650 * w**-PHEOMELANIN_EXPONENT


def albedo_from_absorption(sigma_a) -> np.ndarray:
    """Single-scattering albedo of one fibre [-] from its absorption per diameter (module doc)."""
    rf = _RF
    return rf + (1.0 - rf) * np.exp(-np.asarray(sigma_a, dtype=float) * MEAN_CHORD)


def layer_reflectance(omega) -> np.ndarray:
    """Hapke (1981) diffuse reflectance of a thick layer of isotropic scatterers of albedo omega."""
    gamma = np.sqrt(1.0 - np.clip(omega, 0.0, 1.0))
    return (1.0 - gamma) / (1.0 + gamma)


def hair_reflectance(
    wavelength_um,
    eumelanin: float,
    pheomelanin: float = 0.0,
    white_fraction: float = 0.0,
    other_absorption=0.0,
) -> np.ndarray:
    """Diffuse reflectance [-] of an optically thick head of hair (module doc); ``white_fraction``
    of its fibres carry no melanin (grey hair); ``other_absorption`` per diameter is added to
    every fibre (e.g. :func:`other_absorption`)."""
    if not 0.0 <= white_fraction <= 1.0:
        raise ValueError(f"white_fraction must be in [0, 1], not {white_fraction}")
    if eumelanin < 0 or pheomelanin < 0:
        raise ValueError("melanin concentrations must be >= 0")
    other = np.asarray(other_absorption, dtype=float)
    pigmented = albedo_from_absorption(melanin_absorption(wavelength_um, eumelanin, pheomelanin) + other)
    white = albedo_from_absorption(other + 0.0 * pigmented)
    return layer_reflectance((1.0 - white_fraction) * pigmented + white_fraction * white)


def other_absorption(wavelength_um, measured_reflectance, eumelanin: float, pheomelanin: float = 0.0):
    """Absorption per diameter [-] beyond melanin that a measured hair reflectance needs, for hair
    of the given melanin: the model inverted (R -> omega -> sigma_a) minus the melanin's, >= 0."""
    r = np.clip(np.asarray(measured_reflectance, dtype=float), 1e-6, 1.0 - 1e-6)
    gamma = (1.0 - r) / (1.0 + r)
    omega = 1.0 - gamma**2
    transmitted = np.clip((omega - _RF) / (1.0 - _RF), 1e-12, 1.0)
    total = -np.log(transmitted) / MEAN_CHORD
    return np.maximum(total - melanin_absorption(wavelength_um, eumelanin, pheomelanin), 0.0)


def colour_reflectance(wavelength_um, colour: str, other=0.0) -> np.ndarray:
    """:func:`hair_reflectance` of a named colour of :data:`HAIR_COLOURS`."""
    if colour not in HAIR_COLOURS:
        raise ValueError(f"invalid hair colour {colour!r}: expected one of {list(HAIR_COLOURS)}")
    eu, ph, white = HAIR_COLOURS[colour]
    return hair_reflectance(wavelength_um, eu, ph, white, other)


_RF = diffuse_fresnel()
