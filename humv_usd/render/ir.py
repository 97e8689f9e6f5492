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
approximation that spectral sub-bands (a later issue) will reduce.

Surfaces are one-sided, as Mitsuba's area emitter and ``diffuse`` BSDF are: the back of a face
(seen from inside a closed mesh, or the underside of a single-sided plate) neither emits nor
reflects. Closed meshes with outward normals (USD ``orientation`` honoured) are what compose writes.

The integrator is ``moment`` around ``path`` (``max_depth`` -1: unbiased, Russian roulette), with
next-event estimation of the sky only (see :data:`AREA_EMITTER_SAMPLING_WEIGHT`); the film is
``hdrfilm`` luminance with a ``box`` filter, so every sample lands in exactly one pixel and the
second moment gives the per-pixel Monte Carlo standard error of the mean.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from humv_usd.render import mode
from humv_usd.render.export import CameraPose, Part

#: Near and far clip of the Mitsuba sensors [m]; USD clipping ranges are ignored (no clipping).
NEAR_CLIP_M = 1e-3
FAR_CLIP_M = 1e8
#: Key of the sky emitter in the Mitsuba scene.
SKY_ID = "sky"
#: Next-event estimation never picks the surfaces' area emitters. Mitsuba 3.9.1 samples an area
#: emitter whose radiance is spatially varying (our per-face ``mesh_attribute``) through the
#: texture's UV parameterization, which a UV-less mesh does not have: in ``llvm_ad_mono`` that
#: biased an isothermal box-on-ground furnace scene low by 0.2-0.5 %, and in ``scalar_rgb`` it
#: segfaults. With weight 0, emitters are reached by BSDF sampling, whose MIS weight is then 1:
#: unbiased (the furnace test holds) and, for surfaces that fill a large solid angle as in
#: thermal scenes, little noisier. The sky keeps next-event estimation.
AREA_EMITTER_SAMPLING_WEIGHT = 0.0


def write_ply(path, vertices, triangles, face_attributes: dict[str, np.ndarray]) -> None:
    """Write a binary little-endian PLY with per-face float properties.

    Parameters
    ----------
    path : path-like
        Output file.
    vertices : (V, 3) float
        Vertex positions [m].
    triangles : (T, 3) int
        Vertex indices per triangle (counter-clockwise = front).
    face_attributes : dict of str to (T,) float
        Per-face float properties, e.g. ``{'radiance_0': ...}``. Mitsuba turns a property
        ``<name>_0`` into the mesh attribute ``face_<name>`` (a bare name is ignored).
    """
    vertices = np.ascontiguousarray(vertices, dtype="<f4").reshape(-1, 3)
    triangles = np.asarray(triangles, dtype="<i4").reshape(-1, 3)
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(vertices)}",
              "property float x", "property float y", "property float z",
              f"element face {len(triangles)}", "property list uchar int vertex_indices"]
    header += [f"property float {name}" for name in face_attributes]
    header.append("end_header")
    dtype = np.dtype([("n", "u1"), ("v", "<i4", 3)] + [(name, "<f4") for name in face_attributes])
    faces = np.zeros(len(triangles), dtype=dtype)
    faces["n"] = 3
    faces["v"] = triangles
    for name, values in face_attributes.items():
        faces[name] = np.asarray(values, dtype=float).ravel()
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(vertices.tobytes())
        f.write(faces.tobytes())


@dataclass
class SensorSetup:
    """A sensor as the Mitsuba scene sees it."""

    id: str  # Mitsuba id
    width: int
    height: int
    pose: CameraPose


