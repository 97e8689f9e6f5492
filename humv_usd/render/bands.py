"""Band quantities of a material for a sensor, computed once per render and material.

The render and the thermal solve take a material's band emissivity from one function,
:func:`humv_usd.usd.materials.band_emissivity` (the Planck weighting at
:data:`humv_usd.constants.EMISSIVITY_WEIGHTING_TEMPERATURE_K` through the sensor response,
:func:`humv_usd.physics.planck.band_emissivity`); this module caches its values per
(material, sensor) for the frames and sensors of one render, so that no pass re-derives them.
"""

from __future__ import annotations

import numpy as np

from humv_usd.physics.sensor import SensorModel
from humv_usd.usd import materials as usd_materials


def band_emissivity(cache: dict, material, sensor: SensorModel) -> float:
    """Band emissivity of a material for a sensor (cached): the one function the thermal solve
    uses too (:func:`humv_usd.usd.materials.band_emissivity`)."""
    key = (material.path, sensor.name)
    if key not in cache:
        cache[key] = usd_materials.band_emissivity(material, sensor.wavelength_range_um, sensor.band_response)
    return cache[key]


def subband_emissivity(cache: dict, material, sensor: SensorModel, sub) -> np.ndarray:
    """Sub-band emissivities (n,) of a material for a sensor (cached;
    :func:`humv_usd.usd.materials.subband_emissivity`)."""
    key = (material.path, sensor.name)
    if key not in cache:
        cache[key] = usd_materials.subband_emissivity(
            material, sensor.wavelength_range_um, sub.bands, sub.response
        )
    return cache[key]


def subband_transmittance(cache: dict, material, sensor: SensorModel, sub) -> np.ndarray | None:
    """Sub-band transmittances (n,) of a see-through material (glass), None when opaque."""
    key = ("transmittance", material.path, sensor.name)
    if key not in cache:
        cache[key] = usd_materials.subband_transmittance(material, sub.bands, sub.response)
    return cache[key]
