"""Light after sunset for the reflective bands (EO, NIR, SWIR): twilight, moon, natural night sky.

:func:`night_light` gives, for one frame of a stage whose sun is below the horizon, on any
wavelength grid (0.36-2.5 um):

- the sky: a uniform radiance, the sum of the twilight sky (sun 0 to -18 deg), the moonlit sky
  and the natural night sky (starlight, zodiacal light, airglow);
- the moon as a directional source (direction and beam-normal spectral irradiance) when it is
  above the horizon.

Models and sources: :mod:`humv_usd.physics.nightsky`; the moon's position, phase and clear-sky
illuminance from the environment layer (/World/Environment/Moon, computed at compose by
:func:`humv_usd.environment.moon.moon_at`, PyEphem; :func:`frame_moon`), or for a stage without it
from PyEphem at the stage's site and frame time (the scenario metadata on /World). The render adds these to the atmosphere layer's sky (in the visible
and short-wave infrared its night value is thermal emission only, ~1e-24 W m-2 sr-1 nm-1 at
0.55 um) and takes the moon in place of the sun. The photometric scale is the CIE 1931 y-bar
(:mod:`humv_usd.render.cie`) with 683 lm W-1. Clear sky; cloud cover is not applied (noted).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

import numpy as np

from humv_usd.environment.moon import moon_at
from humv_usd.errors import InputError
from humv_usd.physics import nightsky
from humv_usd.physics.sun import cloud_reduction
from humv_usd.render.cie import CMF_WAVELENGTHS_NM, CMF_XYZ
from humv_usd.usd import environment as usd_environment

#: CIE photopic efficiency V = CIE 1931 y-bar on its 5-nm grid [um].
PHOTOPIC = (CMF_WAVELENGTHS_NM / 1000.0, np.asarray(CMF_XYZ, float).reshape(-1, 3)[:, 1])
#: Wavelengths [um] night light is defined over (short of the thermal sky's own range).
NIGHT_RANGE_UM = (0.36, 2.5)


@dataclass
class NightLight:
    """Night illumination of one frame on a grid: ``sky`` (W,) [W m-2 sr-1 um-1] uniform,
    ``moon_direction`` (3,) toward the moon or None, ``moon_irradiance`` (W,) [W m-2 um-1]
    beam-normal or None, and what was used (``ran``)."""

    sky: np.ndarray
    moon_direction: np.ndarray | None
    moon_irradiance: np.ndarray | None
    ran: dict = field(default_factory=dict)


def frame_utc(stage, time_code) -> dt.datetime | None:
    """UTC time of a stage time code from /World's start time and the stage's frames per second
    (None when the stage has no scenario metadata)."""
    try:
        site = usd_environment.read_site(stage)
        start = dt.datetime.fromisoformat(site.start_time)
    except (InputError, ValueError):
        return None
    if start.tzinfo is None:
        start = start.replace(tzinfo=dt.UTC)
    code = float(getattr(time_code, "GetValue", lambda: time_code)())
    fps = float(stage.GetTimeCodesPerSecond()) or 24.0
    return (start + dt.timedelta(seconds=code / fps)).astimezone(dt.UTC)


def frame_moon(stage, time_code) -> tuple[usd_environment.MoonSample | None, str]:
    """The moon at ``time_code`` and where it came from: the environment layer's
    (:func:`humv_usd.usd.environment.read_moon`, computed at compose), else, for a stage without
    it (composed before the moon was authored there, or made elsewhere), PyEphem at the frame's
    UTC time from /World's site (:func:`humv_usd.environment.moon.moon_at`, as the environment
    tool computes it); (None, why) without either."""
    code = float(getattr(time_code, "GetValue", lambda: time_code)())
    sample = usd_environment.read_moon(stage, code)
    if sample is not None:
        return sample, f"{usd_environment.MOON_LIGHT_PATH} at time code {code:g} (environment layer)"
    when = frame_utc(stage, time_code)
    if when is None:
        return None, "no moon on the stage, and no site and start time on /World (HumvScenarioAPI)"
    site = usd_environment.read_site(stage)
    m = moon_at(site.latitude_deg, site.longitude_deg, site.elevation_m, [when])
    el, alpha, dist = float(m.elevation_deg[0]), float(m.phase_angle_deg[0]), float(m.distance_km[0])
    return usd_environment.MoonSample(
        direction=np.asarray(m.direction[0], float),
        elevation_deg=el,
        azimuth_deg=float(m.azimuth_deg[0]),
        phase_angle_deg=alpha,
        illuminated_fraction=float(m.illuminated_fraction[0]),
        distance_km=dist,
        illuminance_lux=float(nightsky.moon_illuminance_lux(el, alpha, dist)),
    ), f"PyEphem at {when.isoformat()} (no {usd_environment.MOON_LIGHT_PATH} on the stage)"


def cloud_cover_at(stage, time_code) -> float | None:
    """The environment layer's cloud cover [0-1] at ``time_code`` (None without a weather)."""
    code = float(getattr(time_code, "GetValue", lambda: time_code)())
    try:
        return float(usd_environment.read_weather(stage, [code]).cloud_cover[0])
    except (InputError, AttributeError):
        return None


