"""The light of one frame, read once from the stage and shared by every sensor pass.

The infrared pass (sky and sun per sub-band, :func:`humv_usd.render.radiometry.frame_radiometry`)
and the visible pass (:func:`humv_usd.render.eo.illumination`) both start from the same three
values of the frame: the atmosphere's spectral tables (sky radiance against zenith, solar
irradiance), the direction toward the sun and the broadband direct normal irradiance. The render
reads them once per frame (:func:`read_frame_light`) and hands the same object to each pass.

A new light source (the night sky, the moon, artificial lights) plugs in by adding a field here
and reading it in :func:`read_frame_light`; each pass turns the fields into its own spectral
quantities (the lamps: :func:`humv_usd.render.lights.lamp_table` per sub-band).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd

from humv_usd.usd import environment as usd_environment
from humv_usd.usd import lights as usd_lights
from humv_usd.usd.atmosphere import AtmosphereSpectra, atmosphere_spectra


@dataclass(frozen=True)
class FrameLight:
    """What lights one frame, as the stage states it (nothing derived)."""

    time_code: Usd.TimeCode
    #: ``humv:atmosphere:*`` spectral tables at the frame (fields None when not authored)
    spectra: AtmosphereSpectra
    #: unit vector toward the sun (stage coordinates), None when not authored
    sun_direction: np.ndarray | None
    #: broadband direct normal irradiance [W m-2], None when not authored
    dni_w_m2: float | None
    #: the stage's lamps and lit windows at the frame (:func:`humv_usd.usd.lights.read_lamps`)
    lamps: tuple = ()


def read_frame_light(stage: Usd.Stage, time_code) -> FrameLight:
    """The frame's light (:class:`FrameLight`) at ``time_code`` (a frame number or time code)."""
    t = time_code if isinstance(time_code, Usd.TimeCode) else Usd.TimeCode(time_code)
    return FrameLight(
        time_code=t,
        spectra=atmosphere_spectra(stage, t),
        sun_direction=usd_environment.sun_direction(stage, t),
        dni_w_m2=usd_environment.direct_normal_irradiance(stage, t),
        lamps=tuple(usd_lights.read_lamps(stage, t)),
    )
