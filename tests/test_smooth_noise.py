"""The error of a per-face field shaded smooth (geometry.shading.smooth_noise), against the
spread of the shaded field itself over random draws of the faces' errors (the fast estimator's
corner blend and one-ring gain steps, geometry.shading.ring_gains): the render states the
thermal layer's per-face temperature noise per pixel this way (pipeline.ir_pass.thermal_noise)."""

import numpy as np
import pytest
import trimesh

from humv_usd.geometry import shading


def _shaded(blend, values, steps, tri, bary):
    corners = shading.ring_gains(blend, values, np.asarray(blend @ values).reshape(-1, 3), steps)
    return np.einsum("ij,ij->i", bary, corners[tri])


@pytest.mark.parametrize("steps", [0, 1])
def test_smooth_noise_is_the_spread_of_the_shaded_field(steps):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    blend = shading.corner_blend([(v, f)], crease_deg=60.0)
    n_t = len(f)
    rng = np.random.default_rng(5)
    face_of = np.arange(n_t) // 2  # pairs of triangles share a value and its error (a quad)
    n_f = face_of.max() + 1
    sigma = rng.uniform(0.01, 0.05, n_f)  # [K]
    base = 305.0 + 2.0 * np.asarray(mesh.triangles_center)[:, 2] / 0.1  # a smooth field [K]
    tri = rng.integers(0, n_t, 300)
    bary = rng.dirichlet(np.ones(3), 300)
    draws = 4000
    eps = rng.standard_normal((draws, n_f)) * sigma
    ref = _shaded(blend, base, steps, tri, bary)
    spread = np.std([_shaded(blend, base + e[face_of], steps, tri, bary) - ref for e in eps], axis=0)
    stated = shading.smooth_noise(blend, face_of, sigma, tri, bary, steps)
    ratio = stated / spread
    # 4000 draws: each point's spread within ~1.1 % (1 sigma); the linearised gain step holds
    # for errors of ~1e-4 of the field
    assert np.sqrt(np.mean((ratio - 1.0) ** 2)) < 0.02
    assert np.all(np.abs(ratio - 1.0) < 0.06)
    # blending averages the faces' errors: well below a flat face's own sigma
    assert np.mean(stated / sigma[face_of[tri]]) < 0.85


def test_smooth_noise_of_a_flat_blend_is_the_face_sigma():
    """An identity blend (every corner its own triangle's value: flat faces) gives each point
    its face's sigma, with or without gain steps (a uniform ring of one face is its own mean)."""
    from scipy import sparse

    n_t = 10
    blend = sparse.csr_matrix((np.ones(3 * n_t), (np.arange(3 * n_t), np.repeat(np.arange(n_t), 3))))
    face_of = np.arange(n_t) // 2
    sigma = np.linspace(0.01, 0.05, 5)
    bary = np.tile([0.2, 0.3, 0.5], (n_t, 1))
    for steps in (0, 1, 2):
        got = shading.smooth_noise(blend, face_of, sigma, np.arange(n_t), bary, steps)
        assert np.allclose(got, sigma[face_of], rtol=1e-12)
