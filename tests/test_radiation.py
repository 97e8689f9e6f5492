"""Radiance maps, scene radiance and per-facet absorbed radiation (humv_usd.thermal.radiance_map,
scene_radiance, qrad; .sky)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from numpy.testing import assert_allclose

from humv_usd.bench import thermal as BT
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.thermal import qrad as Q
from humv_usd.thermal import radiance_map as RM
from humv_usd.thermal import scene_radiance as SR
from humv_usd.thermal.sky import ClearSky, UniformSky, angular_sky_emissivity


def _facets(centers, normal=(0.0, 0.0, 1.0), size=1e-3):
    """Tiny separate triangles at the given centres, all facing ``normal``."""
    n = np.asarray(normal, dtype=float)
    n /= np.linalg.norm(n)
    t = np.cross([1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0], n)
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    tri = size * np.array([t, -0.5 * t + 0.866 * b, -0.5 * t - 0.866 * b])
    v = (np.asarray(centers, dtype=float)[:, None, :] + tri[None]).reshape(-1, 3)
    return trimesh.Trimesh(v, np.arange(len(v)).reshape(-1, 3), process=False)


def _quads(quads):
    """Mesh of planar quads (4 corners each, counter-clockwise seen from the front)."""
    v = np.asarray(quads, dtype=float).reshape(-1, 3)
    f = np.concatenate(
        [[[4 * i, 4 * i + 1, 4 * i + 2], [4 * i, 4 * i + 2, 4 * i + 3]] for i in range(len(quads))]
    )
    return trimesh.Trimesh(v, f, process=False)


def test_latlong_solid_angles_sum_to_4pi():
    d, omega = RM.latlong_directions((45, 90))
    assert_allclose(omega.sum(), 4 * np.pi, rtol=1e-12)
    assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
    assert_allclose(RM.latlong_index(d, (45, 90)), np.arange(len(d)))


def test_uniform_map_hemisphere_integral_360():
    env = RM.RadianceMap(np.full((2, 360, 360), 50.0))
    rng = np.random.default_rng(1)
    n = rng.normal(size=(40, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e = env.irradiance(np.vstack([n, [[0, 0, 1], [1, 0, 0]]]), normalize=False)
    assert_allclose(e, np.pi * 50.0, rtol=1e-3)


@pytest.mark.parametrize("method", ["brute", "fast", "adaptive"])
def test_uniform_full_sphere_closed_form(method):
    mesh = trimesh.creation.icosphere(2)
    env = SR.radiance_map([0, 0, 0], UniformSky((10.0, 100.0)), None, 36)
    q = Q.absorbed_radiation(mesh, env, [0.6, 0.9], method=method, rays=16)
    assert_allclose(q[0], 0.6 * np.pi * 10.0, rtol=1e-5)
    assert_allclose(q[1], 0.9 * np.pi * 100.0, rtol=1e-5)


@pytest.mark.parametrize("method", ["brute", "fast", "adaptive"])
def test_degenerate_facets_stay_finite(method):
    """A facet folded flat (zero area: trimesh gives it a zero normal) must not turn the ray
    directions into NaN (it did in frame ~200 of a 301-frame jos3 walk); the others keep the
    closed form of a uniform sky."""
    sphere = trimesh.creation.icosphere(2)
    v = sphere.vertices
    flat = [[len(v), len(v) + 1, len(v) + 2]]  # three collinear points
    line = np.array([[3.0, 0.0, 0.0], [3.5, 0.0, 0.0], [4.0, 0.0, 0.0]])
    mesh = trimesh.Trimesh(np.vstack([v, line]), np.vstack([sphere.faces, flat]), process=False)
    env = SR.radiance_map([0, 0, 0], UniformSky((10.0, 100.0)), None, 36)
    q = Q.absorbed_radiation(mesh, env, [0.6, 0.9], method=method, rays=16)
    assert np.all(np.isfinite(q))
    assert_allclose(q[1][: len(sphere.faces)], 0.9 * np.pi * 100.0, rtol=1e-5)


@pytest.mark.parametrize("method,rtol", [("brute", 2e-3), ("fast", 5e-3), ("adaptive", 5e-3)])
def test_wall_fills_half_the_hemisphere(method, rtol):
    # horizontal facets at the foot of a huge vertical wall x = 0.01 facing -x: F_wall = 1/2
    big = 50.0
    wall = _quads([[[0.01, -big, -big], [0.01, -big, big], [0.01, big, big], [0.01, big, -big]]])
    assert wall.face_normals[0][0] < 0
    l_sky, l_wall = 100.0, 160.0
    sky = UniformSky((0.0, l_sky))
    scene = SR.SceneSurfaces(wall, np.array([[0.0, 0.0], [l_wall, l_wall]]))
    env = SR.radiance_map([0, 0, 0.5], sky, scene, 180)
    ys = np.linspace(-0.5, 0.5, 64)
    facets = _facets(np.c_[np.zeros_like(ys), ys, np.zeros_like(ys)])
    q = Q.absorbed_radiation(facets, env, [1.0, 0.9], scene=scene, method=method, rays=256)
    expected = 0.9 * np.pi * (0.5 * l_wall + 0.5 * l_sky)
    assert_allclose(q[1].mean(), expected, rtol=rtol)
    assert_allclose(q[1], expected, rtol=rtol if method == "brute" else 10 * rtol)


def _well(half_width, height):
    """Four walls of a square well, normals pointing into the well."""
    a, h = half_width, height
    m = _quads(
        [[[x, -a, 0], [x, a, 0], [x, a, h], [x, -a, h]] for x in (a, -a)]
        + [[[-a, y, 0], [a, y, 0], [a, y, h], [-a, y, h]] for y in (a, -a)]
    )
    outward = np.einsum("ij,ij->i", m.face_normals[:, :2], m.triangles_center[:, :2]) > 0
    m.faces[outward] = m.faces[outward][:, ::-1]
    return trimesh.Trimesh(m.vertices, m.faces, process=False)


@pytest.mark.parametrize("method", ["brute", "fast", "adaptive"])
def test_plate_at_bottom_of_deep_well(method):
    a, h = 0.5, 2.0
    walls = _well(a, h)
    assert np.all(np.einsum("ij,ij->i", walls.face_normals[:, :2], walls.triangles_center[:, :2]) < 0)
    scene = SR.SceneSurfaces(walls, np.zeros((2, len(walls.faces))))  # cold black walls
    l_sky = 120.0
    env = SR.radiance_map([0, 0, 5.0], UniformSky((0.0, l_sky)), None, 180)  # map sees open sky
    xy = np.linspace(-4e-3, 4e-3, 8)
    plate = _facets(np.c_[np.repeat(xy, 8), np.tile(xy, 8), np.zeros(64)])  # 64 facets, centre
    q = Q.absorbed_radiation(plate, env, [0.7, 1.0], scene=scene, method=method, rays=1024).mean(axis=1)[
        :, None
    ]
    s = (a / h) / np.sqrt(1 + (a / h) ** 2)
    f_open = 4.0 / np.pi * s * np.arctan(s)  # element under the centre of a square opening
    assert_allclose(q[1, 0], np.pi * l_sky * f_open, rtol=1.5e-2)  # fast: MC, ~0.4 % std
    assert q[1, 0] < 0.5 * np.pi * l_sky  # most of the sky is blocked
    # sun straight down the well reaches the plate, low sun does not
    env.sun_direction, env.sun_irradiance = np.array([0.0, 0.0, 1.0]), np.array([900.0, 0.0])
    q = Q.absorbed_radiation(plate, env, [0.7, 1.0], scene=scene, method=method, rays=64)
    assert_allclose(q[0], 0.7 * 900.0, rtol=1e-12)
    env.sun_direction = np.array([np.sin(1.0), 0.0, np.cos(1.0)])
    q = Q.absorbed_radiation(plate, env, [0.7, 1.0], scene=scene, method=method, rays=64)
    assert np.all(q[0] == 0.0)


@pytest.mark.parametrize("zenith_deg", [0.0, 30.0, 60.0, 85.0])
@pytest.mark.parametrize("method", ["brute", "fast", "adaptive"])
def test_sun_on_horizontal_plate(zenith_deg, method):
    z = np.radians(zenith_deg)
    sky = ClearSky(300.0, 0.5, sun_direction=(np.sin(z), 0.0, np.cos(z)), direct_normal_irradiance=1000.0)
    env = SR.radiance_map([0, 0, 0], sky, None, 24)
    q = Q.absorbed_radiation(_facets([[0, 0, 0]]), env, [0.8, 0.0], method=method)
    assert_allclose(q[0, 0], 0.8 * 1000.0 * np.cos(z), rtol=1e-12)


def test_sun_below_horizon_is_no_sun():
    sky = ClearSky(300.0, 0.5, sun_direction=(1.0, 0.0, -0.1), direct_normal_irradiance=1000.0)
    assert sky.sun is None
    env = SR.radiance_map([0, 0, 0], sky, None, 12)
    assert env.sun_direction is None and np.all(env.sun_irradiance == 0)


def test_fast_vs_brute_icosphere_mixed_environment():
    _, scene, sky, alpha, _ = BT.bench_scene(2000)
    sphere = trimesh.creation.icosphere(3, radius=0.4)
    sphere.apply_translation([0.0, 0.0, 0.6])
    env = SR.radiance_map([0.0, 0.0, 0.6], sky, scene, 90)
    q_ref = Q.absorbed_radiation(sphere, env, alpha, scene=scene, method="brute")
    q_fast = Q.absorbed_radiation(sphere, env, alpha, scene=scene, method="fast", rays=64)
    err = BT.relative_errors(q_fast, q_ref)
    assert err["rms_rel_error"] < 0.01, err
    assert np.ptp(q_ref.sum(0)) > 100.0  # the environment is really mixed (sun, wall, ground)


def test_clear_sky_hemispherical_flux_matches_sky_emissivity():
    for model in ("martin_berdahl", "unsworth_monteith", "isotropic"):
        sky = ClearSky(290.0, 0.6, model=model, ground_temperature_k=290.0)
        env = SR.radiance_map([0, 0, 0], sky, None, 360)
        e_down = env.irradiance(np.array([[0.0, 0.0, 1.0]]))[1, 0]
        assert_allclose(e_down, sky.emissivity * STEFAN_BOLTZMANN * 290.0**4, rtol=3e-3)
    eps = angular_sky_emissivity(np.radians([0, 30, 60, 80, 89.9]), 0.75)
    assert np.all(np.diff(eps) > 0) and eps[0] < 0.75 < eps[-1] <= 1.0
    with pytest.raises(ValueError, match="invalid model"):
        angular_sky_emissivity(0.1, 0.7, model="nope")


def test_mean_radiant_temperature_of_a_blackbody_enclosure():
    t = 305.0
    mesh = trimesh.creation.icosphere(2)
    env = SR.radiance_map([0, 0, 0], UniformSky((0.0, STEFAN_BOLTZMANN * t**4 / np.pi)), None, 24)
    q = Q.absorbed_radiation(mesh, env, [0.7, 0.97], method="brute")
    seg = np.arange(len(mesh.faces)) % 3
    mrt = Q.mean_radiant_temperature(q, mesh.area_faces, seg, emissivity=0.97, n_segments=4)
    assert_allclose(mrt[:3], t, rtol=1e-6)
    assert np.isnan(mrt[3])


def test_invalid_method():
    env = RM.RadianceMap(np.zeros((2, 4, 8)))
    with pytest.raises(ValueError, match="invalid method"):
        Q.absorbed_radiation(trimesh.creation.icosphere(0), env, [1, 1], method="sh")


def test_bench_qrad_small():
    rows = BT.bench_qrad(facets=400, resolutions=(12, 24), fast_rays=(4, 16), adaptive_rays=(16,))
    assert rows[0]["reference"] and rows[0]["resolution"] == 24
    assert len(rows) == 1 + 1 + 2 * 3
    for r in rows:
        assert r["seconds"] >= 0 and np.isfinite(r["rms_rel_error"]) and r["facets"] > 300


def test_irradiance_table_fft_equals_dense_sum_at_nodes():
    # the FFT in azimuth is exact: compare with the dense double-precision cosine sum
    _, scene, sky, _, _ = BT.bench_scene(500)
    env = SR.radiance_map([0.0, 0.0, 1.0], sky, scene, (30, 48))
    grid = 12
    table = RM.irradiance_table(env, grid)
    assert table.shape == (2, grid + 1, 48 + 1)
    assert_allclose(table[:, :, -1], table[:, :, 0], rtol=0, atol=0)
    th = np.repeat(np.linspace(0.0, np.pi, grid + 1), 48)
    ph = np.tile(np.arange(48) * 2.0 * np.pi / 48, grid + 1)
    n = np.c_[np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)]
    d, omega = env.geometry()
    w = RM.cosine_weights(n, d, omega, normalize=True)
    dense = (w @ env.flat().T).T.reshape(2, grid + 1, 48)
    assert_allclose(table[:, :, :-1], dense, rtol=1e-10, atol=1e-9)


def test_adaptive_rays_go_to_partly_occluded_facets():
    # facets at the foot of a wall (half the sky blocked) and facets beside them facing away
    # from it (nothing blocked; they see what the map shows: the sky. Facets 200 m away, as
    # this test had, see sky where the map, centred at the wall, shows the wall: their rays
    # disagree with the control variate since escaping rays see the sky)
    big = 50.0
    wall = _quads([[[0.01, -big, -big], [0.01, -big, big], [0.01, big, big], [0.01, big, -big]]])
    scene = SR.SceneSurfaces(wall, np.array([[0.0, 0.0], [160.0, 160.0]]))
    env = SR.radiance_map([0, 0, 0.5], UniformSky((0.0, 100.0)), scene, 90)
    line = np.linspace(-0.5, 0.5, 50)
    facets = trimesh.util.concatenate(
        [
            _facets(np.c_[np.zeros(50), line, np.zeros(50)]),
            _facets(np.c_[np.full(50, -0.5), line, np.zeros(50)], normal=(-1.0, 0.0, 0.0)),
        ]
    )
    normals, centroids = facets.face_normals, facets.triangles_center
    occ = Q._Occluders(facets, 2, None, scene)
    table = RM.irradiance_table(env, 32)
    alpha = np.ones((2, 100))
    _, var, counts = Q._diffuse_adaptive(env, centroids, normals, occ, 1e-6, 64, 0, table, 16, alpha, 1024)
    assert np.all(counts[50:] == 16) and np.all(var[50:] == 0.0)  # open: pilot only, exact
    assert counts[:50].mean() > 100 and counts.sum() <= 64 * 100 * 1.3
    # facets whose flux nobody uses (importance 0) keep their pilot rays; the budget goes to
    # the others, which get more than without the weights
    importance = np.r_[np.ones(25), np.zeros(25), np.ones(50)]
    _, _, counts_w = Q._diffuse_adaptive(
        env, centroids, normals, occ, 1e-6, 64, 0, table, 16, alpha, 1024, importance=importance
    )
    assert np.all(counts_w[25:50] == 16) and counts_w[:25].sum() > counts[:25].sum()
    stats = {}
    Q.absorbed_radiation(facets, env, [1.0, 1.0], scene=scene, method="adaptive", rays=64, stats=stats)
    assert 0.0 < stats["rms_rel_error_estimate"] < 0.05 and stats["rays"] == counts.sum()


def test_weighted_rays_spend_the_budget_where_the_weights_are():
    """With ``importance`` the second-stage rays go ~ sqrt(w_i) s_i (the optimum of
    sum_i w_i Var(q_i) for a fixed ray count, Cochran 1977 section 5.5), spending the whole
    budget: facets weighed 4x get ~2x the rays of equal facets weighed 1x, and a few heavy
    facets may take more than 1024 rays (the old cap left most of the budget unspent)."""
    big = 50.0
    wall = _quads([[[0.01, -big, -big], [0.01, -big, big], [0.01, big, big], [0.01, big, -big]]])
    scene = SR.SceneSurfaces(wall, np.array([[0.0, 0.0], [160.0, 160.0]]))
    env = SR.radiance_map([0, 0, 0.5], UniformSky((0.0, 100.0)), scene, 90)
    # 40 facets at the foot of the wall (half the sky blocked: the same per-ray spread each)
    facets = _facets(np.c_[np.zeros(40), np.linspace(-0.5, 0.5, 40), np.zeros(40)])
    occ = Q._Occluders(facets, 2, None, scene)
    table = RM.irradiance_table(env, 32)
    alpha = np.ones((2, 40))
    args = (env, facets.triangles_center, facets.face_normals, occ, 1e-6)
    w = np.r_[np.ones(20), np.full(20, 4.0)]
    _, _, counts = Q._diffuse_adaptive(*args, 256, 0, table, 16, alpha, 4096, importance=w)
    ratio = (counts[20:] - 16).sum() / (counts[:20] - 16).sum()
    assert 1.6 < ratio < 2.5, ratio
    # four heavy facets among 40: their share of 256 x 40 rays is ~2,500 each
    w = np.r_[np.full(4, 1e4), np.ones(36)]
    _, _, counts = Q._diffuse_adaptive(*args, 256, 0, table, 16, alpha, 4096, importance=w)
    assert counts[:4].min() > 1040 and counts.sum() > 0.75 * 256 * 40, counts
    stats = {}
    Q.absorbed_radiation(
        facets, env, [1.0, 1.0], scene=scene, method="adaptive", rays=256, stats=stats, importance=w
    )
    assert stats["rays"] > 0.75 * 256 * 40  # the default cap lets them


def _sphere_over_seeds(method: str, importance=None, seeds: int = 8):
    """A sphere above the bench scene estimated with 8 seeds (64 rays, 160 replicate facets):
    (the scene's pieces, the per-seed absorbed flux, and each seed's stats)."""
    _, scene, sky, alpha, _ = BT.bench_scene(2000)
    sphere = trimesh.creation.icosphere(2, radius=0.4)
    sphere.apply_translation([0.0, 0.0, 0.6])
    env = SR.radiance_map([0.0, 0.0, 0.6], sky, scene, 40)
    w = None if importance is None else importance(sphere)
    runs, all_stats = [], []
    for seed in range(seeds):
        stats = {}
        q = Q.absorbed_radiation(
            sphere,
            env,
            alpha,
            scene=scene,
            method=method,
            rays=64,
            seed=seed,
            stats=stats,
            replicate_facets=160,
            importance=w,
        )
        runs.append(q.sum(axis=0))
        all_stats.append(stats)
    return (sphere, env, alpha, scene), runs, all_stats


def test_replicates_measure_the_error_of_weighted_adaptive_rays():
    """The adaptive method with importance weights (as a person's thermal layer calls it):
    the stated per-facet error, measured by replicates, matches the spread over seeds."""
    _, runs, stats = _sphere_over_seeds("adaptive", lambda s: s.area_faces / s.area_faces.mean())
    stated = [np.mean(st["variance"]) for st in stats]
    seeds = np.mean(np.var(np.array(runs), axis=0, ddof=1))
    assert 0.75 < np.sqrt(np.mean(stated) / seeds) < 1.33, np.sqrt(np.mean(stated) / seeds)


@pytest.mark.parametrize("method", ["fast", "adaptive"])
def test_rays_that_pass_over_a_wall_see_the_sky(method):
    """A facet facing up just above the top of a long wall 1 m high, 1 m away, under a
    uniform sky: the wall is below its horizon, so it absorbs pi L_sky exactly (closed form).
    The map's centre on the ground sees the wall up to 45 deg; a ray from the facet that passes
    over the wall sees the sky, not the map's wall (before: + pi (L_wall - L_sky) / 4, the
    cosine-weighted share of the wall's directions in the map, 25 % high here)."""
    wall = _quads([[[1.0, -1e3, 0.0], [1.0, 1e3, 0.0], [1.0, 1e3, 1.0], [1.0, -1e3, 1.0]]])
    wall.invert()  # faces the facet (-x)
    l_sky, l_wall = 100.0, 200.0
    scene = SR.SceneSurfaces(wall, np.array([[0.0, 0.0], [l_wall, l_wall]]))
    env = SR.radiance_map([0.0, 0.0, 0.0], UniformSky((0.0, l_sky)), scene, 90)
    assert env.radiance[1].max() == l_wall  # the map shows the wall
    facet = _facets([[0.0, 0.0, 1.001]])
    stats = {}
    q = Q.absorbed_radiation(facet, env, [1.0, 1.0], scene=scene, method=method, rays=256, stats=stats)
    assert_allclose(q[1], np.pi * l_sky, rtol=0.03)  # the old rule: 25 % high


def test_error_estimate_bounds_the_actual_error():
    _, scene, sky, alpha, _ = BT.bench_scene(2000)
    sphere = trimesh.creation.icosphere(2, radius=0.4)
    sphere.apply_translation([0.0, 0.0, 0.6])
    env = SR.radiance_map([0.0, 0.0, 0.6], sky, scene, 40)
    q_ref = Q.absorbed_radiation(sphere, env, alpha, scene=scene, method="brute")
    for method in ("fast", "adaptive"):
        stats = {}
        q = Q.absorbed_radiation(sphere, env, alpha, scene=scene, method=method, rays=16, stats=stats)
        actual = BT.relative_errors(q, q_ref)["nrmse"]
        assert 0.5 * actual < stats["nrmse_estimate"] < 10.0 * actual, (method, stats, actual)


def test_replicates_measure_the_error_that_seeds_show():
    """The stated error is measured by independent replicates on random facets: its RMS
    matches the spread of the estimate over seeds, where the per-ray sample variance (which
    ignores the rays' stratification) overstates it."""
    (sphere, env, alpha, scene), runs, stats = _sphere_over_seeds("fast")
    stated = [np.mean(st["variance"]) for st in stats]
    per_ray = [np.mean(st["per_ray_variance"]) for st in stats]
    for st in stats:
        assert len(st["replicate_facets"]) == 160 and st["stratification_ratio"] > 0.0
    seeds = np.mean(np.var(np.array(runs), axis=0, ddof=1))  # mean over facets of the variance
    stated_ratio, per_ray_ratio = np.sqrt(np.mean(stated) / seeds), np.sqrt(np.mean(per_ray) / seeds)
    assert 0.8 < stated_ratio < 1.25, (stated_ratio, per_ray_ratio)
    assert per_ray_ratio > 1.1 and abs(np.log(stated_ratio)) < abs(np.log(per_ray_ratio))
    # without replicates the per-ray variance is what is stated; the estimate is the same
    stats = {}
    q = Q.absorbed_radiation(
        sphere, env, alpha, scene=scene, method="fast", rays=64, seed=7, stats=stats, replicate_facets=0
    )
    assert "replicate_facets" not in stats and np.array_equal(q.sum(axis=0), runs[7])


def test_mitsuba_ray_backend_matches_embree():
    mesh, scene, sky, alpha, center = BT.bench_scene(600)
    env = SR.radiance_map(center, sky, scene, 24)
    q_e = Q.absorbed_radiation(mesh, env, alpha, scene=scene, method="fast", rays=16)
    q_m = Q.absorbed_radiation(mesh, env, alpha, scene=scene, method="fast", rays=16, backend="mitsuba")
    # same rays; float32 ray casters may differ on a grazing ray or two
    assert BT.relative_errors(q_m, q_e)["nrmse"] < 1e-3
    with pytest.raises(ValueError, match="ray backend"):
        Q.absorbed_radiation(mesh, env, alpha, method="fast", backend="optix")


@pytest.mark.parametrize("method", ["fast", "adaptive"])
def test_visibility_cache_replays_the_same_rays_with_new_radiances(method):
    mesh, scene, sky, alpha, center = BT.bench_scene(600)
    env = SR.radiance_map(center, sky, scene, 24)
    cache, stats = {}, {}
    q1 = Q.absorbed_radiation(mesh, env, alpha, scene=scene, method=method, rays=32, cache=cache, stats=stats)
    assert not stats["cached"] and len(cache["records"][0]) > 0
    # same geometry, new radiances (a warmer sky, hotter scene, weaker sun)
    env2 = RM.RadianceMap(
        env.radiance * 1.1, env.center, env.bands, env.sun_direction, env.sun_irradiance * 0.5
    )
    scene2 = SR.SceneSurfaces(scene.mesh, scene.radiance * 1.3)
    q2 = Q.absorbed_radiation(
        mesh, env2, alpha, scene=scene2, method=method, rays=32, cache=cache, stats=stats, seed=5
    )
    assert stats["cached"]
    fresh = Q.absorbed_radiation(mesh, env2, alpha, scene=scene2, method=method, rays=32)
    if method == "fast":  # the same rays as a fresh run with the recording's seed
        assert_allclose(q2, fresh, rtol=1e-9, atol=1e-9)
    else:  # the allocation depends on the radiances: equal within the noise
        assert BT.relative_errors(q2, fresh)["nrmse"] < 0.05
    assert not np.allclose(q1, q2)
    # the person moved: the cache is stale and is rebuilt
    moved = mesh.copy()
    moved.apply_translation([0.3, 0.0, 0.0])
    Q.absorbed_radiation(moved, env2, alpha, scene=scene2, method=method, rays=32, cache=cache, stats=stats)
    assert not stats["cached"]


def _grid_plate(n=8, size=0.2, z=0.0):
    """A connected horizontal n x n grid of facets (shared vertices: edge neighbours)."""
    g = np.linspace(-size / 2, size / 2, n + 1)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    v = np.c_[xx.ravel(), yy.ravel(), np.full(xx.size, z)]
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i, i + (n + 1), i + (n + 2), i + 1
    f = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]]
    return trimesh.Trimesh(v, f, process=False)


