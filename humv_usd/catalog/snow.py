"""Shallow snow over a material (issue 30.4): the library ``snow`` is a deep snowpack; snow
thinner than its visible e-folding depths (10-30 cm) shows the ground under it.

``<material>__snow<mm>`` is the library snow ``mm`` millimetres deep over the library material
(:func:`snow_over`): its reflectance where ice is translucent (0.4-2.5 um) is the two-flux
albedo of the layer over the material (:func:`humv_usd.physics.snow.layer_albedo`, with the
library snow's deep albedo and its asymptotic extinction coefficient); beyond 2.5 um ice is
opaque within a millimetre and it is the snow's. Thermal data are the snow's. Depths are
rounded to :data:`LEVELS_MM` (:func:`cover_name`); from :data:`DEEP_M` on the snow is the
library ``snow`` itself. :func:`humv_usd.catalog.dyes.material` resolves these names.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from humv_usd.catalog.materials import LIBRARY, SNOW_DENSITY, SNOW_SPECIFIC_SURFACE_AREA, Material
from humv_usd.physics import snow as optics

SEPARATOR = "__snow"
#: depths [mm] shallow snow is rounded to (nearest in log depth)
LEVELS_MM = (5, 10, 20, 50, 100, 200)
#: from this depth on [m] snow is the library's deep ``snow`` (its visible albedo within 0.01
#: of the deep value over a black ground at 0.55 um)
DEEP_M = 0.3
#: the deep snow's material name
DEEP = "snow"


def cover_name(base: str, depth_m: float) -> str:
    """Material name of snow ``depth_m`` deep over the material ``base``: ``snow`` from
    :data:`DEEP_M` on, else ``<base>__snow<mm>`` at the nearest of :data:`LEVELS_MM`."""
    if depth_m >= DEEP_M:
        return DEEP
    levels = np.asarray(LEVELS_MM, dtype=float)
    mm = int(levels[np.argmin(np.abs(np.log(max(depth_m, 1e-4) * 1e3) - np.log(levels)))])
    return f"{base}{SEPARATOR}{mm}"


def split_snow_name(name: str) -> tuple[str, int] | None:
    """(base material name, depth mm) of ``<base>__snow<mm>``, else None."""
    base, sep, mm = name.rpartition(SEPARATOR)
    if not sep or not base or not mm.isdigit() or int(mm) not in LEVELS_MM:
        return None
    return base, int(mm)


def snow_over(base: Material, mm: int) -> Material:
    """The library snow ``mm`` millimetres deep over ``base`` (see the module doc)."""
    snow = LIBRARY[DEEP]
    depth = mm / 1000.0
    wl = np.union1d(snow.spectrum_wavelengths, base.spectrum_wavelengths)
    deep = snow.at(wl, "reflectance")
    translucent = wl <= optics.ICE_ABSORPTION_INDEX[-1][0]
    d = optics.optical_diameter_m(SNOW_SPECIFIC_SURFACE_AREA)
    k_e = optics.extinction_coefficient(np.minimum(wl, 2.5), d, SNOW_DENSITY)
    layer = optics.layer_albedo(deep, k_e, depth, base.at(wl, "reflectance"))
    rho = np.where(translucent, layer, deep)
    out = dataclasses.replace(
        snow,
        name=f"{base.name}{SEPARATOR}{mm}",
        spectrum_wavelengths=tuple(round(float(v), 4) for v in wl),
        spectrum_reflectance=tuple(round(float(v), 4) for v in rho),
        thickness=depth,
        source=f"{mm} mm of the library snow over {base.name} (humv_usd.catalog.snow: two-flux layer "
        "albedo, Kubelka 1948, with the snow's deep albedo and asymptotic extinction, Kokhanovsky & "
        f"Zege 2004). {snow.source}",
    )
    return dataclasses.replace(out, solar_absorptivity=round(out.spectral_solar_absorptivity, 4))
