"""The sun's term resolved inside each facet (humv_usd.thermal.qrad: smooth normals, several
shadow points per facet) and the surface-step measures (humv_usd.bench.surface_steps)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

from humv_usd.bench import surface_steps as SS
from humv_usd.thermal import qrad as Q
from humv_usd.thermal import radiance_map as RM
from humv_usd.thermal import scene_radiance as SR

E_SUN = 1000.0


def _sun_env(s):
    s = np.asarray(s, dtype=float)
    return RM.RadianceMap(
        np.zeros((2, 12, 24)), sun_direction=s / np.linalg.norm(s), sun_irradiance=np.array([E_SUN, 0.0])
    )


def _cos_on_sphere(mesh, s, n=60):
    """Mean over each flat face of max(0, n(p) . s) with n(p) = p / |p| the normal of the sphere
    that the faces approximate, by the composite centroid rule on an n-fold subdivision."""
    b = Q.face_points(n)
    p = np.einsum("pc,fcx->fpx", b, mesh.triangles)
    nn = p / np.linalg.norm(p, axis=2, keepdims=True)
    return np.maximum(nn @ s, 0.0).mean(axis=1)


def _cylinder(segments=24, rings=4, radius=0.1, height=0.4):
    """Open cylinder of quads split along one diagonal, shared vertices, outward normals."""
    phi = 2 * np.pi * np.arange(segments) / segments
    z = np.linspace(0.0, height, rings + 1)
    v = np.array([[radius * np.cos(a), radius * np.sin(a), h] for h in z for a in phi])
    f = []
    for r in range(rings):
        for i in range(segments):
            a, b = r * segments + i, r * segments + (i + 1) % segments
            c, d = b + segments, a + segments
            f += [[a, b, c], [a, c, d]]
    return trimesh.Trimesh(v, np.array(f), process=False), phi


@pytest.mark.parametrize("subdivisions", [1, 2])
def test_smooth_normals_match_the_sphere_far_better_than_flat(subdivisions):
    sphere = trimesh.creation.icosphere(subdivisions, radius=0.3)
    s = np.array([np.sin(0.7), 0.0, np.cos(0.7)])
    ref = _cos_on_sphere(sphere, s)
    err = {}
    for mode, k in (("flat", 1), ("smooth", 16)):
        q = Q.absorbed_radiation(sphere, _sun_env(s), [1.0, 1.0], sun_normals=mode, sun_points=k)[0]
        d = q / E_SUN - ref
        err[mode] = np.sqrt(np.mean(d**2)), np.abs(d).max()
    # error of the face mean of the cosine (sun 40 deg from the zenith), measured:
    # icosphere(1) (80 faces): flat rms 0.019, max 0.052; smooth rms 0.0006, max 0.0014
    # icosphere(2) (320 faces): flat rms 0.0064, max 0.025; smooth rms 0.0011, max 0.0035
    # (flat is exact only where the whole face is lit: max(0, n.s) is linear in n there)
    assert err["smooth"][0] < 0.3 * err["flat"][0], err
    assert err["smooth"][1] < 0.3 * err["flat"][1], err
    assert err["smooth"][1] < 0.005, err


def test_smooth_normals_on_a_cylinder_match_the_analytic_face_mean():
    # flat quads of a 24-sided cylinder, sun 30 deg above the horizon: the mean over a quad of
    # max(0, cos(phi - phi_s)) cos(elev), phi the angle of the radially projected point; along
    # the chord tan(phi - phi_c) = (2u - 1) tan(dphi / 2) for u uniform in [0, 1]
    from scipy.integrate import quad

    segments = 24
    mesh, phi = _cylinder(segments)
    elev, phi_s = np.radians(30.0), np.radians(10.0)
    s = np.array([np.cos(elev) * np.cos(phi_s), np.cos(elev) * np.sin(phi_s), np.sin(elev)])
    half = np.pi / segments
    ref = []
    for a in phi:
        pc = a + half

        def cos_u(u, pc=pc):
            return max(0.0, np.cos(pc + np.arctan((2 * u - 1) * np.tan(half)) - phi_s)) * np.cos(elev)

        ref.append(quad(cos_u, 0.0, 1.0, points=[0.5], limit=200)[0])
    ref = np.tile(np.repeat(ref, 2), 4)  # every triangle of a quad has the quad's mean
    area = mesh.area_faces
    err = {}
    for mode, k in (("flat", 1), ("smooth", 16)):
        q = Q.absorbed_radiation(mesh, _sun_env(s), [1.0, 1.0], sun_normals=mode, sun_points=k)[0] / E_SUN
        quad_mean = np.repeat((q * area).reshape(-1, 2).sum(1) / area.reshape(-1, 2).sum(1), 2)
        err[mode] = np.abs(quad_mean - ref).max()
    # largest error, measured: flat 0.0127 (the terminator quads: all or nothing, and the
    # chord's sinc(dphi / 2) elsewhere); smooth 0.0008
    assert err["smooth"] < 0.002, err
    assert err["flat"] > 10 * err["smooth"], err


def _grid_plate(n=10, size=0.2):
    g = np.linspace(-size / 2, size / 2, n + 1)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    v = np.c_[xx.ravel(), yy.ravel(), np.zeros(xx.size)]
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i, i + (n + 1), i + (n + 2), i + 1
    f = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]]
    return trimesh.Trimesh(v, f, process=False)


def _clip_area(tri, a, b, c):
    """Area of the part of triangle ``tri`` (3, 2) where a x + b y > c (Sutherland-Hodgman)."""
    poly = []
    for i in range(3):
        p, q = tri[i], tri[(i + 1) % 3]
        fp, fq = a * p[0] + b * p[1] - c, a * q[0] + b * q[1] - c
        if fp > 0:
            poly.append(p)
        if fp * fq < 0:
            poly.append(p + fp / (fp - fq) * (q - p))
    if len(poly) < 3:
        return 0.0
    x, y = np.array(poly).T
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_half_shadowed_facets_get_their_lit_area_fraction():
    # a roof at height h covers the side left of a slanted edge; the sun, tilted by theta
    # towards +x, casts the edge onto the plate shifted by -h tan(theta): the lit fraction of
    # each facet is the area of the facet right of the shadow line (polygon clipping)
    plate = _grid_plate(20)
    h, theta = 0.05, np.radians(35.0)
    x1, x2 = 0.013, 0.061  # the roof's edge from (x1, -1) to (x2, 1)
    roof = trimesh.Trimesh(
        [[-2.0, -1.0, h], [x1, -1.0, h], [x2, 1.0, h], [-2.0, 1.0, h]], [[0, 1, 2], [0, 2, 3]], process=False
    )
    scene = SR.SceneSurfaces(roof, np.zeros((2, 2)))
    s = np.array([np.sin(theta), 0.0, np.cos(theta)])
    shift = h * np.tan(theta)
    a, b = 2.0, -(x2 - x1)  # the line through (x1 - shift, -1) and (x2 - shift, 1)
    c = a * (x1 - shift) + b * -1.0
    tri2 = plate.triangles[:, :, :2]
    ref = np.array([_clip_area(t, a, b, c) for t in tri2]) / plate.area_faces
    crossed = (ref > 0.02) & (ref < 0.98)
    assert crossed.sum() >= 20  # the edge really cuts facets
    out = {}
    for k in (1, 16):
        q = Q.absorbed_radiation(plate, _sun_env(s), [1.0, 1.0], scene=scene, sun_points=k)[0]
        frac = q / (E_SUN * np.cos(theta))
        out[k] = np.abs(frac - ref)[crossed]
        assert_allclose(frac[ref == 1.0], 1.0, rtol=1e-12)
        assert np.all(frac[ref == 0.0] == 0.0)
    # one ray per facet: all or nothing (mean error 0.22, worst 0.52); 16 points: mean 0.037,
    # worst 0.13 (a line crosses about 2m - 1 of the m^2 cells)
    assert out[16].mean() < 0.05 and out[16].max() < 0.15, out[16]
    assert out[1].mean() > 3 * out[16].mean()


def test_sun_options_are_checked():
    mesh = _grid_plate(2)
    env = _sun_env([0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="sun_normals"):
        Q.absorbed_radiation(mesh, env, [1.0, 1.0], sun_normals="phong")
    with pytest.raises(ValueError, match="sun_points"):
        Q.absorbed_radiation(mesh, env, [1.0, 1.0], sun_points=8)


def test_face_points_are_the_centroids_of_an_equal_subdivision():
    for m in (1, 2, 3, 4):
        b = Q.face_points(m)
        assert b.shape == (m * m, 3)
        assert_allclose(b.sum(axis=1), 1.0)
        assert_allclose(b.mean(axis=0), 1.0 / 3.0)  # equal cells: their centroids average out
        assert np.all(b > 0)
    # the composite centroid rule integrates a quadratic to O(1/m^2): int x^2 over the unit
    # triangle (0,0), (1,0), (0,1) is 1/12, i.e. a mean of 1/6
    b = Q.face_points(40)
    assert abs(np.mean(b[:, 1] ** 2) - 1 / 6) < 1e-4


def test_corner_normals_keep_a_cube_sharp_and_a_sphere_radial():
    cube = trimesh.creation.box()
    cn = Q.corner_normals(cube)
    assert_allclose(cn, np.repeat(cube.face_normals[:, None, :], 3, axis=1), atol=1e-12)
    sphere = trimesh.creation.icosphere(3)
    cn = Q.corner_normals(sphere)
    radial = sphere.vertices[sphere.faces]
    radial /= np.linalg.norm(radial, axis=2, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.einsum("fcx,fcx->fc", cn, radial), -1, 1))).max() < 0.5


def test_split_seam_is_smoothed_across():
    # the same cylinder with the vertices of one column duplicated (a UV seam): same normals
    mesh, _ = _cylinder(16, 2)
    f = mesh.faces.copy()
    v = np.r_[mesh.vertices, mesh.vertices[::16]]  # copies of the column at phi = 0
    seam = np.arange(0, len(mesh.vertices), 16)
    for col, new in zip(seam, range(len(mesh.vertices), len(v))):
        last = np.any(np.isin(f, [15, 31, 47]), axis=1)  # faces of the last quad column
        f[last[:, None] & (f == col)] = new
    split = trimesh.Trimesh(v, f, process=False)
    assert_allclose(Q.corner_normals(split), Q.corner_normals(mesh), atol=1e-12)


# ------------------------------------------------------------------ surface-step measures
def test_face_neighbours_match_trimesh_adjacency():
    sphere = trimesh.creation.icosphere(2)
    pairs = SS.face_neighbours(np.full(len(sphere.faces), 3), sphere.faces.ravel())
    ref = np.unique(np.sort(sphere.face_adjacency, axis=1), axis=0)
    assert_allclose(pairs, ref)
    # two quads sharing an edge, one of them with its shared vertices duplicated
    pts = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0], [1, 0, 0], [1, 1, 0]], float
    )
    idx = [0, 1, 2, 3, 6, 4, 5, 7]
    assert len(SS.face_neighbours([4, 4], idx)) == 0
    assert_allclose(SS.face_neighbours([4, 4], idx, pts), [[0, 1]])


def test_face_steps_on_a_smooth_body_are_small():
    # a linear temperature field T = 300 + g z over a fine sphere: every step between edge
    # neighbours is at most g times the largest distance between neighbouring centroids
    sphere = trimesh.creation.icosphere(4, radius=0.3)
    g = 10.0  # K/m
    t = 300.0 + g * sphere.triangles_center[:, 2]
    pairs = SS.face_neighbours(np.full(len(sphere.faces), 3), sphere.faces.ravel())
    st = SS.face_steps(t, pairs)
    c = sphere.triangles_center
    bound = g * np.linalg.norm(c[pairs[:, 0]] - c[pairs[:, 1]], axis=1).max()
    assert st["n"] == 3 * len(sphere.faces) // 2
    assert st["max"] <= bound + 1e-12 and bound < 0.2
    # a checkerboard of +-1 K on the same faces: every step is 0 or 2 K
    chk = SS.face_steps(np.where(np.arange(len(t)) % 2 == 0, 1.0, -1.0), pairs)
    assert chk["max"] == 2.0


def test_pixel_steps_of_pure_noise_follow_the_half_normal():
    # neighbouring pixels with independent N(0, sigma^2) noise differ by N(0, 2 sigma^2): the
    # median |step| is 0.6745 sqrt(2) sigma, the 90th percentile 1.6449 sqrt(2) sigma
    rng = np.random.default_rng(3)
    sigma = 0.05
    ramp = np.add.outer(np.zeros(400), np.zeros(400))
    img = ramp + sigma * rng.standard_normal(ramp.shape)
    st = SS.pixel_steps(img, np.ones_like(img, dtype=bool), margin=0)
    assert st["n"] == 2 * 400 * 399
    assert_allclose(st["p50"], 0.6745 * np.sqrt(2) * sigma, rtol=0.02)
    assert_allclose(st["p90"], 1.6449 * np.sqrt(2) * sigma, rtol=0.02)
    noise = SS.noise_steps(np.full(100_000, sigma), np.full(100_000, sigma))
    assert_allclose(noise["p50"], 0.6745 * np.sqrt(2) * sigma, rtol=0.02)
    # the margin and the exclusion leave out the mask's edge and the excluded pixels
    mask = np.zeros((10, 10), bool)
    mask[2:8, 2:8] = True
    step = np.where(np.arange(10)[None, :] >= 5, 1.0, 0.0) * np.ones((10, 1))
    assert SS.pixel_steps(step, mask, margin=1)["max"] == 1.0
    excl = np.zeros_like(mask)
    excl[:, 5] = True
    assert SS.pixel_steps(step, mask, margin=1, exclude=excl)["max"] == 0.0


def _ridge(fold_deg, concave=False):
    """Two facets meeting at the y axis, each tilted by fold_deg / 2: a convex ridge (both
    slope down away from the edge) or a concave valley."""
    half = np.radians(fold_deg / 2)
    z = np.sin(half) * (1.0 if concave else -1.0)
    v = [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0], [-np.cos(half), 0.0, z], [np.cos(half), 0.0, z]]
    return trimesh.Trimesh(v, [[0, 1, 2], [1, 0, 3]], process=False)


def _below_facet_a(mesh, degrees, towards):
    """The sun ``degrees`` below facet 0's plane, in the x-z plane, ``towards`` +1: the ridge
    line, -1: away from it."""
    n_a = mesh.face_normals[0]
    t_a = np.cross([0.0, 1.0, 0.0], n_a)
    t_a *= towards / np.linalg.norm(t_a)
    tilt = np.radians(-degrees)
    return np.cos(tilt) * t_a + np.sin(tilt) * n_a


def test_a_lit_smooth_point_is_not_shadowed_by_its_own_flat_facet():
    # a convex ridge of two facets 40 deg apart, the sun 3 deg below facet A's plane: A's flat
    # normal faces away, but near the ridge its smooth normal faces the sun. Without the lift
    # of the shadow ray's origin onto the smooth surface, those rays would cross A's own plane
    # at once and be shadowed by A (the dark staircase along a terminator)
    ridge = _ridge(40.0)
    s = _below_facet_a(ridge, 3.0, +1.0)
    b = Q.face_points(4)
    n = np.einsum("pc,fcx->fpx", b, Q.corner_normals(ridge))
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    expected = E_SUN * np.maximum(n @ s, 0.0).mean(axis=1)  # every such point lit
    assert expected[0] > 0.01 * E_SUN and ridge.face_normals[0] @ s < 0
    q = Q.absorbed_radiation(ridge, _sun_env(s), [1.0, 1.0], sun_points=16)[0]
    assert_allclose(q, expected, rtol=1e-9)


def test_a_concave_facet_facing_away_from_the_sun_stays_dark():
    # a valley, the sun 3 deg below facet A's plane going up A's slope: near the valley line
    # A's smooth normal faces the sun, but the surface rising beside the point (A itself)
    # shadows it, as on a smooth valley
    valley = _ridge(40.0, concave=True)
    s = _below_facet_a(valley, 3.0, -1.0)
    assert s[2] > 0 and valley.face_normals[0] @ s < 0
    cn = Q.corner_normals(valley)
    assert np.max(cn[0] @ s) > 0.05  # the smooth normals at the valley line do face the sun
    q = Q.absorbed_radiation(valley, _sun_env(s), [1.0, 1.0], sun_points=16)[0]
    assert q[0] == 0.0
