"""Smooth shading of the facet field (issue 25, deliverable 2): the fast estimator blends each
face's surface terms to its corners (:func:`humv_usd.render.estimator.corner_blend`) and
interpolates them at the hit, so a faceted garment no longer renders as a checkerboard."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.testing import assert_allclose
from test_render import add_camera, add_material, add_mesh, box, new_stage
from test_render_eo_fast import _uv_sphere
from test_render_radiometry import MWIR, atmosphere_tables, sun
from test_render_radiometry import new_stage as sun_stage

from humv_usd.physics import planck
from humv_usd.render import estimator as E


def _grid(n: int, flip: bool = False):
    xs = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(xs, xs)
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1).astype(np.float32)
    tris = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = (
                i * (n + 1) + j,
                i * (n + 1) + j + 1,
                (i + 1) * (n + 1) + j + 1,
                (i + 1) * (n + 1) + j,
            )
            tris += [[a, b, c], [a, c, d]]
    return v, np.asarray(tris)


def _scene(*parts):
    """A stand-in for IRScene: parts (key, vertices, triangles, flipped)."""
    objs = [SimpleNamespace(key=k, triangles=t) for k, _, t, _ in parts]
    verts = {k: v for k, v, _, _ in parts}
    flips = {k: f for k, _, _, f in parts}
    return SimpleNamespace(
        parts=objs, vertices=lambda p: verts[p.key], flipped=lambda p: flips[p.key], geometry_version=0
    )


def _corner_points(scene):
    """World position of every corner in the blend's order (winding flips applied)."""
    out = []
    for p in scene.parts:
        t = p.triangles[:, [0, 2, 1]] if scene.flipped(p) else p.triangles
        out.append(scene.vertices(p)[t].reshape(-1, 3))
    return np.concatenate(out)


def test_corner_blend_reproduces_a_linear_field_inside_a_surface():
    """Gouraud from face values sampled at the centroids of a regular grid: exact at every
    interior vertex for a field linear over the surface (winding flipped or not)."""
    for flip in (False, True):
        v, t = _grid(12)
        scene = _scene(("a", v, t, flip))
        blend = E.corner_blend(scene)
        centroid = v[t].mean(axis=1)
        field = lambda p: 3.0 * p[:, 0] - 2.0 * p[:, 1] + 7.0  # noqa: E731
        corners = blend @ field(centroid)
        p = _corner_points(scene)
        inside = (p[:, 0] > 1e-6) & (p[:, 0] < 1 - 1e-6) & (p[:, 1] > 1e-6) & (p[:, 1] < 1 - 1e-6)
        assert inside.sum() > 700
        assert_allclose(corners[inside], field(p)[inside], atol=1e-5)
        # the flat face values, in contrast, are off by up to half a cell's gradient
        assert np.abs(np.repeat(field(centroid), 3) - field(p))[inside].max() > 0.1
        assert_allclose(np.asarray(blend.sum(axis=1)).ravel(), 1.0)  # a weighted mean


def test_corner_blend_keeps_creases_and_part_boundaries():
    """A box's 90 deg edges and the seam between two parts (two materials) stay sharp: a corner
    there takes only the faces of its own side; coplanar faces of one side blend."""
    pts, counts, idx = box((0.0, 0.0, 0.0), 2.0)
    quads = np.asarray(idx).reshape(-1, 4)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    v = np.asarray(pts, dtype=np.float32)
    scene = _scene(("box", v, tris, False))
    blend = E.corner_blend(scene)
    normal_of = E.face_normals(scene)[0]
    side = np.argmax(np.abs(normal_of) * [1, 2, 4], axis=1) * 2 + (normal_of.sum(axis=1) > 0)
    value = side.astype(float) * 10.0  # one value per side of the box
    assert_allclose(blend @ value, np.repeat(value, 3), atol=1e-9)
    # two coplanar parts sharing an edge: no blending across it
    v, t = _grid(4)
    left = t[v[t].mean(axis=1)[:, 0] < 0.5]
    right = t[v[t].mean(axis=1)[:, 0] >= 0.5]
    scene = _scene(("l", v, left, False), ("r", v, right, False))
    blend = E.corner_blend(scene)
    value = np.r_[np.zeros(len(left)), np.ones(len(right))]
    corners = (blend @ value).reshape(-1, 3)
    assert_allclose(corners[: len(left)], 0.0)
    assert_allclose(corners[len(left) :], 1.0)


