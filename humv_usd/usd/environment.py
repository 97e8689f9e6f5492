"""Typed readers and writers of the environment layer (/World: HumvScenarioAPI; /World/Environment:
HumvEnvironmentAPI): the only code that knows these attribute names.

The environment tool computes the weather and the sun once and writes them here; every other tool
and the render read them back at the time codes they need (frames; USD interpolates linearly
between samples and holds the first / last sample outside them).

Time codes of the environment layer:

* frames 0 .. N-1 (every frame, or strided frames of long scenarios, see
  :func:`humv_usd.scenario.times.frame_times`): what the render and the per-frame tools read;
* negative time codes, the scene-surface spin-up window before frame 0
  (:func:`humv_usd.scenario.times.spin_up_times`, 10-minute steps over
  ``[thermal] surface_spin_up_s``): read by the thermal tool's slab spin-up only. USD holds the
  frame-0 sample for every time code >= 0 beyond the samples, so readers at frames >= 0 see the
  same values as without them.

Constant weather is authored as default values (the same at every time code).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

from humv_usd.errors import InputError, bad_value, summary
from humv_usd.physics.sun import SunState
from humv_usd.physics.weather import Weather
from humv_usd.scenario.spec import ATMOSPHERE
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, WORLD

ENVIRONMENT_PATH = SCOPES["environment"]

#: (attribute, Weather field)
WEATHER_ATTRS = (
    (S.ENVIRONMENT_AIR_TEMPERATURE, "air_temperature_k"),
    (S.ENVIRONMENT_RELATIVE_HUMIDITY, "relative_humidity"),
    (S.ENVIRONMENT_WIND_SPEED, "wind_speed_m_s"),
    (S.ENVIRONMENT_WIND_DIRECTION, "wind_direction_deg"),
    (S.ENVIRONMENT_PRESSURE, "pressure_pa"),
    (S.ENVIRONMENT_CLOUD_COVER, "cloud_cover"),
)

#: (attribute, SunState field) of the scalar sun quantities
SUN_ATTRS = (
    (S.ENVIRONMENT_SUN_ZENITH, "zenith_deg"),
    (S.ENVIRONMENT_SUN_AZIMUTH, "azimuth_deg"),
    (S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE, "dni_w_m2"),
    (S.ENVIRONMENT_DIFFUSE_HORIZONTAL_IRRADIANCE, "dhi_w_m2"),
    (S.ENVIRONMENT_GLOBAL_HORIZONTAL_IRRADIANCE, "ghi_w_m2"),
)

#: (attribute, Site field)
SITE_ATTRS = (
    (S.SCENARIO_NAME, "name"),
    (S.SCENARIO_DESCRIPTION, "description"),
    (S.SCENARIO_START_TIME, "start_time"),
    (S.SCENARIO_TIME_ZONE, "time_zone"),
    (S.SCENARIO_LATITUDE, "latitude_deg"),
    (S.SCENARIO_LONGITUDE, "longitude_deg"),
    (S.SCENARIO_ELEVATION, "elevation_m"),
    (S.SCENARIO_SEED, "seed"),
)


@dataclass
class Site:
    """Scenario metadata of /World (HumvScenarioAPI): frame 0's local ISO date-time with its UTC
    offset, latitude / longitude [deg], elevation [m]."""

    name: str
    description: str
    start_time: str
    time_zone: str
    latitude_deg: float
    longitude_deg: float
    elevation_m: float
    seed: int


# --- writers (the environment tool) --------------------------------------------------------------
def define_environment(stage: Usd.Stage) -> Usd.Prim:
    """The environment scope (:data:`ENVIRONMENT_PATH`) with HumvEnvironmentAPI applied: the
    prim :func:`write_weather` and :func:`write_sun` write to."""
    prim = UsdGeom.Scope.Define(stage, ENVIRONMENT_PATH).GetPrim()
    prim.ApplyAPI(S.ENVIRONMENT_API)
    return prim


def write_site(stage: Usd.Stage, site: Site) -> None:
    """Apply HumvScenarioAPI to /World and author the site."""
    world = stage.GetPrimAtPath(WORLD)
    world.ApplyAPI(S.SCENARIO_API)
    for attr, key in SITE_ATTRS:
        world.GetAttribute(attr).Set(getattr(site, key))


def _set(attr, values, codes, sampled: bool, convert=float) -> None:
    if sampled:
        for code, v in zip(codes, values):
            attr.Set(convert(v), float(code))
    else:
        attr.Set(convert(values[0]))


def write_weather(prim: Usd.Prim, weather: Weather, codes) -> None:
    """Author the weather at time codes ``codes`` (defaults when it does not vary)."""
    for attr, key in WEATHER_ATTRS:
        _set(prim.GetAttribute(attr), getattr(weather, key), codes, weather.varies)


def write_cloud_size(prim: Usd.Prim, cloud_size_m: float) -> None:
    """Author the size [m] of the broken clouds whose shadows move over the scene
    (``[atmosphere] cloud_size_m``; 0: a uniform cover)."""
    prim.GetAttribute(S.ENVIRONMENT_CLOUD_SIZE).Set(float(cloud_size_m))


def cloud_size_m(stage: Usd.Stage) -> float:
    """The size [m] of the broken clouds (:func:`write_cloud_size`); 0 (a uniform cover) when
    the stage has no environment or does not say. InputError outside the key's range."""
    prim = stage.GetPrimAtPath(ENVIRONMENT_PATH)
    attr = prim.GetAttribute(S.ENVIRONMENT_CLOUD_SIZE) if prim else None
    value = attr.Get() if attr else None
    if value is None:
        return 0.0
    key = ATMOSPHERE.keys["cloud_size_m"]
    if not (math.isfinite(float(value)) and key.lo <= float(value) <= key.hi):
        raise InputError(
            bad_value(
                f"{ENVIRONMENT_PATH}.{S.ENVIRONMENT_CLOUD_SIZE}", value, f"expected {key.lo:g}..{key.hi:g}"
            )
        )
    return float(value)


