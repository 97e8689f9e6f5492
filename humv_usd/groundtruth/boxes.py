"""Per-object boxes and occlusion.

- Full 2D box: the image-plane bounds of the object's whole geometry, occluded parts included:
  its triangles clipped at the near plane (:data:`NEAR_M`, so geometry behind or beside the camera
  bounds the box correctly) and projected with :class:`~humv_usd.geometry.camera.Camera`, then
  clipped to the image. ``[x0, y0, x1, y1]`` in continuous pixel coordinates (COCO convention:
  pixel (i, j) covers [i, i+1) x [j, j+1)); None when nothing is in front of the camera or the
  box misses the image.
- Visible 2D box: the bounds of the object's pixels in the instance mask, ``[x0, y0, x1, y1]``
  with x1 = last column + 1.
- 3D box: world-space axis-aligned box of the posed geometry, ``{"min": [x, y, z], "max": ...}``
  [m], stage axes (x east, y north, z up).
- Oriented 3D box (:func:`box_3d_oriented`): gravity-aligned (yaw only, z up), KITTI / nuScenes
  style. ``center`` [x, y, z] m, ``size`` [length, width, height] m with length >= width,
  ``yaw`` [rad] counter-clockwise from +x to the length axis, in (-pi/2, pi/2] (a box is the same
  box turned by pi, so this half-open range makes it unique; a square footprint, length = width,
  takes yaw in (-pi/4, pi/4]). The footprint is the minimal-area rectangle enclosing the
  vertices projected on the ground plane (z = 0), found on their 2D convex hull
  (``scipy.spatial.ConvexHull``) by rotating calipers: a minimal-area enclosing rectangle has a
  side collinear with a hull edge (Freeman & Shapira 1975, CACM 18(7) 409; Toussaint 1983,
  "Solving geometric problems with the rotating calipers", IEEE MELECON), so every hull edge is
  tried with its three opposite calipers and the smallest area wins. z from the vertices' min / max. ``corners_world`` (8, 3): bottom face (z min)
  then top face, each counter-clockwise seen from above starting at (+l/2, +w/2) in the box
  frame; ``corners_image`` (8, 2) [px] projected with :class:`Camera` (None for a corner at or
  behind the camera plane, flagged in ``behind_camera``).
- Occlusion fraction: 1 - visible / unoccluded pixels, where "unoccluded" casts the pixel-centre
  rays inside the full box against the object's own triangles only (:func:`humv_usd.geometry.raycast.ray_caster`: Embree, or OptiX when the render runs on a GPU).
  Pixels outside the image do not count (truncation is not occlusion).
"""

from __future__ import annotations

import numpy as np

from humv_usd.geometry.camera import Camera
from humv_usd.geometry.raycast import ray_caster

#: Near plane for clipping [m] (the render's near clip, humv_usd.render.elements.NEAR_CLIP_M).
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


#: Corner signs (length, width, height axes of the box frame) in the order of ``corners_world``.
CORNER_SIGNS = np.array(
    [[1, 1, -1], [-1, 1, -1], [-1, -1, -1], [1, -1, -1], [1, 1, 1], [-1, 1, 1], [-1, -1, 1], [1, -1, 1]],
    dtype=float,
)


def _hull_2d(xy: np.ndarray) -> np.ndarray | None:
    """Vertices (counter-clockwise) of the 2D convex hull of xy (N, 2); None when the points
    span no area (fewer than 3, coincident or collinear)."""
    from scipy.spatial import ConvexHull, QhullError

    if len(xy) < 3:
        return None
    try:
        hull = ConvexHull(xy)
    except QhullError:
        return None
    return xy[hull.vertices]


