"""The one sensor reader and writer: a UsdGeom.Camera with HumvSensorAPI → :class:`SensorModel`
(render, sensor chain, labels and atmosphere all read sensors through here), and its pose at a
time → :class:`humv_usd.geometry.camera.CameraPose`. :func:`stage_sensors` lists a stage's
sensor cameras.

:func:`read_sensor` is what the render reads: :func:`read_sensor_model` after the checks the
render needs (band range, resolution, response table, sub-band count; a camera that is not a
perspective one is kept with a ``skip_reason``)."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from pxr import Gf, Usd, UsdGeom, Vt

from humv_usd.errors import InputError, bad_value, summary
from humv_usd.geometry.camera import CameraPose
from humv_usd.physics.sensor import INFRARED_MIN_UM, SensorModel, field_of_view_deg
from humv_usd.scenario.spec import BAND_RANGE_UM, MAX_SUBBANDS
from humv_usd.usd import schemas as S

#: Band of an EO sensor whose ``humv:sensor:wavelengthRange`` is not authored [um].
EO_DEFAULT_RANGE_UM = (0.38, 0.78)
#: Largest accepted sensor width or height [px].
MAX_RESOLUTION = 16384
#: Namespace of the HumvSensorAPI attributes: a camera with one of them authored is a sensor.
SENSOR_NAMESPACE = S.SENSOR_BAND.rpartition(":")[0] + ":"


def write_sensor(
    prim,
    *,
    band: str,
    wavelength_range_um: tuple[float, float],
    resolution: tuple[int, int],
    pixel_pitch_m: float,
    f_number: float,
    netd_k: float,
    bit_depth: int,
    offset: float,
    preset: str,
    platform: str,
    agc: str,
    agc_percentiles: tuple[float, float],
    gain: float | None = None,
    subbands: int | None = None,
    full_well_e: float | None = None,
    read_noise_e: float | None = None,
    response_wavelengths_um=None,
    response=None,
    channel_response=None,
    netd_origin: str = "",
    chain_settings: dict | None = None,
) -> None:
    """Apply HumvSensorAPI to a camera prim and author the sensor (what :func:`read_sensor_model`
    reads back): band token, wavelength range [um], resolution [px], pixel pitch [m], f-number,
    NETD [K] (with ``netd_origin``, where it came from, as the attribute's custom data
    :data:`NETD_ORIGIN_KEY`; :func:`netd_origin` reads it back), bit depth, offset [DN],
    preset and platform tokens, AGC and its percentiles; gain [DN per unit signal] (None: auto
    exposure), the IR sub-band count, an EO sensor's full well and read noise [e-] and the
    relative response table (wavelengths [um], response, optional channel responses
    (C, wavelengths)) only when given; ``chain_settings`` (keys of :data:`CHAIN_ATTRIBUTES`:
    plateau AGC, fixed pattern, vignetting, lag, JPEG) authored when given and not None."""
    prim.ApplyAPI(S.SENSOR_API)
    values = [
        (S.SENSOR_BAND, band),
        (S.SENSOR_WAVELENGTH_RANGE, Gf.Vec2f(*wavelength_range_um)),
        (S.SENSOR_RESOLUTION, Gf.Vec2i(*resolution)),
        (S.SENSOR_PIXEL_PITCH, pixel_pitch_m),
        (S.SENSOR_F_NUMBER, f_number),
        (S.SENSOR_NETD, netd_k),
        (S.SENSOR_BIT_DEPTH, bit_depth),
        (S.SENSOR_OFFSET, offset),
        (S.SENSOR_PRESET, preset),
        (S.SENSOR_PLATFORM, platform),
        (S.SENSOR_AGC, agc),
        (S.SENSOR_AGC_PERCENTILES, Gf.Vec2f(*agc_percentiles)),
    ]
    optional = [
        (S.SENSOR_GAIN, gain),
        (S.SENSOR_SUBBANDS, subbands),
        (S.SENSOR_FULL_WELL, full_well_e),
        (S.SENSOR_READ_NOISE, read_noise_e),
    ]
    values += [(attr, value) for attr, value in optional if value is not None]
    for key, value in (chain_settings or {}).items():
        if value is not None:
            attr, kind = CHAIN_ATTRIBUTES[key]
            values.append((attr, kind(value)))
    if response_wavelengths_um is not None:
        values += [
            (S.SENSOR_RESPONSE_WAVELENGTHS, Vt.FloatArray(np.asarray(response_wavelengths_um).tolist())),
            (S.SENSOR_RESPONSE, Vt.FloatArray(np.asarray(response).tolist())),
        ]
        if channel_response is not None:
            values.append(
                (S.SENSOR_CHANNEL_RESPONSE, Vt.FloatArray(np.asarray(channel_response).ravel().tolist()))
            )
    for attr, value in values:
        prim.GetAttribute(attr).Set(value)
    if netd_origin:
        prim.GetAttribute(S.SENSOR_NETD).SetCustomDataByKey(NETD_ORIGIN_KEY, netd_origin)


#: NETD [K] the reader assumes where a sensor prim authors none
NETD_FALLBACK_K = 0.05
#: customData key of ``humv:sensor:netd`` saying where the value came from (the scenario load's
#: :attr:`humv_usd.scenario.Scenario.netd_origin`); stages composed before it was recorded have
#: ``humv:netdScaling`` on scaled values only
NETD_ORIGIN_KEY = "humv:netdOrigin"
LEGACY_NETD_KEY = "humv:netdScaling"


def _nested(data: dict, key: str):
    """The value of a customData key path ``a:b`` (USD stores it as nested dictionaries)."""
    for part in key.split(":"):
        if not isinstance(data, dict) or part not in data:
            return None
        data = data[part]
    return data


def netd_origin(attr, fallback_k: float) -> str:
    """Where a sensor's NETD comes from, as the render reads it: the origin recorded with the
    strongest authored value (:data:`NETD_ORIGIN_KEY` on the same spec, so a user layer that
    overrides the value without saying why is named, not hidden behind the sensors layer's
    note), else that layer's name, else the reader's ``fallback_k`` when nothing is authored."""
    stack = attr.GetPropertyStack(Usd.TimeCode.Default()) if attr and attr.IsValid() else []
    strongest = next((spec for spec in stack if spec.HasDefaultValue() or spec.HasInfo("timeSamples")), None)
    if strongest is None:
        return f"reader default: {fallback_k:g} K ({S.SENSOR_NETD} not authored)"
    data = dict(strongest.customData)  # a key "a:b" is stored nested, {"a": {"b": ...}}
    origin = next((v for v in (_nested(data, NETD_ORIGIN_KEY), _nested(data, LEGACY_NETD_KEY)) if v), None)
    if origin:
        return str(origin)
    where = strongest.layer.identifier if not strongest.layer.anonymous else "an anonymous layer"
    return f"authored in {where} (no {NETD_ORIGIN_KEY} recorded there)"


#: Sensor-chain settings (scenario key / SensorModel field -> attribute, value type).
CHAIN_ATTRIBUTES = {
    "agc_plateau": (S.SENSOR_AGC_PLATEAU, float),
    "agc_max_gain": (S.SENSOR_AGC_MAX_GAIN, float),
    "agc_midpoint": (S.SENSOR_AGC_MIDPOINT, float),
    "fpn_gain_sigma": (S.SENSOR_FPN_GAIN_SIGMA, float),
    "fpn_offset_sigma_k": (S.SENSOR_FPN_OFFSET_SIGMA, float),
    "fpn_drift_k_per_s": (S.SENSOR_FPN_DRIFT_RATE, float),
    "ffc_interval_s": (S.SENSOR_FFC_INTERVAL, float),
    "fpn_seed": (S.SENSOR_FPN_SEED, int),
    "vignetting": (S.SENSOR_VIGNETTING, str),
    "time_constant_s": (S.SENSOR_TIME_CONSTANT, float),
    "jpeg_quality": (S.SENSOR_JPEG_QUALITY, int),
    "motion_blur": (S.SENSOR_MOTION_BLUR, str),
    "rolling_shutter_s": (S.SENSOR_ROLLING_SHUTTER, float),
    "turbulence_cn2": (S.SENSOR_TURBULENCE_CN2, float),
    "turbulence_path_m": (S.SENSOR_TURBULENCE_PATH, float),
    "h264_crf": (S.SENSOR_H264_CRF, int),
}


def check_subbands(value, where: str = "subbands") -> int:
    """A sub-band count in 1..MAX_SUBBANDS, else InputError naming ``where``."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not 1 <= int(value) <= MAX_SUBBANDS
    ):
        raise InputError(bad_value(where, value, f"expected an integer in 1..{MAX_SUBBANDS}"))
    return int(value)


