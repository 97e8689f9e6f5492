"""Camera rigs: where a camera is and where it points at each frame (pure numpy).

A rig is a platform that carries the camera (a fixed tripod or mast, a vehicle on a road path,
a drone on a flight path or an orbit, a hand with its shake) and a pointing rule (a fixed point,
a person or a path it tracks, or straight along the direction of travel) seen through a gimbal
with angle and rate limits. :func:`rig_poses` turns the per-frame platform positions and target
points into camera axes; the sensor tool (:mod:`humv_usd.sensors.layer`) writes them as the
camera's time samples, so the render, the labels and ``camera.json`` follow the camera.

Conventions: world Z up, compass azimuth (0 = north = +y, 90 = east = +x), elevation (pitch)
positive above the horizon, roll positive clockwise as the camera sees it (right-hand rotation
about the optical axis). Angles in degrees at the interface, radians inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def polyline_track(points, speed_m_s: float, times_s) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and unit direction of travel of a platform moving along the polyline
    ``points`` (N, 3) at constant ``speed_m_s`` from its first point at t = 0; it stops at the
    last point (the direction stays that of the last segment). Zero-length segments are skipped.

    Returns ``(positions (T, 3), directions (T, 3))``.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    seg = np.diff(p, axis=0)
    length = np.linalg.norm(seg, axis=1)
    keep = length > 1e-9
    if not keep.any():
        raise ValueError("path: expected at least two distinct points")
    p = np.vstack([p[:1], p[1:][keep]])
    seg, length = seg[keep], length[keep]
    cum = np.concatenate([[0.0], np.cumsum(length)])
    s = np.clip(float(speed_m_s) * t, 0.0, cum[-1])
    i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = (s - cum[i]) / length[i]
    pos = p[i] + frac[:, None] * seg[i]
    return pos, seg[i] / length[i][:, None]


def direction_angles(direction) -> tuple[np.ndarray, np.ndarray]:
    """(azimuth [deg, compass], elevation [deg]) of world directions (..., 3)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    az = np.degrees(np.arctan2(d[..., 0], d[..., 1]))
    el = np.degrees(np.arcsin(np.clip(d[..., 2], -1.0, 1.0)))
    return az, el