def write_sun(prim: Usd.Prim, sun: SunState, codes) -> None:
    """Author the sun at time codes ``codes`` (defaults for a single sample)."""
    sampled = len(codes) > 1
    _set(
        prim.GetAttribute(S.ENVIRONMENT_SUN_DIRECTION),
        sun.direction,
        codes,
        sampled,
        lambda d: Gf.Vec3f(*map(float, d)),
    )
    for attr, key in SUN_ATTRS:
        _set(prim.GetAttribute(attr), getattr(sun, key), codes, sampled)


#: Luminous efficacy of clear-sky direct sunlight and of diffuse skylight [lm W^-1] (Littlefair
#: 1985, "The luminous efficacy of daylight: a review", Lighting Res. Technol. 17(4): beam about
#: 90-105, diffuse 110-130 lm/W over the measured data sets; mid values): converts the
#: environment's broadband irradiance to the photometric units UsdLux uses.
BEAM_EFFICACY_LM_W = 95.0
DIFFUSE_EFFICACY_LM_W = 120.0
#: Angular diameter of the sun [deg] (UsdLux DistantLight's fallback).
SUN_ANGLE_DEG = 0.53
SUN_LIGHT_PATH = ENVIRONMENT_PATH.AppendChild("Sun")
SKY_LIGHT_PATH = ENVIRONMENT_PATH.AppendChild("Sky")


def _sun_orientation(direction) -> Gf.Matrix4d:
    """A rotation whose -Z axis is the direction sunlight travels (a DistantLight shines along
    its -Z): its +Z axis points at the sun."""
    z = np.asarray(direction, dtype=float)
    z = z / np.linalg.norm(z)
    helper = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = x, y, z  # USD row vectors: rows are the transformed axes
    return Gf.Matrix4d(m.tolist())


