"""What each scene face sees: sky view factor and view factors to the other scene faces.

Per face, rays leave points spread over each of its triangles in cosine-weighted directions
about its normal, so the share of rays that escape upwards is the face's (area-averaged) sky
view factor, and the share that first hits face k is the view factor F_ik (Modest 2013,
Radiative Heat Transfer, 3rd ed., section 4.2 and 8.4: F_ij as the cosine-weighted share of the
hemisphere of dA_i covered by A_j, averaged over A_i; Monte Carlo estimate, section 8.4). The
ray caster is :mod:`humv_usd.geometry.raycast`.

Rays (:func:`ray_samples`): origin on the triangle and direction drawn together from a 4-D
scrambled Sobol' sequence (Owen scrambling, fixed seed; scipy.stats.qmc), directions uniform on
the unit disk lifted onto the hemisphere (Malley's method: uniform on the disk is cosine-weighted
on the hemisphere; Pharr, Jakob & Humphreys 2016, Physically Based Rendering, 3rd ed., section
13.6.3), the same set for every triangle, rotated into its normal's frame (Duff et al. 2017,
"Building an orthonormal basis, revisited", JCGT 6(1)). Every face of one orientation with an
open view therefore gets exactly the same answer (the slab solver shares the work of identical
faces), and the estimate is deterministic.

For a long street canyon of height H and width W the floor centre's sky view factor is
sqrt(1 + (H/W)^2) - H/W (Johnson & Watson 1984; Oke 1988): the tests compare with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.stats import qmc

from humv_usd.geometry.raycast import first_faces, ray_caster

#: rays per triangle of a face (a quad face gets twice this many) for the view factors
VIEW_RAYS = 128
#: rays cast per batch (bounds the memory of the ray arrays, about 0.2 kB per ray)
CHUNK_RAYS = 262_144
#: zenith bins of the escaping rays [deg] (the sky's angular radiance is weighted per bin)
ZENITH_BINS_DEG = np.linspace(0.0, 90.0, 19)


def ray_samples(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n rays of one triangle: ((n, 3) barycentric origins, (n, 3) cosine-weighted unit
    directions about +z), jointly low-discrepancy (a 4-D scrambled Sobol' sequence with a
    fixed seed: origin and direction stratified together, so the estimate of a view factor
    converges about as 1/n, not 1/sqrt(n)).

    Origins: (u, v) folded into the triangle (u + v > 1 -> 1 - u, 1 - v). Directions: uniform
    on the unit disk (r = sqrt(s), phi = 2 pi t) lifted to the hemisphere (Malley's method),
    so each ray carries the weight 1/n of the cosine-weighted hemisphere."""
    m = max(int(np.ceil(np.log2(max(int(n), 1)))), 0)
    s = qmc.Sobol(4, scramble=True, seed=0).random_base2(m)[: int(n)]
    u, v = s[:, 0].copy(), s[:, 1].copy()
    fold = u + v > 1.0
    u[fold], v[fold] = 1.0 - u[fold], 1.0 - v[fold]
    r, phi = np.sqrt(s[:, 2]), 2.0 * np.pi * s[:, 3]
    d = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - r * r, 0.0))], axis=1)
    return np.stack([1.0 - u - v, u, v], axis=1), d


def orthonormal_frames(normals) -> tuple[np.ndarray, np.ndarray]:
    """Two tangents (t, b) per unit normal, (n, 3) each (Duff et al. 2017, branchless)."""
    n = np.asarray(normals, dtype=float)
    sign = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    bt = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, bt


@dataclass
class FaceViews:
    """What each face of a set of scene meshes sees (faces numbered mesh by mesh).

    Every array is a cosine-weighted share of the face's hemisphere, averaged over its area.

    Attributes
    ----------
    sky_bins : (F, B)
        Rays that escape upwards, by zenith bin (:data:`ZENITH_BINS_DEG`).
    open_sky_bins : (F, B)
        All upward rays by zenith bin, as if nothing stood around the face.
    ground_beyond, open_down : (F,)
        Rays that escape downwards (past the modelled ground: the ground beyond it); all
        downward rays.
    enclosed : (F,)
        Rays that hit the back of a face (the point lies inside a closed mesh: ground under a
        building); they see the inside, taken as a black body at the air temperature.
    to_faces : scipy.sparse.csr_matrix (F, F)
        F_ik, the share of face i's rays that first hit face k.
    rays : int
        Rays cast.
    """

    sky_bins: np.ndarray
    open_sky_bins: np.ndarray
    ground_beyond: np.ndarray
    open_down: np.ndarray
    enclosed: np.ndarray
    to_faces: sparse.csr_matrix
    rays: int

    @property
    def sky_view_factor(self) -> np.ndarray:
        """(F,) share of the hemisphere that is open sky [0-1] (Oke's sky view factor)."""
        return self.sky_bins.sum(axis=1)

    @property
    def open_sky_view(self) -> np.ndarray:
        """(F,) the same with nothing around, (1 + n_z) / 2 up to the ray estimate."""
        return self.open_sky_bins.sum(axis=1)

    def sky_ratio(self, weight=None) -> np.ndarray:
        """(F,) sky seen over the sky an unobstructed face sees, each zenith bin weighted by
        ``weight`` (B,) (the sky's radiance at the bin; None: isotropic); 1 where the face sees
        no sky in the open either."""
        w = np.ones(self.sky_bins.shape[1]) if weight is None else np.asarray(weight, float)
        seen, open_ = self.sky_bins @ w, self.open_sky_bins @ w
        return np.where(open_ > 0.0, seen / np.where(open_ > 0.0, open_, 1.0), 1.0)

    @property
    def ground_ratio(self) -> np.ndarray:
        """(F,) downward rays that see the ground beyond the model over all downward rays."""
        d = self.open_down
        return np.where(d > 0.0, self.ground_beyond / np.where(d > 0.0, d, 1.0), 1.0)

    @property
    def coupled(self) -> np.ndarray:
        """(F,) whether a face sees another face."""
        return np.diff(self.to_faces.indptr) > 0


