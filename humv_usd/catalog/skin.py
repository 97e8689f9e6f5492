"""Skin tones: one library material per Fitzpatrick type I-VI (``skin_I`` ... ``skin_VI``).

Each is the library's measured light-skin spectrum (``skin``: Anderson & Parrish 1981, taken as
Fitzpatrick type II) with the subsurface part scaled, wavelength by wavelength, by what the
skin-optics model (:mod:`humv_usd.physics.skin_optics`: melanin, blood and water absorption,
diffusion-dipole dermis, Jacques 2013) gives for that type's epidermal melanin relative to type
II::

    R_type(lambda) = r_s + (R_skin(lambda) - r_s) * B_type(lambda) / B_II(lambda)

where ``B = (R_model - r_s) / (1 - r_s)`` is the model's subsurface reflectance and r_s its
surface reflection. So the measured spectrum fixes the level and the water bands, the model the
pigmentation (melanin absorbs ~ lambda^-3.5: large in the blue, a few % at 1 µm, nothing in the
SWIR). From 2.5 µm on the spectra equal ``skin`` (emissivity 0.98, independent of pigmentation,
Steketee 1973). Thermal data are those of ``skin``.
"""

from __future__ import annotations

import numpy as np

from humv_usd.catalog.variants import spectral_variant, variant_name
from humv_usd.physics.skin_optics import (
    FITZPATRICK_MELANIN,
    SURFACE_REFLECTANCE,
    WAVELENGTH_RANGE_UM,
    skin_reflectance,
)

#: Fitzpatrick type of the measured ``skin`` spectrum
REFERENCE_TYPE = "II"
SKIN_TONES = tuple(FITZPATRICK_MELANIN)


def skin_material_name(tone: str | None) -> str:
    """Library material of a skin tone ('I'..'VI'); None: the measured ``skin``."""
    return variant_name("skin", "skin_tone", tone, FITZPATRICK_MELANIN, "skin")


def tone_spectrum(skin, tone: str) -> tuple[float, ...]:
    """Reflectance of skin tone ``tone`` at the wavelengths of ``skin`` (the measured type II
    :class:`~humv_usd.catalog.materials.Material`); see the module doc."""
    w = np.asarray(skin.spectrum_wavelengths)
    r = np.asarray(skin.spectrum_reflectance, dtype=float)
    inside = w <= WAVELENGTH_RANGE_UM[1] + 1e-9
    rs = SURFACE_REFLECTANCE

    def body(t):
        return (skin_reflectance(w[inside], FITZPATRICK_MELANIN[t]) - rs) / (1.0 - rs)

    out = r.copy()
    out[inside] = rs + np.maximum(r[inside] - rs, 0.0) * body(tone) / body(REFERENCE_TYPE)
    return tuple(round(float(v), 4) for v in np.clip(out, 0.0, 1.0))


def tone_materials(skin) -> dict:
    """``skin_I`` ... ``skin_VI`` made from the measured ``skin`` material (see the module doc).
    Called by :mod:`humv_usd.catalog.materials`, which adds them to its LIBRARY (this module
    does not import it, so either may be imported first)."""
    out = {}
    for tone, f in FITZPATRICK_MELANIN.items():
        name = skin_material_name(tone)
        out[name] = spectral_variant(
            skin,
            name,
            f"Fitzpatrick type {tone} skin (epidermal melanin volume fraction {f:g}): "
            "the measured light-skin spectrum 'skin' scaled by the melanin/blood/water skin "
            "model of humv_usd.physics.skin_optics relative to type II (Jacques 2013 Phys. Med. "
            "Biol. 58:R37; Farrell et al. 1992 Med. Phys. 19:879; Prahl 1999 haemoglobin; Hale & "
            "Querry 1973 water); IR from 2.5 µm and thermal data as 'skin'. ",
            spectrum_reflectance=tone_spectrum(skin, tone),
        )
    return out