@dataclass(frozen=True)
class NightSources:
    """What lights one frame after sunset, as the stage states it (nothing derived; read once
    per frame with the rest of the frame's light, :class:`humv_usd.render.light.FrameLight`):
    the moon (:func:`frame_moon`: None and why without one) and the cloud cover [0-1]
    (:func:`cloud_cover_at`: None without a weather)."""

    moon: usd_environment.MoonSample | None
    moon_source: str
    cloud_cover: float | None


def read_night_sources(stage, time_code) -> NightSources:
    """The frame's :class:`NightSources` from the stage."""
    moon, source = frame_moon(stage, time_code)
    return NightSources(moon, source, cloud_cover_at(stage, time_code))


def frame_night_light(light, wavelengths_um) -> NightLight | None:
    """Night illumination of a frame's light (:class:`humv_usd.render.light.FrameLight`, its
    ``night`` read with it) on ``wavelengths_um``: :func:`night_spectra`; None while the sun is
    up or not authored."""
    if light.night is None:
        return None
    return night_spectra(light.night, light.sun_direction, wavelengths_um)


def night_light(stage, time_code, sun_direction, wavelengths_um, cloud_cover=None) -> NightLight | None:
    """Night illumination at ``time_code`` on ``wavelengths_um`` read from the stage
    (:func:`read_night_sources`, :func:`night_spectra`; ``cloud_cover`` overrides the layer's).
    None when the sun is up or not authored: the day's sky and sun tables hold then."""
    if sun_direction is None or float(sun_direction[2]) > 0.0:
        return None
    return night_spectra(read_night_sources(stage, time_code), sun_direction, wavelengths_um, cloud_cover)


