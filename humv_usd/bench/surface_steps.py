"""Temperature steps across a surface: between neighbouring faces of one mesh (the thermal
layer) and between neighbouring pixels of one labelled region (the rendered images).

A smooth surface under smooth forcing has small steps between neighbours; a faceted one
(one temperature per flat face, each with its own sun cosine or shadow ray) has steps as large
as the facet-to-facet spread of its forcing. These measures say how large, as the distribution
(median, 90th percentile, largest) of the absolute differences, to compare with the render's
stated per-pixel noise (issue 25, deliverable 2).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
from pxr import Usd, UsdGeom

from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.geometry.raycast import RayCaster, first_faces
from humv_usd.groundtruth.labels import CLASS_ID
from humv_usd.human.usdskel import skinned_points
from humv_usd.physics.planck import band_radiance, brightness_temperature, brightness_temperature_sensitivity
from humv_usd.render.estimator import control_variate_table, sky_rows
from humv_usd.render.radiometry import SubBands, frame_radiometry
from humv_usd.usd.atmosphere import atmosphere_spectra, sky_temperature
from humv_usd.usd.environment import direct_normal_irradiance, sun_direction
from humv_usd.usd.sensor import stage_sensors
from humv_usd.usd.thermal import has_face_temperatures, read_face_temperatures


def face_neighbours(counts, indices, points=None, tolerance_m: float = 1e-9) -> np.ndarray:
    """(P, 2) pairs of polygons that share an edge, each pair once.

    Parameters
    ----------
    counts : (F,) int
        Vertices per face (USD faceVertexCounts).
    indices : (sum(counts),) int
        Face-vertex indices (USD faceVertexIndices).
    points : (V, 3) array, optional
        Vertex positions [m]: when given, vertices closer than ``tolerance_m`` count as one (a
        seam split for UVs still joins its two sides).
    tolerance_m : float
        Position tolerance [m] for ``points``.
    """
    counts = np.asarray(counts, dtype=np.int64)
    idx = np.asarray(indices, dtype=np.int64)
    if points is not None:
        p = np.asarray(points, dtype=float)
        _, vid = np.unique(np.round(p / tolerance_m), axis=0, return_inverse=True)
        idx = vid.reshape(-1)[idx]
    face = np.repeat(np.arange(len(counts)), counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    nxt = start + (np.arange(len(idx)) - start + 1) % np.repeat(counts, counts)
    a, b = idx, idx[nxt]
    edges = np.c_[np.minimum(a, b), np.maximum(a, b)]
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    e, f = edges[order], face[order]
    same = np.all(e[1:] == e[:-1], axis=1) & (f[1:] != f[:-1])
    pairs = np.c_[f[:-1][same], f[1:][same]]
    pairs = np.sort(pairs, axis=1)
    return np.unique(pairs, axis=0) if len(pairs) else pairs.reshape(0, 2)


def step_stats(steps) -> dict:
    """Distribution of absolute steps: ``n``, ``p50``, ``p90``, ``p99``, ``max`` (NaN when
    empty), in the steps' unit."""
    s = np.abs(np.asarray(steps, dtype=float).ravel())
    s = s[np.isfinite(s)]
    if len(s) == 0:
        return {"n": 0, "p50": np.nan, "p90": np.nan, "p99": np.nan, "max": np.nan}
    p50, p90, p99 = np.percentile(s, [50, 90, 99])
    return {"n": int(len(s)), "p50": float(p50), "p90": float(p90), "p99": float(p99), "max": float(s.max())}


def face_steps(values, pairs) -> dict:
    """:func:`step_stats` of |values[i] - values[j]| over neighbour ``pairs`` (face_neighbours)."""
    v = np.asarray(values, dtype=float)
    p = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return step_stats(v[p[:, 0]] - v[p[:, 1]])


def _erode(mask: np.ndarray, margin: int) -> np.ndarray:
    """Pixels of ``mask`` whose (2 margin + 1)^2 neighbourhood lies inside it."""
    out = mask.copy()
    for _ in range(int(margin)):
        m = out.copy()
        m[1:] &= out[:-1]
        m[:-1] &= out[1:]
        m[:, 1:] &= out[:, :-1]
        m[:, :-1] &= out[:, 1:]
        m[1:, 1:] &= out[:-1, :-1]
        m[:-1, :-1] &= out[1:, 1:]
        m[1:, :-1] &= out[:-1, 1:]
        m[:-1, 1:] &= out[1:, :-1]
        out = m
    return out


