"""Per-object boxes and occlusion.

- Full 2D box: the image-plane bounds of the object's whole geometry, occluded parts included:
  its triangles clipped at the near plane (:data:`NEAR_M`, so geometry behind or beside the camera
  bounds the box correctly) and projected with :class:`~humv_usd.groundtruth.camera.Camera`, then
  clipped to the image. ``[x0, y0, x1, y1]`` in continuous pixel coordinates (COCO convention:
  pixel (i, j) covers [i, i+1) x [j, j+1)); None when nothing is in front of the camera or the
  box misses the image.
- Visible 2D box: the bounds of the object's pixels in the instance mask, ``[x0, y0, x1, y1]``
  with x1 = last column + 1.
- 3D box: world-space axis-aligned box of the posed geometry, ``{"min": [x, y, z], "max": ...}``
  [m], stage axes (x east, y north, z up).
- Occlusion fraction: 1 - visible / unoccluded pixels, where "unoccluded" casts the pixel-centre
  rays inside the full box against the object's own triangles only (embree through trimesh).
  Pixels outside the image do not count (truncation is not occlusion).
"""
from __future__ import annotations

import numpy as np

from humv_usd.groundtruth.camera import Camera

#: Near plane for clipping [m] (the render's near clip, humv_usd.render.ir.NEAR_CLIP_M).
NEAR_M = 1e-3


def _clip_triangles_near(cam_pts: np.ndarray, near: float) -> np.ndarray:
    """Points (camera space) of the parts of triangles (T, 3, 3) in front of z = near: the
    vertices in front and the crossings of the edges with the plane."""
    z = cam_pts[..., 2]
    front = cam_pts[z > near]
    a = cam_pts
    b = np.roll(cam_pts, -1, axis=1)
    za, zb = a[..., 2], b[..., 2]
    cross = (za > near) != (zb > near)
    if not cross.any():
        return front
    t = (near - za[cross]) / (zb[cross] - za[cross])
    hits = a[cross] + t[:, None] * (b[cross] - a[cross])
    return np.concatenate([front, hits])


def full_box(camera: Camera, triangles_world: np.ndarray) -> list[float] | None:
    """Full 2D box [x0, y0, x1, y1] of triangles (T, 3, 3) [m] (see module doc)."""
    if len(triangles_world) == 0:
        return None
    c = camera.to_camera(triangles_world)
    pts = _clip_triangles_near(c, NEAR_M)
    if len(pts) == 0:
        return None
    z = pts[:, 2]
    u = 0.5 * camera.width * (1.0 + pts[:, 0] / (z * camera.tan_x))
    v = 0.5 * camera.height * (1.0 - pts[:, 1] / (z * camera.tan_y))
    x0, x1 = np.clip([u.min(), u.max()], 0, camera.width)
    y0, y1 = np.clip([v.min(), v.max()], 0, camera.height)
    if x1 <= x0 or y1 <= y0:
        return None
    return [float(x0), float(y0), float(x1), float(y1)]


def visible_box(mask: np.ndarray) -> list[int] | None:
    """Visible 2D box [x0, y0, x1, y1] (pixel edges) of a boolean mask, None if empty."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return [int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1]


def box_3d(points_world: np.ndarray) -> dict | None:
    """World-space axis-aligned box of points (N, 3) [m]."""
    if len(points_world) == 0:
        return None
    return {"min": np.min(points_world, axis=0).tolist(), "max": np.max(points_world, axis=0).tolist()}


def unoccluded_mask(camera: Camera, vertices: np.ndarray, triangles: np.ndarray,
                    box: list[float] | None, visible: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: pixels whose centre ray hits the object's own triangles (nothing else in the
    scene), cast only inside ``box`` (the full 2D box). Pixels in ``visible`` (the object's
    mask: its first hit is the object) are unoccluded without a cast."""
    out = np.zeros((camera.height, camera.width), dtype=bool) if visible is None else visible.copy()
    if box is None or len(triangles) == 0:
        return out
    import trimesh

    c0, r0 = int(np.floor(box[0])), int(np.floor(box[1]))
    c1, r1 = int(np.ceil(box[2])), int(np.ceil(box[3]))
    cols, rows = np.meshgrid(np.arange(c0, c1), np.arange(r0, r1))
    todo = ~out[rows, cols]
    cols, rows = cols[todo], rows[todo]
    if cols.size == 0:
        return out
    dirs = camera.pixel_rays(cols.ravel(), rows.ravel())
    mesh = trimesh.Trimesh(vertices=np.asarray(vertices, dtype=np.float64),
                           faces=np.asarray(triangles, dtype=np.int64), process=False, validate=False)
    origins = np.broadcast_to(camera.origin, dirs.shape)
    hit = _intersector(mesh).intersects_any(np.ascontiguousarray(origins), np.ascontiguousarray(dirs))
    out[rows.ravel()[hit], cols.ravel()[hit]] = True
    return out


def _intersector(mesh):
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector
    except ImportError:  # embreex missing: trimesh's pure-numpy intersector (slower, same answer)
        from trimesh.ray.ray_triangle import RayMeshIntersector
    return RayMeshIntersector(mesh)


def occlusion_fraction(visible_pixels: int, unoccluded_pixels: int) -> float | None:
    """1 - visible / unoccluded (clipped to 0..1); None when the object would cover no pixel."""
    if unoccluded_pixels <= 0:
        return None
    return float(min(1.0, max(0.0, 1.0 - visible_pixels / unoccluded_pixels)))
