"""Ray casts on triangle meshes: first hit, any hit (occlusion), hit distance and point, inside.

The one ray caster of HumV-USD outside the render (the render casts its pixel-centre rays in its
own Mitsuba scene): the thermal tool (sky view, shadows, q_rad), the clothing tool (air gap,
inside tests), the contact solver (ground height), the ground-truth boxes (unoccluded masks) and
the label bench all use it.

- :class:`RayCaster`: Embree through embreex directly (single-threaded), without trimesh's
  per-call copies and re-normalisation of already unit directions. Embree works in float32, so
  the vertices are shifted to the mesh's lower corner and, by default, scaled so that the
  bounding diagonal is 100 units as trimesh does (Embree's epsilons are tuned for scenes of
  that size). The thermal q_rad estimators convert the ray origins into that float32 frame once
  (:meth:`RayCaster.local`, :meth:`RayCaster.first_hit_local`): many rays share one origin.
- :class:`MitsubaRayCaster`: first and any hits through Mitsuba's ``ray_intersect_preliminary``
  (Embree inside, vectorised over the LLVM backend's threads; about twice the throughput of
  embreex on two cores; costs the Mitsuba import, about 1 s, once).

Face indices are those of the ``triangles`` array; -1 is a miss. Directions are unit vectors.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from humv_usd.mode import loaded_backend, mitsuba

#: Ray-casting backends of :func:`ray_caster`.
RAY_BACKENDS = ("embree", "mitsuba")
#: Rays per call of :func:`first_faces` / :func:`unblocked` (bounds the memory of one call).
CHUNK_RAYS = 2_000_000
#: Bounding diagonal of the float32 frame of a normalised caster (as trimesh's embree wrapper).
FRAME_DIAGONAL = 100.0
#: Directions of the ray-parity votes of :meth:`RayCaster.inside` (normalised below).
_PARITY_DIRECTIONS = np.array(
    [
        [0.0, 0.0, 1.0],
        [0.577, -0.577, 0.577],
        [-0.6, 0.48, -0.64],
        [0.36, 0.8, 0.48],
        [-0.8, -0.36, 0.48],
    ]
)


class _Frame:
    """Triangles and the shifted (and optionally scaled) float32 frame of a caster."""

    def __init__(self, points, triangles, normalize: bool):
        v = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self.points = v
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        # the frame's origin at the centre of the bounds: float32 keeps its precision where a
        # scene is (a ground reaching the horizon spans kilometres around it, issue 30)
        self._origin = 0.5 * (v.min(axis=0) + v.max(axis=0)) if len(v) else np.zeros(3)
        if normalize:
            diag = float(np.linalg.norm(np.ptp(v, axis=0))) if len(v) else 1.0
            self._scale = FRAME_DIAGONAL / max(diag, 1e-12)
        else:
            self._scale = 1.0

    def local(self, points) -> np.ndarray:
        """World points [m] -> the caster's shifted and scaled float32 frame, (n, 3)."""
        return ((np.asarray(points, dtype=np.float64) - self._origin) * self._scale).astype(np.float32)

    def first_points(self, origins, directions) -> tuple[np.ndarray, np.ndarray]:
        """(first face hit (n,), -1 = miss; hit points (n, 3) [m], NaN on a miss). The point is
        the ray's intersection with the hit triangle's plane in float64 (as trimesh's
        ``intersects_location``), so it does not carry Embree's float32 distance error."""
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        face = self.intersects_first(o, d)
        out = np.full(o.shape, np.nan)
        hit = np.nonzero(face >= 0)[0]
        if len(hit):
            tri = self.points[self.triangles[face[hit]]]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            t = np.einsum("ij,ij->i", tri[:, 0] - o[hit], n) / np.einsum("ij,ij->i", d[hit], n)
            out[hit] = o[hit] + t[:, None] * d[hit]
        return face, out


class RayCaster(_Frame):
    """Ray casts through Embree (embreex), float32.

    Parameters
    ----------
    points : array (V, 3)
        Vertex positions [m].
    triangles : array (F, 3)
        Vertex indices per triangle.
    normalize : bool
        Scale the float32 frame to a 100-unit bounding diagonal (trimesh's convention; the
        thermal and ground-truth casts). False keeps metres (shifted only), as the clothing
        tool's air gap always did.
    """

    def __init__(self, points, triangles, normalize: bool = True):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        super().__init__(points, triangles, normalize)
        self._scene = rtcore_scene.EmbreeScene()
        TriangleMesh(
            scene=self._scene, vertices=self.local(self.points), indices=self.triangles.astype(np.int32)
        )

    def _run(self, origins, directions, query="INTERSECT", output=None):
        o = self.local(origins)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        if output:
            return self._scene.run(o, d, output=1)
        return self._scene.run(o, d, query=query)

    def intersects_first(self, origins, directions) -> np.ndarray:
        """First face hit per ray (-1: none), (n,) int64."""
        return self._run(origins, directions).astype(np.int64)

    def first_hit_local(self, origins32, directions32) -> np.ndarray:
        """First face hit (-1: none) of rays with origins already in the :meth:`local` frame;
        float32 contiguous (n, 3) arrays."""
        return self._scene.run(origins32, directions32, query="INTERSECT").astype(np.int64)

    def intersects_any(self, origins, directions) -> np.ndarray:
        """Whether each ray hits anything (occlusion query), (n,) bool."""
        return self._run(origins, directions, "OCCLUDED") >= 0

    def any_hit_local(self, origins32, directions32) -> np.ndarray:
        """:meth:`intersects_any` of rays with origins already in the :meth:`local` frame;
        float32 contiguous (n, 3) arrays."""
        return self._scene.run(origins32, directions32, query="OCCLUDED") >= 0

    def hit_distance(self, origins, directions) -> np.ndarray:
        """Distance along each unit direction to the first hit [m]; inf where none."""
        out = self._run(origins, directions, output=True)
        t = np.asarray(out["tfar"], dtype=np.float64) / self._scale
        return np.where(np.asarray(out["primID"]) >= 0, t, np.inf)

    def inside(self, points, directions: int = 3) -> np.ndarray:
        """Ray-parity inside test (majority over a few fixed directions); for closed meshes
        without self-intersections, independent of the normals' sign. (n,) bool."""
        dirs = _PARITY_DIRECTIONS[:directions] / np.linalg.norm(
            _PARITY_DIRECTIONS[:directions], axis=1, keepdims=True
        )
        votes = np.zeros(len(points), dtype=np.int64)
        for d in dirs:
            votes += self._count_hits(points, d) % 2
        return votes * 2 > len(dirs)

    def _count_hits(self, points, direction) -> np.ndarray:
        o = self.local(points)
        d = np.tile(np.asarray(direction, dtype=np.float32), (len(o), 1))
        hits = np.zeros(len(o), dtype=np.int64)
        active = np.arange(len(o))
        step = np.float32(1e-5 * self._scale)  # past a hit: 1e-5 m
        for _ in range(64):
            if not len(active):
                break
            out = self._scene.run(np.ascontiguousarray(o[active]), np.ascontiguousarray(d[active]), output=1)
            hit = np.asarray(out["primID"]) >= 0
            active = active[hit]
            hits[active] += 1
            t = np.asarray(out["tfar"], dtype=np.float32)[hit]
            o[active] = o[active] + d[active] * (t[:, None] + step)
        return hits


