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

    # --- the camera in other tools' conventions ----------------------------------------------
    def intrinsics(self) -> np.ndarray:
        """K (3x3) [px] of the projection above: u = fx x/z + cx, v = fy (-y)/z + cy with
        fx = W / (2 tan(fov_x/2)), fy = H / (2 tan(fov_y/2)), (cx, cy) = (W/2, H/2); pixel
        coordinates with the origin at the top-left corner of the image (pixel centres at
        i + 0.5), as the 2D boxes and keypoints. OpenCV's integer-centre K is this one with
        cx - 0.5, cy - 0.5."""
        return np.array(
            [
                [0.5 * self.width / self.tan_x, 0.0, 0.5 * self.width],
                [0.0, 0.5 * self.height / self.tan_y, 0.5 * self.height],
                [0.0, 0.0, 1.0],
            ]
        )

    def opencv_extrinsics(self) -> tuple[np.ndarray, np.ndarray]:
        """(R (3x3), t (3,) [m]) world -> camera in OpenCV's axes (x right, y down, z forward):
        X_cam = R X_world + t."""
        rot = np.stack([self.right, -self.up, self.forward])
        return rot, -rot @ self.origin

    def world_to_camera_exr(self) -> np.ndarray:
        """OpenEXR ``worldToCamera`` (4x4, Imath row vectors: [x y z 1] M): camera space x right,
        y up, z along the view direction (left-handed, RenderMan's), origin at the camera."""
        rot = np.stack([self.right, self.up, self.forward])
        m = np.eye(4)
        m[:3, :3] = rot
        m[:3, 3] = -rot @ self.origin
        return m.T

    def world_to_ndc_exr(self) -> np.ndarray:
        """OpenEXR ``worldToNDC`` (4x4, row vectors, divide by w): NDC (0, 0) at the top-left and
        (1, 1) at the bottom-right corner of the display window, x right, y down."""
        proj = np.array(
            [
                [0.5 / self.tan_x, 0.0, 0.5, 0.0],
                [0.0, -0.5 / self.tan_y, 0.5, 0.0],
                [0.0, 0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
            ]
        )
        return (proj @ self.world_to_camera_exr().T).T

    def exr_header(self) -> dict:
        """The camera's EXR header attributes: OpenEXR's ``worldToCamera``, ``worldToNDC`` and
        ``humv:K`` (intrinsics, pixel units, see :meth:`intrinsics`)."""
        return {
            "worldToCamera": self.world_to_camera_exr(),
            "worldToNDC": self.world_to_ndc_exr(),
            "humv:K": self.intrinsics(),
        }


def image_velocity(
    camera: Camera, before: Camera, dt_s: float, depth=None, ground_z: float = 0.0
) -> np.ndarray:
    """(H, W, 2) image velocity [px/s] (du/dt, dv/dt) of a static scene at each pixel of
    ``camera`` seen from ``before``, its pose ``dt_s`` earlier: the scene point at pixel p now
    was at the projection q of the same point in ``before``; v = (p - q) / dt.

    ``depth`` (H, W): the distance along the optical axis of each pixel's point [m] (the EXR
    ``depth`` channel; inf: at infinity). Without it the pixel's ray meets the ground plane
    z = ``ground_z`` when it points down, else lies at infinity (exact for a camera that only
    turns; for one that moves, exact on flat ground and off where an object stands above it:
    the error is the parallax of its height, measured in ``humv_usd.bench``-style checks of
    docs/physics/sensor-chain)."""
    rays = camera.pixel_rays()
    h, w = camera.height, camera.width
    if depth is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (ground_z - camera.origin[2]) / rays[..., 2]
        dist = np.where((rays[..., 2] < -1e-9) & (t > 0), t, np.inf)
    else:
        dist = np.asarray(depth, dtype=float) / (rays @ camera.forward)
    far = ~np.isfinite(dist)
    points = camera.origin + rays * np.where(far, 1.0, dist)[..., None]
    points[far] = before.origin + rays[far]  # a direction: its image does not depend on position
    uv, z = before.project(points)
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    vel = np.stack([cols - uv[..., 0], rows - uv[..., 1]], axis=-1) / float(dt_s)
    vel[~np.isfinite(vel) | (z[..., None] <= 0)] = 0.0
    return vel


#: The camera file of each sensor, relative to its output folder (``RENDER/<sensor>/camera.json``).
CAMERA_FILE = "camera.json"

#: The conventions stated in every camera file.
CAMERA_FILE_CONVENTIONS = {
    "pixels": "origin at the top-left corner of the image, u right, v down, pixel (i, j) centre at "
    "(i + 0.5, j + 0.5): the convention of the 2D boxes and keypoints in objects.json and coco.json; "
    "for OpenCV's integer pixel centres use K_integer_centres (cx, cy less 0.5)",
    "extrinsics": "OpenCV: X_cam = R X_world + t, camera axes x right, y down, z forward (optical axis), "
    "metres; projection [u v 1]^T ~ K X_cam",
    "world": "the stage's world: Z up, metres",
    "distortion": "OpenCV (k1, k2, p1, p2, k3); all zero: the render is an ideal pinhole",
    "K": "intrinsics [px] of every frame, unless a frame gives its own K (a zoom)",
}


def camera_file(name: str, frames: list[tuple[int, Camera]]) -> dict:
    """The camera file of one sensor (see :data:`CAMERA_FILE_CONVENTIONS`): intrinsics (of the
    first frame; a frame whose field of view differs carries its own ``K``), distortion, image
    size and the per-frame OpenCV extrinsics."""
    first = frames[0][1]
    k = first.intrinsics()
    k_int = k.copy()
    k_int[:2, 2] -= 0.5
    rows = []
    for frame, cam in frames:
        rot, t = cam.opencv_extrinsics()
        row = {
            "frame": int(frame),
            "R": rot.tolist(),
            "t": t.tolist(),
            "camera_origin_m": cam.origin.tolist(),
        }
        if not np.allclose(cam.intrinsics(), k, rtol=1e-9, atol=0.0):  # a zoom: this frame's own K
            row["K"] = cam.intrinsics().tolist()
        rows.append(row)
    return {
        "sensor": name,
        "conventions": CAMERA_FILE_CONVENTIONS,
        "width": first.width,
        "height": first.height,
        "K": k.tolist(),
        "K_integer_centres": k_int.tolist(),
        "distortion": [0.0] * 5,
        "frames": rows,
    }