def pixel_steps(image, mask, margin: int = 1, exclude=None) -> dict:
    """:func:`step_stats` of the differences between horizontally and vertically neighbouring
    pixels of ``image`` that both lie in ``mask`` at least ``margin`` pixels inside its edge
    (the label's edge mixes in other surfaces) and outside ``exclude`` (e.g. pixels near a
    sun-shadow boundary, where a real step belongs).

    Parameters
    ----------
    image : (H, W) array
        E.g. apparent temperature [K] or radiance.
    mask : (H, W) bool
        One region (a garment's pixels).
    margin : int
        Pixels eroded from the mask's edge.
    exclude : (H, W) bool, optional
        Pixels to leave out.
    """
    img = np.asarray(image, dtype=float)
    ok = _erode(np.asarray(mask, dtype=bool), margin)
    if exclude is not None:
        ok &= ~np.asarray(exclude, dtype=bool)
    dh = (img[:, 1:] - img[:, :-1])[ok[:, 1:] & ok[:, :-1]]
    dv = (img[1:] - img[:-1])[ok[1:] & ok[:-1]]
    return step_stats(np.r_[dh, dv])


def noise_steps(sigma_a, sigma_b, seed: int = 0) -> dict:
    """:func:`step_stats` of the steps that independent Gaussian pixel noise alone gives between
    neighbours whose standard errors are ``sigma_a`` and ``sigma_b`` (one draw per pair,
    N(0, sigma_a^2 + sigma_b^2)): what a perfectly smooth surface would show."""
    s = np.sqrt(np.asarray(sigma_a, dtype=float) ** 2 + np.asarray(sigma_b, dtype=float) ** 2)
    return step_stats(s * np.random.default_rng(seed).standard_normal(s.shape))


def _dilate(mask: np.ndarray, radius: int) -> np.ndarray:
    out = mask.copy()
    for _ in range(int(radius)):
        m = out.copy()
        m[1:] |= out[:-1]
        m[:-1] |= out[1:]
        m[:, 1:] |= out[:, :-1]
        m[:, :-1] |= out[:, 1:]
        out = m
    return out


def _pairs(ok: np.ndarray):
    """Flat index pairs of horizontally and vertically neighbouring pixels both in ``ok``."""
    h, w = ok.shape
    idx = np.arange(h * w).reshape(h, w)
    ph = np.c_[idx[:, :-1][ok[:, :-1] & ok[:, 1:]], idx[:, 1:][ok[:, :-1] & ok[:, 1:]]]
    pv = np.c_[idx[:-1][ok[:-1] & ok[1:]], idx[1:][ok[:-1] & ok[1:]]]
    return np.r_[ph, pv]


def _triples(ok: np.ndarray):
    """Flat index triples of three consecutive pixels in a row or a column, all in ``ok``."""
    h, w = ok.shape
    idx = np.arange(h * w).reshape(h, w)
    mh = ok[:, :-2] & ok[:, 1:-1] & ok[:, 2:]
    mv = ok[:-2] & ok[1:-1] & ok[2:]
    th = np.c_[idx[:, :-2][mh], idx[:, 1:-1][mh], idx[:, 2:][mh]]
    tv = np.c_[idx[:-2][mv], idx[1:-1][mv], idx[2:][mv]]
    return np.r_[th, tv]


def band_lighting(stage, time, sensor, ground_radiance: float) -> tuple[float, np.ndarray]:
    """What lights a surface in ``sensor``'s band (a :class:`~humv_usd.physics.sensor.SensorModel`)
    at ``time``, as the render's radiometry and estimator take it, in one sub-band: the direct
    sun's irradiance E [W m-2] normal to the beam at the surface
    (:func:`humv_usd.render.radiometry.frame_radiometry`: the stage's solar spectral irradiance
    over the band and response, else the blackbody fallback; 0 at night or without a sun), and
    the open environment's cosine-weighted hemispherical mean radiance G [W m-2 sr-1] on
    :data:`humv_usd.render.estimator.CV_NODES` even points of the normal's z in [-1, 1] (the
    sky's zenith rows above the horizon, ``ground_radiance`` below:
    :func:`humv_usd.render.estimator.control_variate_table`, the estimator's control variate)."""
    sub = SubBands(sensor.wavelength_range_um, sensor.band_response, 1)
    rad = frame_radiometry(
        sub,
        sky_temperature(stage, time),
        atmosphere_spectra(stage, time),
        sun_direction(stage, time),
        None,
        dni_w_m2=direct_normal_irradiance(stage, time),
    )
    g_tab = np.asarray(control_variate_table(sky_rows(rad, 0), float(ground_radiance)), dtype=float).ravel()
    e = 0.0 if rad.sun_irradiance is None else float(np.sum(rad.sun_irradiance))
    return e, g_tab