def test_corner_blend_welds_split_vertices_and_survives_degenerate_faces():
    """A mesh split along a seam (duplicated vertices, as a UV seam) blends across it; a
    zero-area face keeps its own value."""
    v, t = _grid(6)
    seam = v[t].mean(axis=1)[:, 0] > 0.5
    v2 = np.concatenate([v, v])
    t2 = np.where(seam[:, None], t + len(v), t)  # the right half uses the copies
    t2 = np.concatenate([t2, [[0, 0, 1]]])  # and a degenerate face
    scene = _scene(("a", v2, t2, False))
    blend = E.corner_blend(scene)
    values = np.r_[np.where(seam, 1.0, 0.0), 5.0]
    corners = (blend @ values).reshape(-1, 3)
    on_seam = np.isclose(v2[t2][..., 0], 0.5)[:-1]
    assert np.all((corners[:-1][on_seam] > 0.0) & (corners[:-1][on_seam] < 1.0))
    assert_allclose(corners[-1], 5.0)


def test_a_kept_corner_blend_follows_moving_vertices_and_refits_when_a_weld_splits():
    """:class:`shading.CornerBlend` (what a scene keeps between frames) gives the matrix that
    :func:`corner_blend` builds from scratch, for moved vertices too (a bend that crosses the
    crease angle on some vertices), and says it no longer fits when welded copies part."""
    from humv_usd.geometry import shading

    v, t = _grid(6)
    seam = v[t].mean(axis=1)[:, 0] > 0.5
    v2 = np.concatenate([v, v])
    t2 = np.concatenate([np.where(seam[:, None], t + len(v), t), [[0, 0, 1]]])
    kept = shading.CornerBlend([(v2, t2)])
    for fold_deg in (0.0, 40.0, 75.0):  # fold the sheet about x = 0.5: blended, then a crease
        moved = v2.astype(float).copy()
        right = moved[:, 0] > 0.5
        a = np.radians(fold_deg)
        dx = moved[right, 0] - 0.5
        moved[right, 0], moved[right, 2] = 0.5 + dx * np.cos(a), dx * np.sin(a)
        moved = moved.astype(np.float32)
        assert kept.fits([(moved, t2)])
        fresh = shading.corner_blend([(moved, t2)])
        assert abs(kept([(moved, t2)]) - fresh).max() < 1e-12
    split = v2.copy()
    split[len(v) + 3, 2] += 0.01  # one copy of a seam vertex moves off its twin
    assert not kept.fits([(split, t2)]) and not kept.fits([(v2, t2[:-1])])


def _prism_stage(tmp_path, sides: int = 12):
    """A vertical prism (radius 1 m, 12 sides) whose face temperatures follow
    T = 300 K + 10 K n_x, black (emissivity 1), seen side-on at 48 x 36 px."""
    stage = new_stage(tmp_path / "stage.usda", sky_k=250.0)
    black = add_material(stage, "black", 1.0)
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = [(np.cos(a), np.sin(a)) for a in phi]
    pts = [(x, y, z) for z in (0.0, 3.0) for x, y in ring]
    counts, idx = [], []
    for k in range(sides):
        a, b = k, (k + 1) % sides
        counts.append(4)
        idx += [a, b, sides + b, sides + a]
    mid = phi + np.pi / sides
    add_mesh(
        stage, "/World/Scene/prism", pts, counts, idx, material=black,
        temperature_k=300.0 + 10.0 * np.cos(mid), instance_id=1,
    )  # fmt: skip
    add_camera(stage, "lwir", eye=(0.0, -6.0, 1.5), target=(0.0, 0.0, 1.5), fov_x_deg=30, resolution=(48, 36))
    stage.Save()
    return tmp_path / "stage.usda"