def _look_at(mi, pose: CameraPose, scalar: bool):
    cls = mi.ScalarTransform4f if scalar else mi.Transform4f
    origin = [float(v) for v in pose.origin]
    target = [float(v) for v in pose.origin + pose.forward]
    return cls().look_at(origin=origin, target=target, up=[float(v) for v in pose.up])


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
    """

    def __init__(self, parts, sensors: list[SensorSetup], spp: int, max_depth: int, workdir):
        mi = mode.mitsuba()
        self.mi = mi
        self.scalar = not mode.is_vectorized()
        self.parts = [p for p, _, _ in parts]
        self.sensors = {s.id: s for s in sensors}
        scene: dict = {
            "type": "scene",
            "integrator": {"type": "moment", "nested": {"type": "path", "max_depth": int(max_depth)}},
            SKY_ID: {"type": "constant", "radiance": {"type": "uniform", "value": 0.0}},
        }
        for s in sensors:
            scene[s.id] = {
                "type": "perspective", "fov": float(s.pose.fov_x_deg), "fov_axis": "x",
                "near_clip": NEAR_CLIP_M, "far_clip": FAR_CLIP_M,
                "to_world": _look_at(mi, s.pose, scalar=True),
                "film": {"type": "hdrfilm", "width": int(s.width), "height": int(s.height),
                         "pixel_format": "luminance", "component_format": "float32",
                         "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": int(spp)},
            }
        for part, vertices, flip in parts:
            tris = part.triangles[:, [0, 2, 1]] if flip else part.triangles
            filename = os.path.join(str(workdir), f"{part.key}.ply")
            write_ply(filename, vertices, tris, {
                "radiance_0": np.zeros(len(tris)),
                "instance_0": np.full(len(tris), float(part.instance_id)),
            })
            scene[part.key] = {
                "type": "ply", "filename": filename, "face_normals": True,
                "bsdf": {"type": "diffuse", "reflectance": {"type": "uniform", "value": 0.5}},
                "emitter": {"type": "area", "sampling_weight": AREA_EMITTER_SAMPLING_WEIGHT,
                            "radiance": {"type": "mesh_attribute", "name": "face_radiance"}},
            }
        # optimize=False: Mitsuba >= 3.6 otherwise merges equal nodes (e.g. two parts' BSDFs that
        # start with the same reflectance) and meshes, and per-part parameters would be shared.
        self.scene = mi.load_dict(scene, optimize=False)
        self.params = mi.traverse(self.scene)
        self._sensor_objects = {s.id(): s for s in self.scene.sensors()}
        channels = ["Y"] + list(self.scene.integrator().aov_names())
        self._m1 = channels.index("nested.Y")
        self._m2 = channels.index("m2_nested.Y")
        self._positions: dict[str, np.ndarray] = {p.key: np.asarray(v, dtype=np.float32) for p, v, _ in parts}

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
        self._set_array(f"{part.key}.vertex_positions", v.ravel())

    def set_surface(self, part: Part, face_radiance, reflectance: float) -> None:
        """Per-triangle emitted radiance [W m^-2 sr^-1] and diffuse reflectance of a part."""
        self._set_array(f"{part.key}.face_radiance", face_radiance)
        self.params[f"{part.key}.bsdf.reflectance.value"] = float(reflectance)

    def set_sky(self, radiance: float) -> None:
        """Sky radiance [W m^-2 sr^-1]."""
        self.params[f"{SKY_ID}.radiance.value"] = float(radiance)

    def set_camera(self, sensor_id: str, pose: CameraPose) -> None:
        self.sensors[sensor_id].pose = pose
        self.params[f"{sensor_id}.to_world"] = _look_at(self.mi, pose, scalar=self.scalar)
        self.params[f"{sensor_id}.x_fov"] = float(pose.fov_x_deg)

    def update(self) -> None:
        self.params.update()

    # --- render ------------------------------------------------------------------------------
    def render(self, sensor_id: str, spp: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """First and second moments of the pixel radiance, (H, W) float64 each."""
        img = self.mi.render(self.scene, sensor=self._sensor_objects[sensor_id], spp=int(spp),
                             seed=int(seed) % 2**32)
        a = np.asarray(img, dtype=np.float64)
        return a[..., self._m1], a[..., self._m2]

    def labels(self, sensor_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Depth along the optical axis [m] (inf for sky) and instance id (0 for sky), (H, W).

        One ray through each pixel centre, from the same Mitsuba sensor that renders.
        """
        mi = self.mi
        setup = self.sensors[sensor_id]
        sensor = self._sensor_objects[sensor_id]
        w, h = setup.width, setup.height
        xs, ys = np.meshgrid((np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)
        origin = np.asarray(setup.pose.origin, dtype=np.float64)
        forward = np.asarray(setup.pose.forward, dtype=np.float64)
        if self.scalar:
            depth = np.full(w * h, np.inf)
            ident = np.zeros(w * h, dtype=np.uint32)
            for i, (x, y) in enumerate(zip(xs.ravel(), ys.ravel())):
                ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(float(x), float(y)), mi.Point2f(0.5, 0.5))
                si = self.scene.ray_intersect(ray)
                if si.is_valid():
                    depth[i] = float(np.dot(np.asarray(si.p, dtype=np.float64) - origin, forward))
                    ident[i] = int(round(si.shape.eval_attribute_1("face_instance", si)))
            return depth.reshape(h, w), ident.reshape(h, w)
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(mi.Float(xs.ravel()), mi.Float(ys.ravel())),
                                   mi.Point2f(0.5, 0.5))
        si = self.scene.ray_intersect(ray)
        valid = si.is_valid()
        ident = si.shape.eval_attribute_1("face_instance", si, valid)
        valid_np = np.asarray(valid, dtype=bool)
        p = np.asarray(si.p, dtype=np.float64)  # (3, N)
        p = p.T if p.shape[0] == 3 and p.ndim == 2 and p.shape[1] == w * h else p
        depth = (p - origin[None, :]) @ forward
        depth = np.where(valid_np, depth, np.inf)
        ident = np.where(valid_np, np.rint(np.asarray(ident, dtype=np.float64)), 0).astype(np.uint32)
        return depth.reshape(h, w), ident.reshape(h, w)


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