def write_lights(stage: Usd.Stage, sun: SunState, codes, frame_samples) -> None:
    """The sun and sky as UsdLux lights, so that viewers and renderers that read only UsdLux
    (Blender, usdview, Omniverse) show the scene lit as HumV's render sees it (issue 27).

    ``frame_samples``: indices into ``sun``/``codes`` of the frame time codes (the spin-up's
    negative time codes are left out). Sun: a normalized DistantLight (intensity = illuminance
    at normal incidence [lx], UsdLux) of the direct normal irradiance x
    :data:`BEAM_EFFICACY_LM_W`, angle :data:`SUN_ANGLE_DEG`, oriented at the sun; zero below the
    horizon. Sky: a uniform DomeLight of luminance E_d / pi [nit] (a uniform sky of luminance L
    gives the horizontal illuminance pi L), E_d = diffuse horizontal irradiance x
    :data:`DIFFUSE_EFFICACY_LM_W`. HumV's own render ignores both: it reads the environment
    and atmosphere attributes."""
    from pxr import UsdLux

    idx = list(frame_samples)
    sampled = len(idx) > 1
    light = UsdLux.DistantLight.Define(stage, SUN_LIGHT_PATH)
    light.CreateAngleAttr(SUN_ANGLE_DEG)
    light.CreateNormalizeAttr(True)
    op = light.AddTransformOp()
    intensity = light.CreateIntensityAttr()
    dome = UsdLux.DomeLight.Define(stage, SKY_LIGHT_PATH)
    # authored: Blender makes a world only from a dome's colour or texture
    dome.CreateColorAttr(Gf.Vec3f(1.0, 1.0, 1.0))
    dome_intensity = dome.CreateIntensityAttr()
    for i in idx:
        code = Usd.TimeCode(float(codes[i])) if sampled else Usd.TimeCode.Default()
        up = bool(sun.up[i])
        op.Set(_sun_orientation(sun.direction[i] if up else (0.0, 0.0, 1.0)), code)
        intensity.Set(float(sun.dni_w_m2[i]) * BEAM_EFFICACY_LM_W if up else 0.0, code)
        dome_intensity.Set(float(sun.dhi_w_m2[i]) * DIFFUSE_EFFICACY_LM_W / np.pi, code)


def write_sky_texture(stage: Usd.Stage, asset_path: str) -> None:
    """Point the sky's DomeLight (:data:`SKY_LIGHT_PATH`) at a lat-long texture ``asset_path``
    (relative to the layer being written), from a layer other than the environment layer (the
    atmosphere tool, which has the sky's spectrum: an ``over`` of the dome). The texture is
    relative (its cosine-weighted mean luminance is 1, :mod:`humv_usd.atmosphere.texture`), so
    the dome's photometric scale stays :func:`write_lights`'s intensity. A DomeLight's pole is
    its +Y axis (UsdLux, OpenEXR's lat-long layout); on this Z-up stage the over adds UsdLux's
    ``xformOp:rotateX:orientToStageUpAxis`` = 90 deg (what ``UsdLuxDomeLight.OrientToStageUpAxis``
    authors), which turns +Y to +Z, so the texture's top row is the zenith."""
    from pxr import UsdLux

    prim = stage.OverridePrim(SKY_LIGHT_PATH)
    dome = UsdLux.DomeLight(prim)
    dome.CreateTextureFileAttr(Sdf.AssetPath(asset_path))
    dome.CreateTextureFormatAttr(UsdLux.Tokens.latlong)
    UsdGeom.Xformable(prim).AddRotateXOp(opSuffix="orientToStageUpAxis").Set(90.0)


