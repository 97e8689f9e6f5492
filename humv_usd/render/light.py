"""The light of one frame, read once from the stage and shared by every sensor pass.

The infrared pass (sky and sun per sub-band, :func:`humv_usd.render.radiometry.frame_radiometry`)
and the visible pass (:func:`humv_usd.render.eo.illumination`) both start from the same three
values of the frame: the atmosphere's spectral tables (sky radiance against zenith, solar
irradiance), the direction toward the sun and the broadband direct normal irradiance. The render
reads them once per frame (:func:`read_frame_light`) and hands the same object to each pass.

A new light source plugs in by adding a field here and reading it in :func:`read_frame_light`
(so are the lamps, the clouds' shadows and, after sunset, the moon and the cloud cover); each
pass turns the fields into its own spectral quantities (the lamps:
:func:`humv_usd.render.lights.lamp_table` per sub-band; the night sky and the moon:
:func:`humv_usd.render.nightlight.frame_night_light` on its wavelength grid).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd

from humv_usd.physics import clouds
from humv_usd.physics.sun import OVERCAST_DNI_FACTOR, cloud_dni_factor
from humv_usd.render.nightlight import NightSources, read_night_sources
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
    #: broken clouds' shadows on the sun at the frame (:func:`cloud_shadows`), None: none
    clouds: CloudShadows | None = None
    #: after sunset (the sun authored and below the horizon): the moon and the cloud cover
    #: (:func:`humv_usd.render.nightlight.read_night_sources`), for every reflective pass's night
    #: light (:func:`humv_usd.render.nightlight.frame_night_light`); None while the sun is up
    night: NightSources | None = None


@dataclass(frozen=True)
class CloudShadows:
    """The broken clouds of one frame (:mod:`humv_usd.physics.clouds`), as the thermal tool
    gates the sun on the scene's faces (:func:`humv_usd.thermal.surfaces.with_cloud_shadows`):
    the seed's ``field``, its ``displacement`` (2,) [m] east/north since frame 0, the
    ``threshold`` q above which a point of the ground is under cloud, and ``clear_factor``, the
    clear-sky beam between the clouds over the layer's mean beam (1 / Kasten & Czeplak's
    DNI / DNI_clear): a sunlit point gets the frame's sun times it, a shadowed one none."""

    field: clouds.CloudField
    displacement: np.ndarray
    threshold: float
    clear_factor: float
    size_m: float
    cover: float

    def sunlit(self, x, y) -> np.ndarray:
        """1 where the points (x, y) [m] (broadcast) see the sun between the clouds, else 0."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        f = clouds.moving_values(self.field, x.ravel(), y.ravel(), self.displacement)[0]
        return (f <= self.threshold).astype(float).reshape(x.shape)

    def describe(self) -> str:
        return (
            f"broken clouds ({self.size_m:g} m, cover {self.cover:g}, humv_usd.physics.clouds) moved "
            f"{float(np.hypot(*self.displacement)):.4g} m since frame 0: no sun under them, "
            f"x {self.clear_factor:.4g} (the clear-sky beam) between them"
        )


def cloud_shadows(stage: Usd.Stage, time_code) -> CloudShadows | None:
    """The frame's :class:`CloudShadows` from the environment layer: ``humv:environment:cloudSize``
    (0 or unauthored: None), the cloud cover at the frame (0, or overcast, DNI / DNI_clear below
    :data:`humv_usd.physics.sun.OVERCAST_DNI_FACTOR`: None, the layer's uniform beam), the
    field of /World's ``humv:scenario:seed`` carried by the cloud-level wind of the frames 0 to
    this one (:func:`humv_usd.physics.clouds.cloud_displacement`) toward the opposite of frame 0's
    wind direction: the thermal tool's field, threshold and motion."""
    size = usd_environment.cloud_size_m(stage)
    if size <= 0.0:
        return None
    code = float(getattr(time_code, "GetValue", lambda: time_code)())
    codes = np.arange(0.0, max(code, 0.0) + 0.5)
    if codes[-1] != max(code, 0.0):
        codes = np.append(codes, max(code, 0.0))
    weather = usd_environment.read_weather(stage, codes)
    cover = float(weather.cloud_cover[-1])
    factor = float(cloud_dni_factor(cover))
    if cover <= 0.0 or factor < OVERCAST_DNI_FACTOR:
        return None
    fps = float(stage.GetTimeCodesPerSecond()) or 24.0
    toward = (float(weather.wind_direction_deg[0]) + 180.0) % 360.0
    shift = clouds.cloud_displacement(codes / fps, clouds.cloud_level_wind(weather.wind_speed_m_s), toward)
    return CloudShadows(
        field=clouds.cloud_field(usd_environment.read_site(stage).seed, size),
        displacement=np.asarray(shift[-1], float),
        threshold=float(clouds.cloud_threshold(cover)),
        clear_factor=1.0 / factor,
        size_m=size,
        cover=cover,
    )


def read_frame_light(stage: Usd.Stage, time_code) -> FrameLight:
    """The frame's light (:class:`FrameLight`) at ``time_code`` (a frame number or time code)."""
    t = time_code if isinstance(time_code, Usd.TimeCode) else Usd.TimeCode(time_code)
    sun_direction = usd_environment.sun_direction(stage, t)
    after_sunset = sun_direction is not None and float(sun_direction[2]) <= 0.0
    return FrameLight(
        time_code=t,
        spectra=atmosphere_spectra(stage, t),
        sun_direction=sun_direction,
        dni_w_m2=usd_environment.direct_normal_irradiance(stage, t),
        lamps=tuple(usd_lights.read_lamps(stage, t)),
        clouds=cloud_shadows(stage, t),
        night=read_night_sources(stage, t) if after_sunset else None,
    )