class MitsubaRayCaster(_Frame):
    """First and any hits through Mitsuba's ray tracer (``scene.ray_intersect_preliminary``),
    in the same normalised float32 frame as :class:`RayCaster`."""

    def __init__(self, points, triangles):
        super().__init__(points, triangles, normalize=True)
        mi = mitsuba()
        self._mi = mi
        m = mi.Mesh("occluders", len(self.points), len(self.triangles))
        params = mi.traverse(m)
        params["vertex_positions"] = mi.Float(self.local(self.points).ravel())
        params["faces"] = mi.UInt32(self.triangles.astype(np.uint32).ravel())
        params.update()
        self._scene = mi.load_dict({"type": "scene", "occluders": m})

    def intersects_first(self, origins, directions) -> np.ndarray:
        """First face hit per ray (-1: none), (n,) int64."""
        mi = self._mi
        o = self.local(origins)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        pi = self._scene.ray_intersect_preliminary(ray)
        hit = np.array(pi.prim_index, dtype=np.int64)
        return np.where(np.array(pi.is_valid(), dtype=bool), hit, -1)

    def intersects_any(self, origins, directions) -> np.ndarray:
        """Whether each ray hits anything, (n,) bool."""
        return self.intersects_first(origins, directions) >= 0

    def any_hit_local(self, origins32, directions32) -> np.ndarray:
        """:meth:`intersects_any` of rays with origins already in the :meth:`local` frame."""
        mi, o, d = self._mi, origins32, directions32
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        return np.array(self._scene.ray_intersect_preliminary(ray).is_valid(), dtype=bool)


def default_backend() -> str:
    """``'mitsuba'`` where the render already runs Dr.Jit on a GPU (the casts then run on the
    same device, through OptiX) or where embreex is not installed; else ``'embree'``."""
    if loaded_backend() == "cuda" or importlib.util.find_spec("embreex") is None:
        return "mitsuba"
    return "embree"


def ray_caster(points, triangles, backend: str | None = None):
    """A :class:`RayCaster` (``'embree'``) or :class:`MitsubaRayCaster` (``'mitsuba'``) on the
    triangles (None: :func:`default_backend`); ValueError for another backend."""
    if backend is None:
        backend = default_backend()
    if backend == "mitsuba":
        return MitsubaRayCaster(points, triangles)
    if backend != "embree":
        raise ValueError(f"invalid ray backend {backend!r}: expected one of {RAY_BACKENDS}")
    return RayCaster(points, triangles)


def first_faces(caster, origins, directions, chunk: int = CHUNK_RAYS) -> np.ndarray:
    """First face hit per ray (-1 = miss), cast in chunks of ``chunk`` rays, (n,) int64."""
    out = np.empty(len(origins), dtype=np.int64)
    for a in range(0, len(origins), chunk):
        out[a : a + chunk] = caster.intersects_first(origins[a : a + chunk], directions[a : a + chunk])
    return out


def unblocked_local(caster, origins32, directions32, chunk: int = CHUNK_RAYS) -> np.ndarray:
    """:func:`unblocked` of rays with origins in the caster's :meth:`~RayCaster.local` frame
    (float32 (n, 3) arrays; many rays from the same points convert them once), (n,) bool."""
    out = np.empty(len(origins32), dtype=bool)
    for a in range(0, len(origins32), chunk):
        o = np.ascontiguousarray(origins32[a : a + chunk], dtype=np.float32)
        d = np.ascontiguousarray(directions32[a : a + chunk], dtype=np.float32)
        out[a : a + chunk] = ~caster.any_hit_local(o, d)
    return out


def unblocked(caster, origins, directions, chunk: int = CHUNK_RAYS) -> np.ndarray:
    """Whether each ray escapes the mesh (hits nothing), in chunks, (n,) bool."""
    out = np.empty(len(origins), dtype=bool)
    for a in range(0, len(origins), chunk):
        out[a : a + chunk] = ~caster.intersects_any(origins[a : a + chunk], directions[a : a + chunk])
    return out