#: The moon (issue 24.4): a UsdLux DistantLight at /World/Environment/Moon whose intensity is the
#: moon's beam-normal illuminance [lx] (as the sun's), with custom attributes for what the render
#: needs (double precision, time-sampled per frame like the sun): unit direction toward the moon
#: (x east, y north, z up), apparent elevation and compass azimuth [deg], phase angle [deg]
#: (Sun-Moon-Earth, 0 = full), illuminated fraction [0-1], Earth-Moon distance [km] and the
#: clear-sky beam-normal illuminance [lx] (:func:`humv_usd.physics.nightsky.moon_illuminance_lux`).
MOON_LIGHT_PATH = ENVIRONMENT_PATH.AppendChild("Moon")
MOON_DIRECTION = "humv:moon:direction"
MOON_ELEVATION = "humv:moon:elevation"
MOON_AZIMUTH = "humv:moon:azimuth"
MOON_PHASE_ANGLE = "humv:moon:phaseAngle"
MOON_ILLUMINATED_FRACTION = "humv:moon:illuminatedFraction"
MOON_DISTANCE = "humv:moon:distance"
MOON_ILLUMINANCE = "humv:moon:illuminance"
#: Angular diameter of the moon [deg] (mean, 31 arc-minutes; Meeus 1998 ch. 55).
MOON_ANGLE_DEG = 0.52
#: (attribute, MoonState field) of the scalar moon quantities
MOON_ATTRS = (
    (MOON_ELEVATION, "elevation_deg"),
    (MOON_AZIMUTH, "azimuth_deg"),
    (MOON_PHASE_ANGLE, "phase_angle_deg"),
    (MOON_ILLUMINATED_FRACTION, "illuminated_fraction"),
    (MOON_DISTANCE, "distance_km"),
)


def write_moon(stage: Usd.Stage, moon, illuminance_lux, codes) -> None:
    """Author the moon (:data:`MOON_LIGHT_PATH`) at time codes ``codes`` (defaults for a single
    sample): ``moon`` a :class:`humv_usd.environment.moon.MoonState`, ``illuminance_lux`` its
    clear-sky beam-normal illuminance per sample. The DistantLight's intensity is that
    illuminance while the moon is above the horizon, else 0, oriented at the moon (UsdLux,
    normalized, so viewers light the scene with it as HumV's night render does)."""
    from pxr import UsdLux

    light = UsdLux.DistantLight.Define(stage, MOON_LIGHT_PATH)
    light.CreateAngleAttr(MOON_ANGLE_DEG)
    light.CreateNormalizeAttr(True)
    op = light.AddTransformOp()
    intensity = light.CreateIntensityAttr()
    prim = light.GetPrim()
    direction = prim.CreateAttribute(MOON_DIRECTION, Sdf.ValueTypeNames.Double3, custom=True)
    scalars = [
        (prim.CreateAttribute(name, Sdf.ValueTypeNames.Double, custom=True), np.asarray(getattr(moon, key)))
        for name, key in MOON_ATTRS
    ]
    lux = prim.CreateAttribute(MOON_ILLUMINANCE, Sdf.ValueTypeNames.Double, custom=True)
    sampled = len(codes) > 1
    for i, c in enumerate(codes):
        code = Usd.TimeCode(float(c)) if sampled else Usd.TimeCode.Default()
        d = np.asarray(moon.direction[i], dtype=float)
        up = float(moon.elevation_deg[i]) > 0.0
        direction.Set(Gf.Vec3d(*map(float, d)), code)
        for attr, values in scalars:
            attr.Set(float(values[i]), code)
        lux.Set(float(illuminance_lux[i]), code)
        op.Set(_sun_orientation(d if up else (0.0, 0.0, 1.0)), code)
        intensity.Set(float(illuminance_lux[i]) if up else 0.0, code)


@dataclass
class MoonSample:
    """The moon of the environment layer at one time code (:func:`read_moon`)."""

    direction: np.ndarray  # (3,) unit, toward the moon
    elevation_deg: float
    azimuth_deg: float
    phase_angle_deg: float
    illuminated_fraction: float
    distance_km: float
    illuminance_lux: float  # clear-sky, beam-normal


