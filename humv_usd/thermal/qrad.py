"""Per-facet absorbed radiation q_rad (seed section 2.2.2, Eq. 3-4) from a radiance map.

Per-facet absorbed radiation (seed Eq. 3, summed over bands as Eq. 4 does):

    q_i,b = alpha_i,b [ sum_j L_b(w_j) max(n_i . w_j, 0) Omega_j 1_ij  +  E_sun,b max(n_i . s, 0) V_i ]

where 1_ij is 1 when the ray from facet i towards w_j reaches the far field. The sun's term is
resolved inside the facet: max(n_i . s, 0) V_i is the facet's mean over stratified points of the
cosine with the interpolated smooth (vertex) normal times the point's visibility (see
``sun_normals`` and ``sun_points`` of :func:`absorbed_radiation`). A blocked ray sees
the face it hits: its per-band leaving radiance (scene surfaces, or the mesh's own faces when the
caller gives their radiance; 0 as in the seed otherwise). Three methods:

* ``brute`` (reference, the seed's): every map pixel in a facet's upper hemisphere x every facet,
  one embree occlusion ray each, in chunks.
* ``fast``: control variate. The unoccluded part T (the cosine-convolved map, an irradiance
  table on a lat-long grid of normals, interpolated; computed exactly by FFT in azimuth) is
  exact up to interpolation; K cosine-weighted rays per facet (Hammersley points with a random
  Cranley-Patterson rotation per facet) see y = L_hit or, when they escape, x = L_map(w), and
  E = beta T + pi/K sum_k (y_k - beta x_k). The coefficient beta per facet and band is the
  regression slope Cov(x, y) / Var(x) of the facet's edge neighbours' rays (independent of its
  own rays, so E stays unbiased): ~1 for open facets (no Monte Carlo error at all when nothing
  is in the way), ~0 for facets buried under one uniform occluder (skin under a garment: also
  exact), in between for partly occluded ones.
* ``adaptive``: the same estimator with a pilot of rays per facet and the rest of the ray
  budget spread by Neyman allocation to the facets whose pilot rays (or neighbours' pilot rays)
  disagree, i.e. the partly occluded ones.

Both ray methods report their own Monte Carlo error (per-ray sample variance) and can replay a
recorded visibility (which face each ray hits) for an unmoved or barely moved mesh with new
radiances (``cache``). Ray casting: :mod:`humv_usd.geometry.raycast` (embreex directly,
single-threaded, or Mitsuba). Maps: :mod:`humv_usd.thermal.radiance_map`.

Units: SI; radiance [W m^-2 sr^-1], irradiance and absorbed flux [W m^-2], temperature [K].
"""

from __future__ import annotations

import numpy as np
import trimesh

from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.geometry.raycast import CHUNK_RAYS, first_faces
from humv_usd.thermal.radiance_map import (
    RadianceMap,
    cosine_weights,
    interp_table,
    irradiance_table,
    map_shape,
)
from humv_usd.thermal.scene_radiance import mesh_caster, ray_offset

_CHUNK_CV_RAYS = 1_048_576  # rays per chunk of the ray methods (moments in float64)


def _facet_hits(occ, facet, centroids, normals, directions, offset, origins=None, hit=None):
    """First face hit by rays leaving facets (``origins``: the offset ray origins when the
    caller has them; ``hit``: the first hits when already cast); a ray that hits its own facet
    (float32 precision of embree on large scenes) is re-cast from farther out."""
    if hit is None:
        if origins is None:
            origins = centroids[facet] + normals[facet] * offset
        hit = first_faces(occ.intersector, origins, directions)
    for k in (10.0, 100.0, 1000.0):
        own = np.nonzero(hit == facet)[0]
        if len(own) == 0:
            break
        f = facet[own]
        hit[own] = first_faces(occ.intersector, centroids[f] + normals[f] * (k * offset), directions[own])
    return hit


class _Occluders:
    """The facet mesh + scene as one embree scene with per-band leaving radiance per face."""

    def __init__(self, mesh, n_bands, mesh_radiance, scene, backend="embree"):
        self.n_mesh = len(mesh.faces)
        rad_mesh = (
            np.zeros((n_bands, self.n_mesh))
            if mesh_radiance is None
            else np.broadcast_to(np.asarray(mesh_radiance, dtype=float), (n_bands, self.n_mesh))
        )
        if scene is not None and len(scene.mesh.faces):
            combined = trimesh.util.concatenate([mesh, scene.mesh])
            self.radiance = np.concatenate([rad_mesh, np.asarray(scene.radiance, dtype=float)], axis=1)
        else:
            combined, self.radiance = mesh, rad_mesh
        self._combined, self._backend, self._intersector = combined, backend, None
        self.extents = combined.extents

    @property
    def intersector(self):
        """The ray caster, built on first use (a cached replay casts no rays)."""
        if self._intersector is None:
            self._intersector = mesh_caster(self._combined, self._backend)
        return self._intersector


def _absorptivity(absorptivity, n_bands, n_faces):
    a = np.asarray(absorptivity, dtype=float)
    if a.ndim == 1 and a.shape[0] == n_bands:
        a = a[:, None]
    return np.broadcast_to(a, (n_bands, n_faces))


SUN_NORMALS = ("smooth", "flat")

#: scene size [m] above which the default ray offset stops growing: a ground to the horizon
#: (issue 30, 40 km across) made it 5.7 cm, so a person's facets escaped the shadows of their
#: own nearby parts (shoes 3.5 K warmer in the sun); 150 m keeps the 0.15 mm a 100 m ground gave
#: (as thermal.surfaces.EPS_SCENE_SIZE_CAP_M for the scene's own rays)
OFFSET_SCENE_SIZE_CAP_M = 150.0


