"""The thermal tool's face-temperature noise (thermal.human._face_temperature_noise) in closed form:
a face's flux variance is sum(a_t^2 var_t) / (sum a_t)^2 over its triangles, sigma_T = sigma_q /
(dq/dT + g) on bare skin; a face of zero area adds nothing (it was 0/0: NaN and a RuntimeWarning
in every compose of a body with degenerate faces)."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np

from humv_usd.thermal.human import _face_temperature_noise


def test_face_noise_closed_form_and_a_zero_area_face():
    # two faces: a unit square (two triangles of area 0.5) and a degenerate one (area 0)
    points = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]], float)
    tris = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 5]])
    part = SimpleNamespace(
        triangles=tris, counts=np.array([4, 3]), tri_face=np.array([0, 0, 1]), path="/P/Body"
    )
    q_var = np.array([4.0, 16.0, 9.0])  # W^2 m^-4 per triangle
    skin_g = np.array([10.0, 10.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = _face_temperature_noise(q_var, [part], [points], skin_g, [np.array([True, True])], None)
    var_face = (0.25 * 4.0 + 0.25 * 16.0) / 1.0**2  # the square; the zero-area face: 0, weight 0
    assert np.isfinite(out["faceTemperatureNoiseRms_K"])
    assert out["faceTemperatureNoiseRms_K"] == np.sqrt(var_face) / 10.0
