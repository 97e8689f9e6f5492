"""geometry.mesh.Surface: the compiled closest-point kernel against plain numpy and brute force."""

import numpy as np
import trimesh

from humv_usd.clothing.collide import LOCAL_RAY, MAX_AIR_GAP, _BodyFrame, _LocalCaster
from humv_usd.geometry.mesh import LocalSurface, Surface, closest_on_triangles
from humv_usd.geometry.raycast import RayCaster


def _bumpy_sphere(seed=0):
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    rng = np.random.default_rng(seed)
    v = np.asarray(s.vertices) * (1 + 0.05 * rng.standard_normal((len(s.vertices), 1)))
    return v, np.asarray(s.faces)


def _queries(v, rng):
    near = v[rng.integers(0, len(v), 300)] + rng.normal(0, 0.02, (300, 3))
    far = rng.normal(0, 1.0, (50, 3))
    # exactly on vertices and edge midpoints (closest-point ties between triangles)
    return np.concatenate([near, far, v[:20], 0.5 * (v[:20] + v[20:40])])


def test_kernel_equals_numpy_reference():
    """Same candidates, same closest point, triangle, normal and sign as the numpy code."""
    v, f = _bumpy_sphere()
    s = Surface(v, f)
    q = _queries(v, np.random.default_rng(1))
    got, ref = s.closest(q), s.closest_reference(q)
    np.testing.assert_allclose(got.point, ref.point, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.signed, ref.signed, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.normal, ref.normal, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.bary.sum(axis=1), 1.0, atol=1e-12)
    # the triangle may differ only where two are equally close (a shared vertex or edge)
    differ = got.triangle != ref.triangle
    assert differ.sum() <= 2


def test_all_candidates_is_brute_force():
    """With every triangle a candidate the result is the exact closest point of the mesh."""
    v, f = _bumpy_sphere(2)
    s = Surface(v, f)
    q = _queries(v, np.random.default_rng(3))[::7]
    got = s.closest(q, k=len(f))
    tri = v[f]
    for i in range(len(q)):
        bary = closest_on_triangles(q[i], tri[:, 0], tri[:, 1], tri[:, 2])
        best = np.linalg.norm(np.einsum("tj,tji->ti", bary, tri) - q[i], axis=1).min()
        assert abs(abs(got.signed[i]) - best) < 1e-12
        assert abs(np.linalg.norm(got.point[i] - q[i]) - best) < 1e-12


def test_sign_and_degenerate_triangles():
    """Inside/outside of a closed box; a zero-area triangle (the face region's 0/0 case)."""
    v = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float
    )
    f = np.array(
        [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
         [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    )  # fmt: skip
    s = Surface(v, f)
    c = s.closest(np.array([[0.5, 0.5, 0.4], [0.5, 0.5, 1.25], [2.0, 0.5, 0.5]]), k=len(f))
    np.testing.assert_allclose(c.signed, [-0.4, 0.25, 1.0], atol=1e-12)
    flat = Surface(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float), np.array([[0, 1, 2]]))
    got = flat.closest(np.array([[1.5, 1.0, 0.0], [-1.0, 0.0, 0.0]]))
    ref = flat.closest_reference(np.array([[1.5, 1.0, 0.0], [-1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(got.point, ref.point, atol=1e-12)
    assert np.all(np.isfinite(got.point))


def _two_spheres():
    """Sphere A at the origin (r 0.1 m) and sphere B 0.26 m away (r 0.1 m): 6 cm apart."""
    a = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    b = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    v = np.concatenate([np.asarray(a.vertices), np.asarray(b.vertices) + [0.26, 0, 0]])
    f = np.concatenate([np.asarray(a.faces), np.asarray(b.faces) + len(a.vertices)])
    return v, f


def test_local_surface_answers_as_the_whole_mesh():
    """Near sphere A's box the local part answers; a point whose nearest triangles are on B
    (not kept) must not take A's: it goes to the whole mesh, and every answer is the whole's."""
    v, f = _two_spheres()
    whole = Surface(v, f)
    built = []

    def get_whole():
        built.append(1)
        return whole

    lo, hi = np.full(3, -0.1), np.full(3, 0.1)
    local = LocalSurface(v, f, lo, hi, 0.03, get_whole)
    assert 0 < len(local.keep) <= len(f) / 2  # A's triangles only
    rng = np.random.default_rng(4)
    on_a = rng.normal(size=(200, 3))
    on_a = 0.1 * on_a / np.linalg.norm(on_a, axis=1, keepdims=True) * rng.uniform(0.9, 1.1, (200, 1))
    got = local.closest(on_a)
    assert not built  # all certified locally
    ref = whole.closest(on_a)
    for name in ("point", "triangle", "bary", "normal", "signed"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
    # 5 mm off B, 5.5 cm off A's box: A's triangles are candidates locally but B's are nearer
    q = np.array([[0.155, 0.0, 0.0], [0.12, 0.0, 0.0]])
    got, ref = local.closest(q), whole.closest(q)
    assert local.fallbacks >= 1 and built
    assert got.point[0, 0] > 0.15  # on B
    for name in ("point", "triangle", "signed"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))


def test_local_caster_gives_the_whole_bodys_air_gap():
    """Rays from A's box: hits on A (first tier), on B 6-16 cm away (second tier), beyond
    MAX_AIR_GAP and misses: the same air gap as with the whole mesh's caster."""
    v, f = _two_spheres()
    frame = _BodyFrame(v, f)
    lo, hi = np.array([-0.1, -0.1, -0.1]), np.array([0.1, 0.1, 0.1])
    caster = _LocalCaster(frame, lo, hi, frame.near_triangles(lo, hi, LOCAL_RAY))
    whole = RayCaster(v, f, normalize=False)
    o = np.array(
        [[0.0, 0.0, 0.105], [0.102, 0.0, 0.0], [0.09, 0.0, 0.05], [0.0, 0.0, -0.105], [0.1, 0.05, 0.0]]
    )
    d = np.array([[0, 0, -1.0], [1.0, 0, 0], [1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_local, t_whole = caster.hit_distance(o, d), whole.hit_distance(o, d)
    assert t_whole[0] < LOCAL_RAY and LOCAL_RAY < t_whole[1] < MAX_AIR_GAP and np.isinf(t_whole[4])
    np.testing.assert_allclose(t_local, t_whole, rtol=0, atol=1e-6)  # float32 frames differ
