"""geometry.mesh.Surface: the compiled closest-point kernel against plain numpy and brute force."""

import numpy as np
import trimesh

from humv_usd.geometry.mesh import Surface, closest_on_triangles


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