@pytest.mark.parametrize("method", ["fast", "adaptive"])
def test_facets_under_a_uniform_occluder_are_exact(method):
    # a plate 10 cm under a huge ceiling of uniform radiance, in a very non-uniform map: every
    # ray sees the ceiling (the most grazing ray, cos = 3e-4, reaches 320 m), so q = pi L_ceiling
    # exactly; the neighbour-fitted control-variate coefficient goes to 0 and no Monte Carlo
    # noise is left (the plain difference estimator pi mean(L_hit - L_map) + T would carry the
    # map's variance over the hemisphere)
    plate = _grid_plate()
    big = 1e3
    ceiling = _quads([[[-big, -big, 0.1], [-big, big, 0.1], [big, big, 0.1], [big, -big, 0.1]]])
    l_c = np.array([30.0, 140.0])
    scene = SR.SceneSurfaces(ceiling, np.repeat(l_c[:, None], 2, axis=1))
    rng = np.random.default_rng(1)
    env = RM.RadianceMap(rng.uniform(0.0, 300.0, (2, 24, 48)))
    stats = {}
    q = Q.absorbed_radiation(plate, env, [1.0, 1.0], scene=scene, method=method, rays=16, stats=stats)
    assert_allclose(q, np.pi * np.repeat(l_c[:, None], len(plate.faces), axis=1), rtol=1e-9)
    assert stats["nrmse_estimate"] < 1e-9