def test_smooth_shading_renders_a_faceted_surface_close_to_its_smooth_field(tmp_path):
    """The prism's image against (a) the Gouraud field computed here independently (vertex
    temperature = mean of its two faces, linear along each face): within the Monte Carlo noise
    with the plain blend (the shadowed term's one-ring gain steps off; with them on, the image's
    mean comes closer to the flat faces' by half or more);
    (b) the field the faces sample (T = 300 + 10 cos(azimuth) at each pixel-centre hit): flat
    shading is off by up to half a face's gradient (2.6 K at 12 sides), smooth shading only by
    the chord's error (at most 2 x 10 K (1 - cos 15 deg) = 0.68 K), and its steps between
    neighbouring pixels shrink accordingly."""
    from humv_usd.bench.render import _Frame

    sides = 12
    fr = _Frame(_prism_stage(tmp_path, sides))
    s = fr.rendered[0]
    sid = fr.sensor_ids[s.name]
    sub, rad, eps, tr = fr.setup(s, 2)
    args = (fr.scene, sid, fr.state, sub, eps, rad, 16, 3, tr)
    band = s.wavelength_range_um
    hits = fr.scene.hits(sid)
    on = (hits.part >= 0) & ~E.geometric_edges(hits)
    x, y = hits.position[..., 0], hits.position[..., 1]
    truth = 300.0 + 10.0 * np.cos(np.arctan2(y, x))
    # Gouraud, independently: the face k between vertices at k and k+1 steps of 30 deg
    step = 2 * np.pi / sides
    face_t = 300.0 + 10.0 * np.cos(np.arange(sides) * step + step / 2)
    vertex_t = 0.5 * (face_t + np.roll(face_t, 1))
    k = np.floor(np.mod(np.arctan2(y, x), 2 * np.pi) / step).astype(int) % sides
    a = np.stack([np.cos(k * step), np.sin(k * step)], -1)
    b = np.stack([np.cos((k + 1) * step), np.sin((k + 1) * step)], -1)
    frac = np.einsum("...i,...i", np.stack([x, y], -1) - a, b - a) / np.sum((b - a) ** 2, axis=-1)
    gouraud = (1 - frac) * vertex_t[k] + frac * vertex_t[(k + 1) % sides]
    errors, means = {}, {}
    for smooth, gains in ((False, None), (True, 0), (True, None)):
        radiance, stderr = E.render_band_fast(*args, smooth=smooth, dark_gain_steps=gains)
        bt = planck.brightness_temperature(np.maximum(radiance, 1e-30), band)
        err = (bt - truth)[on]
        steps = np.abs(np.diff(np.where(on, bt, np.nan), axis=1))
        errors[smooth, gains] = (np.abs(err).max(), np.sqrt(np.mean(err**2)), np.nanpercentile(steps, 99))
        means[smooth, gains] = np.mean(err)
        if smooth and gains == 0:  # the plain blend (the shadowed term's gain steps off)
            sigma_k = stderr / planck.band_radiance_derivative(300.0, band)
            assert np.abs(bt - gouraud)[on].max() < 0.05 + 4 * sigma_k[on].max()
    flat, smooth = errors[False, None], errors[True, None]
    # the shadowed term's one-ring gain brings the mean back toward the faces' (+0.039 -> +0.015 K)
    assert abs(means[True, None]) < 0.5 * abs(means[True, 0]), means
    assert flat[0] > 1.5, flat  # the facets' steps are there to remove
    assert smooth[0] < 0.75 and smooth[1] < 0.45, smooth
    assert smooth[1] < 0.5 * flat[1] and smooth[2] < 0.5 * flat[2], (smooth, flat)


