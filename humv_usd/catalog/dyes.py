"""Garment colours: a fabric dyed another colour, as a library material made on demand.

``human.clothing_colors`` maps garment-name patterns to a colour of :data:`COLOURS`; the garment
is then bound to ``<fabric>__<colour>`` (:func:`garment_material`), which :func:`material` makes
from the fabric:

* visible (0.40-0.70 µm): the colour's reflectance at 0.45 / 0.55 / 0.65 µm (blue, green, red:
  the nodes that :attr:`~humv_usd.catalog.materials.Material.display_color` reads), constant
  below 0.45 and linear between the nodes;
* 0.70-0.80 µm: a linear blend into the fabric's own spectrum;
* from 0.80 µm on: the fabric's own spectrum. Textile dyes absorb in the visible and are
  largely transparent in the near infrared, so a dyed fabric reflects like the undyed one
  there (the reason dyed-cotton camouflage needs NIR additives; carbon black, as in the
  library's black fabrics, is the exception). The thermal infrared (emissivity) and the thermal
  data are the fabric's.

The colour table is a design palette (linear reflectances of common garment colours chosen to
match their sRGB appearance), not measured dye spectra; the NIR transparency is the stated
assumption above.
"""

from __future__ import annotations

import dataclasses
import fnmatch

import numpy as np

from humv_usd.catalog.garments import garment
from humv_usd.catalog.hair import hair_material_name
from humv_usd.catalog.materials import LIBRARY, Material
from humv_usd.catalog.snow import snow_over, split_snow_name
from humv_usd.catalog.wet import split_wet_name, wet_material

#: colour -> reflectance at (0.65, 0.55, 0.45) µm (red, green, blue)
COLOURS = {
    "white": (0.80, 0.80, 0.78),
    "black": (0.04, 0.04, 0.04),
    "grey": (0.30, 0.30, 0.30),
    "red": (0.50, 0.06, 0.05),
    "orange": (0.65, 0.25, 0.04),
    "yellow": (0.70, 0.60, 0.08),
    "green": (0.08, 0.30, 0.08),
    "olive": (0.16, 0.17, 0.07),
    "khaki": (0.45, 0.38, 0.24),
    "brown": (0.20, 0.10, 0.05),
    "blue": (0.05, 0.12, 0.45),
    "navy": (0.04, 0.05, 0.15),
    "pink": (0.75, 0.40, 0.50),
    "purple": (0.25, 0.08, 0.35),
}
SEPARATOR = "__"
#: the fabric of the hair garments (hair_short, hair_long, hair_tied, beard)
HAIR_FABRIC = "hair_dark"
#: visible nodes [µm] and where the blend into the fabric's spectrum ends
_BLEND_START, _BLEND_END = 0.70, 0.80


def dyed_name(fabric: str, colour: str) -> str:
    return f"{fabric}{SEPARATOR}{colour}"


#: wavelengths [µm] a dyed material has besides its fabric's (the colour needs visible nodes)
VISIBLE_NODES = (0.40, 0.45, 0.50, 0.55, 0.60, 0.65, 0.70, 0.75, 0.80)


def dyed_spectrum(base: Material, colour: str) -> dict:
    """``spectrum_wavelengths`` (the fabric's and :data:`VISIBLE_NODES`), ``spectrum_reflectance``
    and ``spectrum_transmittance`` of ``base`` dyed ``colour`` (see the module doc)."""
    r, g, b = COLOURS[colour]
    w = np.union1d(np.asarray(base.spectrum_wavelengths, dtype=float), VISIBLE_NODES)
    own = base.at(w, "reflectance")
    visible = np.interp(w, [0.45, 0.55, 0.65, _BLEND_START], [b, g, r, r])
    t = np.clip((w - _BLEND_START) / (_BLEND_END - _BLEND_START), 0.0, 1.0)
    out = (1.0 - t) * visible + t * own
    trans = None
    if base.spectrum_transmittance is not None:  # keep R + T <= 1
        trans = base.at(w, "transmittance")
        out = np.minimum(out, 1.0 - trans)
        trans = tuple(round(float(v), 4) for v in trans)
    return {
        "spectrum_wavelengths": tuple(round(float(v), 4) for v in w),
        "spectrum_reflectance": tuple(round(float(v), 4) for v in out),
        "spectrum_transmittance": trans,
    }


def material(name: str) -> Material:
    """A library material by name, a dyed one ``<fabric>__<colour>`` made from its fabric, a
    wet one ``<material>__wet<percent>`` (:mod:`humv_usd.catalog.wet`) or one under shallow
    snow ``<material>__snow<mm>`` (:mod:`humv_usd.catalog.snow`)."""
    if name in LIBRARY:
        return LIBRARY[name]
    wet = split_wet_name(name)
    if wet is not None:
        return wet_material(material(wet[0]), wet[1])
    snowy = split_snow_name(name)
    if snowy is not None:
        return snow_over(material(snowy[0]), snowy[1])
    base, sep, colour = name.rpartition(SEPARATOR)
    if not sep or base not in LIBRARY or colour not in COLOURS:
        raise KeyError(name)
    fabric = LIBRARY[base]
    dyed = dataclasses.replace(fabric, name=name, **dyed_spectrum(fabric, colour))
    return dataclasses.replace(
        dyed,
        solar_absorptivity=round(dyed.spectral_solar_absorptivity, 4),
        source=f"{base} dyed {colour} (humv_usd.catalog.dyes: visible from the colour, NIR and "
        f"thermal infrared as the fabric). {fabric.source}",
    )


def garment_colour(garment_name: str, colours) -> str | None:
    """The colour of a garment under ``human.clothing_colors`` ([[pattern, colour], ...] or a
    dict; the first matching pattern wins), None when no pattern matches."""
    items = colours.items() if isinstance(colours, dict) else colours or ()
    name = garment(garment_name).name
    for pattern, colour in items:
        if fnmatch.fnmatchcase(name, pattern) or fnmatch.fnmatchcase(garment_name, pattern):
            return colour
    return None


def garment_material(garment_name: str, colours=None, hair_color: str | None = None) -> str:
    """Library material name a garment is bound to: its fabric, or the fabric dyed the colour
    ``colours`` gives it; a hair garment (fabric ``hair_dark``) not dyed by ``colours`` takes the
    person's ``hair_color`` (``human.hair_color``, :mod:`humv_usd.catalog.hair`)."""
    fabric = garment(garment_name).fabric
    colour = garment_colour(garment_name, colours)
    if colour is None and hair_color is not None and fabric == HAIR_FABRIC:
        return hair_material_name(hair_color)
    return fabric if colour is None else dyed_name(fabric, colour)