def angles_direction(azimuth_deg, elevation_deg) -> np.ndarray:
    """Unit world directions (..., 3) of compass azimuths and elevations [deg]."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def _wrap(deg):
    return (np.asarray(deg, dtype=float) + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class Gimbal:
    """A two-axis (pan/tilt) gimbal on the platform.

    yaw_range_deg: pan limits relative to the platform heading [deg] ((-180, 180): unlimited);
    pitch_range_deg: tilt (elevation) limits [deg]; rate_deg_s: largest slew rate per axis
    [deg/s] (0: unlimited). Defaults: a drone gimbal's tilt range -90..+30 deg (e.g. DJI Zenmuse
    H20T: tilt -120..+30 deg, pan +-320 deg, DJI's product page; the nadir -90 deg is the useful
    limit), unlimited pan and rate.
    """

    yaw_range_deg: tuple[float, float] = (-180.0, 180.0)
    pitch_range_deg: tuple[float, float] = (-90.0, 30.0)
    rate_deg_s: float = 0.0

    def follow(self, heading_deg, azimuth_deg, elevation_deg, times_s) -> tuple[np.ndarray, np.ndarray]:
        """The gimbal's (azimuth, elevation) [deg] per frame when commanded toward
        ``azimuth_deg`` / ``elevation_deg`` (T,) on a platform heading ``heading_deg`` (T,):
        each command is clamped to the angle limits, then each axis moves from its previous
        frame's angle by at most ``rate_deg_s`` x the frame interval (frame 0 starts on its
        clamped command). Pan is relative to the heading; the result is world azimuth."""
        t = np.atleast_1d(np.asarray(times_s, dtype=float))
        heading = np.broadcast_to(np.asarray(heading_deg, dtype=float), t.shape)
        want_yaw = _wrap(np.broadcast_to(np.asarray(azimuth_deg, dtype=float), t.shape) - heading)
        want_pitch = np.broadcast_to(np.asarray(elevation_deg, dtype=float), t.shape)
        y_lo, y_hi = self.yaw_range_deg
        p_lo, p_hi = self.pitch_range_deg
        if y_hi - y_lo < 360.0:
            want_yaw = np.clip(want_yaw, y_lo, y_hi)
        want_pitch = np.clip(want_pitch, p_lo, p_hi)
        yaw, pitch = want_yaw.copy(), want_pitch.copy()
        if self.rate_deg_s > 0:
            for k in range(1, t.size):
                step = self.rate_deg_s * max(t[k] - t[k - 1], 0.0)
                yaw[k] = yaw[k - 1] + np.clip(_wrap(want_yaw[k] - yaw[k - 1]), -step, step)
                pitch[k] = pitch[k - 1] + np.clip(want_pitch[k] - pitch[k - 1], -step, step)
        return _wrap(yaw + heading), pitch


# ---------------------------------------------------------------------------- hand shake
#: Spectral lines of the hand-held shake model [Hz] and their relative power: the 2 Hz sway
#: from pressing and holding the camera and the ~4 Hz hand/forearm microvibration measured on
#: hand-held cameras (Oshima et al. 1995, Jpn. J. Ergonomics 31(6):399, accelerometers on the
#: camera body), and the 8-12 Hz physiological tremor (Golik 2006, Cologne diploma thesis
#: "Development of a test method for image stabilizing systems", ch. 2; Gavant et al. 2011,
#: IEEE Sensors, doi:10.1109/ICSENS.2011.6127172). The relative powers (1 : 1 : 0.1) are our
#: estimate: the tremor line carries little angle because its amplitude falls as 1/f^2 of its
#: acceleration.
SHAKE_LINES_HZ = ((2.0, 1.0), (4.0, 1.0), (10.0, 0.1))
#: Half-width of each line [Hz] (a damped resonance with Q ~ 2-4; estimated)
SHAKE_LINE_WIDTH_HZ = 1.0
#: Default RMS shake angle per axis of a hand-held camera [deg]: estimated (Golik 2006 reports
#: hand-held angular excursions of a few tenths of a degree over an exposure series); roll is
#: taken at half of yaw and pitch.
HANDHELD_SHAKE_RMS_DEG = 0.2


def shake_psd(f_hz) -> np.ndarray:
    """Relative one-sided power spectral density of the hand shake angle at ``f_hz``: a sum of
    Lorentzian lines (:data:`SHAKE_LINES_HZ`, half-width :data:`SHAKE_LINE_WIDTH_HZ`)."""
    f = np.asarray(f_hz, dtype=float)
    g = SHAKE_LINE_WIDTH_HZ
    return sum(w * g**2 / ((f - f0) ** 2 + g**2) for f0, w in SHAKE_LINES_HZ)


def shake_angles(times_s, rms_deg: float, seed: int, duration_s: float | None = None) -> np.ndarray:
    """(T, 3) yaw, pitch, roll shake offsets [deg] at ``times_s``: spectral synthesis (a sum of
    cosines at 0.02 Hz spacing up to 25 Hz, amplitudes sqrt(2 S(f) df) from :func:`shake_psd`,
    random phases from ``seed``), scaled so that each axis' RMS over the synthesis period is
    ``rms_deg`` (roll: half). Deterministic: the same seed gives the same shake at the same
    times, whatever the frame rate."""
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    df = 0.02
    f = np.arange(df, 25.0 + df / 2, df)
    amp = np.sqrt(2.0 * shake_psd(f) * df)
    amp *= 1.0 / math.sqrt(0.5 * float(np.sum(amp**2)))  # unit RMS over the 50 s period
    rng = np.random.default_rng([int(seed), 28])
    phases = rng.uniform(0.0, 2.0 * np.pi, size=(3, f.size))
    scale = np.array([1.0, 1.0, 0.5]) * float(rms_deg)
    out = np.empty((t.size, 3))
    for axis in range(3):
        out[:, axis] = scale[axis] * (np.cos(2.0 * np.pi * np.outer(t, f) + phases[axis]) @ amp)
    return out


# ---------------------------------------------------------------------------- camera axes
def camera_axes(azimuth_deg, elevation_deg, roll_deg=0.0) -> tuple[np.ndarray, np.ndarray]:
    """Unit (forward, up) (..., 3) of cameras looking toward compass ``azimuth_deg`` at
    ``elevation_deg``, the image's up in the vertical plane of the optical axis (straight down:
    up points along the azimuth, so a nadir camera keeps its heading), turned by ``roll_deg``
    about the optical axis (right-handed about forward: positive turns the camera clockwise as
    seen from behind it, up' = cos(r) up + sin(r) right)."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    fwd = angles_direction(azimuth_deg, elevation_deg)
    up = np.stack([-np.sin(az) * np.sin(el), -np.cos(az) * np.sin(el), np.cos(el)], axis=-1)
    right = np.cross(fwd, up)
    r = np.radians(np.asarray(roll_deg, dtype=float))[..., None]
    return fwd, np.cos(r) * up + np.sin(r) * right


def camera_matrix(origin, forward, up) -> np.ndarray:
    """4x4 local-to-world matrix in USD's row-vector layout of a camera at ``origin`` looking
    along ``forward`` with ``up`` (USD cameras look down local -Z with local +Y up)."""
    fwd = np.asarray(forward, dtype=float)
    up = np.asarray(up, dtype=float)
    right = np.cross(fwd, up)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3], m[3, :3] = right, up, -fwd, np.asarray(origin, dtype=float)
    return m + 0.0  # no negative zeros in the written layer


