"""Diffuse reflectance of human skin, 0.4-2.5 µm, from melanin, blood and water content.

A two-layer model: an epidermis of thickness ``epidermis_m`` (melanin, baseline tissue, some
water) that filters the light going into and coming out of a semi-infinite turbid dermis (blood,
water, baseline tissue), plus a wavelength-independent surface (Fresnel) reflection. Pure numpy.

Model
-----
Absorption coefficients [cm-1] (Jacques 2013, Phys. Med. Biol. 58:R37, section 3, and Jacques
1998 "Skin optics", Oregon Medical Laser Center News):

* melanin: mu_a,mel = 519 (lambda / 500 nm)^-3.5;
* baseline (bloodless) skin: mu_a,base = 0.244 + 85.3 exp(-(lambda - 154 nm) / 66.2 nm);
* blood: mu_a = 2.303 e(lambda) c with the molar extinction e [cm-1 M-1] of oxy- and
  deoxy-haemoglobin compiled by Prahl (1999, https://omlc.org/spectra/hemoglobin/), c = 150 g/L
  / 64 500 g/mol, at saturation ``oxygen_saturation``, plus its water (80 %); beyond 1.0 µm
  blood absorbs as its water;
* water: mu_a from Hale & Querry (1973, Appl. Opt. 12:555-563), mu_a = 4 pi k / lambda, read
  at the nodes below (rounded; log-linear between them).

Reduced scattering of skin mu_s' = 46.0 (lambda / 500 nm)^-1.421 cm-1 (Jacques 2013, Table 2,
"skin", mean of the compiled studies).

Dermis: total diffuse reflectance of the diffusion dipole model (Farrell et al. 1992), see
:func:`diffuse_reflectance`, refractive index 1.4. Epidermis: Beer-Lambert filter, path d in
and 2 d out (diffuse), T = exp(-3 mu_a,epi d). Surface: R = r_s + (1 - r_s) T R_dermis.

Fitzpatrick types: epidermal melanin volume fractions after Jacques (1998): light-skinned adults
1.3-6.3 %, moderately pigmented 11-16 %, darkly pigmented 18-43 %; the table
:data:`FITZPATRICK_MELANIN` spreads types I-VI over that range (a choice, stated). Dermal blood
1.5 % (Jacques 2013: 0.2-7 %), oxygen saturation 0.75, dermal water 65 %, epidermal water 20 %,
epidermis 60 µm thick (Jacques 1998).

Valid 0.4-2.5 µm. Beyond 2.5 µm water makes skin black in the infrared (emissivity 0.98,
Steketee 1973), independent of pigmentation: the catalogue keeps the measured IR values there.
"""

from __future__ import annotations

import numpy as np

#: Fitzpatrick type -> epidermal melanin volume fraction (see the module doc)
FITZPATRICK_MELANIN = {"I": 0.02, "II": 0.045, "III": 0.08, "IV": 0.14, "V": 0.24, "VI": 0.38}

_HB_MOLAR_MASS_G = 64500.0
_HB_CONCENTRATION_G_L = 150.0
#: Prahl (1999) molar extinction [cm-1 M-1]: wavelength [nm], HbO2, Hb
_HEMOGLOBIN = np.array(
    [
        (400, 266232.0, 223296.0),
        (450, 62816.0, 103292.0),
        (500, 20932.8, 20862.0),
        (540, 53236.0, 46592.0),
        (560, 32613.2, 53788.0),
        (576, 55540.0, 40092.0),
        (600, 3200.0, 14677.2),
        (650, 368.0, 3750.12),
        (700, 290.0, 1794.28),
        (750, 518.0, 1405.24),
        (800, 816.0, 761.72),
        (900, 1198.0, 761.84),
        (1000, 1024.0, 206.784),
    ]
)
#: Hale & Querry (1973) water absorption coefficient [cm-1] at wavelength [µm]
_WATER = np.array(
    [
        (0.40, 0.0006),
        (0.45, 0.0003),
        (0.50, 0.00025),
        (0.55, 0.00045),
        (0.60, 0.0023),
        (0.65, 0.0032),
        (0.70, 0.006),
        (0.80, 0.02),
        (0.90, 0.07),
        (1.00, 0.36),
        (1.10, 0.17),
        (1.20, 1.0),
        (1.30, 1.1),
        (1.45, 26.0),
        (1.55, 9.5),
        (1.65, 4.5),
        (1.80, 8.0),
        (1.94, 114.0),
        (2.05, 35.0),
        (2.20, 16.5),
        (2.35, 30.0),
        (2.50, 87.0),
    ]
)
#: Default layer composition (see the module doc)
BLOOD_FRACTION = 0.015
OXYGEN_SATURATION = 0.75
DERMIS_WATER = 0.65
EPIDERMIS_WATER = 0.20
EPIDERMIS_M = 60e-6
SURFACE_REFLECTANCE = 0.025
WAVELENGTH_RANGE_UM = (0.4, 2.5)


def melanin_absorption(wavelength_um) -> np.ndarray:
    """Melanosome absorption coefficient [cm-1] = 519 (lambda / 500 nm)^-3.5 (Jacques 2013)."""
    return 519.0 * (np.asarray(wavelength_um, dtype=float) / 0.5) ** -3.5


def baseline_absorption(wavelength_um) -> np.ndarray:
    """Bloodless skin absorption [cm-1] = 0.244 + 85.3 exp(-(lambda[nm] - 154) / 66.2) (Jacques 1998)."""
    return 0.244 + 85.3 * np.exp(-(1000.0 * np.asarray(wavelength_um, dtype=float) - 154.0) / 66.2)


