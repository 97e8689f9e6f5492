"""Pinhole projection of the render's sensors (the model Mitsuba's ``perspective`` sensor uses).

A :class:`CameraPose` (origin, optical axis ``forward``, ``up``, horizontal field of view; read
from a UsdGeom.Camera by :func:`humv_usd.usd.sensor.read_camera_pose`) and a resolution (W, H)
define the :class:`Camera`: ``right = forward x up`` (normalised),
``true_up = right x forward``; a world point at camera coordinates (x right, y up, z along the
axis) lands at continuous pixel coordinates

    u = W/2 * (1 + x / (z tan(fov_x/2))),   v = H/2 * (1 - y / (z tan(fov_y/2)))

with tan(fov_y/2) = tan(fov_x/2) H / W (square pixels). Pixel (column i, row j) covers
[i, i+1) x [j, j+1); its centre is (i + 0.5, j + 0.5), row 0 at the top (the COCO convention).
``depth`` is z, the distance along the optical axis, as in the EXR ``depth`` channel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class CameraPose:
    """A sensor's camera at one frame (world space, metres)."""

    origin: np.ndarray  # (3,) [m]
    forward: np.ndarray  # (3,), unit, the optical axis
    up: np.ndarray  # (3,), unit
    fov_x_deg: float  # full horizontal field of view [deg]


@dataclass(frozen=True)
class Camera:
    """The pinhole camera of a :class:`CameraPose` and a resolution (see the module doc)."""

    origin: np.ndarray
    forward: np.ndarray
    right: np.ndarray
    up: np.ndarray
    tan_x: float
    tan_y: float
    width: int
    height: int

    @classmethod
    def from_pose(cls, pose: CameraPose, width: int, height: int) -> Camera:
        fwd = np.asarray(pose.forward, dtype=float)
        fwd = fwd / np.linalg.norm(fwd)
        right = np.cross(fwd, np.asarray(pose.up, dtype=float))
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        tan_x = math.tan(math.radians(pose.fov_x_deg) / 2.0)
        return cls(
            np.asarray(pose.origin, dtype=float),
            fwd,
            right,
            up,
            tan_x,
            tan_x * height / width,
            int(width),
            int(height),
        )

    def to_camera(self, points) -> np.ndarray:
        """World points (..., 3) [m] -> camera coordinates (x right, y up, z forward) [m]."""
        d = np.asarray(points, dtype=float) - self.origin
        return np.stack([d @ self.right, d @ self.up, d @ self.forward], axis=-1)

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """World points (..., 3) -> (pixel coordinates (..., 2) as (u, v), depth (...,) [m]).

        Points at or behind the camera plane (depth <= 0) get NaN pixel coordinates.
        """
        c = self.to_camera(points)
        z = c[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = 0.5 * self.width * (1.0 + c[..., 0] / (z * self.tan_x))
            v = 0.5 * self.height * (1.0 - c[..., 1] / (z * self.tan_y))
        uv = np.stack([u, v], axis=-1)
        uv[z <= 0] = np.nan
        return uv, z

    def pixel_rays(self, columns=None, rows=None) -> np.ndarray:
        """Unit world directions through pixel centres; default every pixel, shape (H, W, 3)."""
        cols = np.arange(self.width) if columns is None else np.asarray(columns)
        rws = np.arange(self.height) if rows is None else np.asarray(rows)
        sx = ((cols + 0.5) / self.width * 2.0 - 1.0) * self.tan_x
        sy = (1.0 - (rws + 0.5) / self.height * 2.0) * self.tan_y
        if columns is None and rows is None:
            sx, sy = np.meshgrid(sx, sy)
        d = self.forward + sx[..., None] * self.right + sy[..., None] * self.up
        return d / np.linalg.norm(d, axis=-1, keepdims=True)
