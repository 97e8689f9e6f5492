"""geometry.shading.barycentric: points built from known barycentric coordinates come back,
per point or through a per-triangle index (labels' surface temperature: each triangle's edges
computed once), with the same numbers both ways."""

import numpy as np
from numpy.testing import assert_allclose

from humv_usd.geometry import shading


def test_barycentric_recovers_known_weights_per_point_and_by_index():
    rng = np.random.default_rng(4)
    tris = rng.normal(size=(50, 3, 3))
    tris[7] = [[0, 0, 0], [1, 1, 1], [2, 2, 2]]  # degenerate: its first corner
    index = rng.integers(0, 50, size=2000)
    w = rng.dirichlet([1.0, 1.0, 1.0], size=2000)
    points = np.einsum("nc,ncx->nx", w, tris[index])
    per_point = shading.barycentric(tris[index], points)
    by_index = shading.barycentric(tris, points, index=index)
    assert np.array_equal(per_point, by_index)
    ok = index != 7
    assert_allclose(by_index[ok], w[ok], atol=1e-9)
    assert_allclose(by_index[~ok], [[1.0, 0.0, 0.0]] * int((~ok).sum()))