def read_moon(stage: Usd.Stage, code) -> MoonSample | None:
    """The moon authored at :data:`MOON_LIGHT_PATH` at time code ``code`` (USD interpolates
    between frame samples; the direction is renormalised), or None when the stage has none
    (a stage composed before the moon was authored, or made elsewhere)."""
    prim = stage.GetPrimAtPath(MOON_LIGHT_PATH) if stage is not None else None
    if not (prim and prim.IsValid()):
        return None
    t = Usd.TimeCode(float(code))
    raw = prim.GetAttribute(MOON_DIRECTION).Get(t) if prim.GetAttribute(MOON_DIRECTION) else None
    values = {key: _get(prim.GetAttribute(name), float(code)) for name, key in MOON_ATTRS}
    lux = _get(prim.GetAttribute(MOON_ILLUMINANCE), float(code))
    d = None if raw is None else np.array(raw, dtype=float)
    if d is None or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0 or not math.isfinite(lux):
        raise InputError(
            bad_value(
                f"{MOON_LIGHT_PATH}", None, f"expected {MOON_DIRECTION} and {MOON_ILLUMINANCE} at {code:g}"
            )
        )
    if any(math.isnan(v) for v in values.values()):
        missing = next(name for name, key in MOON_ATTRS if math.isnan(values[key]))
        raise InputError(bad_value(f"{MOON_LIGHT_PATH}.{missing}", None, f"expected a value at {code:g}"))
    return MoonSample(direction=d / np.linalg.norm(d), illuminance_lux=lux, **values)


# --- readers -------------------------------------------------------------------------------------
def time_codes(stage: Usd.Stage, times_s) -> np.ndarray:
    """Time codes of ``times_s`` seconds after frame 0 on ``stage`` (its timeCodesPerSecond)."""
    return np.atleast_1d(np.asarray(times_s, dtype=float)) * float(stage.GetTimeCodesPerSecond())


def _environment(stage: Usd.Stage) -> Usd.Prim:
    prim = stage.GetPrimAtPath(ENVIRONMENT_PATH) if stage is not None else None
    if not (prim and prim.IsValid()):
        raise InputError(
            bad_value(str(ENVIRONMENT_PATH), None, "expected the environment layer (HumvEnvironmentAPI)")
        )
    return prim


def _values(prim: Usd.Prim, name: str, codes, lo: float, hi: float) -> np.ndarray:
    attr = prim.GetAttribute(name)
    out = np.array([_get(attr, c) for c in codes], dtype=float)
    bad = ~(np.isfinite(out) & (out >= lo) & (out <= hi))
    if bad.any():
        v = out[np.flatnonzero(bad)[0]]
        raise InputError(
            bad_value(
                f"{prim.GetPath()}.{name}", None if math.isnan(v) else float(v), f"expected {lo:g}..{hi:g}"
            )
        )
    return out


def _get(attr, code) -> float:
    value = attr.Get(float(code)) if attr and attr.IsValid() else None
    return math.nan if value is None else float(value)


def read_site(stage: Usd.Stage) -> Site:
    """The site and start time authored on /World (HumvScenarioAPI)."""
    world = stage.GetPrimAtPath(WORLD)
    values = {}
    for attr, key in SITE_ATTRS:
        a = world.GetAttribute(attr) if world else None
        values[key] = a.Get() if a else None
    if values["start_time"] is None or values["latitude_deg"] is None:
        raise InputError(bad_value(str(WORLD), None, "expected the site and start time (HumvScenarioAPI)"))
    return Site(
        name=str(values["name"] or ""),
        description=str(values["description"] or ""),
        start_time=str(values["start_time"]),
        time_zone=str(values["time_zone"] or ""),
        latitude_deg=float(values["latitude_deg"]),
        longitude_deg=float(values["longitude_deg"] or 0.0),
        elevation_m=float(values["elevation_m"] or 0.0),
        seed=int(values["seed"] or 0),
    )


def read_weather(stage: Usd.Stage, codes) -> Weather:
    """The weather of /World/Environment at time codes ``codes`` (frames; may be negative in the
    spin-up window), SI units. Raises :class:`InputError` when the layer is missing or a value
    is outside the range of its ``[atmosphere]`` key."""
    prim = _environment(stage)
    codes = np.atleast_1d(np.asarray(codes, dtype=float))
    return Weather(
        **{
            key: _values(prim, attr, codes, ATMOSPHERE.keys[key].lo, ATMOSPHERE.keys[key].hi)
            for attr, key in WEATHER_ATTRS
        }
    )


