"""Mesh queries the clothing tool needs: normals, closest points, signed distance.

Pure numpy + scipy (KD-tree); ray casts are in :mod:`humv_usd.geometry.raycast`. Triangles
index a point array; polygons are fan-triangulated (:func:`fan_triangulate`) as the render does.

Closest point on a mesh: the exact point-triangle closest point (Ericson 2005, *Real-Time
Collision Detection*, sec. 5.1.5) over the ``k`` triangles whose centroids are nearest to the
query point (a KD-tree over centroids). For a mesh of near-uniform triangles and queries
within a few edge lengths of the surface (garments: 0-5 cm from the skin, body edges ~1 cm),
the closest triangle is among the 8 nearest centroids (``tests/test_clothing.py`` checks the
distance against all triangles; a miss costs a few µm). Sign: the side of the surface given by the normal interpolated
(barycentric) from the area-weighted vertex normals at the closest point -- robust on a
smooth closed surface like the body, unlike the flat face normal at edges and vertices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: Nearest triangle centroids searched per query point.
CANDIDATES = 8
#: Queries above which the KD-tree search runs on all cores.
PARALLEL_QUERIES = 4096


def fan_triangulate(counts: np.ndarray, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fan-triangulate polygons given as USD face-vertex counts and indices (the one triangulation
    of HumV-USD: the render, thermal, clothing and the USD mesh helpers use it).

    Parameters
    ----------
    counts : (F,) int
        Vertices per face (>= 3).
    indices : (sum(counts),) int
        Face-vertex indices.

    Returns
    -------
    triangles : (T, 3) int
        Vertex indices ``(v0, v_k, v_k+1)`` per face, keeping the face's winding.
    triangle_face : (T,) int
        The face each triangle comes from.
    """
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    ntri = counts - 2
    starts = np.cumsum(counts) - counts
    triangle_face = np.repeat(np.arange(counts.size), ntri)
    k = np.arange(triangle_face.size) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    base = starts[triangle_face]
    triangles = np.stack([indices[base], indices[base + k + 1], indices[base + k + 2]], axis=1)
    return triangles, triangle_face


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (0 for unused vertices)."""
    p = np.asarray(points, dtype=np.float64)
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    fn = np.cross(b - a, c - a)  # length = 2 x area
    n = np.zeros_like(p)
    for k in range(3):
        for axis in range(3):
            n[:, axis] += np.bincount(triangles[:, k], weights=fn[:, axis], minlength=len(p))
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def closest_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (..., 3) of the point of each triangle abc closest to p.

    Vectorized form of Ericson (2005) sec. 5.1.5 (Voronoi regions of vertices, edges, face).
    """
    ab, ac, ap = b - a, c - a, p - a
    bp, cp = p - b, p - c
    d1 = np.einsum("...i,...i->...", ab, ap)
    d2 = np.einsum("...i,...i->...", ac, ap)
    d3 = np.einsum("...i,...i->...", ab, bp)
    d4 = np.einsum("...i,...i->...", ac, bp)
    d5 = np.einsum("...i,...i->...", ab, cp)
    d6 = np.einsum("...i,...i->...", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        total = va + vb + vc
        v_in = np.where(total != 0, vb / total, 1.0 / 3.0)
        w_in = np.where(total != 0, vc / total, 1.0 / 3.0)
        t_ab = np.where(d1 - d3 != 0, d1 / (d1 - d3), 0.0)
        t_ac = np.where(d2 - d6 != 0, d2 / (d2 - d6), 0.0)
        e43, e56 = d4 - d3, d5 - d6
        t_bc = np.where(e43 + e56 != 0, e43 / (e43 + e56), 0.0)
    zero = np.zeros_like(d1)
    one = np.ones_like(d1)
    conditions = [
        (d1 <= 0) & (d2 <= 0),  # vertex a
        (d3 >= 0) & (d4 <= d3),  # vertex b
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),  # edge ab
        (d6 >= 0) & (d5 <= d6),  # vertex c
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),  # edge ac
        (va <= 0) & (e43 >= 0) & (e56 >= 0),  # edge bc
    ]
    v = np.select(conditions, [zero, one, t_ab, zero, zero, 1.0 - t_bc], v_in)
    w = np.select(conditions, [zero, zero, zero, one, t_ac, t_bc], w_in)
    return np.stack([1.0 - v - w, v, w], axis=-1)