def test_fast_error_falls_with_more_rays():
    # unbiased: against the brute reference the error keeps falling as rays are added
    _, scene, sky, alpha, _ = BT.bench_scene(2000)
    sphere = trimesh.creation.icosphere(2, radius=0.4)
    sphere.apply_translation([0.0, 0.0, 0.6])
    env = SR.radiance_map([0.0, 0.0, 0.6], sky, scene, 40)
    q_ref = Q.absorbed_radiation(sphere, env, alpha, scene=scene, method="brute")
    err = [
        np.mean(
            [
                BT.relative_errors(
                    Q.absorbed_radiation(sphere, env, alpha, scene=scene, method="fast", rays=k, seed=s),
                    q_ref,
                )["rms_rel_error"]
                for s in range(2)
            ]
        )
        for k in (4, 32, 256)
    ]
    assert err[0] > 2.0 * err[1] > 4.0 * err[2], err


@pytest.mark.parametrize("sampler", Q.SAMPLERS)
def test_ray_directions_are_cosine_weighted(sampler):
    normals = trimesh.unitize(np.random.default_rng(2).normal(size=(400, 3)))
    frames = Q._float32_frames(normals)
    d = Q._cosine_directions(np.arange(400), 64, np.random.default_rng(3), frames, sampler)
    d = d.reshape(400, 64, 3).astype(float)
    assert_allclose(np.linalg.norm(d, axis=2), 1.0, atol=1e-6)
    cos = np.einsum("fkc,fc->fk", d, normals)
    assert cos.min() >= 0.0
    # cosine-weighted hemisphere: E[cos] = 2/3, E[cos^2] = 1/2; each facet's set is evenly
    # spread, so even per facet the means are close
    assert abs(cos.mean() - 2 / 3) < 2e-3 and abs((cos**2).mean() - 0.5) < 2e-3
    assert np.abs(cos.mean(axis=1) - 2 / 3).max() < 0.05
    with pytest.raises(ValueError, match="sampler"):
        Q._cosine_directions(np.arange(4), 4, np.random.default_rng(0), frames, "sobol")


def test_radical_inverse_and_hammersley():
    assert_allclose(Q._radical_inverse2(np.arange(8)), [0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875])
    p = Q._hammersley(16)
    # a (0, 4, 2)-net: every 2^-a x 2^-(4-a) elementary box holds exactly one point
    for a in range(5):
        cells = np.floor(p[:, 0] * 2**a) * 2 ** (4 - a) + np.floor(p[:, 1] * 2 ** (4 - a))
        assert len(np.unique(cells)) == 16