def water_absorption(wavelength_um) -> np.ndarray:
    """Water absorption coefficient [cm-1] (Hale & Querry 1973), log-linear between nodes."""
    w = np.asarray(wavelength_um, dtype=float)
    return np.exp(np.interp(w, _WATER[:, 0], np.log(_WATER[:, 1])))


def blood_absorption(wavelength_um, oxygen_saturation: float = OXYGEN_SATURATION) -> np.ndarray:
    """Whole-blood absorption [cm-1]: haemoglobin (Prahl 1999) to 1.0 µm, water beyond."""
    w = np.asarray(wavelength_um, dtype=float)
    nm = 1000.0 * w
    eps = oxygen_saturation * np.exp(np.interp(nm, _HEMOGLOBIN[:, 0], np.log(_HEMOGLOBIN[:, 1])))
    eps = eps + (1.0 - oxygen_saturation) * np.exp(
        np.interp(nm, _HEMOGLOBIN[:, 0], np.log(_HEMOGLOBIN[:, 2]))
    )
    hb = 2.303 * eps * _HB_CONCENTRATION_G_L / _HB_MOLAR_MASS_G
    return np.where(w <= 1.0, hb + 0.8 * water_absorption(w), 0.8 * water_absorption(w))


def reduced_scattering(wavelength_um) -> np.ndarray:
    """Reduced scattering of skin [cm-1] = 46.0 (lambda / 500 nm)^-1.421 (Jacques 2013)."""
    return 46.0 * (np.asarray(wavelength_um, dtype=float) / 0.5) ** -1.421


def diffuse_reflectance(mu_a, mu_s_reduced, refractive_index: float = 1.4):
    """Total diffuse reflectance of a semi-infinite turbid medium, diffusion dipole model:
    ``R = a'/2 (1 + exp(-4/3 A sqrt(3 (1 - a')))) exp(-sqrt(3 (1 - a')))`` with the transport
    albedo a' = mu_s' / (mu_a + mu_s') and A = (1 + r_id) / (1 - r_id), r_id the internal
    diffuse reflection of the boundary, r_id = -1.440 n^-2 + 0.710 n^-1 + 0.668 + 0.0636 n.

    Farrell, Patterson & Wilson (1992) Med. Phys. 19:879-888 (eq. 11 integrated over the
    surface); r_id: Groenhuis, Ferwerda & Ten Bosch (1983) Appl. Opt. 22:2456. Same units for
    ``mu_a`` and ``mu_s_reduced``.
    """
    mu_a, mu_s = np.asarray(mu_a, dtype=float), np.asarray(mu_s_reduced, dtype=float)
    n = float(refractive_index)
    r_id = -1.440 / n**2 + 0.710 / n + 0.668 + 0.0636 * n
    big_a = (1.0 + r_id) / (1.0 - r_id)
    albedo = mu_s / (mu_a + mu_s)
    root = np.sqrt(3.0 * (1.0 - albedo))
    return 0.5 * albedo * (1.0 + np.exp(-4.0 / 3.0 * big_a * root)) * np.exp(-root)


def skin_reflectance(
    wavelength_um,
    melanin_fraction: float,
    blood_fraction: float = BLOOD_FRACTION,
    oxygen_saturation: float = OXYGEN_SATURATION,
    epidermis_m: float = EPIDERMIS_M,
    surface_reflectance: float = SURFACE_REFLECTANCE,
) -> np.ndarray:
    """Directional-hemispherical reflectance [0-1] of skin at wavelengths [µm] (0.4-2.5).

    Parameters
    ----------
    wavelength_um : array_like
        Wavelengths [µm], within :data:`WAVELENGTH_RANGE_UM`.
    melanin_fraction : float
        Epidermal melanosome volume fraction [0-1] (:data:`FITZPATRICK_MELANIN`).
    blood_fraction : float
        Dermal blood volume fraction [0-1].
    oxygen_saturation : float
        Blood oxygen saturation [0-1].
    epidermis_m : float
        Epidermis thickness [m].
    surface_reflectance : float
        Specular (Fresnel) reflection of the surface [0-1].
    """
    w = np.asarray(wavelength_um, dtype=float)
    lo, hi = WAVELENGTH_RANGE_UM
    if np.any(w < lo - 1e-9) or np.any(w > hi + 1e-9):
        raise ValueError(f"wavelength_um outside the model's range {lo}-{hi} µm")
    for name, v in (
        ("melanin_fraction", melanin_fraction),
        ("blood_fraction", blood_fraction),
        ("oxygen_saturation", oxygen_saturation),
    ):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} = {v!r}: expected a number in [0, 1]")
    base = baseline_absorption(w)
    water = water_absorption(w)
    mu_epi = (
        melanin_fraction * melanin_absorption(w) + EPIDERMIS_WATER * water + (1 - melanin_fraction) * base
    )
    mu_derm = (
        blood_fraction * blood_absorption(w, oxygen_saturation)
        + DERMIS_WATER * water
        + (1 - blood_fraction - DERMIS_WATER) * base
    )
    r_dermis = diffuse_reflectance(mu_derm, reduced_scattering(w))
    # epidermis: an absorbing filter crossed once on the way in (path d) and once diffusely on
    # the way out (mean path 2 d)
    t_epidermis = np.exp(-3.0 * mu_epi * 100.0 * epidermis_m)  # thickness in cm
    return surface_reflectance + (1.0 - surface_reflectance) * t_epidermis * r_dermis


def fitzpatrick_reflectance(wavelength_um, skin_type: str) -> np.ndarray:
    """:func:`skin_reflectance` of a Fitzpatrick type 'I'..'VI' with the default composition."""
    try:
        f = FITZPATRICK_MELANIN[skin_type]
    except KeyError:
        raise ValueError(f"skin_type = {skin_type!r}: expected one of {list(FITZPATRICK_MELANIN)}") from None
    return skin_reflectance(wavelength_um, f)
