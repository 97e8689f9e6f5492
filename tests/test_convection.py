"""Convective coefficients: Siple-Passel in both unit systems, Mitchell, ISO 7730, h_r."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from humv_usd.compat import trapezoid
from humv_usd.constants import STEFAN_BOLTZMANN
from humv_usd.physics.convection import (
    KCAL_PER_HOUR_TO_WATT,
    convective_coefficient,
    iso7730,
    mitchell,
    natural_iso7730,
    radiative_coefficient,
    siple_passel,
    watmuff,
)


def test_siple_passel_both_unit_systems():
    h = siple_passel(np.array([0.0, 5.0]))
    # kcal m^-2 h^-1 K^-1: 10.45 at rest, 10.45 - 5 + 10 sqrt(5) = 27.8107 at 5 m/s
    assert_allclose(h / KCAL_PER_HOUR_TO_WATT, [10.45, 10.45 - 5.0 + 10.0 * np.sqrt(5.0)], rtol=1e-12)
    assert_allclose(h, [12.15335, 32.343821], rtol=1e-7)  # W m^-2 K^-1


def test_siple_passel_held_beyond_its_maximum():
    assert_allclose(siple_passel(25.0), KCAL_PER_HOUR_TO_WATT * 35.45, rtol=1e-12)
    assert_allclose(siple_passel(30.0), siple_passel(25.0))
    assert np.all(np.diff(siple_passel(np.linspace(0, 30, 61))) >= 0.0)


def test_mitchell():
    assert_allclose(mitchell([0.0, 1.0, 4.0]), [0.0, 8.3, 8.3 * 4.0**0.6], rtol=1e-12)


def test_iso7730_and_natural_floor():
    assert_allclose(natural_iso7730(-16.0), 2.38 * 2.0, rtol=1e-12)
    assert_allclose(iso7730(0.0, 16.0), 4.76, rtol=1e-12)
    assert_allclose(iso7730(1.0, 16.0), 12.1, rtol=1e-12)


def test_convective_coefficient_models():
    assert_allclose(convective_coefficient(0.0, 81.0), 2.38 * 3.0, rtol=1e-12)
    assert_allclose(convective_coefficient(2.0, 0.0), 8.3 * 2.0**0.6, rtol=1e-12)
    assert_allclose(convective_coefficient(5.0, model="siple_passel"), siple_passel(5.0))
    assert_allclose(convective_coefficient(4.0, model="iso7730"), 24.2, rtol=1e-12)
    with pytest.raises(ValueError, match="invalid model selection bogus"):
        convective_coefficient(1.0, model="bogus")


def test_radiative_coefficient_linearizes_t4():
    t1, t2 = 310.0, 290.0
    exact = 0.9 * STEFAN_BOLTZMANN * (t1**4 - t2**4) / (t1 - t2)
    hr = radiative_coefficient(0.9, 300.0)
    assert_allclose(hr * (1.0 + (10.0 / 300.0) ** 2), exact, rtol=1e-12)


def test_watmuff_flat_surface():
    # Duffie & Beckman (2013) Eq. 3.15.3: h = 2.8 + 3.0 V, no wind -> 2.8
    assert_allclose(watmuff([0.0, 1.0, 5.0, -1.0]), [2.8, 5.8, 17.8, 2.8])


def test_coefficients_reject_nan():
    import pytest

    from humv_usd.physics.convection import convective_coefficient, radiative_coefficient

    for model in ("mitchell", "iso7730", "siple_passel"):
        with pytest.raises(ValueError, match="wind_speed"):
            convective_coefficient([1.0, float("nan")], model=model)
        with pytest.raises(ValueError, match="delta_t"):
            convective_coefficient(1.0, float("inf"), model=model)
    with pytest.raises(ValueError, match="emissivity"):
        radiative_coefficient(1.5, 300.0)
    with pytest.raises(ValueError, match="mean_temperature_k"):
        radiative_coefficient(0.9, -1.0)


def test_relative_air_speed_closed_forms():
    """Walking north at 1.4 m/s: calm air 1.4 m/s; a 3 m/s wind from the north (a head wind)
    4.4 m/s; from the south (a tail wind) 1.6 m/s; from the east, across, sqrt(3^2 + 1.4^2)."""
    from humv_usd.physics.convection import relative_air_speed

    v = np.array([0.0, 1.4, 0.0])
    assert relative_air_speed(v, 0.0, 0.0) == pytest.approx(1.4)
    assert relative_air_speed(v, 3.0, 0.0) == pytest.approx(4.4)
    assert relative_air_speed(v, 3.0, 180.0) == pytest.approx(1.6)
    assert relative_air_speed(v, 3.0, 90.0) == pytest.approx(np.hypot(3.0, 1.4))
    assert relative_air_speed(v, 3.0) == pytest.approx(np.hypot(3.0, 1.4))  # no direction
    # standing: the wind alone, whatever its direction
    assert_allclose(relative_air_speed(np.zeros((4, 3)), 2.5, [0, 90, 200, 315]), 2.5)


def test_windward_ratio_cylinder_shape():
    """Mean 1 over the circumference; the stagnation line at Froessling's Nu_0 = 1.14 Re^0.5
    Pr^0.4 over Churchill-Bernstein's mean (Incropera Eq. 7.51, 7.54); 0.5 at the sides."""
    from humv_usd.physics.convection import AIR_PRANDTL, churchill_bernstein, windward_ratio

    theta = np.linspace(0.0, np.pi, 20001)
    for v in (0.5, 3.0, 10.0):
        r = windward_ratio(np.cos(theta), v)
        assert trapezoid(r, theta) / np.pi == pytest.approx(1.0, abs=1e-6)
        re = v * 0.15 / 1.516e-5
        assert r[0] == pytest.approx(1.14 * re**0.5 * AIR_PRANDTL**0.4 / churchill_bernstein(re))
        assert r[10000] == pytest.approx(0.5)
        assert (r >= 0).all()
    # Churchill-Bernstein against Hilpert's table (Incropera Table 7.2) at Re = 1e4: 0.193 Re^0.618 Pr^(1/3)
    hilpert = 0.193 * 1e4**0.618 * AIR_PRANDTL ** (1 / 3)
    assert churchill_bernstein(1e4) == pytest.approx(hilpert, rel=0.1)
