"""The one sensor reader: a UsdGeom.Camera with HumvSensorAPI → :class:`SensorModel`
(render, sensor chain, labels and atmosphere all read sensors through here), and its pose at a
time → :class:`humv_usd.geometry.camera.CameraPose`."""

from __future__ import annotations

import math
import warnings

import numpy as np
from pxr import Gf, UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.geometry.camera import CameraPose
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
    fov_x = math.degrees(2.0 * math.atan(0.5 * h_ap / focal))
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
