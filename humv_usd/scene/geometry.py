"""Simple scene geometry in numpy: a subdivided ground rectangle and oriented boxes."""

from __future__ import annotations

import numpy as np


def ground_grid(size_xy, cells: int = 16):
    """A z = 0 rectangle centred at the origin, ``cells`` x ``cells`` quads, normals +z."""
    nx = ny = cells
    xs = np.linspace(-size_xy[0] / 2, size_xy[0] / 2, nx + 1)
    ys = np.linspace(-size_xy[1] / 2, size_xy[1] / 2, ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    points = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    v00 = (j * (nx + 1) + i).ravel()
    quads = np.stack([v00, v00 + 1, v00 + nx + 2, v00 + nx + 1], axis=1)  # CCW from +z
    return points, np.full(len(quads), 4), quads.ravel()


def box(center_base, size, heading_deg: float = 0.0):
    """A closed box with outward counter-clockwise quads.

    center_base: centre of the bottom face [m]; size: (x, y, z) extents before the rotation of
    heading_deg (counter-clockwise about +z).
    """
    sx, sy, sz = (s / 2 for s in size)
    corners = np.array(
        [
            [-sx, -sy, 0],
            [sx, -sy, 0],
            [sx, sy, 0],
            [-sx, sy, 0],
            [-sx, -sy, 2 * sz],
            [sx, -sy, 2 * sz],
            [sx, sy, 2 * sz],
            [-sx, sy, 2 * sz],
        ],
        dtype=float,
    )
    quads = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
    h = np.radians(heading_deg)
    rot = np.array([[np.cos(h), -np.sin(h), 0], [np.sin(h), np.cos(h), 0], [0, 0, 1]])
    points = corners @ rot.T + np.asarray(center_base, dtype=float)
    return points, np.full(6, 4), quads.ravel()