def _closest_candidates(q, cand, tri, tri_normals):
    """:meth:`Surface.closest` over given candidate triangles ``cand`` (n, k), one query
    point at a time (compiled by numba, :func:`_closest_kernel`): the exact point-triangle
    closest point with :func:`closest_on_triangles`'s float64 operations, the first of equal
    distances winning, then the interpolated normal and the sign, as
    :meth:`Surface.closest_reference` computes them without its (n, k) temporaries. numpy's
    einsum adds a 3-vector dot as (x0 + x2) + x1: kept here, so on this build the numbers
    are the same to the bit (elsewhere they may differ in the last bit).
    """
    n, k = cand.shape
    point = np.empty((n, 3))
    triangle = np.empty(n, dtype=np.int64)
    bary = np.empty((n, 3))
    normal = np.empty((n, 3))
    signed = np.empty(n)
    for i in range(n):
        px, py, pz = q[i, 0], q[i, 1], q[i, 2]
        best_d2 = np.inf
        best_j = -1
        bu = bv = bw = 0.0
        cx = cy = cz = 0.0
        for j in range(k):
            t = cand[i, j]
            ax, ay, az = tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2]
            bx, by, bz = tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2]
            qx, qy, qz = tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2]
            abx, aby, abz = bx - ax, by - ay, bz - az
            acx, acy, acz = qx - ax, qy - ay, qz - az
            apx, apy, apz = px - ax, py - ay, pz - az
            bpx, bpy, bpz = px - bx, py - by, pz - bz
            cpx, cpy, cpz = px - qx, py - qy, pz - qz
            d1 = (abx * apx + abz * apz) + aby * apy
            d2 = (acx * apx + acz * apz) + acy * apy
            d3 = (abx * bpx + abz * bpz) + aby * bpy
            d4 = (acx * bpx + acz * bpz) + acy * bpy
            d5 = (abx * cpx + abz * cpz) + aby * cpy
            d6 = (acx * cpx + acz * cpz) + acy * cpy
            va = d3 * d6 - d5 * d4
            vb = d5 * d2 - d1 * d6
            vc = d1 * d4 - d3 * d2
            e43, e56 = d4 - d3, d5 - d6
            if d1 <= 0 and d2 <= 0:  # vertex a
                v, w = 0.0, 0.0
            elif d3 >= 0 and d4 <= d3:  # vertex b
                v, w = 1.0, 0.0
            elif vc <= 0 and d1 >= 0 and d3 <= 0:  # edge ab
                v = d1 / (d1 - d3) if d1 - d3 != 0 else 0.0
                w = 0.0
            elif d6 >= 0 and d5 <= d6:  # vertex c
                v, w = 0.0, 1.0
            elif vb <= 0 and d2 >= 0 and d6 <= 0:  # edge ac
                v = 0.0
                w = d2 / (d2 - d6) if d2 - d6 != 0 else 0.0
            elif va <= 0 and e43 >= 0 and e56 >= 0:  # edge bc
                t_bc = e43 / (e43 + e56) if e43 + e56 != 0 else 0.0
                v, w = 1.0 - t_bc, t_bc
            else:  # face
                total = va + vb + vc
                if total != 0:
                    v, w = vb / total, vc / total
                else:
                    v, w = 1.0 / 3.0, 1.0 / 3.0
            u = 1.0 - v - w
            ox = u * ax + v * bx + w * qx
            oy = u * ay + v * by + w * qy
            oz = u * az + v * bz + w * qz
            dx, dy, dz = px - ox, py - oy, pz - oz
            dd = (dx * dx + dz * dz) + dy * dy
            if dd < best_d2 or best_j < 0:
                best_d2, best_j = dd, j
                bu, bv, bw = u, v, w
                cx, cy, cz = ox, oy, oz
        t = cand[i, best_j]
        triangle[i] = t
        bary[i, 0], bary[i, 1], bary[i, 2] = bu, bv, bw
        point[i, 0], point[i, 1], point[i, 2] = cx, cy, cz
        nx = bu * tri_normals[t, 0, 0] + bv * tri_normals[t, 1, 0] + bw * tri_normals[t, 2, 0]
        ny = bu * tri_normals[t, 0, 1] + bv * tri_normals[t, 1, 1] + bw * tri_normals[t, 2, 1]
        nz = bu * tri_normals[t, 0, 2] + bv * tri_normals[t, 1, 2] + bw * tri_normals[t, 2, 2]
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0:
            nx, ny, nz = nx / length, ny / length, nz / length
        else:
            nx = ny = nz = 0.0
        normal[i, 0], normal[i, 1], normal[i, 2] = nx, ny, nz
        dist = np.sqrt(best_d2)
        side = ((px - cx) * nx + (pz - cz) * nz) + (py - cy) * ny
        signed[i] = -dist if side < 0 else dist
    return point, triangle, bary, normal, signed


