"""Analytic clear sky: Magnus dew point and Berdahl-Martin emissivity against closed forms."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from humv_usd.physics.sky import berdahl_martin_emissivity, dew_point, effective_sky_temperature


def test_dew_point_saturated_equals_air():
    t = np.array([243.15, 273.15, 300.0, 320.0])
    assert_allclose(dew_point(t, 1.0), t, atol=1e-9)


def test_dew_point_inverts_magnus_saturation_pressure():
    # e_s(T) = 6.1094 exp(17.625 t / (t + 243.04)) hPa (Alduchov & Eskridge 1996);
    # RH = e_s(T_dp) / e_s(T)
    def es(t_k):
        t = t_k - 273.15
        return 6.1094 * np.exp(17.625 * t / (t + 243.04))

    t_air, rh = 295.0, 0.4
    assert_allclose(es(dew_point(t_air, rh)) / es(t_air), rh, rtol=1e-12)


def test_berdahl_martin_polynomial():
    assert_allclose(berdahl_martin_emissivity(273.15), 0.711)
    assert_allclose(berdahl_martin_emissivity(293.15), 0.711 + 0.56 * 0.2 + 0.73 * 0.04)


def test_sky_colder_than_air_and_humidity_warms_it():
    t_dry, _ = effective_sky_temperature(289.0, 0.1)
    t_wet, eps = effective_sky_temperature(289.0, 0.9)
    assert t_dry < t_wet < 289.0
    assert_allclose(t_wet, eps**0.25 * 289.0)