def corner_normals(mesh, crease_deg: float = 60.0) -> np.ndarray:
    """(F, 3, 3) unit shading normal at each corner of each face: the mean of the normals of the
    faces around the corner's vertex weighted by their angle at the vertex (Gouraud 1971,
    IEEE Trans. Computers C-20, 623; angle weights: Thuermer & Wuethrich 1998, J. Graphics
    Tools 3(1), 43), over those faces only whose normal is within ``crease_deg`` of the face's
    own (Blender's auto smooth), so a fold or a sole's edge stays sharp while a coarse
    garment's faces turn smooth. Angle weights, unlike area weights, do not depend on how a
    polygon is cut into triangles (a quad split along one diagonal tilts area-weighted normals
    towards the side with two triangles: 2.5 deg on a 24-sided cylinder).

    Vertices at the same position (a seam split for UVs) count as one; distinct parts that touch
    (skin under a garment) face other ways and stay apart through the crease test. A degenerate
    face keeps its (usable) flat normal at its corners."""
    normals = _usable_normals(mesh)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    n_f = len(faces)
    if n_f == 0:
        return np.zeros((0, 3, 3))
    v = np.asarray(mesh.vertices, dtype=float)
    scale = max(float(np.linalg.norm(np.ptp(v, axis=0))), 1e-12)
    _, vid = np.unique(np.round(v / (1e-9 * scale)), axis=0, return_inverse=True)
    cv = vid.reshape(-1)[faces.reshape(-1)]  # (3F,) position id of each corner
    order = np.argsort(cv, kind="stable")  # corners grouped by vertex
    deg = np.bincount(cv)
    start = np.concatenate([[0], np.cumsum(deg)[:-1]])
    d = deg[cv]  # corners (faces) around each corner's vertex
    corner = np.repeat(np.arange(3 * n_f), d)
    k = np.arange(len(corner)) - np.repeat(np.cumsum(d) - d, d)
    other = order[start[cv][corner] + k]  # a corner at the same vertex
    f, g = corner // 3, other // 3
    angle = np.nan_to_num(np.asarray(mesh.face_angles, dtype=float).reshape(-1))
    w = angle[other] * (np.einsum("ij,ij->i", normals[f], normals[g]) >= np.cos(np.radians(crease_deg)))
    out = np.stack([np.bincount(corner, w * normals[g, c], minlength=3 * n_f) for c in range(3)], axis=1)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    flat = np.repeat(normals, 3, axis=0)
    out = np.where(length > 1e-9, out / np.maximum(length, 1e-300), flat)
    return out.reshape(n_f, 3, 3)


def face_points(m: int) -> np.ndarray:
    """(m^2, 3) barycentric coordinates of the centroids of the m^2 congruent triangles into
    which an m-fold subdivision of each edge cuts a triangle: stratified points of equal weight
    (the composite centroid rule, exact for a linear integrand; m = 1 is the centroid)."""
    up = [((i + 1 / 3) / m, (j + 1 / 3) / m) for i in range(m) for j in range(m - i)]
    down = [((i + 2 / 3) / m, (j + 2 / 3) / m) for i in range(m - 1) for j in range(m - 1 - i)]
    b12 = np.array(up + down, dtype=float).reshape(-1, 2)
    return np.c_[1.0 - b12.sum(axis=1), b12]


def _shadow_origins(tri, cn, bary):
    """Shadow-ray origins at barycentric points of triangles ``tri`` (n, 3, 3) lifted onto the
    curved surface that the corner normals ``cn`` (n, 3, 3) describe: each corner's tangent
    plane is applied where it lies above the point (convex parts), the result interpolated
    (Hanika 2021, Hacking the shadow terminator, Ray Tracing Gems II, ch. 4). Without the lift
    a point near the terminator of a coarse convex mesh is shadowed by its own neighbours
    although its smooth normal faces the sun (a dark staircase along the terminator).

    Returns (n, P, 3) [m]."""
    p = np.matmul(bary, tri)
    lift = np.zeros_like(p)
    for c in range(3):
        dist = np.matmul(p, cn[:, c, :, None])[..., 0] - np.einsum("nx,nx->n", tri[:, c], cn[:, c])[:, None]
        lift -= bary[None, :, c, None] * np.minimum(dist, 0.0)[..., None] * cn[:, None, c]
    return p + lift


def _sun_visible(occ, facet, origins, s, normals, offset):
    """Whether rays from ``origins`` (n, 3) of facets ``facet`` (n,) towards the sun ``s``
    escape. The ray leaves along the facet's flat normal by ``offset``. A ray that hits its own
    facet although the facet faces the sun (float32 precision of embree on large scenes) is
    re-cast from farther out; one whose facet faces away from the sun (its smooth normal does
    not) is shadowed by it: with the origin lifted onto the smooth surface
    (:func:`_shadow_origins`) that happens only where the surface is concave, where the rising
    surface around the point, which the facet stands for, does cast the shadow."""
    n = normals[facet]
    o = origins + n * offset
    hit = first_faces(occ.intersector, o, np.ascontiguousarray(np.broadcast_to(s, o.shape)))
    for k in (10.0, 100.0, 1000.0):
        own = np.nonzero((hit == facet) & (n @ s > 0))[0]
        if len(own) == 0:
            break
        o2 = o[own] + n[own] * (k * offset)
        hit[own] = first_faces(occ.intersector, o2, np.ascontiguousarray(np.broadcast_to(s, o2.shape)))
    return hit < 0


def _sun_factors(mesh, normals, s, occ, offset, facets, sun_normals, sun_points, crease_deg):
    """Mean over ``sun_points`` stratified points of each facet of max(n . s, 0) V, with n the
    interpolated smooth normal ('smooth') or the flat one ('flat') and V the point's sun
    visibility (0 where every n . s <= 0). Returns (len(facets),)."""
    m = int(round(np.sqrt(sun_points)))
    bary = face_points(m)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if sun_normals == "smooth":
        cn = corner_normals(mesh, crease_deg)[facets]
        npnt = np.matmul(bary, cn)
        npnt /= np.maximum(np.linalg.norm(npnt, axis=2, keepdims=True), 1e-300)
        cos = npnt @ s  # (n, P)
    else:
        cn = np.repeat(normals[facets, None, :], 3, axis=1)
        cos = np.repeat((normals[facets] @ s)[:, None], len(bary), axis=1)
    cos = np.maximum(cos, 0.0)
    keep = np.nonzero(cos.max(axis=1) > 0)[0]
    factor = np.zeros(len(facets))
    if len(keep) == 0:
        return factor
    tri = np.asarray(mesh.vertices, dtype=float)[faces[facets[keep]]]
    origins = _shadow_origins(tri, cn[keep], bary) if sun_normals == "smooth" else None
    if origins is None:
        origins = np.matmul(bary, tri)
    fk, pk = np.nonzero(cos[keep] > 0)
    vis = _sun_visible(occ, facets[keep][fk], origins[fk, pk], s, normals, offset)
    factor[keep] = np.bincount(fk, cos[keep][fk, pk] * vis, len(keep))
    return factor / len(bary)