def smooth_apparent_temperature(
    temperature_k, emissivity, normal_z, sun_cosine, sun_irradiance, environment, band_um, response=None
):
    r"""Apparent (brightness) temperature [K] in a band of an opaque grey diffuse surface at
    kinetic temperature ``temperature_k`` with band emissivity ``emissivity``, lit by the open
    environment (``environment``: G against the normal's z ``normal_z``, :func:`band_lighting`)
    and a sun of in-band irradiance ``sun_irradiance`` [W m-2] (normal to the beam) at cosine
    ``sun_cosine`` (0 in shadow):
    :math:`T_b = B^{-1}\big(\varepsilon B(T) + (1-\varepsilon)(G(n_z) + E \cos\theta_s / \pi)\big)`.

    Emission by Kirchhoff's law and diffuse (Lambertian) reflection with the reflectance
    :math:`\rho = 1 - \varepsilon` of an opaque surface (Siegel & Howell, *Thermal Radiation
    Heat Transfer*, 4th ed., 2002, chs. 1-3): the render's surface term
    (:func:`humv_usd.render.estimator.surface_table`) on a smooth surface; B the band radiance
    (Planck's law over the band and response, :func:`humv_usd.physics.planck.band_radiance`).
    Reflections of other surfaces nearby (an arm seeing the torso) are left out. NaN where the
    temperature or emissivity is NaN."""
    t = np.asarray(temperature_k, dtype=float)
    eps = np.clip(np.asarray(emissivity, dtype=float), 0.0, 1.0)
    ok = np.isfinite(t) & np.isfinite(eps) & (t > 0)
    out = np.full(t.shape, np.nan)
    if not ok.any():
        return out
    env = np.asarray(environment, dtype=float).ravel()
    nz = np.clip(np.nan_to_num(np.asarray(normal_z, dtype=float)[ok]), -1.0, 1.0)
    g = np.interp(nz, np.linspace(-1.0, 1.0, len(env)), env)
    sun = float(sun_irradiance) * np.asarray(sun_cosine, dtype=float)[ok] / np.pi
    lum = eps[ok] * band_radiance(t[ok], band_um, response) + (1.0 - eps[ok]) * (g + sun)
    out[ok] = brightness_temperature(lum, band_um, response)
    return out