@dataclass(frozen=True)
class RigPoses:
    """Per-frame camera poses of a rig: origin [m], unit forward and up, (T, 3) each, and the
    gimbal azimuth / elevation [deg] before shake and roll, (T,)."""

    origin: np.ndarray
    forward: np.ndarray
    up: np.ndarray
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray


def rig_poses(
    origins,
    headings_deg,
    times_s,
    *,
    targets=None,
    mount_deg: tuple[float, float] = (0.0, 0.0),
    gimbal: Gimbal | None = None,
    roll_deg: float = 0.0,
    shake_deg=None,
) -> RigPoses:
    """Camera poses of a rig per frame.

    origins (T, 3) [m]: the camera on its platform; headings_deg (T,): the platform's compass
    heading (direction of travel); targets (T, 3) [m] or None: the point the camera is
    commanded to look at, else it looks along the heading turned by ``mount_deg`` = (yaw
    relative to the heading, elevation) [deg]; ``gimbal``: limits applied to the command
    (None: an ideal one); ``roll_deg``: about the optical axis; ``shake_deg`` (T, 3): yaw,
    pitch, roll offsets [deg] added after the gimbal (a hand, a vibrating mount)."""
    o = np.asarray(origins, dtype=float).reshape(-1, 3)
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    heading = np.broadcast_to(np.asarray(headings_deg, dtype=float), t.shape)
    if targets is not None:
        d = np.asarray(targets, dtype=float).reshape(-1, 3) - o
        if np.any(np.linalg.norm(d, axis=1) < 1e-9):
            raise ValueError("target: coincides with the camera")
        az, el = direction_angles(d)
    else:
        az = heading + float(mount_deg[0])
        el = np.full(t.shape, float(mount_deg[1]))
    az, el = (gimbal or Gimbal(pitch_range_deg=(-90.0, 90.0))).follow(heading, az, el, t)
    roll = np.full(t.shape, float(roll_deg))
    a, e = az.copy(), el.copy()
    if shake_deg is not None:
        s = np.asarray(shake_deg, dtype=float).reshape(-1, 3)
        a, e, roll = a + s[:, 0], np.clip(e + s[:, 1], -90.0, 90.0), roll + s[:, 2]
    fwd, up = camera_axes(a, e, roll)
    return RigPoses(o, fwd, up, az, el)