def _sun_term(
    env, mesh, normals, occ, offset, cache=None, sun_normals="smooth", sun_points=16, crease_deg=60.0
):
    """Beam irradiance per band and facet [W m^-2]: E_sun times the facet's mean over
    ``sun_points`` stratified points of max(n . s, 0) V (seed Eq. 3's sun term resolved inside
    the facet): the facet's temperature is one value, but the sun it absorbs is the mean over
    the smooth surface that the facets approximate, and a shadow edge that crosses a facet
    takes its area fraction, not all or nothing."""
    out = np.zeros((env.n_bands, len(normals)))
    if env.sun_direction is None or not np.any(env.sun_irradiance > 0):
        return out
    s = np.asarray(env.sun_direction, dtype=float)
    sun_key = (cache or {}).get("key"), (cache or {}).get("generation"), tuple(s), sun_normals, sun_points
    if cache is not None and cache.get("sun_key") == sun_key:
        factor = cache["sun_factor"]
    else:
        factor = _sun_factors(
            mesh, normals, s, occ, offset, np.arange(len(normals)), sun_normals, sun_points, crease_deg
        )
    if cache is not None:
        cache.update(sun_key=sun_key, sun_factor=factor)
    out[:] = np.asarray(env.sun_irradiance)[:, None] * factor
    return out


