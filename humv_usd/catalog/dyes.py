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

Prints. ``human.clothing_prints`` maps garment-name patterns to a print (:data:`PRINTS`:
``stripes``, ``checks``, ``blobs``), ``human.clothing_print_colors`` to its second colour
(default black); the first colour is the garment's (``clothing_colors``, or the undyed fabric,
named ``<fabric>__fabric``). Each face of the garment takes one of the two dyes by the print
evaluated at its centre in the garment's rest pose (so the print moves with the cloth):
:func:`print_faces`. The two dyes are two materials of the same fabric (faces bound by
GeomSubsets ``PrintA``/``PrintB``), so the render sees the print per face in every band; in the
thermal infrared both keep the fabric's emissivity (the assumption above: a dye changes the
visible, not the fibre's infrared absorption). The garment mesh itself is bound to the print's
mix ``<fabric>__print_<a>_<b>`` (the two dyes' reflectance and transmittance spectra averaged
half and half, the prints' design ratio; the solar absorptivity recomputed from them): the
thermal tool, which reads one material per garment, absorbs sunlight as the print does on
average (the measured share of each garment is recorded, customData ``humv:print``).
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


#: garment prints: kind -> period [m] (one stripe, square or blob and its gap). A print is per
#: face and the catalogue's garment faces are 2-4 cm across, so its features are >= 8 cm (finer
#: prints would need textures)
PRINTS = {"stripes": 0.16, "checks": 0.20, "blobs": 0.30}
#: the first colour of a print on an undyed garment: the fabric's own spectrum
FABRIC_COLOUR = "fabric"
#: the print's second colour when ``clothing_print_colors`` gives none
DEFAULT_PRINT_COLOUR = "black"
_PRINT = "print"


def print_name(fabric: str, colour_a: str, colour_b: str) -> str:
    """The mix material of a print: ``<fabric>__print_<a>_<b>`` (a USD name)."""
    return f"{fabric}{SEPARATOR}{_PRINT}_{colour_a}_{colour_b}"


def _dye(fabric: str, colour: str) -> str:
    return fabric if colour == FABRIC_COLOUR else dyed_name(fabric, colour)


def garment_materials(garment_name: str, colours=None, hair_color=None, prints=None, print_colours=None):
    """Every material a garment's mesh binds: :func:`garment_material`, or with a print its two
    dyes and their mix."""
    printed = garment_print(garment_name, prints, print_colours, colours)
    if printed is None:
        return (garment_material(garment_name, colours, hair_color),)
    return print_materials(garment(garment_name).fabric, printed)


def garment_print(garment_name: str, prints=None, print_colours=None, colours=None):
    """(kind, colour a, colour b) of a garment under ``human.clothing_prints`` /
    ``clothing_print_colors`` / ``clothing_colors``, None when it has no print (first match wins)."""
    kind = garment_colour(garment_name, prints)
    if kind is None:
        return None
    a = garment_colour(garment_name, colours) or FABRIC_COLOUR
    b = garment_colour(garment_name, print_colours) or DEFAULT_PRINT_COLOUR
    return kind, a, b


def print_faces(kind: str, points: np.ndarray, face_counts, face_indices, seed: int = 0) -> np.ndarray:
    """(F,) bool: the faces that take the print's second colour, by the print evaluated at each
    face's centre (rest pose, metres, z up) with period p = :data:`PRINTS` [kind]:

    * ``stripes``: horizontal bands p/2 high, alternating (floor(2 z / p) odd);
    * ``checks``: a 3-D checkerboard of p/2 cubes (so front, back and sides are checked);
    * ``blobs``: camouflage-like blobs: the sign of a sum of 8 plane waves of wavelength p in
      random directions with random phases (``seed``), about half the area each colour.
    """
    counts = np.asarray(face_counts)
    idx = np.asarray(face_indices)
    face_of = np.repeat(np.arange(len(counts)), counts)
    centre = np.zeros((len(counts), 3))
    np.add.at(centre, face_of, np.asarray(points, dtype=float)[idx])
    centre /= counts[:, None]
    p = PRINTS[kind]
    if kind == "stripes":
        return np.floor(2.0 * centre[:, 2] / p).astype(np.int64) % 2 == 1
    if kind == "checks":
        return np.floor(2.0 * centre / p).astype(np.int64).sum(axis=1) % 2 == 1
    if kind == "blobs":
        rng = np.random.default_rng([int(seed), 29])
        k = rng.standard_normal((8, 3))
        k *= 2.0 * np.pi / p / np.linalg.norm(k, axis=1, keepdims=True)
        phase = rng.uniform(0.0, 2.0 * np.pi, 8)
        return np.cos(centre @ k.T + phase).sum(axis=1) > 0.0
    raise ValueError(f"print = {kind!r}: allowed {', '.join(PRINTS)}")


def print_materials(fabric: str, kind_a_b) -> tuple[str, str, str]:
    """(material of colour a, of colour b, their half-and-half mix) of a print on ``fabric``."""
    _, a, b = kind_a_b
    return _dye(fabric, a), _dye(fabric, b), print_name(fabric, a, b)


def _mixed(fabric: Material, a: str, b: str, name: str) -> Material:
    ma, mb = material(_dye(fabric.name, a)), material(_dye(fabric.name, b))
    w = np.union1d(ma.spectrum_wavelengths, mb.spectrum_wavelengths)
    t = 0.5
    refl = (1 - t) * ma.at(w, "reflectance") + t * mb.at(w, "reflectance")
    trans = None
    if fabric.spectrum_transmittance is not None:
        trans = (1 - t) * ma.at(w, "transmittance") + t * mb.at(w, "transmittance")
        trans = tuple(round(float(v), 4) for v in trans)
    mixed = dataclasses.replace(
        fabric,
        name=name,
        spectrum_wavelengths=tuple(round(float(v), 4) for v in w),
        spectrum_reflectance=tuple(round(float(v), 4) for v in refl),
        spectrum_transmittance=trans,
    )
    return dataclasses.replace(
        mixed,
        solar_absorptivity=round(mixed.spectral_solar_absorptivity, 4),
        source=f"{fabric.name} printed {a} and {b}, half and half (humv_usd.catalog.dyes). {fabric.source}",
    )


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
    if sep and base in LIBRARY and colour.startswith(_PRINT + "_") and colour.count("_") == 2:
        _, a, b = colour.split("_")
        if not {a, b} <= set(COLOURS) | {FABRIC_COLOUR}:
            raise KeyError(name)
        return _mixed(LIBRARY[base], a, b, name)
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
