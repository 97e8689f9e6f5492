"""Hair colours: one library material per colour (``hair_black`` ... ``hair_grey``).

Each is the library's ``hair_dark`` (short dark head hair; its thermal data, its emissivity and
its SWIR bands) with the reflectance up to 2.5 µm recomputed by the melanin model of
:mod:`humv_usd.physics.hair_optics` for the colour's eumelanin and pheomelanin:

1. ``hair_dark`` is taken as black hair (eumelanin 8: the model gives 0.03 / 0.06 / 0.21 at
   0.55 / 0.7 / 1.0 µm against its 0.05 / 0.07 / 0.20);
2. the absorption that ``hair_dark``'s spectrum needs beyond black hair's melanin
   (:func:`~humv_usd.physics.hair_optics.other_absorption`: keratin and water, the SWIR bands)
   is added to every colour's melanin absorption;
3. the colour's reflectance is the model's for that total (grey: half the fibres white).

So ``hair_black`` is ``hair_dark``'s spectrum where the model does not need to be darker, and
lighter hair is brighter in the visible and the near infrared, where melanin absorbs, while
sharing the measured SWIR bands. From 2.5 µm on the spectra equal ``hair_dark`` (emissivity
does not depend on pigmentation). Visible nodes are added at 0.45, 0.5, 0.6, 0.65, 0.8 µm so
that the colour (``display_color`` at 0.45 / 0.55 / 0.65 µm) is resolved.
"""

from __future__ import annotations

import numpy as np

from humv_usd.catalog.variants import spectral_variant, variant_name
from humv_usd.physics.hair_optics import HAIR_COLOURS, colour_reflectance, other_absorption

#: the colour ``hair_dark`` is taken as
REFERENCE_COLOUR = "black"
VISIBLE_NODES_UM = (0.45, 0.5, 0.6, 0.65, 0.8)
MODEL_UP_TO_UM = 2.5


def hair_material_name(colour: str | None) -> str:
    """Library material of a hair colour; None: ``hair_dark`` (the default)."""
    return variant_name("hair", "hair_color", colour, HAIR_COLOURS, "hair_dark")


def colour_spectrum(hair, colour: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(wavelengths [µm], reflectance) of ``colour`` made from the ``hair_dark`` material
    ``hair`` (module doc)."""
    w0 = np.asarray(hair.spectrum_wavelengths, dtype=float)
    w = np.union1d(w0, VISIBLE_NODES_UM)
    measured = hair.at(w, "reflectance")
    eu, ph, _ = HAIR_COLOURS[REFERENCE_COLOUR]
    inside = w <= MODEL_UP_TO_UM + 1e-9
    other = other_absorption(w[inside], measured[inside], eu, ph)
    out = measured.copy()
    out[inside] = colour_reflectance(w[inside], colour, other)
    if colour == REFERENCE_COLOUR:  # where the model is darker than the measurement: measured
        out[inside] = np.maximum(out[inside], measured[inside])
    return tuple(round(float(v), 4) for v in w), tuple(round(float(v), 4) for v in np.clip(out, 0.0, 1.0))


def hair_materials(hair) -> dict:
    """``hair_<colour>`` for every colour of :data:`HAIR_COLOURS`, made from ``hair_dark``.
    Called by :mod:`humv_usd.catalog.materials`, which adds them to its LIBRARY."""
    out = {}
    for colour, (eu, ph, white) in HAIR_COLOURS.items():
        name = hair_material_name(colour)
        wavelengths, reflectance = colour_spectrum(hair, colour)
        out[name] = spectral_variant(
            hair,
            name,
            f"{colour} hair (eumelanin {eu:g}, pheomelanin {ph:g}, white fibres {white:g}): "
            "hair_dark's spectrum recomputed by the melanin model of humv_usd.physics.hair_optics "
            "(Donner & Jensen 2006 melanin spectra, Chiang et al. 2016 concentrations, Hapke 1981 "
            "layer); thermal data and emissivity as hair_dark. ",
            spectrum_wavelengths=wavelengths,
            spectrum_reflectance=reflectance,
        )
    return out
