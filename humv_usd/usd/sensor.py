"""The one sensor reader: a UsdGeom.Camera with HumvSensorAPI → :class:`SensorModel`
(render, sensor chain, labels and atmosphere all read sensors through here)."""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.physics.sensor import SensorModel
from humv_usd.usd import schemas as S


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
    rng = get(S.SENSOR_WAVELENGTH_RANGE)
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
            netd_k=float(get(S.SENSOR_NETD, 0.05)),
            bit_depth=int(get(S.SENSOR_BIT_DEPTH, 14)),
            gain=None if gain is None else float(gain),
            offset=float(get(S.SENSOR_OFFSET, 0.0)),
            agc=str(get(S.SENSOR_AGC, "linear")),
            agc_percentiles=(float(pct[0]), float(pct[1])),
            full_well_e=float(get(S.SENSOR_FULL_WELL, 10500.0)),
            read_noise_e=float(get(S.SENSOR_READ_NOISE, 2.5)),
            reference_temperature_k=float(get(S.SENSOR_REFERENCE_TEMPERATURE, 300.0)),
            preset=str(get(S.SENSOR_PRESET, "")),
            netd_note=str(prim.GetAttribute(S.SENSOR_NETD).GetCustomDataByKey("humv:netdScaling") or "")
            if prim.GetAttribute(S.SENSOR_NETD)
            else "",
        )
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


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