def garment_image_steps(
    stage_path, render_dir, sensor: str, frame: int = 0, margin: int = 1, shadow_px: int = 2
):
    """Steps between neighbouring pixels of each garment of each person in a rendered IR image.

    Which garment a pixel shows and whether that point is in the sun come from an independent
    ray cast of the pixel centres (the camera of ``<sensor>/camera.json``) onto the people's
    posed meshes, the sun shadow ray from that point against the same meshes; a pixel counts
    when its ray hits the garment, the render labels it a garment (``label.material_kind`` 2),
    it lies ``margin`` pixels inside the garment's mask and at least ``shadow_px`` pixels from a
    lit / shadowed change.

    Returns {garment prim path: {"image": step_stats of IR.brightness_temperature [K],
    "surface": of surface.temperature (the layer's temperatures, noise-free) [K],
    "noise": what the render's stated per-pixel error (IR.radiance_stderr through dT/dL)
    alone would give (:func:`noise_steps`) [K], "vertex": the same surface temperatures
    interpolated linearly over each triangle from vertex temperatures (the area-weighted mean of
    the faces around each vertex) [K], "field": the apparent temperature of that smooth surface
    in the band, its smooth reflected sun included (:func:`smooth_apparent_temperature`), i.e.
    what a render that interpolates would show [K], "pixels": pixels used; with the suffix
    "_d2" the same for second differences |T_a - 2 T_b + T_c| of three consecutive pixels,
    which a smooth gradient (a curved surface turning from the sun) leaves near 0 while a step
    between faces shows in full; noise_d2 from N(0, s_a^2 + 4 s_b^2 + s_c^2)}}.

    The vertex temperatures alone are not the field the image shows: in MWIR a white T-shirt
    reflects about 2 K of its apparent temperature from the sun (humvvex, 14:05 in October),
    which the smooth surface shades with its normal; a reference without it counted that real
    shading as roughness (issue 25).
    """
    render_dir = Path(render_dir)
    buf = oiio.ImageBuf(str(render_dir / sensor / f"{frame:04d}.exr"))
    spec = buf.spec()
    names = list(spec.channelnames)
    pix = buf.get_pixels(oiio.FLOAT)
    chan = lambda n: pix[..., names.index(n)].astype(np.float64)  # noqa: E731
    kind = np.rint(chan("label.material_kind") * 2.0**32).astype(np.int64)  # uint32 read as float
    band = [float(x) for x in str(spec.get_string_attribute("humv:band_um")).split("-")]
    radiance, stderr = chan("IR.radiance"), chan("IR.radiance_stderr")
    _, slope = brightness_temperature_sensitivity(np.maximum(radiance, 1e-30), band)
    sigma_k = stderr / np.where(slope > 0, slope, np.inf)
    t_img, t_surf = chan("IR.brightness_temperature"), chan("surface.temperature")
    eps_img = chan("surface.emissivity") if "surface.emissivity" in names else np.full(t_img.shape, np.nan)

    cam = json.loads((render_dir / sensor / "camera.json").read_text())
    fr = next(f for f in cam["frames"] if int(f["frame"]) == int(frame))
    k = np.asarray(fr.get("K", cam["K"]), dtype=float)
    r, t = np.asarray(fr["R"], dtype=float), np.asarray(fr["t"], dtype=float).ravel()
    h, w = int(cam["height"]), int(cam["width"])
    jj, ii = np.meshgrid(np.arange(h) + 0.5, np.arange(w) + 0.5, indexing="ij")
    d_cam = np.stack([ii.ravel(), jj.ravel(), np.ones(h * w)], axis=1) @ np.linalg.inv(k).T
    d = d_cam @ r  # R^T d_cam, row-wise
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = -r.T @ t

    stage = Usd.Stage.Open(str(stage_path))
    time = Usd.TimeCode(frame)
    s = sun_direction(stage, time)
    sun = None if s is None else np.asarray(s, dtype=float) / np.linalg.norm(s)
    pts, tris, owner, paths, t_vertex, c_vertex, n_vertex = [], [], [], [], [], [], []
    off = 0
    for prim in stage.Traverse():
        path = str(prim.GetPath())
        if not prim.IsA(UsdGeom.Mesh) or "/Humans/" not in path:
            continue
        m = UsdGeom.Mesh(prim)
        counts = np.asarray(m.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
        tri, tri_face = fan_triangulate(
            counts, np.asarray(m.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
        )
        p = skinned_points(stage, path, time, space="world")
        tv = np.full(len(p), np.nan)
        cv = np.zeros(len(p))
        nv = np.zeros((len(p), 3))
        if has_face_temperatures(prim):
            cr = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
            area = 0.5 * np.linalg.norm(cr, axis=1)
            tf = read_face_temperatures(prim, len(counts), time)[tri_face]
            wsum = np.bincount(tri.ravel(), np.repeat(area, 3), len(p))
            wsum = np.where(wsum > 0, wsum, np.nan)
            tv = np.bincount(tri.ravel(), np.repeat(area * tf, 3), len(p)) / wsum
            side = -1.0 if m.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded else 1.0
            # area-weighted vertex normals (cr is twice the area times the unit normal)
            nv = np.stack(
                [np.bincount(tri.ravel(), np.repeat(side * cr[:, k], 3), len(p)) for k in range(3)], 1
            )
            if sun is not None:  # each face's unshadowed sun cosine, to the vertices as tf
                cf = np.maximum(side * (cr @ sun) / np.maximum(2.0 * area, 1e-300), 0.0)
                cv = np.nan_to_num(np.bincount(tri.ravel(), np.repeat(area * cf, 3), len(p)) / wsum)
        t_vertex.append(tv)
        c_vertex.append(cv)
        n_vertex.append(nv)
        pts.append(p)
        tris.append(tri + off)
        owner.append(np.full(len(tri), len(paths)))
        paths.append(path)
        off += len(p)
    caster = RayCaster(np.concatenate(pts), np.concatenate(tris))
    v, f = caster.points, caster.triangles
    hit = first_faces(caster, np.broadcast_to(origin, d.shape).copy(), d)
    part = np.where(hit >= 0, np.concatenate(owner)[np.maximum(hit, 0)], -1).reshape(h, w)
    t_interp = np.full(h * w, np.nan)
    c_interp = np.zeros(h * w)
    nz_interp = np.zeros(h * w)
    on = np.nonzero(hit >= 0)[0]
    if len(on):
        tri = v[f[hit[on]]]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        tt = np.einsum("ij,ij->i", tri[:, 0] - origin, n) / np.einsum("ij,ij->i", d[on], n)
        x = origin + tt[:, None] * d[on]
        # barycentric coordinates of the hit point (areas of the sub-triangles)
        nn = np.einsum("ij,ij->i", n, n)
        b1 = np.einsum("ij,ij->i", np.cross(tri[:, 2] - tri[:, 1], x - tri[:, 1]), n) / nn
        b2 = np.einsum("ij,ij->i", np.cross(tri[:, 0] - tri[:, 2], x - tri[:, 2]), n) / nn
        tv = np.concatenate(t_vertex)[f[hit[on]]]
        t_interp[on] = b1 * tv[:, 0] + b2 * tv[:, 1] + (1.0 - b1 - b2) * tv[:, 2]
        cv = np.concatenate(c_vertex)[f[hit[on]]]
        c_interp[on] = b1 * cv[:, 0] + b2 * cv[:, 1] + (1.0 - b1 - b2) * cv[:, 2]
        nv = np.concatenate(n_vertex)[f[hit[on]]]  # (N, 3 corners, 3)
        ni = b1[:, None] * nv[:, 0] + b2[:, None] * nv[:, 1] + (1.0 - b1 - b2)[:, None] * nv[:, 2]
        nz_interp[on] = ni[:, 2] / np.maximum(np.linalg.norm(ni, axis=1), 1e-300)  # Phong's normal
    lit = np.zeros(h * w, dtype=bool)
    if sun is not None:
        on = np.nonzero(hit >= 0)[0]
        tri = v[f[hit[on]]]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        tt = np.einsum("ij,ij->i", tri[:, 0] - origin, n) / np.einsum("ij,ij->i", d[on], n)
        x = origin + tt[:, None] * d[on]
        n = np.where((np.einsum("ij,ij->i", n, d[on]) > 0)[:, None], -n, n)  # towards the camera
        lit[on] = (n @ sun > 0) & (
            first_faces(caster, x + 1e-4 * n, np.broadcast_to(sun, x.shape).copy()) < 0
        )
    model = next((x for x in stage_sensors(stage) if x.name == sensor), None)
    if model is None:
        raise ValueError(f"sensor {sensor!r}: no such sensor camera on {stage_path}")
    ground = np.zeros(radiance.shape, dtype=bool)
    if "label.class_id" in names:
        ground = (np.rint(chan("label.class_id") * 2.0**32) == CLASS_ID["ground"]) & np.isfinite(radiance)
    # the ground's radiance in the band from the image itself (none seen: a blackbody at the
    # median surface temperature the image sees)
    if ground.any():
        ground_l = float(np.median(radiance[ground]))
    else:
        ground_l = float(band_radiance(float(np.nanmedian(t_surf)), band, model.band_response))
    sun_e, env = band_lighting(stage, time, model, ground_l)
    t_field = smooth_apparent_temperature(
        t_interp,
        eps_img.ravel(),
        nz_interp,
        np.where(lit, c_interp, 0.0),
        sun_e,
        env,
        model.wavelength_range_um,
        model.band_response,
    )
    lit = lit.reshape(h, w)
    person = part >= 0
    change = np.zeros((h, w), dtype=bool)
    both = person[:, 1:] & person[:, :-1]
    dh = both & (lit[:, 1:] != lit[:, :-1])
    change[:, 1:] |= dh
    change[:, :-1] |= dh
    both = person[1:] & person[:-1]
    dv = both & (lit[1:] != lit[:-1])
    change[1:] |= dv
    change[:-1] |= dv
    near_shadow = _dilate(change, shadow_px)

    out = {}
    for gi, path in enumerate(paths):
        if "/Clothing/" not in path:
            continue
        ok = _erode((part == gi) & (kind == 2), margin) & ~near_shadow
        pr = _pairs(ok)
        if len(pr) == 0:
            continue
        a, b = pr[:, 0], pr[:, 1]
        ti, ts, sk, tv, tfld = t_img.ravel(), t_surf.ravel(), sigma_k.ravel(), t_interp, t_field
        out[path] = {
            "image": step_stats(ti[a] - ti[b]),
            "surface": step_stats(ts[a] - ts[b]),
            "noise": noise_steps(sk[a], sk[b]),
            "vertex": step_stats(tv[a] - tv[b]),
            "field": step_stats(tfld[a] - tfld[b]),
            "pixels": int(ok.sum()),
        }
        tr = _triples(ok)
        if len(tr):
            a, b, c = tr.T
            for key, x in (("image", ti), ("surface", ts), ("vertex", tv), ("field", tfld)):
                out[path][key + "_d2"] = step_stats(x[a] - 2.0 * x[b] + x[c])
            sd = np.sqrt(sk[a] ** 2 + 4.0 * sk[b] ** 2 + sk[c] ** 2)
            out[path]["noise_d2"] = step_stats(sd * np.random.default_rng(0).standard_normal(len(sd)))
    return out