#: Wavelengths [um] the render can do per band token: the reflective bands as the scenario's
#: BAND_RANGE_UM (EO: Mitsuba's spectral range; NIR/SWIR: the night light and the material
#: detail), MWIR/LWIR anything from 3 um (rendered from emission; the scenario keeps them to the
#: atmospheric windows, a hand-made stage may go wider).
RENDERABLE_UM = {
    **{b: BAND_RANGE_UM[b] for b in ("EO", "NIR", "SWIR")},
    "MWIR": (INFRARED_MIN_UM, 1000.0),
    "LWIR": (INFRARED_MIN_UM, 1000.0),
}


def _value(prim, name):
    attr = prim.GetAttribute(name)
    return attr.Get() if attr and attr.IsValid() else None


def read_sensor(prim) -> SensorModel:
    """The render's read of a sensor camera: :func:`read_sensor_model` with ``path``,
    ``subbands``, ``skip_reason`` and ``response_authored`` set, after checking the band range
    (0 < lower < upper <= 1000 um), the resolution (authored, 1..MAX_RESOLUTION), an IR
    sensor's response table and sub-band count. InputError names the attribute."""
    path = str(prim.GetPath())
    band = _value(prim, S.SENSOR_BAND)
    band = str(band) if band else ""
    rng = _value(prim, S.SENSOR_WAVELENGTH_RANGE)
    where = f"{path}.{S.SENSOR_WAVELENGTH_RANGE}"
    if band == "EO" and rng is None:
        rng = EO_DEFAULT_RANGE_UM
    if rng is None:
        raise InputError(bad_value(where, None, "expected (lower, upper) [um] of the sensor band"))
    lo, hi = float(rng[0]), float(rng[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi <= 1000):
        raise InputError(bad_value(where, (lo, hi), "expected 0 < lower < upper [um]"))
    # a band the render cannot do at these wavelengths is refused, never rendered as another
    # (band "EO" at 0.9-1.7 um was rendered as visible light)
    # (an unauthored band token, the schema's fallback, is the band whose range holds the edges)
    lo, hi = round(lo, 6), round(hi, 6)  # float32 edges: 0.9 reads 0.89999998
    attr = prim.GetAttribute(S.SENSOR_BAND)
    if not (attr and attr.HasAuthoredValue()):
        band = next((b for b, (a, z) in BAND_RANGE_UM.items() if a <= lo and hi <= z), band)
    if band in RENDERABLE_UM:
        a, z = RENDERABLE_UM[band]
        if not (a <= lo and hi <= z):
            raise InputError(bad_value(where, [lo, hi], f"allowed range for band {band}: {a:g}..{z:g} µm"))
    projection = UsdGeom.Camera(prim).GetProjectionAttr().Get()
    if projection and projection != UsdGeom.Tokens.perspective:
        return dataclasses.replace(
            read_sensor_model(prim),
            path=path,
            skip_reason=f"projection {projection!r}: only perspective cameras are rendered",
        )
    res = _value(prim, S.SENSOR_RESOLUTION)
    where = f"{path}.{S.SENSOR_RESOLUTION}"
    if res is None:
        raise InputError(
            bad_value(where, None, f"expected two integers in 1..{MAX_RESOLUTION} (width, height) [px]")
        )
    w, h = int(res[0]), int(res[1])
    if not (1 <= w <= MAX_RESOLUTION and 1 <= h <= MAX_RESOLUTION):
        raise InputError(
            bad_value(where, [w, h], f"expected two integers in 1..{MAX_RESOLUTION} (width, height) [px]")
        )
    model = read_sensor_model(prim)
    if band and model.band != band:
        model = dataclasses.replace(model, band=band)
    if model.kind == "EO":  # colour comes from the CIE observer (render.eo), not a band response
        return dataclasses.replace(model, path=path, response_authored=False)
    response = _check_response(prim, (lo, hi))
    subbands = _value(prim, S.SENSOR_SUBBANDS)
    if subbands is not None:
        subbands = check_subbands(subbands, f"{path}.{S.SENSOR_SUBBANDS}")
    return dataclasses.replace(model, path=path, subbands=subbands, response_authored=response is not None)


def _is_sensor(prim) -> bool:
    """A camera with HumvSensorAPI applied or any ``humv:sensor:*`` attribute authored (the
    render reads attributes by name, so an unregistered or unapplied schema still counts)."""
    if not prim.IsA(UsdGeom.Camera):
        return False
    if S.SENSOR_API in prim.GetAppliedSchemas():
        return True
    return any(
        a.GetName().startswith(SENSOR_NAMESPACE) and a.HasAuthoredValue() for a in prim.GetAttributes()
    )


def stage_sensors(stage) -> list[SensorModel]:
    """Every sensor camera of ``stage`` (instance proxies included), in stage order, read by
    :func:`read_sensor`. InputError when two sensors share a name (the camera prim name)."""
    sensors: list[SensorModel] = []
    names: dict[str, str] = {}
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if not _is_sensor(prim):
            continue
        sensor = read_sensor(prim)
        if sensor.name in names:
            raise InputError(
                bad_value(
                    str(prim.GetPath()),
                    sensor.name,
                    f"sensor names (camera prim names) must be unique; {names[sensor.name]} has it too",
                )
            )
        names[sensor.name] = str(prim.GetPath())
        sensors.append(sensor)
    return sensors


def _check_response(prim, band):
    """The authored (wavelengths, response) of an IR sensor, None when neither is authored;
    InputError for one without the other, a bad table, or a response zero over the band."""
    path = str(prim.GetPath())
    wl = _value(prim, S.SENSOR_RESPONSE_WAVELENGTHS)
    r = _value(prim, S.SENSOR_RESPONSE)
    has_wl = wl is not None and len(wl) > 0
    has_r = r is not None and len(r) > 0
    if not has_wl and not has_r:
        return None
    if has_wl != has_r:
        missing = S.SENSOR_RESPONSE if has_wl else S.SENSOR_RESPONSE_WAVELENGTHS
        raise InputError(
            bad_value(
                f"{path}.{missing}",
                None,
                f"expected both {S.SENSOR_RESPONSE_WAVELENGTHS} and {S.SENSOR_RESPONSE}, or neither",
            )
        )
    wl = np.asarray(wl, dtype=float)
    r = np.asarray(r, dtype=float)
    where = f"{path}.{S.SENSOR_RESPONSE}"
    if wl.size < 2 or wl.size != r.size:
        raise InputError(
            bad_value(
                where,
                f"<{r.size} values for {wl.size} wavelengths>",
                "expected one response value per wavelength, at least two",
            )
        )
    if not np.all(np.isfinite(wl)) or np.any(np.diff(wl) <= 0):
        raise InputError(
            bad_value(
                f"{path}.{S.SENSOR_RESPONSE_WAVELENGTHS}",
                summary(wl),
                "expected finite, strictly ascending wavelengths [um]",
            )
        )
    if not np.all(np.isfinite(r)) or np.any(r < 0) or np.any(r > 1):
        raise InputError(bad_value(where, summary(r), "expected relative response values in 0-1"))
    inside = np.interp(np.linspace(band[0], band[1], 1001), wl, r, left=0.0, right=0.0)
    if not np.any(inside > 0):
        raise InputError(
            bad_value(where, summary(r), f"response is zero over the band {band[0]:g}-{band[1]:g} um")
        )
    return wl, r


def read_sensor_model(prim) -> SensorModel:
    """Read a UsdGeom.Camera with HumvSensorAPI (schema fallbacks for unauthored values).

    Focal length comes from the camera (tenths of a scene unit, scaled by the stage's
    metersPerUnit); everything else from ``humv:sensor:*``.
    """
    path = str(prim.GetPath())

    def get(name, default=None):
        attr = prim.GetAttribute(name)
        value = attr.Get() if attr else None
        return default if value is None else value

    band = str(get(S.SENSOR_BAND, "LWIR"))
    rng = get(S.SENSOR_WAVELENGTH_RANGE, EO_DEFAULT_RANGE_UM if band == "EO" else None)
    if rng is None:
        raise InputError(
            bad_value(f"{path}.{S.SENSOR_WAVELENGTH_RANGE}", None, "expected (lower, upper) [um]")
        )
    lo, hi = float(rng[0]), float(rng[1])
    wl = get(S.SENSOR_RESPONSE_WAVELENGTHS)
    r = get(S.SENSOR_RESPONSE)
    if wl is None or len(wl) < 2:
        wl, r = np.array([lo, hi]), np.array([1.0, 1.0])
    wl = np.asarray(wl, dtype=float)
    r = np.asarray(r, dtype=float)
    channel = get(S.SENSOR_CHANNEL_RESPONSE)
    if channel is not None and len(channel) > 0:
        channel = np.asarray(channel, dtype=float)
        if channel.size % wl.size:
            raise InputError(
                bad_value(
                    f"{path}.{S.SENSOR_CHANNEL_RESPONSE}",
                    f"<{channel.size} values>",
                    f"expected a multiple of {wl.size} (channels x responseWavelengths)",
                )
            )
        channel = channel.reshape(-1, wl.size)
    else:
        channel = None
    res = get(S.SENSOR_RESOLUTION, (640, 512))
    stage = prim.GetStage()
    mpu = UsdGeom.GetStageMetersPerUnit(stage) if stage else 1.0
    focal = UsdGeom.Camera(prim).GetFocalLengthAttr().Get()
    focal_m = float(focal) * 0.1 * mpu if focal else 0.0
    gain = get(S.SENSOR_GAIN)
    pct = get(S.SENSOR_AGC_PERCENTILES, (1.0, 99.0))
    agc_attr = prim.GetAttribute(S.SENSOR_AGC)
    if agc_attr and agc_attr.HasAuthoredValue():
        agc = str(agc_attr.Get())
    else:  # IR previews keep people readable by default; EO keeps the percentile stretch
        agc = "linear" if band == "EO" else "plateau"
    chain = {}
    for key, (attr, kind) in CHAIN_ATTRIBUTES.items():
        value = get(attr)
        if value is not None:
            chain[key] = kind(value)
    try:
        return SensorModel(
            name=prim.GetName(),
            band=band,
            wavelength_range_um=(lo, hi),
            response_wavelengths_um=wl,
            response=r,
            channel_response=channel,
            resolution=(int(res[0]), int(res[1])),
            pixel_pitch_m=float(get(S.SENSOR_PIXEL_PITCH, 12e-6)),
            f_number=float(get(S.SENSOR_F_NUMBER, 1.0)),
            focal_length_m=focal_m,
            netd_k=float(get(S.SENSOR_NETD, NETD_FALLBACK_K)),
            bit_depth=int(get(S.SENSOR_BIT_DEPTH, 14)),
            gain=None if gain is None else float(gain),
            offset=float(get(S.SENSOR_OFFSET, 0.0)),
            agc=agc,
            agc_percentiles=(float(pct[0]), float(pct[1])),
            full_well_e=float(get(S.SENSOR_FULL_WELL, 10500.0)),
            read_noise_e=float(get(S.SENSOR_READ_NOISE, 2.5)),
            reference_temperature_k=float(get(S.SENSOR_REFERENCE_TEMPERATURE, 300.0)),
            preset=str(get(S.SENSOR_PRESET, "")),
            netd_note=netd_origin(prim.GetAttribute(S.SENSOR_NETD), NETD_FALLBACK_K),
            **chain,
        )
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


def read_camera_pose(prim, time) -> CameraPose:
    """A sensor's camera (UsdGeom.Camera prim) at ``time``: position [m], optical axis (local -Z), up (local +Y) and
    horizontal field of view 2 atan(horizontalAperture / (2 focalLength)).

    The vertical field of view follows from the resolution (square pixels); USD clipping
    ranges are ignored.
    """
    path = str(prim.GetPath())
    cam = UsdGeom.Camera(prim).GetCamera(time)
    m = cam.transform
    origin = np.array(m.Transform(Gf.Vec3d(0, 0, 0)), dtype=float)
    forward = np.array(m.TransformDir(Gf.Vec3d(0, 0, -1)), dtype=float)
    up = np.array(m.TransformDir(Gf.Vec3d(0, 1, 0)), dtype=float)
    nf, nu = np.linalg.norm(forward), np.linalg.norm(up)
    if not (nf > 0 and nu > 0 and np.all(np.isfinite(origin))):
        raise InputError(
            bad_value(
                f"{path}.xformOp",
                "<degenerate transform>",
                "expected an invertible camera transform",
            )
        )
    forward, up = forward / nf, up / nu
    h_ap, focal = float(cam.horizontalAperture), float(cam.focalLength)
    if not (h_ap > 0 and focal > 0):
        raise InputError(
            bad_value(
                f"{path}.horizontalAperture/focalLength",
                (h_ap, focal),
                "expected positive values (tenths of a scene unit)",
            )
        )
    if cam.horizontalApertureOffset or cam.verticalApertureOffset:
        warnings.warn(f"{path}: aperture offsets are ignored by the renderer", RuntimeWarning, stacklevel=2)
    fov_x = field_of_view_deg(h_ap, focal)  # aperture and focal length in the same unit
    if not 0 < fov_x < 179:
        raise InputError(
            bad_value(
                f"{path}.horizontalAperture/focalLength",
                (h_ap, focal),
                "expected a field of view below 179 deg",
            )
        )
    return CameraPose(
        origin=origin * UsdGeom.GetStageMetersPerUnit(prim.GetStage()),
        forward=forward,
        up=up,
        fov_x_deg=fov_x,
    )


def camera_positions(stage, path, frames) -> np.ndarray:
    """World position [m] of the camera at ``path`` at each frame of ``frames``, (n, 3).

    Raises :class:`InputError` when the stage has no camera there (the sensors layer must be
    composed before a tool that reads cameras)."""
    prim = stage.GetPrimAtPath(str(path)) if stage is not None else None
    if not (prim and prim.IsValid() and prim.IsA(UsdGeom.Camera)):
        raise InputError(bad_value(str(path), None, "expected a sensor camera (the sensors layer)"))
    xf = UsdGeom.Xformable(prim)
    codes = [float(f) for f in np.atleast_1d(frames)]
    if not xf.TransformMightBeTimeVarying():
        codes = codes[:1]
    pos = np.array([np.asarray(xf.ComputeLocalToWorldTransform(c).ExtractTranslation()) for c in codes])
    return np.broadcast_to(pos, (len(np.atleast_1d(frames)), 3)).copy() if len(codes) == 1 else pos


def override_resolution(stage, resolution) -> list[str]:
    """Give every sensor camera of ``stage`` the pixel count ``resolution`` = (W, H) at its field
    of view, in the stage's session layer (the files stay as they are): the pixel pitch becomes
    pitch x W0 / W, the horizontal aperture (W x pitch) and the focal length stay, so the
    horizontal field of view is kept; the vertical one follows from H (square pixels). Returns one
    line per camera (``name: W0xH0 -> WxH, pitch p0 -> p um``); InputError for a size outside
    1..MAX_RESOLUTION."""
    w, h = (int(v) for v in resolution)
    if not (1 <= w <= MAX_RESOLUTION and 1 <= h <= MAX_RESOLUTION):
        raise InputError(
            bad_value("resolution", [w, h], f"expected WIDTHxHEIGHT, each 1..{MAX_RESOLUTION} [px]")
        )
    lines = []
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
            if not _is_sensor(prim):
                continue
            res = _value(prim, S.SENSOR_RESOLUTION)
            if res is None:  # read_sensor refuses it with its own line
                continue
            pitch = _value(prim, S.SENSOR_PIXEL_PITCH)
            w0, h0 = int(res[0]), int(res[1])
            cam = UsdGeom.Camera(prim)
            h_ap = cam.GetHorizontalApertureAttr().Get()
            prim.GetAttribute(S.SENSOR_RESOLUTION).Set(Gf.Vec2i(w, h))
            if h_ap:  # vertical aperture: H pixels of the new pitch, in the aperture's unit
                cam.GetVerticalApertureAttr().Set(float(h_ap) * h / w)
            # a camera without an authored pitch (a hand-made stage) gets the pixel count too: it
            # was skipped, and --resolution 16384x16384 rendered the stage's 16x12 (fuzzing, 2026-11-27)
            if pitch is None:
                lines.append(f"{prim.GetName()}: {w0}x{h0} -> {w}x{h} (no pixel pitch authored)")
                continue
            new_pitch = float(pitch) * w0 / w
            prim.GetAttribute(S.SENSOR_PIXEL_PITCH).Set(new_pitch)
            lines.append(
                f"{prim.GetName()}: {w0}x{h0} -> {w}x{h}, pitch {pitch * 1e6:g} -> {new_pitch * 1e6:g} um"
            )
    return lines