def _triangles_near_box(points, triangles, lo, hi, reach, by_bounds):
    """Mask of the triangles whose centroid (``by_bounds`` False) or bounding box (True) lies
    within ``reach`` of the box [lo, hi] (compiled by numba, :func:`triangles_near_box`)."""
    out = np.zeros(triangles.shape[0], dtype=np.bool_)
    r2 = reach * reach
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        g2 = 0.0
        for ax in range(3):
            pa, pb, pc = points[a, ax], points[b, ax], points[c, ax]
            if by_bounds:
                low, high = min(pa, pb, pc), max(pa, pb, pc)
            else:
                low = high = (pa + pb + pc) / 3.0
            gap = max(low - hi[ax], lo[ax] - high, 0.0)
            g2 += gap * gap
        out[t] = g2 <= r2
    return out


_COMPILED: list = []
_NEAR_BOX: list = []


def triangles_near_box(points, triangles, lo, hi, reach: float, by_bounds: bool = False) -> np.ndarray:
    """Indices of the triangles whose centroid (or, ``by_bounds``, bounding box: then every
    triangle with a point that near) lies within ``reach`` [m] of the box [lo, hi]."""
    if not _NEAR_BOX:
        import numba

        _NEAR_BOX.append(numba.njit(cache=True, nogil=True)(_triangles_near_box))
    mask = _NEAR_BOX[0](
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(triangles, dtype=np.int64),
        np.asarray(lo, dtype=np.float64),
        np.asarray(hi, dtype=np.float64),
        float(reach),
        bool(by_bounds),
    )
    return np.flatnonzero(mask)


def _closest_kernel():
    """:func:`_closest_candidates` compiled by numba on first use (cached on disk; numba is
    imported only here, so modules that never query a Surface do not pay its import)."""
    if not _COMPILED:
        import numba

        _COMPILED.append(numba.njit(cache=True, nogil=True)(_closest_candidates))
    return _COMPILED[0]


@dataclass
class Closest:
    """Closest surface points of query points (all arrays have the query count first)."""

    point: np.ndarray  # (n, 3) closest point on the surface
    triangle: np.ndarray  # (n,) triangle index
    bary: np.ndarray  # (n, 3) barycentric coordinates in that triangle
    normal: np.ndarray  # (n, 3) interpolated unit normal at the closest point
    signed: np.ndarray  # (n,) signed distance [m], < 0 inside (behind the normal)


class Surface:
    """A triangle mesh for closest-point and signed-distance queries (see module doc)."""

    def __init__(self, points: np.ndarray, triangles: np.ndarray, normals: np.ndarray | None = None):
        self.points = np.asarray(points, dtype=np.float64)
        self.triangles = np.asarray(triangles, dtype=np.int64)
        self.normals = vertex_normals(self.points, self.triangles) if normals is None else normals
        self._tri_points = self.points[self.triangles]  # (T, 3, 3)
        self._tri_normals = np.ascontiguousarray(self.normals[self.triangles], dtype=np.float64)
        # median splits are not needed for the queries: the sliding midpoint build is ~1.6x faster
        self._tree = cKDTree(self._tri_points.mean(axis=1), balanced_tree=False)

    def closest(self, query: np.ndarray, k: int = CANDIDATES) -> Closest:
        return self.closest_within(query, k)[0]

    def closest_within(self, query: np.ndarray, k: int = CANDIDATES) -> tuple[Closest, np.ndarray]:
        """:meth:`closest` and, per query point, the distance to the k-th nearest centroid
        (the radius within which the candidates were taken)."""
        q = np.ascontiguousarray(query, dtype=np.float64).reshape(-1, 3)
        k = min(k, len(self.triangles))
        # threads only pay off for large queries (their start-up costs ~0.1 ms per call)
        dist, cand = self._tree.query(q, k=k, workers=-1 if len(q) > PARALLEL_QUERIES else 1)
        cand = np.ascontiguousarray(cand.reshape(len(q), k), dtype=np.int64)
        point, triangle, bary, normal, signed = _closest_kernel()(
            q, cand, self._tri_points, self._tri_normals
        )
        return Closest(point, triangle, bary, normal, signed), np.asarray(dist).reshape(len(q), k)[:, -1]

    def closest_reference(self, query: np.ndarray, k: int = CANDIDATES) -> Closest:
        """:meth:`closest` in plain numpy (:func:`closest_on_triangles` over the same
        candidates); the compiled kernel must give the same numbers (tests)."""
        q = np.asarray(query, dtype=np.float64)
        k = min(k, len(self.triangles))
        # threads only pay off for large queries (their start-up costs ~0.1 ms per call)
        _, cand = self._tree.query(q, k=k, workers=-1 if len(q) > PARALLEL_QUERIES else 1)
        cand = cand.reshape(len(q), k)
        tri = self._tri_points[cand]  # (n, k, 3, 3)
        bary = closest_on_triangles(q[:, None, :], tri[:, :, 0], tri[:, :, 1], tri[:, :, 2])
        cp = np.einsum("nkj,nkji->nki", bary, tri)
        d2 = np.einsum("nki,nki->nk", q[:, None, :] - cp, q[:, None, :] - cp)
        best = np.argmin(d2, axis=1)
        rows = np.arange(len(q))
        triangle = cand[rows, best]
        bary = bary[rows, best]
        point = cp[rows, best]
        normal = np.einsum("nj,nji->ni", bary, self.normals[self.triangles[triangle]])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
        offset = q - point
        dist = np.sqrt(d2[rows, best])
        side = np.einsum("ni,ni->n", offset, normal)
        signed = np.where(side < 0, -dist, dist)
        return Closest(point, triangle, bary, normal, signed)