def _support(pts: np.ndarray, alpha: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Max of p . (cos phi, sin phi) over a convex polygon's vertices ``pts`` (h, 2),
    counter-clockwise, whose edge angles ``alpha`` (edge k: pts[k] -> pts[k+1]) are unwrapped
    (increasing, spanning 2 pi). Vertex k is extreme for the directions between the outward
    normals of its edges, alpha[k-1] - pi/2 .. alpha[k] - pi/2: a binary search (O(log h) per
    direction); the two neighbours are checked too against rounding at the cone boundaries."""
    h = len(pts)
    q = alpha[0] + np.mod(phi + 0.5 * np.pi - alpha[0], 2.0 * np.pi)
    k = np.searchsorted(alpha, q, side="left")
    w = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    cand = pts[np.stack([(k - 1) % h, k % h, (k + 1) % h], axis=-1)]  # (n, 3, 2)
    return np.max(np.einsum("nkc,nc->nk", cand, w), axis=1)


def min_area_rectangle(xy) -> tuple[np.ndarray, float, float, float]:
    """Minimal-area rectangle enclosing 2D points (N, 2): (centre (2,), length, width, yaw).

    Rotating calipers on the convex hull (Toussaint 1983): a minimal-area enclosing rectangle
    has a side collinear with a hull edge (Freeman & Shapira 1975), so for every hull edge the
    three other calipers (the farthest vertices along the edge, against it, and across it) are
    found as support points of the convex polygon (:func:`_support`, O(h log h) in all) and the
    smallest area wins. Canonical form: length >= width, yaw (direction of the length side,
    counter-clockwise from +x) in (-pi/2, pi/2]; for length = width (to 1e-9 relative) yaw in
    (-pi/4, pi/4]. Degenerate input (collinear or coincident points) gives width 0 along the
    points' principal direction.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    hull = _hull_2d(xy)
    if hull is None:
        if len(xy) > 1:
            _, _, vt = np.linalg.svd(xy - xy.mean(axis=0), full_matrices=False)
            yaw = float(np.arctan2(vt[0, 1], vt[0, 0]))
        else:
            yaw = 0.0
        d = np.array([np.cos(yaw), np.sin(yaw)])
        n = np.array([-d[1], d[0]])
        u, v = xy @ d, xy @ n
        length, width = float(np.ptp(u)), float(np.ptp(v))
        mid_u, mid_v = 0.5 * (u.max() + u.min()), 0.5 * (v.max() + v.min())
    else:
        origin = hull.mean(axis=0)  # conditioning: far-off coordinates
        pts = hull - origin
        edges = np.roll(pts, -1, axis=0) - pts
        alpha = np.unwrap(np.arctan2(edges[:, 1], edges[:, 0]))  # exterior angles in (0, pi)
        d = np.stack([np.cos(alpha), np.sin(alpha)], axis=-1)
        n = np.stack([-d[:, 1], d[:, 0]], axis=-1)  # inward normal (counter-clockwise hull)
        u_max = _support(pts, alpha, alpha)
        u_min = -_support(pts, alpha, alpha + np.pi)
        v_min = np.einsum("nc,nc->n", pts, n)  # the edge itself
        v_max = _support(pts, alpha, alpha + 0.5 * np.pi)
        area = (u_max - u_min) * (v_max - v_min)
        k = int(np.argmin(area))
        yaw = float(alpha[k])
        length, width = float(u_max[k] - u_min[k]), float(v_max[k] - v_min[k])
        mid_u = 0.5 * (u_max[k] + u_min[k]) + origin @ d[k]
        mid_v = 0.5 * (v_max[k] + v_min[k]) + origin @ n[k]
    c, s = np.cos(yaw), np.sin(yaw)
    centre = np.array([mid_u * c - mid_v * s, mid_u * s + mid_v * c])
    if width > length:
        length, width, yaw = width, length, yaw + 0.5 * np.pi
    half = 0.25 * np.pi if np.isclose(length, width, rtol=1e-9, atol=0.0) else 0.5 * np.pi
    yaw = float(yaw - 2.0 * half * np.ceil((yaw - half) / (2.0 * half)))  # into (-half, half]
    return centre, float(length), float(width), yaw


def box_3d_oriented(points_world: np.ndarray, camera: Camera | None = None) -> dict | None:
    """Gravity-aligned oriented 3D box of points (N, 3) [m] (see the module doc), with its
    corners projected by ``camera`` when given."""
    pts = np.asarray(points_world, dtype=float).reshape(-1, 3)
    if len(pts) == 0:
        return None
    centre_xy, length, width, yaw = min_area_rectangle(pts[:, :2])
    z0, z1 = float(pts[:, 2].min()), float(pts[:, 2].max())
    centre = np.array([centre_xy[0], centre_xy[1], 0.5 * (z0 + z1)])
    corners = box_corners(centre, (length, width, z1 - z0), yaw)
    out = {
        "center": centre.tolist(),
        "size": [length, width, z1 - z0],
        "yaw": yaw,
        "corners_world": corners.tolist(),
    }
    if camera is not None:
        uv, depth = camera.project(corners)
        behind = depth <= 0
        out["corners_image"] = [None if b else [float(p[0]), float(p[1])] for p, b in zip(uv, behind)]
        out["behind_camera"] = [bool(b) for b in behind]
    return out


def box_corners(center, size, yaw: float) -> np.ndarray:
    """The 8 world corners (8, 3) of a yaw-only box (order: :data:`CORNER_SIGNS`)."""
    local = 0.5 * CORNER_SIGNS * np.asarray(size, dtype=float)
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return local @ rot.T + np.asarray(center, dtype=float)


def unoccluded_mask(
    camera: Camera,
    vertices: np.ndarray,
    triangles: np.ndarray,
    box: list[float] | None,
    visible: np.ndarray | None = None,
) -> np.ndarray:
    """(H, W) bool: pixels whose centre ray hits the object's own triangles (nothing else in the
    scene), cast only inside ``box`` (the full 2D box). Pixels in ``visible`` (the object's
    mask: its first hit is the object) are unoccluded without a cast."""
    out = np.zeros((camera.height, camera.width), dtype=bool) if visible is None else visible.copy()
    if box is None or len(triangles) == 0:
        return out
    c0, r0 = int(np.floor(box[0])), int(np.floor(box[1]))
    c1, r1 = int(np.ceil(box[2])), int(np.ceil(box[3]))
    cols, rows = np.meshgrid(np.arange(c0, c1), np.arange(r0, r1))
    todo = ~out[rows, cols]
    cols, rows = cols[todo], rows[todo]
    if cols.size == 0:
        return out
    dirs = camera.pixel_rays(cols.ravel(), rows.ravel())
    origins = np.broadcast_to(camera.origin, dirs.shape)
    hit = ray_caster(vertices, triangles).intersects_any(origins, dirs)
    out[rows.ravel()[hit], cols.ravel()[hit]] = True
    return out


def occlusion_fraction(visible_pixels: int, unoccluded_pixels: int) -> float | None:
    """1 - visible / unoccluded (clipped to 0..1); None when the object would cover no pixel."""
    if unoccluded_pixels <= 0:
        return None
    return float(min(1.0, max(0.0, 1.0 - visible_pixels / unoccluded_pixels)))
