"""Scene elements: each gives its Mitsuba dict and the parameter keys it updates per frame.

Eradiate's pattern (STYLE.md): a scene is a flat dict of elements, and an element knows the
parameters (``mi.traverse`` keys) it changes from frame to frame. The infrared scene
(:class:`humv_usd.render.ir.IRScene`) and the visible path tracer's scene
(:class:`humv_usd.render.eo.EOScene`) are built from the same elements; they differ only in
what a surface, the sky and the sun carry (band radiance and a gray reflectance, or spectra).

A new light (the moon, a street lamp) or a new band plugs in as one more element here: its dict,
and the keys its per-frame update writes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from humv_usd.geometry.camera import CameraPose
from humv_usd.render.scene_export import face_corners

#: Near and far clip of the Mitsuba sensors [m]; USD clipping ranges are ignored (no clipping).
NEAR_CLIP_M = 1e-3
FAR_CLIP_M = 1e8
#: Key of the sky emitter in the Mitsuba scene.
SKY_ID = "sky"
#: Key of the sun (directional emitter) in the Mitsuba scene.
SUN_ID = "sun"


@dataclass(frozen=True)
class Element:
    """One scene element: its key in the scene dict, its Mitsuba dict and the parameter keys
    (``mi.traverse(scene)`` names) it updates per frame."""

    key: str
    mitsuba: dict
    updates: tuple[str, ...] = ()


def look_at(mi, pose: CameraPose, scalar: bool = True):
    """The camera's to-world transform (Mitsuba ``look_at``: local +Z along ``pose.forward``)."""
    cls = mi.ScalarTransform4f if scalar else mi.Transform4f
    origin = [float(v) for v in pose.origin]
    target = [float(v) for v in pose.origin + pose.forward]
    return cls().look_at(origin=origin, target=target, up=[float(v) for v in pose.up])


def integrator(max_depth: int) -> dict:
    """``moment`` around ``path`` (``max_depth`` -1: unbounded, Russian roulette): the per-pixel
    first and second moments give the Monte Carlo standard error."""
    return {"type": "moment", "nested": {"type": "path", "max_depth": int(max_depth)}}


def perspective_sensor(mi, setup, spp: int, pixel_format: str) -> Element:
    """A pinhole camera (horizontal field of view of its pose) with an ``hdrfilm`` of
    ``pixel_format`` ("luminance" for a band, "xyz" for colour) and a box filter: every sample
    lands in exactly one pixel. Per frame: its pose and field of view."""
    return Element(
        setup.id,
        {
            "type": "perspective",
            "fov": float(setup.pose.fov_x_deg),
            "fov_axis": "x",
            "near_clip": NEAR_CLIP_M,
            "far_clip": FAR_CLIP_M,
            "to_world": look_at(mi, setup.pose, scalar=True),
            "film": {
                "type": "hdrfilm",
                "width": int(setup.width),
                "height": int(setup.height),
                "pixel_format": pixel_format,
                "component_format": "float32",
                "rfilter": {"type": "box"},
            },
            "sampler": {"type": "independent", "sample_count": int(spp)},
        },
        (f"{setup.id}.to_world", f"{setup.id}.x_fov"),
    )


def constant_sky(radiance: dict, value_key: str) -> Element:
    """A uniform sky of ``radiance`` (a Mitsuba spectrum dict); per frame its ``value_key``
    (under ``sky.radiance``) and its next-event sampling weight."""
    return Element(
        SKY_ID,
        {"type": "constant", "radiance": radiance},
        (f"{SKY_ID}.radiance.{value_key}", f"{SKY_ID}.sampling_weight"),
    )


def envmap_sky(mi, bitmap) -> Element:
    """A sky that varies with zenith angle: a lat-long ``envmap`` (row 0 = zenith). Mitsuba's
    envmap is Y-up in its local frame: rotating +90 deg about X takes local +Y to the stage's +Z."""
    return Element(
        SKY_ID,
        {
            "type": "envmap",
            "bitmap": mi.Bitmap(bitmap),
            "to_world": mi.ScalarTransform4f().rotate([1.0, 0.0, 0.0], 90.0),
        },
        (f"{SKY_ID}.data", f"{SKY_ID}.sampling_weight"),
    )


def directional_sun(irradiance: dict, value_key: str) -> Element:
    """The sun as a ``directional`` emitter (beam-normal ``irradiance``, a Mitsuba spectrum
    dict); per frame its direction, irradiance and next-event sampling weight."""
    return Element(
        SUN_ID,
        {"type": "directional", "direction": [0.0, 0.0, -1.0], "irradiance": irradiance},
        (f"{SUN_ID}.to_world", f"{SUN_ID}.irradiance.{value_key}", f"{SUN_ID}.sampling_weight"),
    )


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
    header = [
        "ply",
        "format binary_little_endian 1.0",
        f"element vertex {len(vertices)}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {len(triangles)}",
        "property list uchar int vertex_indices",
    ]
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


#: Smallest value of a spectrum handed to Mitsuba (a zero would collapse it to a constant, whose
#: values then cannot be updated per frame).
SPECTRUM_FLOOR = 1e-12


def regular_spectrum(wavelengths_nm, values) -> dict:
    """A Mitsuba ``regular`` spectrum: ``values`` (floored at :data:`SPECTRUM_FLOOR`) evenly
    spaced from the first to the last of ``wavelengths_nm`` [nm] (the sky, the sun, a lamp, a
    reflectance in the spectral variant)."""
    v = np.maximum(np.asarray(values, dtype=float), SPECTRUM_FLOOR)
    return {
        "type": "regular",
        "wavelength_min": float(wavelengths_nm[0]),
        "wavelength_max": float(wavelengths_nm[-1]),
        "values": ", ".join(f"{x:.9g}" for x in v),
    }


def mesh(
    part, vertices, flip: bool, workdir, bsdf: dict, updates=(), emitter=None, face_attributes=None, prefix=""
) -> Element:
    """A part as a PLY mesh (written to ``workdir``, read at load) with face normals, its
    ``instance`` id as the face attribute ``face_instance`` (labels), ``bsdf`` and an optional
    area ``emitter``; ``flip`` reverses the winding. Per frame: its vertex positions and the
    ``updates`` keys (under the part's key) the caller names."""
    tris = face_corners(part.triangles, flip)
    filename = os.path.join(str(workdir), f"{prefix}{part.key}.ply")
    attributes = dict(face_attributes or {})
    attributes["instance_0"] = np.full(len(tris), float(part.instance_id))
    write_ply(filename, vertices, tris, attributes)
    d = {"type": "ply", "filename": filename, "face_normals": True, "bsdf": bsdf}
    if emitter is not None:
        d["emitter"] = emitter
    return Element(part.key, d, (f"{part.key}.vertex_positions", *(f"{part.key}.{k}" for k in updates)))


def scene_dict(max_depth: int, elements) -> dict:
    """The Mitsuba scene dict of ``elements`` with the moment/path integrator."""
    scene: dict = {"type": "scene", "integrator": integrator(max_depth)}
    for e in elements:
        scene[e.key] = e.mitsuba
    return scene