def read_sun(stage: Usd.Stage, codes) -> SunState:
    """The sun of /World/Environment at time codes ``codes``: apparent zenith and compass
    azimuth [deg], unit direction towards the sun (x east, y north, z up; renormalised after
    USD's linear interpolation), broadband DNI, DHI, GHI [W m-2]; ``up`` where the zenith is
    below 90 deg."""
    prim = _environment(stage)
    codes = np.atleast_1d(np.asarray(codes, dtype=float))
    fields = {
        "zenith_deg": _values(prim, S.ENVIRONMENT_SUN_ZENITH, codes, 0.0, 180.0),
        "azimuth_deg": _values(prim, S.ENVIRONMENT_SUN_AZIMUTH, codes, 0.0, 360.0),
        "dni_w_m2": _values(prim, S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE, codes, 0.0, 2000.0),
        "dhi_w_m2": _values(prim, S.ENVIRONMENT_DIFFUSE_HORIZONTAL_IRRADIANCE, codes, 0.0, 2000.0),
        "ghi_w_m2": _values(prim, S.ENVIRONMENT_GLOBAL_HORIZONTAL_IRRADIANCE, codes, 0.0, 2000.0),
    }
    attr = prim.GetAttribute(S.ENVIRONMENT_SUN_DIRECTION)
    direction = np.array([[math.nan] * 3 if (v := attr.Get(float(c))) is None else list(v) for c in codes])
    norm = np.linalg.norm(direction, axis=1, keepdims=True)
    if not np.all(np.isfinite(direction)) or np.any(norm < 0.5):
        raise InputError(
            bad_value(f"{prim.GetPath()}.{S.ENVIRONMENT_SUN_DIRECTION}", None, "expected unit 3-vectors")
        )
    fps = float(stage.GetTimeCodesPerSecond())
    return SunState(
        times_s=codes / fps,
        direction=direction / norm,
        up=fields["zenith_deg"] < 90.0,
        **fields,
    )


def sun_direction(stage: Usd.Stage, time) -> np.ndarray | None:
    """Unit vector toward the sun (stage coordinates) at time code ``time``, or None if not
    authored (an EO-free or hand-made stage may have no sun)."""
    prim = stage.GetPrimAtPath(ENVIRONMENT_PATH)
    attr = prim.GetAttribute(S.ENVIRONMENT_SUN_DIRECTION) if prim and prim.IsValid() else None
    value = attr.Get(time) if attr and attr.IsValid() else None
    if value is None:
        return None
    d = np.asarray(value, dtype=float).ravel()
    n = float(np.linalg.norm(d)) if d.size == 3 else 0.0
    if not (np.all(np.isfinite(d)) and n > 0.5):
        raise InputError(
            bad_value(
                f"{ENVIRONMENT_PATH}.{S.ENVIRONMENT_SUN_DIRECTION}",
                summary(d),
                "expected a unit 3-vector toward the sun",
            )
        )
    return d / n


def direct_normal_irradiance(stage: Usd.Stage, time) -> float | None:
    """Broadband direct normal irradiance [W m-2] at time code ``time``, or None if not authored."""
    prim = stage.GetPrimAtPath(ENVIRONMENT_PATH)
    attr = prim.GetAttribute(S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE) if prim and prim.IsValid() else None
    value = attr.Get(time) if attr and attr.IsValid() else None
    if value is None:
        return None
    v = float(value)
    if not (math.isfinite(v) and 0.0 <= v <= 2000.0):
        raise InputError(
            bad_value(
                f"{ENVIRONMENT_PATH}.{S.ENVIRONMENT_DIRECT_NORMAL_IRRADIANCE}",
                v,
                "expected a direct normal irradiance in 0..2000 W m-2",
            )
        )
    return v
