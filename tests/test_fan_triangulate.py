"""The one fan triangulation (humv_usd.geometry.mesh.fan_triangulate)."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose, assert_array_equal

from humv_usd.geometry.mesh import fan_triangulate
from humv_usd.usd.mesh import triangle_areas


def test_fans_keep_winding_and_face_order():
    counts = [3, 5, 4]
    indices = [0, 1, 2, 10, 11, 12, 13, 14, 20, 21, 22, 23]
    tris, face = fan_triangulate(counts, indices)
    assert_array_equal(
        tris,
        [[0, 1, 2], [10, 11, 12], [10, 12, 13], [10, 13, 14], [20, 21, 22], [20, 22, 23]],
    )
    assert_array_equal(face, [0, 1, 1, 1, 2, 2])


def test_fan_areas_sum_to_the_polygon_area():
    # a regular hexagon of circumradius 1 and a 2 x 3 rectangle: 3 sqrt(3) / 2 and 6 [m^2]
    ang = np.arange(6) * np.pi / 3
    hexagon = np.c_[np.cos(ang), np.sin(ang), np.zeros(6)]
    rect = np.array([[0.0, 0, 1], [2, 0, 1], [2, 3, 1], [0, 3, 1]])
    points = np.r_[hexagon, rect]
    area = triangle_areas(points, [6, 4], np.arange(10))
    assert_allclose(area, [3 * np.sqrt(3) / 2, 6.0], rtol=1e-12)


def test_no_faces():
    tris, face = fan_triangulate([], [])
    assert tris.shape == (0, 3) and face.shape == (0,)