def _diffuse_brute(env, centroids, normals, occ, offset):
    d, omega = env.geometry()
    lmap = env.flat()
    n_pix = len(d)
    n_f = len(normals)
    out = np.zeros((env.n_bands, n_f))
    chunk = max(1, CHUNK_RAYS // max(1, n_pix // 2))
    for a in range(0, n_f, chunk):
        b = min(n_f, a + chunk)
        w = cosine_weights(normals[a:b], d, omega, normalize=True)  # (fc, P), rows sum to pi
        out[:, a:b] = (w @ lmap.T).T  # unoccluded part
        fi, pj = np.nonzero(w > 0)
        hit = _facet_hits(occ, a + fi, centroids, normals, d[pj], offset)
        m = hit >= 0
        if np.any(m):  # blocked rays see the hit face instead of the far field (1_ij = 0)
            wij = w[fi[m], pj[m]]
            delta = occ.radiance[:, hit[m]] - lmap[:, pj[m]]
            for k in range(env.n_bands):
                out[k, a:b] += np.bincount(fi[m], weights=wij * delta[k], minlength=b - a)
    return out


def _usable_normals(mesh) -> np.ndarray:
    """The facets' unit normals; a degenerate facet (zero area, e.g. a garment triangle folded flat
    in one frame of a long walk) has none (trimesh gives a zero vector), which would turn every
    direction built on it into NaN. It gets +z instead: it absorbs a finite flux and, having no
    area, weighs nothing in the area-weighted sums (MRT, segment means)."""
    normals = np.array(mesh.face_normals, dtype=float)
    bad = ~(np.abs(np.linalg.norm(normals, axis=1) - 1.0) < 1e-3)
    if np.any(bad):
        normals[bad] = (0.0, 0.0, 1.0)
    return normals


def _tangent_frames(normals):
    helper = np.where(np.abs(normals[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    t = np.cross(helper, normals)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(normals, t)


def _stratified_unit_square(n, k, rng):
    """(n, k, 2) jittered-grid samples, independent jitter per row (facet)."""
    m = int(np.sqrt(k))
    g = np.stack(np.meshgrid(np.arange(m), np.arange(m), indexing="ij"), -1).reshape(-1, 2)
    u = (g[None] + rng.random((n, m * m, 2))) / m
    return np.concatenate([u, rng.random((n, k - m * m, 2))], axis=1) if k > m * m else u


def _radical_inverse2(j) -> np.ndarray:
    """Van der Corput radical inverse in base 2 of integers j (< 2**32)."""
    j = np.asarray(j, dtype=np.uint64)
    out = np.zeros(j.shape)
    f = 0.5
    while np.any(j):
        out += f * (j & np.uint64(1))
        j = j >> np.uint64(1)
        f *= 0.5
    return out


def _hammersley(k) -> np.ndarray:
    """(k, 2) Hammersley points ((j + 1/2) / k, phi_2(j)) in the unit square (a (0, m, 2)-net
    for k = 2^m; Niederreiter 1992, Random Number Generation and Quasi-Monte Carlo Methods,
    ch. 3-4)."""
    j = np.arange(int(k))
    return np.stack([(j + 0.5) / k, _radical_inverse2(j)], axis=1)


SAMPLERS = ("hammersley", "jitter")


def _cosine_directions(f, k, rng, frames, sampler="hammersley"):
    """(len(f) * k, 3) float32 cosine-weighted directions around each facet's normal.

    The unit square (u, v) maps to the hemisphere by Malley's method (r = sqrt(u),
    phi = 2 pi v, z = sqrt(1 - u)). ``sampler``:

    * ``'hammersley'``: k Hammersley points with an independent uniform Cranley-Patterson
      rotation (u, v) -> ({u + s}, {v + t}) per facet (Cranley & Patterson 1976, SIAM J.
      Numer. Anal. 13, 904): every point is uniform on the square, so the per-facet mean is
      unbiased, while the points stay evenly spread (randomised QMC; Owen 2013, ch. 17). The
      shift in v is a rotation of the facet's tangent frame, so the point set's sines and
      cosines are computed once for all facets.
    * ``'jitter'``: a sqrt(k) x sqrt(k) jittered grid, independent jitter per ray.
    """
    t32, bt32, n32 = frames
    fc = len(f)
    if sampler == "jitter":
        u = _stratified_unit_square(fc, k, rng).astype(np.float32)
        r = np.sqrt(u[..., 0])
        ang = np.float32(2.0 * np.pi) * u[..., 1]
        z = np.sqrt(np.float32(1.0) - u[..., 0])
        x, y = r * np.cos(ang), r * np.sin(ang)
        t, bt = t32[f], bt32[f]
    elif sampler == "hammersley":
        p = _hammersley(k)
        shift = rng.random((fc, 2))
        u = (p[None, :, 0] + shift[:, :1]).astype(np.float32)
        u[u >= 1.0] -= np.float32(1.0)
        u = np.minimum(u, np.float32(1.0 - 1e-7))
        r = np.sqrt(u)
        z = np.sqrt(np.float32(1.0) - u)
        x = r * np.cos(2.0 * np.pi * p[:, 1]).astype(np.float32)
        y = r * np.sin(2.0 * np.pi * p[:, 1]).astype(np.float32)
        rot = 2.0 * np.pi * shift[:, 1:]
        c, s = np.cos(rot).astype(np.float32), np.sin(rot).astype(np.float32)
        t = c * t32[f] + s * bt32[f]
        bt = c * bt32[f] - s * t32[f]
    else:
        raise ValueError(f"invalid sampler {sampler!r}: expected one of {SAMPLERS}")
    d = np.empty((fc, k, 3), dtype=np.float32)
    nf = n32[f]
    for c in range(3):  # float32 is what the ray caster takes; half the memory traffic
        d[..., c] = x * t[:, None, c] + y * bt[:, None, c] + z * nf[:, None, c]
    return d.reshape(-1, 3)


def _latlong_index32(d, resolution) -> np.ndarray:
    """:func:`latlong_index` in float32 (the ray directions' precision), for many rays."""
    n_theta, n_phi = map_shape(resolution)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.arctan2(d[:, 1], d[:, 0])
    phi[phi < 0] += np.float32(2.0 * np.pi)
    i = np.minimum((theta * np.float32(n_theta / np.pi)).astype(np.int64), n_theta - 1)
    j = np.minimum((phi * np.float32(n_phi / (2.0 * np.pi))).astype(np.int64), n_phi - 1)
    return i * n_phi + j


def _ray_moments(env, radiance, d, hit, fc, k):
    """Per-facet sums of v = (x, y) and of v v^T over k consecutive rays per facet, with
    x_b = L_map,b(w) the map's radiance in the ray's direction and y_b the radiance the ray
    actually sees: the hit face's, or, when it misses every face, the far field's (the map's
    ``sky_radiance``; x_b for a map without it). The map shows the scene as its centre sees it,
    and a facet away from the centre sees past a roof line or wall edge that the map shows in
    that direction: with x_b there, the cap of the demo person (0.64 m above the centre) took
    the sunlit warehouse wall for the sky above its roof line, 0.14 K warm on average.

    Returns (S1 (fc, 2B), S2 (fc, 2B, 2B)) in float64."""
    nb, nr = env.n_bands, radiance.shape[1]
    pix = _latlong_index32(d, env.resolution)
    lookup = np.concatenate([env.flat(), np.asarray(radiance, dtype=float)], axis=1)
    v = np.empty((2 * nb, len(pix)))
    np.take(lookup, pix, axis=1, out=v[:nb])
    if env.sky_radiance is None:
        np.take(lookup, np.where(hit >= 0, hit + len(lookup[0]) - nr, pix), axis=1, out=v[nb:])
    else:
        far = np.concatenate([env.sky_radiance.reshape(nb, -1), np.asarray(radiance, dtype=float)], axis=1)
        np.take(far, np.where(hit >= 0, hit + len(far[0]) - nr, pix), axis=1, out=v[nb:])
    v = v.reshape(2 * nb, fc, k)
    s2 = np.empty((fc, len(v), len(v)))
    for i in range(len(v)):
        for j in range(i, len(v)):
            s2[:, i, j] = s2[:, j, i] = np.einsum("fk,fk->f", v[i], v[j])
    return v.sum(axis=2).T, s2


class _Moments:
    """Running per-facet ray moments (count, S1, S2) for the control-variate estimator."""

    def __init__(self, n_f, n_bands):
        self.n = np.zeros(n_f)
        self.s1 = np.zeros((n_f, 2 * n_bands))
        self.s2 = np.zeros((n_f, 2 * n_bands, 2 * n_bands))

    def add(self, env, radiance, f, k, d, hit):
        s1, s2 = _ray_moments(env, radiance, d, hit, len(f), k)
        self.n[f] += k
        self.s1[f] += s1
        self.s2[f] += s2


def _cast_facets(env, centroids, normals, occ, offset, facets, k, rng, frames, local, moments, record=None):
    """k cosine-weighted rays from each facet in ``facets``; their moments go into
    ``moments``; with a ``record`` list, appends (facets, k, directions, faces hit) per chunk."""
    chunk = max(1, _CHUNK_CV_RAYS // k)
    for a in range(0, len(facets), chunk):
        f = facets[a : a + chunk]
        d = _cosine_directions(f, k, rng, frames)
        fr = np.repeat(f, k)
        it = occ.intersector
        if local is not None and hasattr(it, "first_hit_local"):
            hit = it.first_hit_local(np.repeat(local[f], k, axis=0), d)
        else:
            hit = None
        hit = _facet_hits(occ, fr, centroids, normals, d, offset, hit=hit)
        if record is not None:
            record.append((f.astype(np.int32), int(k), d, hit.astype(np.int32)))
        moments.add(env, occ.radiance, f, k, d, hit)


def _neighbour_matrix(mesh):
    """Sparse (F, F) 0/1 matrix of edge-adjacent facets (None when no facet has one)."""
    from scipy import sparse

    n_f = len(mesh.faces)
    try:
        adj = np.asarray(mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
    except Exception:  # pragma: no cover - degenerate meshes
        return None
    if len(adj) == 0:
        return None
    rows = np.r_[adj[:, 0], adj[:, 1]]
    cols = np.r_[adj[:, 1], adj[:, 0]]
    a = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_f, n_f))
    a.data[:] = 1.0  # duplicate pairs count once
    return a


def _cv_estimate(moments, e_table, weight, neighbours):
    """Control variate with a per-facet coefficient beta fitted on the neighbours' rays.

    For facet i and band b, with x = L_map,b(w) and y = L_b(w) (what the ray sees) over
    cosine-weighted directions w, E[pi y] is the occluded irradiance and E[pi x] = T_b(n_i), the
    irradiance table. The estimator

        E_b = beta_b T_b + pi (mean(y_b) - beta_b mean(x_b))

    is unbiased for any beta_b independent of facet i's own rays (Glasserman 2004, Monte Carlo
    Methods in Financial Engineering, section 4.1; Owen 2013, Monte Carlo theory, methods and
    examples, section 8.9). The variance-optimal beta_b = Cov(x_b, y_b) / Var(x_b) is taken
    from the pooled rays of the facet's edge neighbours (which see nearly the same hemisphere
    but are independent of its own rays), clipped to [0, 1]: beta = 1 is the plain difference
    estimator (exact for an open facet, y = x), beta = 0 plain Monte Carlo of y (exact for a
    facet buried under one uniform occluder, e.g. skin under a garment). A facet without edge
    neighbours (e.g. a triangle soup) keeps beta = 1.

    Returns (per-band flux (B, F), variance of the ``weight``-summed flux (F,)).
    """
    nb = e_table.shape[0]
    n, s1, s2 = moments.n, moments.s1, moments.s2
    bi = np.arange(nb)
    beta = np.ones((len(n), nb))
    if neighbours is not None:
        nn = neighbours @ n
        p1 = neighbours @ s1
        p2 = (neighbours @ s2.reshape(len(n), -1)).reshape(s2.shape)
        with np.errstate(invalid="ignore", divide="ignore"):
            mp = p1 / nn[:, None]
            cxx = p2[:, bi, bi] / nn[:, None] - mp[:, bi] ** 2
            cxy = p2[:, bi, nb + bi] / nn[:, None] - mp[:, bi] * mp[:, nb + bi]
            ok = (nn[:, None] > 1) & (cxx > 1e-12 * np.maximum(mp[:, bi] ** 2, 1e-300))
            beta = np.where(ok, np.clip(cxy / cxx, 0.0, 1.0), 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        m = s1 / n[:, None]
        est = beta.T * e_table + np.pi * (m[:, nb:] - beta * m[:, :nb]).T
        cov = (s2 / n[:, None, None] - m[:, :, None] * m[:, None, :]) * (n / np.maximum(n - 1.0, 1.0))[
            :, None, None
        ]
    w = np.broadcast_to(np.asarray(weight, dtype=float), e_table.shape).T
    c = np.concatenate([-w * beta, w], axis=1)
    var_z = np.einsum("fi,fij,fj->f", c, cov, c)
    return est, np.pi**2 * np.maximum(var_z, 0.0) / n


def _float32_frames(normals):
    t, bt = _tangent_frames(normals)
    return tuple(np.asarray(x, dtype=np.float32) for x in (t, bt, normals))


def _local_origins(occ, centroids, normals, offset):
    it = occ.intersector
    if hasattr(it, "first_hit_local"):
        return it.local(centroids + normals * offset)
    return None


#: facets whose diffuse estimate is repeated with independent rays to measure the estimator's
#: real error (:func:`_replicate_differences`); ~6 % more rays on a 16,000-facet person
REPLICATE_FACETS = 1024


def _replicate_differences(ctx, mom, casts, n_rep, seed, e_table, weight, neighbours, est):
    """Differences, on ``n_rep`` facets drawn at random, between the diffuse estimate and a
    second one from independent rays (a new Cranley-Patterson rotation of the same point
    sets, the same rays per facet); the other facets keep their rays, so each facet's control
    variate coefficient is fitted as before. ``n_rep``: a count, or the facets themselves
    (e.g. drawn per part by the caller).

    The two estimates are independent and identically distributed, so d_i^2 / 2 is an unbiased
    estimate of facet i's variance, and its mean over facets drawn uniformly estimates the mean
    variance over all facets: the error of randomised quasi-Monte Carlo is measured by
    independent replicates (Owen 2013, Monte Carlo theory, methods and examples, ch. 17;
    L'Ecuyer & Lemieux 2002, in Modeling Uncertainty, 419). The per-ray sample variance of
    :func:`_cv_estimate` treats the rays as independent and ignores their stratification: on
    the demo's person it overstated the face-temperature noise about six times.

    ``casts``: (rays, facets) of every cast of the estimate. Returns (facets (n,), d (n,))
    for the ``weight``-summed flux [W m^-2]."""
    n_f = len(mom.n)
    rng = np.random.default_rng([int(seed), 0x5EED])
    if np.ndim(n_rep) == 0:
        facets = np.sort(rng.choice(n_f, size=min(int(n_rep), n_f), replace=False))
    else:
        facets = np.unique(np.asarray(n_rep, dtype=np.int64))
    rep = _Moments(n_f, mom.s1.shape[1] // 2)
    rep.n[:], rep.s1[:], rep.s2[:] = mom.n, mom.s1, mom.s2
    rep.n[facets], rep.s1[facets], rep.s2[facets] = 0.0, 0.0, 0.0
    chosen = np.zeros(n_f, dtype=bool)
    chosen[facets] = True
    for k, f in casts:
        f = f[chosen[f]]
        if len(f):
            _cast_facets(*ctx[:5], f, int(k), rng, *ctx[5:], rep)
    e_rep, _ = _cv_estimate(rep, e_table, weight, neighbours)
    w = np.broadcast_to(np.asarray(weight, dtype=float), e_table.shape)
    d = (w[:, facets] * (e_rep[:, facets] - est[:, facets])).sum(axis=0)
    return facets, d


def _diffuse_fast(
    env,
    centroids,
    normals,
    occ,
    offset,
    rays,
    seed,
    table,
    weight,
    record=None,
    neighbours=None,
    replicate=None,
):
    """Control variate: the irradiance table (unoccluded part) + ``rays`` stratified
    cosine-weighted rays per facet (:func:`_cv_estimate`).

    ``replicate``: a dict with ``n``, filled with the facets and differences of
    :func:`_replicate_differences`.

    Returns (per-band flux (bands, F), variance of the ``weight``-summed flux (F,))."""
    mom = _Moments(len(normals), env.n_bands)
    ctx = (
        env,
        centroids,
        normals,
        occ,
        offset,
        _float32_frames(normals),
        _local_origins(occ, centroids, normals, offset),
    )
    everyone = np.arange(len(normals))
    _cast_facets(*ctx[:5], everyone, int(rays), np.random.default_rng(seed), *ctx[5:], mom, record)
    e_table = interp_table(table, normals)
    est, var = _cv_estimate(mom, e_table, weight, neighbours)
    if replicate is not None:
        replicate["facets"], replicate["d"] = _replicate_differences(
            ctx, mom, [(int(rays), everyone)], replicate["n"], seed, e_table, weight, neighbours, est
        )
    return est, var


_LEVELS = (16, 32, 64, 128, 256, 512, 1024, 2048, 4096)  # powers of two: Hammersley sets are (0, m, 2)-nets


def _diffuse_adaptive(
    env,
    centroids,
    normals,
    occ,
    offset,
    rays,
    seed,
    table,
    pilot,
    weight,
    max_rays,
    record=None,
    neighbours=None,
    replicate=None,
    importance=None,
):
    """Control variate with two-stage (Neyman) allocation of the correction rays.

    Stage 1: ``pilot`` stratified rays per facet. Stage 2: the remaining budget
    (rays - pilot) x facets goes to facets in proportion to their sample standard deviation
    of the per-ray control-variate term relative to the facet's flux, K_i ~ s_i / q_i, which
    minimises sum_i Var(q_i) / q_i^2 for a fixed ray count (Neyman 1934; Cochran 1977,
    Sampling Techniques, section 5.5). Facets whose pilot rays all agree (typically: nothing in
    the way, or one uniform occluder everywhere) and whose neighbours' pilot rays agree too get
    no more rays. ``importance`` (F,) >= 0, when given, replaces the relative objective by
    sum_i w_i Var(q_i) with the caller's weights w_i (e.g. the variance of an area-weighted
    face temperature per unit flux variance): the optimum is then K_i ~ sqrt(w_i) s_i; 0 for a
    facet whose flux nobody uses (skin under a garment, whose temperature the garment's
    balance sets) leaves it its pilot rays.

    Returns (per-band flux (bands, F), variance of the ``weight``-summed flux (F,), rays per
    facet (F,)).
    """
    n_f = len(normals)
    e_table = interp_table(table, normals)  # unoccluded part
    rng = np.random.default_rng(seed)
    frames = _float32_frames(normals)
    local = _local_origins(occ, centroids, normals, offset)
    mom = _Moments(n_f, env.n_bands)
    _cast_facets(env, centroids, normals, occ, offset, np.arange(n_f), pilot, rng, frames, local, mom, record)
    e1, var1 = _cv_estimate(mom, e_table, weight, neighbours)
    w = np.asarray(weight, dtype=float)
    # pilot estimate of the facet's flux, floored at a quarter of the median so that facets
    # buried inside other geometry (q -> 0) do not take the whole budget
    score = np.sqrt(var1 * pilot)  # the per-ray standard deviation s_i
    if importance is None:
        q1 = np.abs(np.broadcast_to(w, e1.shape) * e1).sum(axis=0)
        score = score / np.maximum(q1, 0.25 * max(float(np.median(q1)), 1e-30))
    # a facet's own pilot can miss a small opening (all rays hit one uniform occluder, zero
    # sample variance); its neighbours see nearly the same hemisphere, so each facet takes the
    # larger of its own score and the mean score of its 8 nearest facets
    if n_f > 1:
        from scipy.spatial import cKDTree

        _, nb = cKDTree(centroids).query(centroids, min(8, n_f))
        score = np.maximum(score, score[nb].mean(axis=1))
    if importance is not None:
        score = score * np.sqrt(np.clip(np.asarray(importance, dtype=float), 0.0, None))
    budget = max(0, int(rays) - pilot) * n_f
    extra = np.zeros(n_f, dtype=np.int64)
    if budget > 0 and score.sum() > 0:
        want = budget * score / score.sum()
        levels = np.array([lv for lv in _LEVELS if lv <= max_rays], dtype=np.int64)
        # round each wish to the nearest level (0 below half the smallest)
        idx = np.searchsorted(levels, want)
        lo = levels[np.maximum(idx - 1, 0)]
        hi = levels[np.minimum(idx, len(levels) - 1)]
        extra = np.where(want - lo < hi - want, lo, hi)
        extra = np.where(want < 0.5 * levels[0], 0, extra)
    casts = [(pilot, np.arange(n_f))]
    for lv in np.unique(extra[extra > 0]):
        f = np.nonzero(extra == lv)[0]
        casts.append((int(lv), f))
        _cast_facets(env, centroids, normals, occ, offset, f, int(lv), rng, frames, local, mom, record)
    out, variance = _cv_estimate(mom, e_table, weight, neighbours)
    if replicate is not None:
        ctx = (env, centroids, normals, occ, offset, frames, local)
        replicate["facets"], replicate["d"] = _replicate_differences(
            ctx, mom, casts, replicate["n"], seed, e_table, weight, neighbours, out
        )
    return out, variance, mom.n.copy()


def _replay(env, radiance, records, counts, table, normals, weight, neighbours=None):
    """The ray methods' estimate from recorded rays, for a new environment: the geometry (and
    hence which face each ray hits) is unchanged, only the radiances are new."""
    mom = _Moments(len(normals), env.n_bands)
    for f, k, d, hit in records:
        mom.add(env, radiance, f, k, d, hit)
    return _cv_estimate(mom, interp_table(table, normals), weight, neighbours)


def _geometry_key(mesh, scene, *params) -> str:
    """Hash of the facet mesh's topology, the scene geometry and the ray settings (the facet
    mesh's vertex positions are compared separately, with a tolerance)."""
    import hashlib

    h = hashlib.sha1()
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    if scene is not None:
        h.update(np.ascontiguousarray(scene.mesh.vertices, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(scene.mesh.faces, dtype=np.int64).tobytes())
    h.update(repr(params).encode())
    return h.hexdigest()


def _cache_valid(cache, key, mesh, tolerance_m) -> bool:
    if cache is None or cache.get("key") != key:
        return False
    v = np.asarray(mesh.vertices, dtype=float)
    old = cache["vertices"]
    return old.shape == v.shape and float(np.max(np.abs(v - old), initial=0.0)) <= tolerance_m


def absorbed_radiation(
    mesh,
    environment: RadianceMap,
    absorptivity,
    *,
    scene=None,
    mesh_radiance=None,
    method="brute",
    rays=64,
    seed=0,
    table_grid=64,
    offset=None,
    pilot=16,
    max_rays=4096,
    backend="embree",
    stats: dict | None = None,
    cache: dict | None = None,
    cache_tolerance_m: float = 0.0,
    sun_normals: str = "smooth",
    sun_points: int = 16,
    crease_deg: float = 60.0,
    replicate_facets: int | np.ndarray = REPLICATE_FACETS,
    importance: np.ndarray | None = None,
) -> np.ndarray:
    """Absorbed radiation per facet and band, with occlusion (seed Eq. 3-4).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        Facets to evaluate (e.g. body + garments), outward normals.
    environment : RadianceMap
        Far-field radiance around the mesh plus the sun.
    absorptivity : array (bands,) or (bands, faces)
        Absorptivity per band [0-1] (shortwave: solar absorptivity; longwave: emissivity).
    scene : SceneSurfaces, optional
        Near-field occluders; a facet ray that hits one sees that face's radiance.
    mesh_radiance : array (bands, faces), optional
        Leaving radiance of the mesh's own faces for self-occluded rays [W m^-2 sr^-1]
        (e.g. eps sigma T^4 / pi from the previous thermal iterate). Default 0: a blocked ray
        brings nothing, as in the seed (1_ij = 0).
    method : {'brute', 'fast', 'adaptive'}
        'brute': every map pixel x facet with an occlusion ray (reference).
        'fast': irradiance-table control variate (coefficient fitted on the neighbouring
        facets' rays) + ``rays`` cosine-weighted rays (Cranley-Patterson-rotated Hammersley
        points) per facet.
        'adaptive': the same control variate with ``pilot`` rays per facet, then the rest of
        a budget of ``rays`` x facets spread by Neyman allocation (more rays where the pilot
        rays disagree, none where nothing is in the way).
    rays : int
        Rays per facet for 'fast'; mean rays per facet for 'adaptive'.
    seed : int
        Random seed for 'fast' / 'adaptive'.
    table_grid : int
        Irradiance table rows over the normal's zenith (columns: the map's).
    offset : float, optional
        Ray origin offset along the normal [m]; default the larger of 1e-5 x the mesh's and
        1e-6 x the mesh-plus-scene bounding diagonal, the latter capped at
        :data:`OFFSET_SCENE_SIZE_CAP_M` (embree works in float32).
    pilot : int
        'adaptive': first-stage rays per facet (a power of two keeps the Hammersley set a
        (0, m, 2)-net).
    max_rays : int
        'adaptive': cap of the second-stage rays of one facet (4096: a few heavily weighted
        facets may take several times the mean; 1024 left most of a weighted budget unspent).
    backend : {'embree', 'mitsuba'}
        Ray caster: embreex through trimesh (single-threaded) or Mitsuba's
        (:class:`humv_usd.geometry.raycast.MitsubaRayCaster`, multi-threaded, costs the Mitsuba import).
    stats : dict, optional
        Filled with the ray methods' Monte Carlo error (0 for 'brute'):
        ``rms_rel_error_estimate`` (RMS over facets of the standard error relative to the
        facet's q_rad, floored at a quarter of the median q_rad), ``nrmse_estimate`` (RMS
        standard error / mean q_rad), ``variance`` (per facet, of q_rad [W^2 m^-4]), ``rays``
        (rays behind the diffuse part) and ``cached`` (True when they were replayed from
        ``cache``). With ``replicate_facets`` > 0 and new rays, the error is measured:
        that many facets drawn at random are estimated again from independent rays
        (:func:`_replicate_differences`), the RMS errors are the replicates' and the per-facet
        variances are the per-ray sample variances scaled by the measured / per-ray ratio over
        those facets (``stratification_ratio``; the per-ray variance alone ignores the rays'
        stratification). Otherwise (a replay, or none asked) they are the per-ray sample
        variance, an upper estimate.
    cache : dict, optional
        Visibility cache for 'fast' / 'adaptive' across calls (e.g. the frames of a person who
        stands still): the first call records every ray that hit something (facet, direction,
        face); a later call with the same facet topology, scene geometry and ray settings, and
        no vertex moved by more than ``cache_tolerance_m``, replays those rays with the new
        radiances instead of casting new ones (the same random rays, whatever ``seed``); the
        sun's shadow test is reused while neither the mesh nor the sun moves.
    cache_tolerance_m : float
        Largest vertex displacement [m] for which the cached visibility is reused (0: the
        geometry must be identical).
    sun_normals : {'smooth', 'flat'}
        Normal of the sun's cosine: 'smooth' interpolates the area-weighted vertex normals
        (:func:`corner_normals`) over the facet, so the absorbed sun varies as on the smooth
        surface the facets approximate instead of in steps from facet to facet; 'flat' takes the
        facet's own normal (the seed's).
    sun_points : int
        Points per facet (a square number: the centroids of an m x m subdivision,
        :func:`face_points`) at which the cosine and the sun's visibility are evaluated and
        averaged; 1 is the centroid alone (one shadow ray per facet). A shadow edge across a
        facet then gives it the lit area fraction, resolved to 1 / sun_points.
    crease_deg : float
        'smooth': faces around a vertex whose normals differ by more than this [deg] are not
        averaged (an edge that is meant to be sharp).
    importance : array (faces,), optional
        'adaptive': the weight w_i of each facet's flux variance in the error that the
        second-stage rays minimise, sum_i w_i Var(q_i) (rays ~ sqrt(w_i) x the facet's per-ray
        standard deviation; e.g. w_i = (dT/dq)^2 a_i^2 / A for a triangle of area a_i in a face
        of area A whose temperature T responds to its flux by dT/dq, so that the error of the
        area-weighted face temperatures is minimised). Default: the facets' relative errors
        (w_i = 1 / q_i^2). 0 keeps a facet at its ``pilot`` rays (a face whose flux no one
        uses), so the budget of ``rays`` x facets goes to the others.
    replicate_facets : int or array of int
        Facets re-estimated with independent rays to measure the error (only with ``stats``): a
        count drawn at random, or the facets' indices.

    Returns
    -------
    array (bands, faces)
        Absorbed flux per band [W m^-2]; q_rad (seed Eq. 3) is ``.sum(axis=0)``.
    """
    if method not in ("brute", "fast", "adaptive"):
        raise ValueError(f"invalid method selection {method}")
    if sun_normals not in SUN_NORMALS:
        raise ValueError(f"invalid sun_normals {sun_normals!r}: expected one of {SUN_NORMALS}")
    if int(sun_points) < 1 or round(np.sqrt(int(sun_points))) ** 2 != int(sun_points):
        raise ValueError(f"invalid sun_points {sun_points}: expected a square number >= 1 (1, 4, 9, 16, ...)")
    normals = _usable_normals(mesh)
    centroids = np.asarray(mesh.triangles_center, dtype=float)
    occ = _Occluders(mesh, environment.n_bands, mesh_radiance, scene, backend)
    if offset is None:
        scene_size = min(float(np.linalg.norm(occ.extents)), OFFSET_SCENE_SIZE_CAP_M)
        offset = max(ray_offset(mesh), 1e-6 * scene_size)
    if method == "brute":
        e = _diffuse_brute(environment, centroids, normals, occ, offset)
        var, counts, replayed = np.zeros(len(normals)), None, False
    else:
        table = irradiance_table(environment, table_grid)
        alpha = _absorptivity(absorptivity, environment.n_bands, len(normals))
        key = (
            None
            if cache is None
            else _geometry_key(
                mesh,
                scene,
                method,
                int(rays),
                int(pilot),
                int(max_rays),
                None if importance is None else hash(np.asarray(importance, dtype=float).tobytes()),
            )
        )
        replayed = _cache_valid(cache, key, mesh, cache_tolerance_m)
        neighbours = _neighbour_matrix(mesh)
        if replayed:
            counts = cache["counts"]
            e, var = _replay(
                environment, occ.radiance, cache["records"], counts, table, normals, alpha, neighbours
            )
        else:
            record = None if cache is None else []
            wanted = np.size(replicate_facets) > 1 or int(np.ravel(replicate_facets)[0]) > 0
            replicate = {"n": replicate_facets} if stats is not None and wanted else None
            if method == "adaptive":
                e, var, counts = _diffuse_adaptive(
                    environment,
                    centroids,
                    normals,
                    occ,
                    offset,
                    int(rays),
                    seed,
                    table,
                    int(pilot),
                    alpha,
                    int(max_rays),
                    record,
                    neighbours,
                    replicate,
                    importance,
                )
            else:
                e, var = _diffuse_fast(
                    environment,
                    centroids,
                    normals,
                    occ,
                    offset,
                    int(rays),
                    seed,
                    table,
                    alpha,
                    record,
                    neighbours,
                    replicate,
                )
                counts = np.full(len(normals), float(rays))
            if cache is not None:
                generation = cache.get("generation", 0) + 1
                cache.clear()
                cache.update(
                    key=key,
                    generation=generation,
                    vertices=np.array(mesh.vertices, dtype=float),
                    counts=counts,
                    records=tuple(record),
                )
    # the sun's shadow test (sun_points rays per facet) is reused only for an unmoved mesh
    same = (
        cache is not None
        and "vertices" in cache
        and np.array_equal(cache["vertices"], np.asarray(mesh.vertices, dtype=float))
    )
    e += _sun_term(
        environment,
        mesh,
        normals,
        occ,
        offset,
        cache if same else None,
        sun_normals,
        int(sun_points),
        crease_deg,
    )
    q = _absorptivity(absorptivity, environment.n_bands, len(normals)) * e
    if stats is not None:
        tot = q.sum(axis=0)
        floor = np.maximum(tot, 0.25 * max(float(np.median(np.abs(tot))), 1e-30))
        rep = None if method == "brute" or replayed else replicate
        if rep is not None and "d" in rep:  # measured: independent replicates on random facets
            f, measured = rep["facets"], 0.5 * rep["d"] ** 2
            per_ray = float(var[f].sum())
            ratio = float(measured.sum()) / per_ray if per_ray > 0 else 0.0
            stats["rms_rel_error_estimate"] = float(np.sqrt(np.mean(measured / floor[f] ** 2)))
            stats["nrmse_estimate"] = float(np.sqrt(np.mean(measured)) / max(float(np.mean(tot)), 1e-30))
            stats["stratification_ratio"] = ratio
            stats["replicate_facets"] = f
            stats["replicate_variance"] = measured
            stats["per_ray_variance"] = np.asarray(var, dtype=float)
            var = var * ratio
        else:
            stats["rms_rel_error_estimate"] = float(np.sqrt(np.mean(var / floor**2)))
            stats["nrmse_estimate"] = float(np.sqrt(np.mean(var)) / max(float(np.mean(tot)), 1e-30))
        stats["variance"] = np.asarray(var, dtype=float)
        stats["rays"] = 0 if counts is None else int(counts.sum())
        stats["cached"] = bool(replayed)
    return q


def mean_radiant_temperature(absorbed, areas, segment_ids, emissivity=0.97, n_segments=None):
    """Mean radiant temperature per body segment (seed Eq. 1 with an absorptivity).

    Parameters
    ----------
    absorbed : array (faces,) or (bands, faces)
        Absorbed radiation per facet [W m^-2] (bands are summed).
    areas : array (faces,)
        Facet areas [m^2].
    segment_ids : array of int (faces,)
        Segment index per facet (>= 0; e.g. the JOS-3 segment primvar).
    emissivity : float
        Longwave emissivity of the body surface [0-1]; ISO 7726 uses 0.97. Use 1 for the
        seed's E = sigma MRT^4 with E the incident flux.
    n_segments : int, optional
        Output length; default max(segment_ids) + 1.

    Returns
    -------
    array (n_segments,)
        T_mrt = (q_mean / (eps sigma))^(1/4) [K] with q_mean the area-weighted mean absorbed
        flux of the segment; NaN for a segment without facets.

    References
    ----------
    .. [1] ISO 7726:1998 Ergonomics of the thermal environment - Instruments for measuring
       physical quantities, Annex B (mean radiant temperature).
    """
    q = np.asarray(absorbed, dtype=float)
    if q.ndim == 2:
        q = q.sum(axis=0)
    seg = np.asarray(segment_ids, dtype=np.int64)
    n = int(seg.max()) + 1 if n_segments is None else int(n_segments)
    area = np.bincount(seg, weights=areas, minlength=n)
    qa = np.bincount(seg, weights=q * np.asarray(areas, dtype=float), minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(area > 0, qa / area, np.nan)
    return (np.maximum(mean, 0.0) / (emissivity * STEFAN_BOLTZMANN)) ** 0.25
