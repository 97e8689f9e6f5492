r"""Smooth shading of a field given per flat face (issue 25: one temperature per flat face drew
garments as checkerboards in the infrared images).

:func:`corner_blend` turns per-triangle values into per-corner values; interpolated at a point
of a triangle with its barycentric coordinates (:func:`barycentric`), they give Gouraud's
continuous field over smooth parts of a surface (Gouraud, "Continuous shading of curved
surfaces", IEEE Trans. Comput. C-20 (1971) 623), sharp across creases and between meshes. The
render's estimator shades the surface terms this way (:mod:`humv_usd.render.estimator`) and the
ground truth's ``surface_temperature`` follows the same field (:mod:`humv_usd.groundtruth`).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix

#: Largest angle [deg] between two faces' normals across which their values are blended at a
#: shared vertex: 60 deg, the crease of the thermal tool's smooth normals for the sun
#: (:mod:`humv_usd.thermal.qrad`), so a box's or a wall's 90 deg edges stay sharp while a
#: garment's 7-30 deg facet steps (issue 25: median 7.4, p90 28.5 deg) blend.
SMOOTH_CREASE_DEG = 60.0


def corner_angles(tri: np.ndarray) -> np.ndarray:
    """(T, 3) interior angle [rad] of each triangle (T, 3, 3) at each of its corners (0 for a
    degenerate one)."""
    tri = np.asarray(tri, dtype=float)
    out = np.zeros(tri.shape[:2])
    for c in range(3):
        u = tri[:, (c + 1) % 3] - tri[:, c]
        v = tri[:, (c + 2) % 3] - tri[:, c]
        out[:, c] = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))
    return out


def triangle_normals(tri: np.ndarray) -> np.ndarray:
    """(T, 3) unit normals (right-handed winding) of triangles (T, 3, 3); 0 for degenerate ones."""
    tri = np.asarray(tri, dtype=float)
    cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cr, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, cr / norm, 0.0)


def corner_blend(meshes, crease_deg: float = SMOOTH_CREASE_DEG) -> csr_matrix:
    r"""(3T, T) sparse matrix from per-triangle values to per-corner values.

    ``meshes``: a sequence of (vertices (V, 3), triangles (t, 3)); the T triangles are theirs
    in order, and corner ``3 f + c`` is corner ``c`` of triangle ``f`` as given (so a caller
    whose ray tracer reverses a mesh's winding passes the reversed triangles). Values never
    blend between meshes (a mesh is one material).

    A corner takes the mean of the faces of its mesh around that vertex whose normals lie
    within ``crease_deg`` of its own face's normal, each weighted by its angle at the vertex
    (Thuermer & Wuethrich, "Computing vertex normals from polygonal facets", J. Graphics Tools
    3 (1998) 43: independent of how the polygons were split into triangles; weighted by area,
    a quad split in two would count twice on one side of its vertex). Vertices are welded by
    position, so a mesh split at UV seams blends across them. A field linear over a surface is
    reproduced exactly at its interior vertices. A corner of a degenerate face keeps its own
    face's value. Each row sums to 1.
    """
    cos_c = float(np.cos(np.radians(crease_deg)))
    rows, cols, vals = [], [], []
    first = 0
    for vertices, triangles in meshes:
        tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        t = len(tris)
        if t == 0:
            continue
        v = np.asarray(vertices)
        _, weld = np.unique(v, axis=0, return_inverse=True)
        inc_v = weld.reshape(-1)[tris].ravel()  # welded vertex of each corner (f * 3 + c)
        inc_f = np.repeat(np.arange(t), 3)
        order = np.argsort(inc_v, kind="stable")
        sv = inc_v[order]
        start = np.searchsorted(sv, sv, "left")
        size = np.searchsorted(sv, sv, "right") - start
        by_size = np.argsort(-size, kind="stable")  # entries with the most partners first
        order_s, start_s, size_s = order[by_size], start[by_size], size[by_size]
        corner_tri = v.astype(float)[tris]
        n_f = triangle_normals(corner_tri)
        angle = corner_angles(corner_tri).ravel()  # (3t,)
        for k in range(int(size_s[0])):
            m = int(np.searchsorted(-size_s, -k, "left"))  # the entries with more than k partners
            i = order_s[:m]
            j = order[start_s[:m] + k]
            ok = np.einsum("ij,ij->i", n_f[inc_f[i]], n_f[inc_f[j]]) >= cos_c
            rows.append(3 * first + i[ok])
            cols.append(first + inc_f[j[ok]])
            vals.append(angle[j[ok]])
        first += t
    total = first
    if rows:
        r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    else:
        r = c = np.zeros(0, np.int64)
        w = np.zeros(0)
    weight = np.bincount(r, weights=w, minlength=3 * total)
    keep = weight[r] > 0.0
    r, c, w = r[keep], c[keep], w[keep] / weight[r[keep]]
    own = np.flatnonzero(weight <= 0.0)  # degenerate: the face's own value
    r = np.concatenate([r, own])
    c = np.concatenate([c, own // 3])
    w = np.concatenate([w, np.ones(len(own))])
    return csr_matrix((w, (r, c)), shape=(3 * total, total))


def barycentric(tri: np.ndarray, p: np.ndarray, index=None) -> np.ndarray:
    """(N, 3) barycentric coordinates of points ``p`` (N, 3) projected onto triangles
    ``tri`` (N, 3, 3) (least squares in the triangle's plane; a degenerate triangle: its first
    corner). ``index`` (N,): point i lies on triangle ``index[i]`` of ``tri`` (T, 3, 3) (each
    triangle's edges and their products computed once; the same numbers)."""
    tri = np.asarray(tri, dtype=float)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    a11, a12, a22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    det = a11 * a22 - a12 * a12
    ok = det > 1e-30 * np.maximum(a11 * a22, 1e-300)
    safe = np.where(ok, det, 1.0)
    v0 = tri[:, 0]
    if index is not None:
        at = np.asarray(index)
        e1, e2, v0, a11, a12, a22, ok, safe = (x[at] for x in (e1, e2, v0, a11, a12, a22, ok, safe))
    d = np.asarray(p, dtype=float) - v0
    r1, r2 = (d * e1).sum(1), (d * e2).sum(1)
    b1 = np.where(ok, (a22 * r1 - a12 * r2) / safe, 0.0)
    b2 = np.where(ok, (a11 * r2 - a12 * r1) / safe, 0.0)
    return np.stack([1.0 - b1 - b2, b1, b2], axis=1)