def ball_frame(path):
    """The saved stage at ``path`` (one camera seeing a ball, instance 1) as the render bench's
    frame: (frame, sensor id, its setup (sub-bands, radiometry, emissivity, transmittance), the
    pixel-centre hits, the ball's pixels away from geometric edges and two pixels inside its
    outline)."""
    from humv_usd.bench.render import _Frame

    fr = _Frame(path)
    cam = fr.rendered[0]
    sid = fr.sensor_ids[cam.name]
    setup = fr.setup(cam, 1)
    hits = fr.scene.hits(sid)
    inner = (hits.instance == 1) & ~E.geometric_edges(hits)
    for _ in range(2):  # two pixels inside the outline
        inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
        inner[[0, -1], :] = inner[:, [0, -1]] = False
    assert inner.sum() > 1500
    return fr, sid, setup, hits, inner


def test_smooth_shading_keeps_a_curved_surfaces_sunlit_mean_in_mwir(tmp_path):
    """A gray faceted sphere (eps 0.2, 48 x 24 segments, 7.5 deg between neighbouring normals,
    the garments' median) at 300 K in a 300 K blackbody surround (sky and ground), in a strong
    MWIR sun, seen from above: every pixel is B(T) + rho E max(0, n.s) / pi in band (Kirchhoff:
    eps B(T) + rho B(T_surround) = B(T)) with n the flat face's normal at the pixel centre, the
    flat-faced path tracer's field; the smooth-shaded mean over the pixels away from the outline
    keeps it within 0.2 % of the sun term + 4 sigma (measured: -0.03 %). The plain blend of the
    faces' sun terms to the corners shrank it (about cos^2 of half the angle between
    neighbours; -0.53 % here): the close-up MWIR person 52 mK under the IR path tracer (issue 25;
    :func:`humv_usd.render.estimator.corner_table`, ``sun_gain_steps``)."""
    t_k, eps, e_um = 300.0, 0.2, 500.0  # solar spectral irradiance [W m-2 um-1], flat over the band
    stage = sun_stage(tmp_path / "s.usda", sky_k=t_k)
    gray, black = add_material(stage, "gray", eps), add_material(stage, "black", 1.0)
    pts, tris = _uv_sphere(48, 24)
    add_mesh(stage, "/World/Scene/ball", pts, [3] * len(tris), tris.ravel(), gray, t_k, instance_id=1)
    g = [(-200.0, -200.0, -5.0), (200.0, -200.0, -5.0), (200.0, 200.0, -5.0), (-200.0, 200.0, -5.0)]
    add_mesh(stage, "/World/Scene/ground", g, [4], [0, 1, 2, 3], black, t_k, instance_id=2)
    add_camera(
        stage, "cam", (0, 0, 12), (0, 0, 0), fov_x_deg=11, resolution=(64, 64), band=MWIR,
        band_token="MWIR", up=(0, 1, 0),
    )  # fmt: skip
    atmosphere_tables(stage, [1.0, 3.0, 5.0, 20.0], solar=[e_um] * 4)
    s = np.array([0.3, 0.2, 0.9]) / np.linalg.norm([0.3, 0.2, 0.9])
    sun(stage, tuple(s))
    stage.Save()
    fr, sid, (sub, rad, emissivity, trans), hits, inner = ball_frame(tmp_path / "s.usda")
    sun_term = (1.0 - eps) * e_um * (MWIR[1] - MWIR[0]) * np.maximum(hits.normal @ s, 0.0) / np.pi
    want_sun = sun_term[inner].mean()
    emitted = planck.band_radiance(t_k, MWIR)
    errors = {}
    for gains in (None, 0):
        radiance, stderr = E.render_band_fast(
            fr.scene, sid, fr.state, sub, emissivity, rad, 4, 5, trans, sun_gain_steps=gains
        )
        sigma = np.sqrt(np.sum(stderr[inner] ** 2)) / inner.sum()
        errors[gains] = (radiance[inner].mean() - emitted - want_sun, sigma)
    got, sigma = errors[None]
    assert abs(got) < 4 * sigma + 2e-3 * want_sun, (got / want_sun, sigma / want_sun)
    old, sigma = errors[0]  # the plain blend: the test can fail
    assert old < -(4 * sigma + 2e-3 * want_sun), (old / want_sun, sigma / want_sun)
