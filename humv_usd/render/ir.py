"""Infrared rendering with Mitsuba 3: scene build, per-frame update, render, moments, labels.

One Mitsuba scene holds every (mesh, material) part, every infrared sensor and the sky; it is
built once per mesh topology and then updated in place each frame (``mi.traverse`` +
``params.update()``): vertex positions per frame, and per sensor band the per-face emitted
radiance, the BSDF reflectance and the sky radiance.

Radiometry (gray band model, Kirchhoff, opaque Lambertian surfaces)
-------------------------------------------------------------------
A part with band emissivity :math:`\\varepsilon_b` (see
:func:`humv_usd.physics.planck.band_emissivity`) emits :math:`\\varepsilon_b L_b(T_{face})` from
its front side and reflects diffusely with reflectance :math:`1 - \\varepsilon_b`; the sky is a
constant environment of radiance :math:`L_b(T_{sky})`. Using the same band-averaged
:math:`\\varepsilon_b` for emission and reflection keeps an isothermal enclosure exactly at
:math:`L_b(T)` for any emissivity (furnace test); for a non-gray material the band average is an
approximation, so :func:`render_band` renders the band as sub-bands (each a gray band of its own,
:mod:`humv_usd.render.radiometry`) and adds the atmospheric path per pixel. The sky is either
that constant environment or an ``envmap`` against zenith; the sun an optional ``directional``
emitter.

Surfaces are one-sided, as Mitsuba's area emitter and ``diffuse`` BSDF are: the back of a face
(seen from inside a closed mesh, or the underside of a single-sided plate) neither emits nor
reflects. Closed meshes with outward normals (USD ``orientation`` honoured) are what compose writes.

The integrator is ``moment`` around ``path`` (``max_depth`` -1: unbiased, Russian roulette), with
next-event estimation of the sky and sun only (see :data:`AREA_EMITTER_SAMPLING_WEIGHT`); the film is
``hdrfilm`` luminance with a ``box`` filter, so every sample lands in exactly one pixel and the
second moment gives the per-pixel Monte Carlo standard error of the mean.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd import mode
from humv_usd.geometry import shading
from humv_usd.geometry.camera import CameraPose
from humv_usd.render import elements as el
from humv_usd.render.elements import SKY_ID, SUN_ID
from humv_usd.render.radiometry import apply_path, range_weights, sky_latlong
from humv_usd.render.scene_export import Part, face_corners

#: Next-event estimation never picks the surfaces' area emitters. Mitsuba 3.9.1 samples an area
#: emitter whose radiance is spatially varying (our per-face ``mesh_attribute``) through the
#: texture's UV parameterization, which a UV-less mesh does not have: in ``llvm_ad_mono`` that
#: biased an isothermal box-on-ground furnace scene low by 0.2-0.5 %, and in ``scalar_rgb`` it
#: segfaults. With weight 0, emitters are reached by BSDF sampling, whose MIS weight is then 1:
#: unbiased (the furnace test holds) and, for surfaces that fill a large solid angle as in
#: thermal scenes, little noisier. The sky keeps next-event estimation.
AREA_EMITTER_SAMPLING_WEIGHT = 0.0


@dataclass
class SensorSetup:
    """A sensor as the Mitsuba scene sees it."""

    id: str  # Mitsuba id
    width: int
    height: int
    pose: CameraPose


def corner_blend(scene, crease_deg: float = shading.SMOOTH_CREASE_DEG):
    """(3T, T) sparse matrix from per-triangle values (the global order of the scene's parts'
    triangles) to per-corner values: :func:`humv_usd.geometry.shading.corner_blend` of the
    parts' current vertices, corners in the order of the Mitsuba meshes' faces
    (:func:`~humv_usd.render.scene_export.face_corners`, winding flips applied), so a hit's
    barycentric coordinates (``si.uv``) weight the right corners. ``scene`` gives ``parts``,
    ``vertices(part)`` and ``flipped(part)`` (an :class:`IRScene` or a stand-in)."""
    meshes = [(scene.vertices(p), face_corners(p.triangles, scene.flipped(p))) for p in scene.parts]
    return shading.corner_blend(meshes, crease_deg)


class IRScene:
    """A Mitsuba scene for one set of visible meshes (built once, updated per frame).

    Parameters
    ----------
    parts : list of (Part, vertices (V, 3) [m], flip bool)
        The parts with their initial world-space vertices; ``flip`` reverses the winding.
    sensors : list of SensorSetup
        All sensors rendered from this scene.
    spp : int
        Samples per pixel.
    max_depth : int
        Path depth; -1 is unbounded (Russian roulette).
    workdir : path-like
        Directory for the PLY files (read at load; may be deleted afterwards).
    sky_map : bool, default False
        True: the sky is an ``envmap`` (lat-long bitmap against zenith, :meth:`set_sky_map`);
        False: a ``constant`` environment (:meth:`set_sky`).
    sun : bool, default False
        Add a ``directional`` emitter for the sun (:meth:`set_sun`; off until set).
    """

    #: Mitsuba variant family of the scene (True in the EO subclass).
    spectral = False

    def __init__(
        self,
        parts,
        sensors: list[SensorSetup],
        spp: int,
        max_depth: int,
        workdir,
        sky_map: bool = False,
        sun: bool = False,
    ):
        mi = mode.mitsuba()
        self.mi = mi
        self.scalar = not mode.is_vectorized()
        self.parts = [p for p, _, _ in parts]
        self.sensors = {s.id: s for s in sensors}
        self.sky_map = bool(sky_map)
        self.has_sun = bool(sun)
        elements = [el.constant_sky({"type": "uniform", "value": 0.0}, "value")]
        if self.sky_map:
            elements = [el.envmap_sky(mi, sky_latlong([0.0, 90.0], [1.0, 1.0]))]
        if self.has_sun:
            elements.append(el.directional_sun({"type": "uniform", "value": 0.0}, "value"))
        elements += [el.perspective_sensor(mi, s, spp, "luminance") for s in sensors]
        for part, vertices, flip in parts:
            n = len(part.triangles)
            elements.append(
                el.mesh(
                    part,
                    vertices,
                    flip,
                    workdir,
                    bsdf={"type": "diffuse", "reflectance": {"type": "uniform", "value": 0.5}},
                    updates=("face_radiance", "bsdf.reflectance.value"),
                    emitter={
                        "type": "area",
                        "sampling_weight": AREA_EMITTER_SAMPLING_WEIGHT,
                        "radiance": {"type": "mesh_attribute", "name": "face_radiance"},
                    },
                    face_attributes={"radiance_0": np.zeros(n)},
                )
            )
        #: the scene's elements (Mitsuba dicts and the parameter keys each updates per frame)
        self.elements = elements
        scene = el.scene_dict(max_depth, elements)
        # optimize=False: Mitsuba >= 3.6 otherwise merges equal nodes (e.g. two parts' BSDFs that
        # start with the same reflectance) and meshes, and per-part parameters would be shared.
        self.scene = mi.load_dict(scene, optimize=False)
        self.params = mi.traverse(self.scene)
        self._sensor_objects = {s.id(): s for s in self.scene.sensors()}
        channels = ["Y"] + list(self.scene.integrator().aov_names())
        self._m1 = channels.index("nested.Y")
        self._m2 = channels.index("m2_nested.Y")
        self._positions: dict[str, np.ndarray] = {p.key: np.asarray(v, dtype=np.float32) for p, v, _ in parts}
        self._flips: dict[str, bool] = {p.key: bool(f) for p, _, f in parts}
        #: counts vertex updates: what is derived from the geometry (the estimator's smooth-
        #: shading blend) is cached against it
        self.geometry_version = 0

    # --- what the estimators read ------------------------------------------------------------
    def vertices(self, part: Part) -> np.ndarray:
        """World-space vertex positions (V, 3) [m, float32] of a part as last set (read-only)."""
        return self._positions[part.key]

    def flipped(self, part: Part) -> bool:
        """Whether the part's winding is reversed in the scene (USD ``orientation``)."""
        return self._flips[part.key]

    def corner_blend(self):
        """(3T, T) sparse matrix from per-triangle values (the global order of the parts'
        triangles) to per-corner values, corners in the order of the Mitsuba meshes' faces
        (winding flips applied, as ``si.uv``'s barycentric coordinates):
        :func:`humv_usd.geometry.shading.corner_blend` of the current geometry, computed once
        per geometry (the fast estimator's smooth shading and the ground truth's surface
        temperature share it)."""
        cached = getattr(self, "_blend", None)
        if cached is not None and cached[0] == self.geometry_version:
            return cached[1]
        meshes = [(self.vertices(p), self.face_corners(p)) for p in self.parts]
        blender = getattr(self, "_blender", None)  # the weld and pattern, kept while they fit
        if blender is None or not blender.fits(meshes):
            blender = self._blender = shading.CornerBlend(meshes)
        blend = blender(meshes)
        self._blend = (self.geometry_version, blend)
        return blend

    def face_corners(self, part: Part) -> np.ndarray:
        """(t, 3) vertex indices of a part's triangles in the scene's winding (flips applied)."""
        return face_corners(part.triangles, self.flipped(part))

    def mitsuba_sensor(self, sensor_id: str):
        """The Mitsuba sensor object of ``sensor_id`` (for ``mi.render`` and ``sample_ray``)."""
        return self._sensor_objects[sensor_id]

    # --- updates -----------------------------------------------------------------------------
    def _set_array(self, key: str, values) -> None:
        # mi.Float in JIT variants, drjit.scalar.ArrayXf in scalar ones
        self.params[key] = type(self.params[key])(np.ascontiguousarray(values, dtype=np.float32))

    def set_vertices(self, part: Part, vertices) -> None:
        """Vertex positions (V, 3) [m] of a part; skipped when unchanged (no BVH rebuild)."""
        v = np.ascontiguousarray(vertices, dtype=np.float32)
        if np.array_equal(v, self._positions[part.key]):
            return
        self._positions[part.key] = v
        self.geometry_version += 1
        self._set_array(f"{part.key}.vertex_positions", v.ravel())
        self._hits = {}  # the geometry changed

    def set_surface(self, part: Part, face_radiance, reflectance: float) -> None:
        """Per-triangle emitted radiance [W m^-2 sr^-1] and diffuse reflectance of a part."""
        self._set_array(f"{part.key}.face_radiance", face_radiance)
        self.params[f"{part.key}.bsdf.reflectance.value"] = float(reflectance)

    def set_sky(self, radiance: float) -> None:
        """Sky radiance [W m^-2 sr^-1] (constant sky)."""
        self.params[f"{SKY_ID}.radiance.value"] = float(radiance)

    def set_sky_map(self, bitmap) -> None:
        """Sky lat-long bitmap (H, W, 3) [W m^-2 sr^-1] (envmap sky, see ``radiometry.sky_latlong``)."""
        key = f"{SKY_ID}.data"
        current = self.params[key]
        shape = tuple(int(n) for n in current.shape)
        bitmap = np.asarray(bitmap, dtype=np.float32)
        if bitmap.shape != shape:  # some variants pad the azimuth columns; the sky is azimuth-free
            bitmap = np.broadcast_to(bitmap[:, :1, :], shape)
        self.params[key] = type(current)(np.ascontiguousarray(bitmap))

    def set_sun(self, toward_sun, irradiance: float) -> None:
        """Sun along the unit vector ``toward_sun`` with irradiance [W m^-2] on a surface normal
        to the beam; irradiance 0 switches it off (and out of next-event estimation)."""
        d = -np.asarray(toward_sun, dtype=float)
        helper = [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0]
        cls = self.mi.ScalarTransform4f if self.scalar else self.mi.Transform4f
        # look_at takes local +Z (the emitter's propagation direction) to d
        self.params[f"{SUN_ID}.to_world"] = cls().look_at(
            origin=[0.0, 0.0, 0.0], target=[float(v) for v in d], up=helper
        )
        self.params[f"{SUN_ID}.irradiance.value"] = float(irradiance)
        # next-event estimation picks sun or sky in proportion to these weights: the beam-normal
        # irradiance here, pi x the mean sky radiance for the sky (:meth:`set_sky_weight`)
        self.params[f"{SUN_ID}.sampling_weight"] = max(float(irradiance), 0.0)

    def set_sky_weight(self, irradiance: float) -> None:
        """Next-event sampling weight of the sky [W m^-2], e.g. pi x its mean radiance."""
        self.params[f"{SKY_ID}.sampling_weight"] = max(float(irradiance), 1e-30)

    def set_camera(self, sensor_id: str, pose: CameraPose) -> None:
        getattr(self, "_hits", {}).pop(sensor_id, None)
        self.sensors[sensor_id].pose = pose
        self.params[f"{sensor_id}.to_world"] = el.look_at(self.mi, pose, scalar=self.scalar)
        self.params[f"{sensor_id}.x_fov"] = float(pose.fov_x_deg)

    def update(self) -> None:
        self.mi = mode.mitsuba()  # the EO render may have switched the variant
        self.params.update()

    # --- render ------------------------------------------------------------------------------
    def render(self, sensor_id: str, spp: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """First and second moments of the pixel radiance, (H, W) float64 each."""
        self.mi = mode.mitsuba()
        img = self.mi.render(
            self.scene, sensor=self.mitsuba_sensor(sensor_id), spp=int(spp), seed=int(seed) % 2**32
        )
        a = np.asarray(img, dtype=np.float64)
        return a[..., self._m1], a[..., self._m2]

    def labels(self, sensor_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Depth along the optical axis [m] (inf for sky) and instance id (0 for sky), (H, W).

        One ray through each pixel centre, from the same Mitsuba sensor that renders.
        """
        hits = self.hits(sensor_id)
        return hits.depth, hits.instance

    def hits(self, sensor_id: str) -> Hits:
        """The first surface hit by the ray through each pixel centre (exact, no Monte Carlo).

        Rays come from the same Mitsuba sensor that renders (``sample_ray`` at the pixel centre,
        aperture sample 0.5), so labels and image agree by construction. See :class:`Hits`.
        Cached per sensor until its camera (:meth:`set_camera`) or a part's vertices
        (:meth:`set_vertices`) change; treat the arrays as read-only.
        """
        cache = self.__dict__.setdefault("_hits", {})
        if sensor_id not in cache:
            cache[sensor_id] = self._cast_hits(sensor_id)
        return cache[sensor_id]

    def _cast_hits(self, sensor_id: str) -> Hits:
        mi = self.mi = mode.mitsuba(spectral=self.spectral)  # the other render may have switched it
        setup = self.sensors[sensor_id]
        sensor = self.mitsuba_sensor(sensor_id)
        w, h = setup.width, setup.height
        n = w * h
        xs, ys = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
        origin = np.asarray(setup.pose.origin, dtype=np.float64)
        forward = np.asarray(setup.pose.forward, dtype=np.float64)
        part_of_key = {p.key: k for k, p in enumerate(self.parts)}
        part = np.full(n, -1, dtype=np.int64)
        triangle = np.full(n, -1, dtype=np.int64)
        ident = np.zeros(n, dtype=np.uint32)
        p = np.full((n, 3), np.nan)
        normal = np.zeros((n, 3))
        if self.scalar:
            for i, (x, y) in enumerate(zip(xs.ravel(), ys.ravel())):
                ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(float(x), float(y)), mi.Point2f(0.5, 0.5))
                si = self.scene.ray_intersect(ray)
                if si.is_valid():
                    p[i] = np.asarray(si.p, dtype=np.float64)
                    normal[i] = np.asarray(si.n, dtype=np.float64)
                    ident[i] = int(round(si.shape.eval_attribute_1("face_instance", si)))
                    part[i] = part_of_key[si.shape.id()]
                    triangle[i] = int(si.prim_index)
        else:
            ray, _ = sensor.sample_ray(
                0.0, 0.5, mi.Point2f(mi.Float(xs.ravel()), mi.Float(ys.ravel())), mi.Point2f(0.5, 0.5)
            )
            import drjit as dr

            si = self.scene.ray_intersect(ray)
            valid = si.is_valid()
            ident_dr = si.shape.eval_attribute_1("face_instance", si, valid)
            # the shape pointer as its registry index: one array for all shapes
            shape_index = dr.reinterpret_array(mi.UInt32, si.shape)
            dr.eval(si.p, si.n, si.prim_index, valid, ident_dr, shape_index)  # one kernel
            valid_np = np.asarray(valid, dtype=bool)
            ident = np.where(valid_np, np.rint(np.asarray(ident_dr, dtype=np.float64)), 0).astype(np.uint32)
            p = np.asarray(si.p, dtype=np.float64).reshape(3, n).T
            normal = np.asarray(si.n, dtype=np.float64).reshape(3, n).T
            triangle = np.where(valid_np, np.asarray(si.prim_index, dtype=np.int64), -1)
            shape_np = np.asarray(shape_index, dtype=np.int64)
            for shape in self.scene.shapes():
                key = int(np.asarray(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape)))[0])
                on = (shape_np == key) & valid_np
                if on.any():  # an emitter shape (a lit window, render.lights) is no part: background
                    part[on] = part_of_key.get(shape.id(), -1)
        valid_np = part >= 0
        depth = np.where(valid_np, (np.nan_to_num(p) - origin[None, :]) @ forward, np.inf)
        normal[~valid_np] = 0.0
        return Hits(
            depth=depth.reshape(h, w),
            instance=ident.reshape(h, w),
            part=part.reshape(h, w),
            triangle=triangle.reshape(h, w),
            position=p.reshape(h, w, 3),
            normal=normal.reshape(h, w, 3),
        )

    def _part_of_shape_index(self) -> np.ndarray:
        """Part index (``parts`` order) by a shape's registry index (vectorised variants), cached."""
        if getattr(self, "_shape_parts", None) is None:
            import drjit as dr

            mi = self.mi
            part_of_key = {p.key: k for k, p in enumerate(self.parts)}
            keys = {
                int(np.asarray(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape)))[0]): part_of_key.get(
                    shape.id(), -1
                )  # an emitter shape (a lit window, render.lights) is no part
                for shape in self.scene.shapes()
            }
            table = np.full(max(keys) + 1, -1, dtype=np.int64)
            table[list(keys)] = list(keys.values())
            self._shape_parts = table
        return self._shape_parts

    def cast(self, origin, directions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """First hits of rays from ``origin`` (3,) along unit ``directions`` (N, 3) [m]:
        (distance along the ray [m], inf on a miss; part index, -1; triangle index, -1)."""
        mi = self.mi = mode.mitsuba(spectral=self.spectral)
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        o = np.asarray(origin, dtype=np.float64)
        part_of_key = {p.key: k for k, p in enumerate(self.parts)}
        t = np.full(len(d), np.inf)
        part = np.full(len(d), -1, dtype=np.int64)
        tri = np.full(len(d), -1, dtype=np.int64)
        if not self.scalar and len(d):
            # one vectorised cast: one kernel launch (a loop of single rays launched several
            # kernels per ray, each compiled on a cold Dr.Jit cache: 26 s on a first render)
            import drjit as dr

            n = len(d)
            ray = mi.Ray3f(
                mi.Point3f(*[mi.Float(np.full(n, v, dtype=np.float32)) for v in o]),
                mi.Vector3f(*[mi.Float(np.ascontiguousarray(d[:, k], dtype=np.float32)) for k in range(3)]),
            )
            si = self.scene.ray_intersect(ray)
            valid = si.is_valid()
            shape_index = dr.reinterpret_array(mi.UInt32, si.shape)
            dr.eval(si.t, si.prim_index, valid, shape_index)
            ok = np.asarray(valid, dtype=bool)
            t = np.where(ok, np.asarray(si.t, dtype=np.float64), np.inf)
            tri = np.where(ok, np.asarray(si.prim_index, dtype=np.int64), -1)
            part = np.where(ok, self._part_of_shape_index()[np.asarray(shape_index, dtype=np.int64)], -1)
            return t, part, tri
        for i, di in enumerate(d):  # scalar variant: one ray at a time
            ray = mi.Ray3f(mi.Point3f(*[float(v) for v in o]), mi.Vector3f(*[float(v) for v in di]))
            si = self.scene.ray_intersect(ray)
            if bool(np.asarray(si.is_valid()).ravel()[0]):
                t[i] = float(np.asarray(si.t).ravel()[0])
                shape = si.shape if self.scalar else si.shape[0]
                part[i] = part_of_key[shape.id()]
                tri[i] = int(np.asarray(si.prim_index).ravel()[0])
        return t, part, tri


@dataclass
class Hits:
    """Per pixel (H, W) first hits of the pixel-centre rays of one sensor.

    ``part`` indexes :attr:`IRScene.parts` (-1 for sky), ``triangle`` the triangle of that part
    (``Part.triangles`` / ``Part.triangle_face`` order; -1 for sky); ``position`` is the world hit
    point [m] (NaN for sky), ``normal`` the unit geometric normal of the hit triangle in world
    space (its front side by winding, flips applied; 0 for sky); ``depth`` the distance along the
    optical axis [m] (inf for sky), ``instance`` the part's instance id (0 for sky).
    """

    depth: np.ndarray
    instance: np.ndarray
    part: np.ndarray
    triangle: np.ndarray
    position: np.ndarray
    normal: np.ndarray


#: Relative resolution of m2 - m1^2 from float32 film accumulation (a few float32 ulps of m2).
MOMENT_RESOLUTION = 4.0 * 2.0**-24


def monte_carlo_stderr(m1, m2, spp: int) -> np.ndarray:
    """Standard error of the per-pixel mean from the first and second sample moments.

    Parameters
    ----------
    m1, m2 : array
        Mean and mean square of the ``spp`` samples of each pixel (float32 film accumulations).
    spp : int
        Samples per pixel.

    Returns
    -------
    array
        :math:`\\sqrt{\\max(m_2 - m_1^2,\\ r\\,m_2) / (n - 1)}` with n = spp (the unbiased
        sample variance over n); NaN for n = 1 (not estimable).

    Notes
    -----
    Mitsuba accumulates both moments in float32, so :math:`m_2 - m_1^2` is known only to about
    :math:`r\\,m_2` with :math:`r` = :data:`MOMENT_RESOLUTION` (4 ulp). Smaller variances are
    reported as that floor, i.e. a standard error of about :math:`1.3\\times10^{-4}\\,m_1` at 16 spp:
    an upper bound, never a false zero.
    """
    m1 = np.asarray(m1, dtype=np.float64)
    m2 = np.asarray(m2, dtype=np.float64)
    if spp <= 1:
        return np.full_like(m1, np.nan)
    var = np.maximum(m2 - m1**2, MOMENT_RESOLUTION * np.abs(m2))
    return np.sqrt(var / (int(spp) - 1))


#: Fewest samples per pixel of one sub-band render (when spp allows): the per-pixel standard
#: error is estimated from each sub-band's own samples and needs a few.
MIN_SUBBAND_SPP = 4


def subband_spp(spp: int, n: int) -> int:
    """Samples per pixel of each of ``n`` sub-band renders: the pixel's ``spp`` split over the
    sub-bands (rounded up), but at least ``min(spp, MIN_SUBBAND_SPP)``.

    Splitting keeps the cost of a band near that of one gray render, and the noise too: the
    sub-band radiances add, so their variances (each ~ (1/n)^2 of the band's per sample, with
    n times fewer samples) add up to about the band's.
    """
    per = -(-int(spp) // int(n))
    return max(per, min(int(spp), MIN_SUBBAND_SPP))


def render_band(
    scene: IRScene,
    sensor_id: str,
    state,
    sub,
    emissivity_of,
    radiometry,
    spp: int,
    seed: int,
    transmittance_of=None,
):
    """At-sensor band radiance of one IR sensor at one frame, rendered sub-band by sub-band.

    Parameters
    ----------
    scene : IRScene
        With the frame's vertices and camera already set.
    sensor_id : str
        Mitsuba id of the sensor.
    state : frame.FrameState
        The frame (face temperatures per mesh).
    sub : radiometry.SubBands
        The sensor's sub-bands.
    emissivity_of : callable(Material) -> (n,) array
        Sub-band emissivity of a material.
    transmittance_of : callable(Material) -> (n,) array or None, optional
        Sub-band transmittance of a see-through material (glass), None when opaque. Such a face
        reflects only R = 1 - eps - T; what it transmits is not traced (the surfaces are
        opaque to the render), so the scene behind a window is missing where T > 0.
    radiometry : radiometry.FrameRadiometry
        Sky, sun and path per sub-band at this frame.
    spp, seed : int
        Samples per pixel of each sub-band render (see :func:`subband_spp`) and the frame's seed
        (sub-band k of n renders with Mitsuba seed ``seed * n + k``: distinct for every frame and
        sub-band).

    Returns
    -------
    radiance, stderr : (H, W) float64
        :math:`\\sum_k \\tau_k(r) S_k + P_k(r)` [W m^-2 sr^-1] (see :mod:`humv_usd.render.radiometry`)
        and its Monte Carlo standard error :math:`\\sqrt{\\sum_k \\tau_k^2 \\sigma_k^2}` (independent
        sub-band renders).

    Notes
    -----
    Per sub-band k a face emits :math:`\\varepsilon_k L_k(T)` and reflects with
    :math:`1-\\varepsilon_k` (Kirchhoff); the sky (constant or envmap) and the sun carry their
    sub-band radiance / irradiance. The range r of a pixel is that of its centre ray's first hit
    (:meth:`IRScene.hits`); pixels whose centre ray misses the scene get no path term (the sky
    radiance is already the at-sensor value), so pixels straddling a silhouette against the sky
    are approximate.
    """

    planck_k = {m.path: sub.radiance(state.temperatures[m.path]) for m in state.meshes}  # (F, n)
    range_m = weights = None
    if radiometry.path is not None:
        hits = scene.hits(sensor_id)
        origin = np.asarray(scene.sensors[sensor_id].pose.origin, dtype=np.float64)
        hit = np.isfinite(hits.depth)  # the positions of missed rays are undefined
        range_m = np.where(
            hit, np.linalg.norm(np.where(hit[..., None], hits.position, 0.0) - origin, axis=-1), np.inf
        )
        weights = range_weights(
            radiometry.path.ranges_m, np.where(hit, range_m, 0.0)
        )  # shared by the sub-bands
    total = None
    var = None
    for k in range(len(sub)):
        for m in state.meshes:
            for part in m.parts:
                eps = float(emissivity_of(part.material)[k])
                tau = None if transmittance_of is None else transmittance_of(part.material)
                rho = 1.0 - eps - (0.0 if tau is None else float(tau[k]))
                scene.set_surface(part, eps * planck_k[m.path][part.triangle_face, k], max(rho, 0.0))
        if radiometry.sky_maps is not None and scene.sky_map:
            scene.set_sky_map(radiometry.sky_maps[k])
        else:
            if radiometry.sky_maps is not None:  # scene built without the envmap: the map mean
                value = float(np.mean(radiometry.sky_maps[k]))
            else:
                value = float(radiometry.sky_constant[k])
            if scene.sky_map:
                scene.set_sky_map(sky_latlong([0.0, 90.0], [value, value]))
            else:
                scene.set_sky(value)
        if scene.has_sun:  # weigh sky against sun in next-event estimation
            if radiometry.sky_maps is not None:
                upper = radiometry.sky_maps[k][: radiometry.sky_maps[k].shape[0] // 2 + 1]
                scene.set_sky_weight(np.pi * float(np.mean(upper)))
            else:
                scene.set_sky_weight(np.pi * float(radiometry.sky_constant[k]))
            if radiometry.sun_irradiance is not None:
                scene.set_sun(radiometry.sun_direction, float(radiometry.sun_irradiance[k]))
            else:
                scene.set_sun([0.0, 0.0, 1.0], 0.0)
        scene.update()
        m1, m2 = scene.render(sensor_id, spp=spp, seed=(int(seed) * len(sub) + k) % 2**32)
        se = monte_carlo_stderr(m1, m2, spp)
        at_sensor, tau = apply_path(m1, range_m, radiometry.path, k, weights)
        total = at_sensor if total is None else total + at_sensor
        var = (tau * se) ** 2 if var is None else var + (tau * se) ** 2
    return total, np.sqrt(var)
