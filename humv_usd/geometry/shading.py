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
from scipy import sparse
from scipy.sparse import csr_matrix

#: Largest angle [deg] between two faces' normals across which their values are blended at a
#: shared vertex: 60 deg, the crease of the thermal tool's smooth normals for the sun
#: (:mod:`humv_usd.thermal.qrad`), so a box's or a wall's 90 deg edges stay sharp while a
#: garment's 7-30 deg facet steps (issue 25: median 7.4, p90 28.5 deg) blend.
SMOOTH_CREASE_DEG = 60.0
#: One-ring gain steps (:func:`ring_gains`) of a positive per-face field shaded smooth: the
#: render's shadowed term (:data:`humv_usd.render.estimator.DARK_GAIN_STEPS`) and the ground
#: truth's ``surface_temperature``, which follows the field the render shades.
FIELD_GAIN_STEPS = 1
#: Largest (and 1 / smallest) one-ring gain.
FIELD_GAIN_CAP = 4.0


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
    return CornerBlend(meshes, crease_deg)(meshes)


class CornerBlend:
    """:func:`corner_blend` for meshes whose vertices move while their triangles and welds stay
    (a skinned person, frame after frame): which corners meet at a welded vertex, and the
    sparse matrix's pattern, are found once; a call computes the normals, the crease test and
    the angle weights of the current vertices (the same numbers as :func:`corner_blend`).
    :meth:`fits` says whether ``meshes`` still have these triangles and welds (two vertices
    welded at the first geometry that have come apart: no; two that have come together stay
    apart, as a vertex's copies along a seam never do)."""

    def __init__(self, meshes, crease_deg: float = SMOOTH_CREASE_DEG):
        self.cos_c = float(np.cos(np.radians(crease_deg)))
        self.meshes = []  # per mesh: (triangles, first vertex of each weld group, group of each vertex)
        pair_i, pair_j = [], []  # global corner indices: corner i takes face-of-j's value
        first = 0
        for vertices, triangles in meshes:
            tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
            v = np.asarray(vertices)
            t = len(tris)
            if t == 0:
                self.meshes.append((tris, None, None))
                continue
            _, rep, weld = np.unique(v, axis=0, return_index=True, return_inverse=True)
            weld = weld.reshape(-1)
            self.meshes.append((tris, rep, weld))
            inc_v = weld[tris].ravel()  # welded vertex of each corner (f * 3 + c)
            order = np.argsort(inc_v, kind="stable")
            sv = inc_v[order]
            start = np.searchsorted(sv, sv, "left")
            size = np.searchsorted(sv, sv, "right") - start
            by_size = np.argsort(-size, kind="stable")  # entries with the most partners first
            order_s, start_s, size_s = order[by_size], start[by_size], size[by_size]
            for k in range(int(size_s[0])):
                m = int(np.searchsorted(-size_s, -k, "left"))  # the entries with more than k partners
                pair_i.append(3 * first + order_s[:m])
                pair_j.append(3 * first + order[start_s[:m] + k])
            first += t
        self.triangles = first
        cat = lambda parts: np.concatenate(parts) if parts else np.zeros(0, np.int64)  # noqa: E731
        self.pair_i, self.pair_j = cat(pair_i), cat(pair_j)
        rows, cols = self.pair_i, self.pair_j // 3
        key, self.slot = np.unique(rows * max(first, 1) + cols, return_inverse=True)
        self.slot = self.slot.reshape(-1)
        self.indices = (key % max(first, 1)).astype(np.int32)
        self.indptr = np.zeros(3 * first + 1, dtype=np.int64)
        np.cumsum(np.bincount(key // max(first, 1), minlength=3 * first), out=self.indptr[1:])
        # each corner's pair with itself (its own face: the value of a degenerate corner)
        own = np.full(3 * first, -1, dtype=np.int64)
        same = self.pair_i == self.pair_j
        own[self.pair_i[same]] = self.slot[same]
        self.own_slot = own

    def fits(self, meshes) -> bool:
        """Whether ``meshes`` have this blend's triangles and welded vertices."""
        if len(meshes) != len(self.meshes):
            return False
        for (vertices, triangles), (tris, rep, weld) in zip(meshes, self.meshes):
            if not np.array_equal(np.asarray(triangles, dtype=np.int64).reshape(-1, 3), tris):
                return False
            if rep is not None:
                v = np.asarray(vertices)
                if len(v) != len(weld) or not np.array_equal(v[rep][weld], v):
                    return False
        return True

    def __call__(self, meshes) -> csr_matrix:
        """The (3T, T) matrix of :func:`corner_blend` at ``meshes``' current vertices."""
        n_f, angle = [], []
        for (vertices, _), (tris, _, _) in zip(meshes, self.meshes):
            if len(tris) == 0:
                continue
            corner_tri = np.asarray(vertices).astype(float)[tris]
            n_f.append(triangle_normals(corner_tri))
            angle.append(corner_angles(corner_tri).ravel())
        total = self.triangles
        if not n_f:
            return csr_matrix((0, 0))
        n_f, angle = np.concatenate(n_f), np.concatenate(angle)
        fi, fj = self.pair_i // 3, self.pair_j // 3
        ok = np.einsum("ij,ij->i", n_f[fi], n_f[fj]) >= self.cos_c
        w = np.where(ok, angle[self.pair_j], 0.0)
        weight = np.bincount(self.pair_i, weights=w, minlength=3 * total)
        with np.errstate(invalid="ignore", divide="ignore"):
            data = np.bincount(
                self.slot, weights=np.where(ok, w / weight[self.pair_i], 0.0), minlength=len(self.indices)
            )
        degenerate = np.flatnonzero(weight <= 0.0)  # the face's own value
        data[self.own_slot[degenerate]] = 1.0
        return csr_matrix((data, self.indices, self.indptr), shape=(3 * total, total))


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


def ring_gains(
    blend, face_values: np.ndarray, corners: np.ndarray, steps: int = FIELD_GAIN_STEPS
) -> np.ndarray:
    r"""Corner values (T, 3[, n]) of a positive per-face field ``face_values`` (T[, n]) shaded
    smooth, ``corners`` (its :func:`corner_blend` ``blend``), after ``steps`` one-ring gain
    steps: each corner is scaled by :math:`g = \sum_f w_f v_f / \sum_f w_f \bar c_f`, the
    blend's weights w_f over the faces f around it, v_f a face's own value and
    :math:`\bar c_f` the mean of its corners (the linear interpolant's mean over the face),
    clipped to [1 / :data:`FIELD_GAIN_CAP`, :data:`FIELD_GAIN_CAP`].

    Blending a per-face field to the corners loses its covariance with what weights the faces
    (on a sunlit person the faces turned to the sun, which a camera near the sun's direction
    sees face-on, are the hot ones); a gain step makes each corner's ring of faces keep the
    mean of its flat faces, as each face's energy balance has it, while the gain varies
    smoothly. The multiplicative counterpart of a Van Cittert step (Van Cittert, Z. Phys. 69
    (1931) 298; Richardson, J. Opt. Soc. Am. 62 (1972) 55; Lucy, Astron. J. 79 (1974) 745):
    positive, exact for a uniform field. Where ``blend @ mean`` is not positive the corner
    keeps its value."""
    v = np.asarray(face_values, dtype=float)
    c = np.asarray(corners, dtype=float)
    t = c.shape[0]
    tail = c.shape[2:]
    ring = np.asarray(blend @ v).reshape((t, 3) + tail)
    for _ in range(int(steps)):
        now = np.asarray(blend @ c.mean(axis=1)).reshape((t, 3) + tail)
        with np.errstate(invalid="ignore", divide="ignore"):
            gain = np.where(now > 0.0, ring / now, 1.0)
        c = c * np.clip(gain, 1.0 / FIELD_GAIN_CAP, FIELD_GAIN_CAP)
    return c


def smooth_noise(
    blend,
    face_of: np.ndarray,
    face_sigma: np.ndarray,
    triangle: np.ndarray,
    bary: np.ndarray,
    steps: int = FIELD_GAIN_STEPS,
) -> np.ndarray:
    r"""Standard deviation (N,) of a per-face field shaded smooth, at N points, when each face's
    value carries an independent error of standard deviation ``face_sigma`` (n_faces,) (e.g.
    the thermal layer's face temperatures, from its q_rad rays).

    ``blend`` (3T, T): :func:`corner_blend`; ``face_of`` (T,): the face of each triangle (the
    triangles of one face share its value and its error); ``triangle`` (N,) and ``bary`` (N, 3):
    the triangle of each point and its barycentric coordinates (the corners' order of
    ``blend``); ``steps``: the one-ring gain steps (:func:`ring_gains`) of the shaded field.

    The shaded value at a point is :math:`\sum_c b_c c_c` over its triangle's corners. A gain
    step :math:`c \leftarrow c\, (B v) / (B \bar c)` (B the blend, :math:`\bar c = A c` the
    faces' corner means), linearised about a locally uniform field (gain 1), maps an error
    :math:`\epsilon` of the faces to :math:`dc \leftarrow dc + B\epsilon - B A\, dc`, from
    :math:`dc = B\epsilon` without a step. With :math:`r_f` the point's resulting weight of face
    f, the variance is :math:`\sum_f r_f^2 \sigma_f^2` (Gaussian error propagation, the faces'
    errors independent; JCGM 100:2008, GUM, section 5.1). A flat face reads
    :math:`\sigma_f` itself; blending averages the errors of the faces around each corner."""
    b = sparse.csr_matrix(blend)
    n_t = b.shape[1]
    face_of = np.asarray(face_of, dtype=np.int64)
    n_f = int(face_of.max()) + 1 if len(face_of) else 0
    to_face = sparse.csr_matrix((np.ones(n_t), (np.arange(n_t), face_of)), shape=(n_t, max(n_f, 1)))
    t = np.asarray(triangle, dtype=np.int64)
    n = len(t)
    pick = sparse.csr_matrix(
        (
            np.asarray(bary, dtype=float).ravel(),
            (np.repeat(np.arange(n), 3), (3 * t[:, None] + np.arange(3)).ravel()),
        ),
        shape=(n, 3 * n_t),
    )
    pb = (pick @ b).tocsr()  # the points' rows of B
    r = pb
    if int(steps) > 0:
        # M_{k+1} = M_k + B - B Q_k with Q_k = A M_k: Q_0 = A B, Q_{k+1} = Q_k + Q_0 - Q_0 Q_k
        mean = sparse.csr_matrix(
            (np.full(3 * n_t, 1.0 / 3.0), (np.repeat(np.arange(n_t), 3), np.arange(3 * n_t))),
            shape=(n_t, 3 * n_t),
        )
        q0 = (mean @ b).tocsr()
        q = q0
        for k in range(int(steps)):
            r = (r + pb - pb @ q).tocsr()
            if k + 1 < int(steps):
                q = (q + q0 - q0 @ q).tocsr()
    r = (r @ to_face).tocsr()  # (N, faces) weight of each face's error at each point
    s2 = np.asarray(face_sigma, dtype=float) ** 2
    return np.sqrt(np.maximum(np.asarray(r.multiply(r) @ s2).ravel(), 0.0))