def night_spectra(
    sources: NightSources, sun_direction, wavelengths_um, cloud_cover=None
) -> NightLight | None:
    """Night illumination on ``wavelengths_um`` from the frame's :class:`NightSources` and the
    direction toward the sun (None when the sun is up or not authored).

    Clouds (``cloud_cover`` N in 0-1, default the sources', clear without one): Kasten
    & Czeplak (1980) as for the sun (:func:`humv_usd.physics.sun.cloud_reduction`): the global
    illuminance of each source falls as 1 - 0.75 N^3.4 and its diffuse share rises as
    kd + (1 - kd) N^2 (kd the clear-sky share: 1 for the twilight and night skies, the moonlit
    sky's for the moon), so an overcast sky has no moon beam and a quarter of the clear light,
    uniform; the clouds' own reflection of city light is not modelled."""
    if sun_direction is None or float(sun_direction[2]) > 0.0:
        return None
    wl = np.asarray(wavelengths_um, dtype=float)
    ran: dict = {}
    n = sources.cloud_cover if cloud_cover is None else float(cloud_cover)
    global_factor = 1.0 if n is None else float(1.0 - 0.75 * np.clip(n, 0.0, 1.0) ** 3.4)
    sun_el = float(np.degrees(np.arcsin(np.clip(sun_direction[2], -1.0, 1.0))))
    e_tw = float(nightsky.twilight_illuminance_lux(sun_el))
    sky = np.zeros(wl.size)
    if e_tw > 0:
        shape = nightsky.scattered_shape(wl, nightsky.solar_shape(wl))
        sky += nightsky.scale_to_photometric(wl, shape, e_tw / np.pi, PHOTOPIC)
        ran["twilight"] = (
            f"uniform sky, sun at {sun_el:.2f} deg: horizontal illuminance {e_tw:.4g} lx (USNO "
            "Circular 171), Rayleigh-scattered solar spectrum"
        )
    else:
        ran["twilight"] = f"none: sun at {sun_el:.2f} deg (below -18 deg)"
    night = nightsky.night_sky_radiance(wl)
    sky = (sky + night) * global_factor
    ran["night_sky"] = (
        "natural moonless sky (starlight, zodiacal light, airglow) from dark-site sky brightness "
        f"(humv_usd.physics.nightsky.NIGHT_SKY_MAG): {float(np.interp(0.55, wl, night)):.3g} "
        "W m-2 sr-1 um-1 at 0.55 um"
    )
    moon_dir = moon_e = None
    m, source = sources.moon, sources.moon_source
    if m is None:
        ran["moon"] = f"skipped: {source}"
    else:
        el, alpha, e_moon = m.elevation_deg, m.phase_angle_deg, m.illuminance_lux
        what = (
            f"{source}: altitude {el:.2f} deg, azimuth {m.azimuth_deg:.1f} deg, "
            f"phase angle {alpha:.1f} deg (illuminated {m.illuminated_fraction:.2f})"
        )
        if el <= 0.0 or e_moon <= 0.0:
            ran["moon"] = f"below the horizon: {what}"
        else:
            moon_dir = np.asarray(m.direction, float)
            e_h = e_moon * float(moon_dir[2])
            f = nightsky.MOONLIT_SKY_FRACTION
            _, dhi, dni = cloud_reduction(e_h * (1 + f), f * e_h, 90.0 - el, 0.0 if n is None else n)
            e_moon, e_diffuse = float(dni), float(dhi)  # beam-normal and diffuse-horizontal [lx]
            moon_e = nightsky.scale_to_photometric(wl, nightsky.moon_shape(wl), e_moon, PHOTOPIC)
            sky_shape = nightsky.scattered_shape(wl, nightsky.moon_shape(wl))
            sky += nightsky.scale_to_photometric(wl, sky_shape, e_diffuse / np.pi, PHOTOPIC)
            if e_moon <= 0.0:
                moon_dir = moon_e = None
            ran["moon"] = (
                f"directional, {e_moon:.4g} lx normal to the beam (USNO Circular 171 x Allen's phase "
                f"law), moonlit sky {e_diffuse:.4g} lx diffuse on the ground; {what}"
                if moon_dir is not None
                else f"behind the clouds: moonlit sky {e_diffuse:.4g} lx diffuse on the ground; {what}"
            )
    ran["clouds"] = (
        "clear: no cloud cover on the stage"
        if n is None
        else f"cloud cover {n:g}: global x {global_factor:.3g}, diffuse share raised (Kasten & Czeplak 1980)"
    )
    return NightLight(sky=sky, moon_direction=moon_dir, moon_irradiance=moon_e, ran=ran)


def add_to_subbands(frame_rad, night: NightLight, sub, wavelengths_um) -> None:
    """Add a frame's night light to an infrared sensor's sub-band radiometry (NIR, SWIR) in place:
    the uniform night sky integrated per sub-band with the response (:meth:`SubBands.integrate`)
    onto the sky (constant or every row of the envmaps) and, when the sun is down and the moon up,
    the moon as the directional source. ``frame_rad``: a
    :class:`humv_usd.render.radiometry.FrameRadiometry`; ``ran`` gets ``night``."""
    wl = np.asarray(wavelengths_um, dtype=float)
    per_k = sub.integrate(wl, night.sky)  # (n,) [W m-2 sr-1]
    if frame_rad.sky_maps is not None:
        frame_rad.sky_maps = [np.asarray(m, float) + per_k[k] for k, m in enumerate(frame_rad.sky_maps)]
    else:
        base = np.zeros(len(sub)) if frame_rad.sky_constant is None else np.nan_to_num(frame_rad.sky_constant)
        frame_rad.sky_constant = base + per_k
    frame_rad.ran["night"] = night.ran
    if night.moon_direction is not None and frame_rad.sun_direction is None:
        frame_rad.sun_direction = np.asarray(night.moon_direction, float)
        frame_rad.sun_irradiance = sub.integrate(wl, night.moon_irradiance)
        frame_rad.ran["sun"] = (
            f"{frame_rad.ran.get('sun')}; the moon takes the directional light (night.moon)"
        )
