"""Wet surfaces (issue 30.4): a material under rain water, as a material made on demand.

A surface whose share ``delta`` is wet (the Deardorff wet fraction the thermal tool's slab
keeps, :func:`humv_usd.physics.evaporation.wet_fraction`) reflects (1 - delta) R_dry + delta
R_film, R_film a water film over the dry material (:mod:`humv_usd.physics.water_film`: Lekner &
Dorf 1988 with the film's absorption, water after Hale & Querry 1973); the film is as thick as
the material's water capacity (:func:`humv_usd.catalog.materials.surface_water`) and the wet
share imply. Emissivity is 1 - R - T (Kirchhoff), so a wet surface's thermal-infrared emissivity
moves towards water's; the visible darkens; thermal data stay the dry material's.

The wet share is rounded to :data:`WET_LEVELS` (a quarter at a time), so a scene has at most
four wet variants per material: ``<material>__wet25`` ... ``<material>__wet100``
(:func:`wet_name`); :func:`humv_usd.catalog.dyes.material` resolves these names.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from humv_usd.catalog.materials import Material, surface_water
from humv_usd.physics.water_film import wet_reflectance

SEPARATOR = "__wet"
#: wet shares [percent] a wet surface is rounded to
WET_LEVELS = (25, 50, 75, 100)
#: a face whose wet share is below this renders dry
DRY_BELOW = 0.125


def wet_level(wet_fraction) -> np.ndarray:
    """The :data:`WET_LEVELS` percent nearest each wet share [0-1]; 0 below :data:`DRY_BELOW`."""
    d = np.clip(np.asarray(wet_fraction, dtype=float), 0.0, 1.0)
    level = 25 * np.clip(np.round(d * 4.0), 1, 4).astype(int)
    return np.where(d < DRY_BELOW, 0, level)


def wet_name(base: str, level: int) -> str:
    return f"{base}{SEPARATOR}{int(level)}"


def split_wet_name(name: str) -> tuple[str, int] | None:
    """(dry material name, level percent) of ``<material>__wet<level>``, else None."""
    base, sep, level = name.rpartition(SEPARATOR)
    if not sep or not base or not level.isdigit() or int(level) not in WET_LEVELS:
        return None
    return base, int(level)


def wet_spectrum(wavelengths_um, reflectance, transmittance, wet_fraction: float, capacity_mm: float):
    """(reflectance, transmittance) of a material under water (see the module doc) on its own
    wavelength grid [um]; a see-through material (glass) keeps its transmittance and its wet
    reflectance is held to R + T <= 1."""
    rho = np.asarray(reflectance, dtype=float)
    wet = wet_reflectance(np.asarray(wavelengths_um, dtype=float), rho, wet_fraction, capacity_mm)
    if transmittance is None:
        return wet, None
    tau = np.asarray(transmittance, dtype=float)
    return np.minimum(wet, 1.0 - tau), tau


def wet_material(base: Material, level: int) -> Material:
    """The library material ``base`` with ``level`` percent of its surface under water."""
    capacity = surface_water(base.name).water_capacity_kg_m2
    rho, tau = wet_spectrum(
        base.spectrum_wavelengths,
        base.spectrum_reflectance,
        base.spectrum_transmittance,
        level / 100.0,
        capacity,
    )
    wet = dataclasses.replace(
        base,
        name=wet_name(base.name, level),
        spectrum_reflectance=tuple(round(float(v), 6) for v in rho),
        spectrum_transmittance=None if tau is None else tuple(round(float(v), 6) for v in tau),
    )
    return dataclasses.replace(
        wet,
        solar_absorptivity=round(wet.spectral_solar_absorptivity, 4),
        source=f"{base.name} with {level} % of its surface under a water film of "
        f"{capacity * (level / 100.0) ** 0.5:.3g} mm (humv_usd.catalog.wet: Lekner & Dorf 1988 "
        f"film over the substrate, water after Hale & Querry 1973). {base.source}",
    )