def box_distance(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Euclidean distance [m] of each point (n, 3) to the axis-aligned box [lo, hi] (0 inside)."""
    out = np.maximum(np.maximum(lo - points, points - hi), 0.0)
    return np.sqrt(np.einsum("ni,ni->n", out, out))


class LocalSurface:
    """The part of a mesh near a box, answering :meth:`Surface.closest` exactly as the whole
    mesh's :class:`Surface` does (a garment that covers a small part of the body, such as
    hair or shoes, then needs no KD-tree of the whole body).

    Kept: the triangles whose centroids lie within ``reach`` of the box [lo, hi], with the
    whole mesh's vertex normals (summed over every triangle at their vertices, in the same
    order: the same numbers). A query point q whose k-th nearest kept centroid lies within
    ``reach - box_distance(q)`` has the same k nearest centroids in the whole mesh (every
    other centroid lies farther than ``reach`` from the box, so farther than that from q),
    hence the same candidates and the same answer; the other query points are answered by
    the whole mesh's Surface, which ``whole()`` returns (built on first need).
    """

    def __init__(self, points, triangles, lo, hi, reach: float, whole, keep=None):
        self.lo, self.hi, self.reach = np.asarray(lo, float), np.asarray(hi, float), float(reach)
        self._whole, self._total = whole, len(triangles)
        if keep is None:  # (the caller may have selected them already)
            keep = triangles_near_box(points, triangles, self.lo, self.hi, self.reach)
        self.keep = keep
        tris = triangles[self.keep]
        used = np.zeros(len(points), dtype=bool)
        used[tris.ravel()] = True
        touching = triangles[used[triangles].any(axis=1)]
        # compact: the vertices of the touching triangles, in the whole mesh's order (the
        # normals' sums run over the same triangles in the same order: the same numbers)
        used[touching.ravel()] = True
        verts = np.flatnonzero(used)
        local = np.full(len(points), -1, dtype=np.int64)
        local[verts] = np.arange(len(verts))
        normals = vertex_normals(points[verts], local[touching])
        self.surface = Surface(points[verts], local[tris], normals) if len(tris) else None
        #: query points the whole mesh answered (for benchmarks)
        self.fallbacks = 0

    def closest(self, query: np.ndarray, k: int = CANDIDATES) -> Closest:
        q = np.ascontiguousarray(query, dtype=np.float64).reshape(-1, 3)
        if self.surface is None or len(self.keep) < min(k, self._total):
            self.fallbacks += len(q)
            return self._whole().closest(q, k)
        near, kth = self.surface.closest_within(q, k)
        near.triangle = self.keep[near.triangle]
        miss = np.flatnonzero(~(kth <= self.reach - box_distance(q, self.lo, self.hi)))
        if len(miss):
            self.fallbacks += len(miss)
            other = self._whole().closest(q[miss], k)
            for name in ("point", "triangle", "bary", "normal", "signed"):
                getattr(near, name)[miss] = getattr(other, name)
        return near


def closed_box(center_base, size, heading_deg: float = 0.0):
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