def face_views(points, triangles, tri_face, n_faces: int, rays=VIEW_RAYS, eps: float | None = None):
    """:class:`FaceViews` of the faces of one triangle soup (all scene meshes together).

    Parameters
    ----------
    points : (P, 3) [m]
    triangles : (T, 3)
    tri_face : (T,)
        Face of each triangle (0 .. n_faces - 1).
    n_faces : int
    rays : int or (T,) ints
        Rays per triangle.
    eps : float, optional
        Offset of the ray origins along the normal [m] (default: 2e-5 of the scene's diagonal
        + 0.1 mm, as the shadow rays).
    """
    pts = np.asarray(points, dtype=float)
    tris = np.asarray(triangles, dtype=np.int64)
    tri_face = np.asarray(tri_face, dtype=np.int64)
    v = pts[tris]
    cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0.0
    normal = cross / np.maximum(2.0 * area, 1e-300)[:, None]
    face_area = np.bincount(tri_face, area, n_faces)
    share = np.where(keep, area / np.maximum(face_area[tri_face], 1e-300), 0.0)  # of its face
    n_rays = np.broadcast_to(np.asarray(rays, dtype=np.int64), (len(tris),))
    if eps is None:
        # relative to the scene's size, capped for a ground that reaches the horizon (issue 30)
        eps = 2e-5 * min(float(np.linalg.norm(np.ptp(pts, axis=0))), 150.0) + 1e-4 if len(pts) else 1e-4
    t_axis, b_axis = orthonormal_frames(normal)
    caster = ray_caster(pts, tris)
    nb = len(ZENITH_BINS_DEG) - 1
    sky = np.zeros(n_faces * nb)
    open_sky = np.zeros(n_faces * nb)
    beyond = np.zeros(n_faces)
    down = np.zeros(n_faces)
    inside = np.zeros(n_faces)
    rows, cols, vals = [], [], []
    cast = 0
    for n in np.unique(n_rays[keep]):
        bary, local = ray_samples(int(n))
        chunk = max(1, CHUNK_RAYS // int(n))
        tri_ids = np.flatnonzero(keep & (n_rays == n))
        cast += len(tri_ids) * int(n)
        for a in range(0, len(tri_ids), chunk):
            ids = tri_ids[a : a + chunk]
            d = (
                local[None, :, 0:1] * t_axis[ids][:, None, :]
                + local[None, :, 1:2] * b_axis[ids][:, None, :]
                + local[None, :, 2:3] * normal[ids][:, None, :]
            ).reshape(-1, 3)
            o = (np.einsum("rk,tkx->trx", bary, v[ids]) + eps * normal[ids][:, None, :]).reshape(-1, 3)
            hit = first_faces(caster, o, d)
            face = np.repeat(tri_face[ids], n)
            w = np.repeat(share[ids] / n, n)
            up = d[:, 2] > 0.0
            zen = np.degrees(np.arccos(np.clip(d[:, 2], 0.0, 1.0)))
            zbin = np.clip(np.searchsorted(ZENITH_BINS_DEG, zen, side="right") - 1, 0, nb - 1)
            key = face * nb + zbin
            open_sky += np.bincount(key[up], w[up], n_faces * nb)
            esc = hit < 0
            sky += np.bincount(key[up & esc], w[up & esc], n_faces * nb)
            down += np.bincount(face[~up], w[~up], n_faces)
            beyond += np.bincount(face[~up & esc], w[~up & esc], n_faces)
            back = np.zeros(len(hit), dtype=bool)
            back[~esc] = np.einsum("ij,ij->i", d[~esc], normal[hit[~esc]]) > 0.0
            inside += np.bincount(face[back], w[back], n_faces)
            front = ~esc & ~back
            rows.append(face[front])
            cols.append(tri_face[hit[front]])
            vals.append(w[front])
    to = sparse.csr_matrix(
        (
            np.concatenate(vals) if vals else np.zeros(0),
            (
                np.concatenate(rows) if rows else np.zeros(0, int),
                np.concatenate(cols) if cols else np.zeros(0, int),
            ),
        ),
        shape=(n_faces, n_faces),
    )
    to.sum_duplicates()
    return FaceViews(
        sky.reshape(n_faces, nb),
        open_sky.reshape(n_faces, nb),
        beyond,
        down,
        inside,
        to,
        int(cast),
    )
