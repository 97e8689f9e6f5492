"""Simple scene geometry in numpy: a subdivided ground rectangle and oriented boxes."""

from __future__ import annotations

import numpy as np

from humv_usd.geometry.mesh import closed_box


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


#: a closed box with outward counter-clockwise quads (:func:`humv_usd.geometry.mesh.closed_box`)
box = closed_box


#: growth of the half-width from one square ring of the ground beyond the rectangle to the next
HORIZON_GROWTH = 1.5
#: segments per side of each ring (cells about a quarter of the ring's half-width across)
HORIZON_SEGMENTS = 8


def terrain_grid(terrain, size_xy, cell_m: float):
    """Triangles over the ground rectangle on a terrain (:class:`humv_usd.geometry.terrain.Terrain`):
    ``size / cell_m`` square cells per axis (rounded up), each split into two triangles along
    alternating diagonals, heights :meth:`Terrain.height` at the vertices, counter-clockwise
    from +z. Triangles, not quads: a quad of a curved ground is not planar, and the thermal
    tool's refinement and shadow rays assume planar faces. Returns (points, counts, indices,
    centroids (F, 2))."""
    nx = max(1, int(np.ceil(size_xy[0] / cell_m - 1e-9)))
    ny = max(1, int(np.ceil(size_xy[1] / cell_m - 1e-9)))
    xs = np.linspace(-size_xy[0] / 2, size_xy[0] / 2, nx + 1)
    ys = np.linspace(-size_xy[1] / 2, size_xy[1] / 2, ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    points = np.stack([gx.ravel(), gy.ravel(), terrain.height(gx, gy).ravel()], axis=1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    v00 = (j * (nx + 1) + i).ravel()
    a, b, c, d = v00, v00 + 1, v00 + nx + 2, v00 + nx + 1
    flip = ((i + j) % 2 == 1).ravel()  # alternating diagonals: no bias in one direction
    t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
    t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
    tris = np.stack([t1, t2], axis=1).reshape(-1, 3)
    centroids = points[tris][:, :, :2].mean(axis=1)
    return points, np.full(len(tris), 3), tris.ravel(), centroids


def horizon_rings(terrain, size_xy, radius_m: float):
    """The ground beyond the rectangle out to ``radius_m`` (half-width of the outermost square):
    square rings whose half-widths grow by :data:`HORIZON_GROWTH`, :data:`HORIZON_SEGMENTS`
    trapezoids per side, on the terrain's plane (planar faces). The rings' inner edge is the
    rectangle's edge (T-junctions with a finer grid there lie on the plane: no gap).
    Returns (points, counts, indices); empty when ``radius_m`` does not exceed the rectangle."""
    hx, hy = size_xy[0] / 2.0, size_xy[1] / 2.0
    if radius_m <= max(hx, hy):
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    n = HORIZON_SEGMENTS
    t = np.linspace(-1.0, 1.0, n + 1)
    # a loop of 4n points around a unit square, counter-clockwise, starting at (-1, -1)
    loop = np.concatenate(
        [
            np.stack([t[:-1], -np.ones(n)], 1),
            np.stack([np.ones(n), t[:-1]], 1),
            np.stack([-t[:-1], np.ones(n)], 1),
            np.stack([-np.ones(n), -t[:-1]], 1),
        ]
    )
    scales = [1.0]
    while max(hx, hy) * scales[-1] < radius_m:
        scales.append(min(scales[-1] * HORIZON_GROWTH, radius_m / max(hx, hy)))
    rings = [loop * np.array([hx * s, hy * s]) for s in scales]
    xy = np.concatenate(rings)
    points = np.column_stack([xy, terrain.plane(xy[:, 0], xy[:, 1])])
    m = len(loop)
    quads = []
    for r in range(len(rings) - 1):
        a, b = r * m, (r + 1) * m
        for k in range(m):
            k1 = (k + 1) % m
            quads.append([a + k, b + k, b + k1, a + k1])  # counter-clockwise seen from +z
    quads = np.asarray(quads, dtype=np.int64)
    return points, np.full(len(quads), 4), quads.ravel()


def snap_to_edges(points, triangles, signed_distance, locked=None):
    """Move grid vertices onto a zone's boundary so that it runs along triangle edges.

    ``signed_distance(x, y)`` is negative inside the zone, positive outside (its zero set is
    the boundary). For every triangle edge whose ends lie on both sides, the end nearer to the
    boundary moves to where the edge crosses it (found by bisection along the edge), each
    vertex once, nearest first; vertices in ``locked`` (another zone's boundary) stay. A
    vertex moves less than half its edge, so no triangle of the grid turns over.
    Returns (points (P, 3) with x, y moved, z untouched, locked (P,) bool)."""
    pts = np.asarray(points, dtype=float).copy()
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    locked = np.zeros(len(pts), dtype=bool) if locked is None else locked.copy()
    edges = np.unique(
        np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1), axis=0
    )
    f = signed_distance(pts[:, 0], pts[:, 1])
    cross = edges[(f[edges[:, 0]] < 0.0) != (f[edges[:, 1]] < 0.0)]
    if not len(cross):
        return pts, locked
    a, b = pts[cross[:, 0], :2], pts[cross[:, 1], :2]
    lo, hi = np.zeros(len(cross)), np.ones(len(cross))
    inside_a = f[cross[:, 0]] < 0.0
    for _ in range(30):  # bisection on the edge's parameter
        mid = 0.5 * (lo + hi)
        m = a + mid[:, None] * (b - a)
        same = (signed_distance(m[:, 0], m[:, 1]) < 0.0) == inside_a
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    t = 0.5 * (lo + hi)
    near = np.where(t < 0.5, cross[:, 0], cross[:, 1])
    target = a + t[:, None] * (b - a)
    for k in np.argsort(np.minimum(t, 1.0 - t), kind="stable"):
        v = near[k]
        if not locked[v]:
            pts[v, :2] = target[k]
            locked[v] = True
    return pts, locked


def drop_degenerate(points, triangles):
    """Triangles (T', 3) of ``triangles`` with an area in the x-y plane (snapping may leave
    three ends of one on a boundary)."""
    v = np.asarray(points)[np.asarray(triangles)]
    area = 0.5 * np.abs(np.cross(v[:, 1, :2] - v[:, 0, :2], v[:, 2, :2] - v[:, 0, :2]))
    return np.asarray(triangles)[area > 1e-9 * max(float(area.max()), 1e-12)]
