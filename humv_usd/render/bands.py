"""Band quantities of a material for a sensor, computed once per render and material.

The render and the thermal solve take a material's band emissivity from one function,
:func:`humv_usd.usd.materials.band_emissivity` (the Planck weighting at
:data:`humv_usd.constants.EMISSIVITY_WEIGHTING_TEMPERATURE_K` through the sensor response,
:func:`humv_usd.physics.planck.band_emissivity`); this module caches its values per
(material, sensor) for the frames and sensors of one render, so that no pass re-derives them,
and checks each material's tables against Kirchhoff's law, :math:`\varepsilon + \rho + \tau = 1`,
with one table taken as given per band (:func:`authority`, :func:`check_closure`).
"""

from __future__ import annotations

import logging

import numpy as np

from humv_usd.physics.sensor import INFRARED_MIN_UM, SensorModel
from humv_usd.usd import materials as usd_materials

log = logging.getLogger(__name__)


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


# --- Kirchhoff closure: eps + rho + tau = 1, one authority per band ----------------------------

#: Largest |eps + rho + tau - 1| at a material's wavelength nodes within a sensor band before the
#: render warns and the manifest flags it.
CLOSURE_TOLERANCE = 0.02


def authority(band_um) -> str:
    """The material table a band takes as given; the reflectance the render uses there is
    derived from it by Kirchhoff's law for an opaque or transmitting surface,
    :math:`\\varepsilon = \\alpha = 1 - \\rho - \\tau`:

    - thermal bands (lower edge >= :data:`humv_usd.physics.sensor.INFRARED_MIN_UM`):
      ``"emissivity"`` (the render emits :math:`\\varepsilon L_b(T)` and reflects
      :math:`1 - \\varepsilon - \\tau`; the stored reflectance is only checked against it);
    - reflective bands (visible, NIR, SWIR): ``"reflectance"`` (what the EO render reflects; the
      materials catalog derives its emissivity as :math:`1 - \\rho - \\tau` at each node,
      :attr:`humv_usd.catalog.materials.Material.spectrum_emissivity`).
    """
    return "emissivity" if float(band_um[0]) >= INFRARED_MIN_UM else "reflectance"


def closure_error(material, band_um) -> float | None:
    """Largest :math:`|\\varepsilon + \\rho + \\tau - 1|` over the material's table nodes within
    ``band_um`` (with the nodes just outside it, which the band mean interpolates from); None
    when the material has no reflectance table."""
    if material.reflectance is None:
        return None
    wl = np.asarray(material.wavelengths_um, dtype=float)
    eps = np.asarray(material.emissivity, dtype=float)
    rho = np.asarray(material.reflectance, dtype=float)
    tau = np.zeros_like(eps) if material.transmittance is None else np.asarray(material.transmittance, float)
    lo = max(int(np.searchsorted(wl, band_um[0], side="right")) - 1, 0)
    hi = min(int(np.searchsorted(wl, band_um[1], side="left")) + 1, wl.size)
    return float(np.max(np.abs(eps[lo:hi] + rho[lo:hi] + tau[lo:hi] - 1.0)))


def check_closure(cache: dict, material, sensor: SensorModel) -> dict | None:
    """Kirchhoff closure of a material in a sensor's band (cached per material and sensor):
    ``{"material", "band_um", "authority", "max_error", "ok"}``, None without a reflectance
    table. Warns once when the error exceeds :data:`CLOSURE_TOLERANCE`."""
    key = ("closure", material.path, sensor.name)
    if key not in cache:
        band = tuple(float(v) for v in sensor.wavelength_range_um)
        err = closure_error(material, band)
        rec = None
        if err is not None:
            rec = {
                "material": material.path,
                "band_um": list(band),
                "authority": authority(band),
                "max_error": err,
                "ok": err <= CLOSURE_TOLERANCE,
            }
            if not rec["ok"]:
                log.warning(
                    "%s: emissivity + reflectance + transmittance differs from 1 by %.3g in %s's band "
                    "%g-%g um (more than %g); the render takes the %s as given there",
                    material.path,
                    err,
                    sensor.name,
                    *band,
                    CLOSURE_TOLERANCE,
                    rec["authority"],
                )
        cache[key] = rec
    return cache[key]
