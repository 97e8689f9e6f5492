"""Artificial lights as scene elements: lamps and lit windows of the stage as Mitsuba emitters.

A :class:`humv_usd.usd.lights.Lamp` becomes one :class:`humv_usd.render.elements.Element`
(:func:`lamp_element`) on a wavelength grid:

- a sphere light without a cone: a ``point`` emitter of spectral intensity
  :math:`I_\\lambda = \\frac{\\Phi_v}{4\\pi}\\,\\frac{s(\\lambda)}{K_m\\int V s\\,d\\lambda}`
  [W sr-1 nm-1] (:math:`\\Phi_v` the luminous flux, s the lamp type's relative SPD,
  :mod:`humv_usd.catalog.lights`; :math:`K_m` = 683 lm W-1);
- a sphere light with a cone (UsdLux ShapingAPI): a ``spot`` along the light's -Z axis, full
  intensity out to ``(1 - softness)`` of the cone angle and falling linearly in angle to zero at
  the cone angle (Mitsuba's spot), its flux spread over the solid angle of the mean of those two
  angles, :math:`2\\pi(1 - \\cos\\bar\\theta)` (an approximation of the linear fall-off; exact
  without softness);
- a rect light (a lit window): a ``rectangle`` with an ``area`` emitter of spectral radiance
  :math:`L_\\lambda = L_v s(\\lambda)/(K_m\\int V s\\,d\\lambda)` facing the light's -Z.

The visible path tracer (:class:`humv_usd.render.eo.EOScene`) adds these elements. The fast
estimator (:func:`humv_usd.render.estimator.render_band_fast`, EO bins and NIR/SWIR sub-bands)
takes the same lamps as a :class:`LampTable` per sub-band (:func:`lamp_table`) and adds their
direct light by next-event estimation (a shadow ray per lamp per hit; a window by one sampled
point on its rectangle). Photometric scale: the CIE 1931 y-bar
(:data:`humv_usd.render.nightlight.PHOTOPIC`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from humv_usd.catalog.lights import LAMPS
from humv_usd.physics.nightsky import scale_to_photometric
from humv_usd.render.elements import Element, regular_spectrum
from humv_usd.render.nightlight import PHOTOPIC
from humv_usd.usd.lights import Lamp


def luminous_intensity_cd(lamp: Lamp) -> float:
    """Luminous intensity on the lamp's axis [cd]: flux over the solid angle it fills (see the
    module notes)."""
    if lamp.cone_angle_deg >= 180.0:
        return lamp.luminous_flux_lm / (4.0 * math.pi)
    beam = lamp.cone_angle_deg * (1.0 - lamp.cone_softness)
    mean = math.radians(0.5 * (beam + lamp.cone_angle_deg))
    return lamp.luminous_flux_lm / (2.0 * math.pi * (1.0 - math.cos(mean)))


def spectral_per_nm(lamp: Lamp, photometric: float, wavelengths_nm) -> np.ndarray:
    """The lamp type's SPD scaled to ``photometric`` (cd -> W sr-1 nm-1, cd m-2 ->
    W m-2 sr-1 nm-1) on ``wavelengths_nm``."""
    wl = np.asarray(wavelengths_nm, float) / 1000.0
    return scale_to_photometric(wl, LAMPS[lamp.spectrum].spd(wl), photometric, PHOTOPIC) / 1000.0


def _frame(lamp: Lamp):
    """Unit axes and origin of the light in world space (its scale removed)."""
    m = np.asarray(lamp.to_world, float)
    x, y, z = (m[i, :3] / np.linalg.norm(m[i, :3]) for i in range(3))
    return x, y, z, m[3, :3]


def lamp_element(mi, lamp: Lamp, key: str, wavelengths_nm) -> Element:
    """The Mitsuba emitter of one lamp (see the module notes) on ``wavelengths_nm`` [nm]."""
    x, y, z, origin = _frame(lamp)
    if lamp.kind == "rect":
        # Mitsuba's rectangle spans [-1, 1]^2 with normal +Z; a UsdLux RectLight emits along -Z
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x * lamp.width_m / 2, -y * lamp.height_m / 2, -z, origin
        return Element(
            key,
            {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f(m.tolist()),
                "emitter": {
                    "type": "area",
                    "radiance": regular_spectrum(
                        wavelengths_nm, spectral_per_nm(lamp, lamp.luminance, wavelengths_nm)
                    ),
                },
                "bsdf": {"type": "diffuse", "reflectance": {"type": "uniform", "value": 0.0}},
            },
        )
    intensity = regular_spectrum(
        wavelengths_nm, spectral_per_nm(lamp, luminous_intensity_cd(lamp), wavelengths_nm)
    )
    if lamp.cone_angle_deg >= 180.0:
        return Element(key, {"type": "point", "position": [float(v) for v in origin], "intensity": intensity})
    d = -z
    up = y
    return Element(
        key,
        {
            "type": "spot",
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[float(v) for v in origin],
                target=[float(v) for v in origin + d],
                up=[float(v) for v in up],
            ),
            "cutoff_angle": float(lamp.cone_angle_deg),
            "beam_width": float(max(lamp.cone_angle_deg * (1.0 - lamp.cone_softness), 1e-3)),
            "intensity": intensity,
        },
    )


def lamp_elements(mi, lamps: list[Lamp], wavelengths_nm) -> list[Element]:
    """The emitters of every lamp (keys ``lamp_<i>``)."""
    return [lamp_element(mi, lamp, f"lamp_{i}", wavelengths_nm) for i, lamp in enumerate(lamps)]


def describe(lamps: list[Lamp]) -> str:
    """One line for the manifest: what lamps lit the frame."""
    if not lamps:
        return "none"
    parts = []
    for lamp in lamps:
        if lamp.kind == "rect":
            parts.append(
                f"{lamp.path}: {lamp.spectrum} window {lamp.width_m:g}x{lamp.height_m:g} m, {lamp.luminance:g} cd m-2"
            )
        else:
            cone = "" if lamp.cone_angle_deg >= 180.0 else f", cone {lamp.cone_angle_deg:g} deg"
            parts.append(
                f"{lamp.path}: {lamp.spectrum}, {lamp.luminous_flux_lm:g} lm ({luminous_intensity_cd(lamp):.4g} cd){cone}"
            )
    return "; ".join(parts)


@dataclass(frozen=True)
class LampTable:
    """The lamps of one frame per sub-band, as the fast estimator reads them.

    Point lamps and spots (P of them): ``position`` (P, 3) [m], ``axis`` (P, 3) unit vector the
    light points along, ``cutoff_rad`` / ``beam_rad`` (P,) the cone angle and the angle up to
    which the intensity is full (a bare lamp: pi / pi, no falloff), ``intensity`` (P, n) on the
    axis [W sr-1 per the sub-band's unit: per nm for EO bins, integrated for NIR/SWIR sub-bands].
    Windows (R): ``rect_centre`` (R, 3), ``rect_u`` / ``rect_v`` (R, 3) half-width and
    half-height vectors, ``rect_normal`` (R, 3) the unit direction it emits into,
    ``rect_radiance`` (R, n) [W m-2 sr-1 per the sub-band's unit]."""

    position: np.ndarray
    axis: np.ndarray
    cutoff_rad: np.ndarray
    beam_rad: np.ndarray
    intensity: np.ndarray
    rect_centre: np.ndarray
    rect_u: np.ndarray
    rect_v: np.ndarray
    rect_normal: np.ndarray
    rect_radiance: np.ndarray

    def __len__(self) -> int:
        return len(self.position) + len(self.rect_centre)


def spot_falloff(cos_theta, cutoff_rad: float, beam_rad: float) -> np.ndarray:
    """Relative intensity of a spot at angle arccos(``cos_theta``) off its axis: 1 inside the
    beam angle, linear in angle to 0 at the cutoff, 0 beyond (Mitsuba 3's ``spot`` emitter,
    ``falloff_curve``; a bare lamp, cutoff = pi, is 1 everywhere)."""
    theta = np.arccos(np.clip(np.asarray(cos_theta, float), -1.0, 1.0))
    if cutoff_rad >= math.pi:
        return np.ones_like(theta)
    ramp = (cutoff_rad - theta) / max(cutoff_rad - beam_rad, 1e-12)
    return np.where(theta <= beam_rad, 1.0, np.where(theta < cutoff_rad, np.clip(ramp, 0.0, 1.0), 0.0))


def lamp_table(lamps: list[Lamp], wavelengths_nm, reduce) -> LampTable | None:
    """The lamps' :class:`LampTable` (None without lamps): each lamp's spectral intensity
    (:func:`spectral_per_nm` of :func:`luminous_intensity_cd`) or a window's spectral radiance
    on ``wavelengths_nm`` [per nm], turned into n sub-band values by ``reduce(values_per_nm) ->
    (n,)`` (EO: the bins' sensitivity-weighted mean, :meth:`humv_usd.render.eo_fast.VisibleBins.mean`;
    NIR/SWIR: the response-weighted integral, :meth:`humv_usd.render.radiometry.SubBands.integrate`).
    The same geometry as :func:`lamp_element` (a spot's beam angle at least 1e-3 deg)."""
    if not lamps:
        return None
    pos, axis, cut, beam, inten = [], [], [], [], []
    centre, u, v, normal, rad = [], [], [], [], []
    for lamp in lamps:
        x, y, z, origin = _frame(lamp)
        if lamp.kind == "rect":
            centre.append(origin)
            u.append(x * lamp.width_m / 2)
            v.append(y * lamp.height_m / 2)
            normal.append(-z)
            rad.append(np.asarray(reduce(spectral_per_nm(lamp, lamp.luminance, wavelengths_nm)), float))
            continue
        pos.append(origin)
        axis.append(-z)
        if lamp.cone_angle_deg >= 180.0:
            cut.append(math.pi)
            beam.append(math.pi)
        else:
            cut.append(math.radians(lamp.cone_angle_deg))
            beam.append(math.radians(max(lamp.cone_angle_deg * (1.0 - lamp.cone_softness), 1e-3)))
        inten.append(
            np.asarray(reduce(spectral_per_nm(lamp, luminous_intensity_cd(lamp), wavelengths_nm)), float)
        )
    n = len((inten or rad)[0])

    def rows(values, width):
        return np.asarray(values, float).reshape(-1, width)

    return LampTable(
        position=rows(pos, 3),
        axis=rows(axis, 3),
        cutoff_rad=np.asarray(cut, float),
        beam_rad=np.asarray(beam, float),
        intensity=rows(inten, n),
        rect_centre=rows(centre, 3),
        rect_u=rows(u, 3),
        rect_v=rows(v, 3),
        rect_normal=rows(normal, 3),
        rect_radiance=rows(rad, n),
    )
