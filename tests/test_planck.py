"""Planck's law, band radiance and its inverse against closed forms and independent quadrature."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import quad

from humv_usd.physics import planck

LWIR = (8.0, 14.0)
MWIR = (3.0, 5.0)
# A made-up trapezoidal response, zero outside 7.5-14.5 um.
RESPONSE = (np.array([7.5, 8.0, 12.0, 14.5]), np.array([0.0, 1.0, 0.8, 0.0]))


def _quad_band(t, band, response=None):
    if response is None:

        def f(lam):
            return planck.spectral_radiance(lam, t)

        points = None
    else:

        def f(lam):
            return np.interp(lam, response[0], response[1], left=0.0, right=0.0) * planck.spectral_radiance(
                lam, t
            )

        points = [p for p in response[0] if band[0] < p < band[1]]
    return quad(f, band[0], band[1], points=points, epsabs=0.0, epsrel=1e-12, limit=500)[0]


def test_constants_codata_2018():
    # c2 = hc/k = 14387.768775 um K (CODATA 2018, exact constants)
    assert_allclose(planck.C2, 14387.768775039337, rtol=1e-14)
    # c1L = 2hc^2 = 1.191042972e-16 W m^2 sr^-1 -> per um with wavelength in um: 1.191042972e8
    assert_allclose(planck.C1L, 1.1910429723971884e8, rtol=1e-14)


def test_spectral_radiance_wien_peak_and_stefan_boltzmann():
    t = 300.0
    lam = np.linspace(9.0, 10.5, 200001)
    peak = lam[np.argmax(planck.spectral_radiance(lam, t))]
    assert_allclose(peak, 2897.771955 / t, atol=1e-5)  # Wien's displacement law, b [um K]
    sigma = 5.670374419e-8  # Stefan-Boltzmann [W m^-2 K^-4], CODATA 2018
    total = planck.band_radiance(t, (0.5, 1e5))  # the rest of the spectrum holds < 1e-9 of it
    assert_allclose(total, sigma * t**4 / np.pi, rtol=1e-8)


def test_band_radiance_reference_values():
    assert_allclose(planck.band_radiance(300.0, LWIR), 54.93, rtol=1e-3)
    assert_allclose(planck.band_radiance(300.0, MWIR), 1.866, rtol=1e-3)


@pytest.mark.parametrize("band", [LWIR, MWIR])
@pytest.mark.parametrize("t", [5.0, 150.0, 300.0, 1500.0, 5000.0])
def test_band_radiance_matches_adaptive_quadrature(band, t):
    assert_allclose(planck.band_radiance(t, band), _quad_band(t, band), rtol=1e-10)


def test_band_radiance_with_response():
    band = (7.0, 15.0)
    for t in (200.0, 300.0, 900.0):
        assert_allclose(planck.band_radiance(t, band, RESPONSE), _quad_band(t, band, RESPONSE), rtol=1e-10)
    # a response of 1 everywhere is no response
    flat = (np.array([1.0, 20.0]), np.array([1.0, 1.0]))
    assert_allclose(planck.band_radiance(300.0, LWIR, flat), planck.band_radiance(300.0, LWIR), rtol=1e-13)


def test_band_radiance_shapes():
    t = np.array([[250.0, 300.0], [310.0, 400.0]])
    out = planck.band_radiance(t, LWIR)
    assert out.shape == (2, 2)
    assert isinstance(planck.band_radiance(300.0, LWIR), float)
    with pytest.raises(ValueError):
        planck.band_radiance(-1.0, LWIR)
    with pytest.raises(ValueError):
        planck.band_radiance(300.0, (14.0, 8.0))


@pytest.mark.parametrize("band,response", [(LWIR, None), (MWIR, None), ((7.0, 15.0), RESPONSE)])
def test_brightness_temperature_inverts_band_radiance(band, response):
    t = np.linspace(150.0, 1500.0, 2701)
    radiance = planck.band_radiance(t, band, response)
    assert np.max(np.abs(planck.brightness_temperature(radiance, band, response) - t)) < 1e-6


@pytest.mark.parametrize("band", [LWIR, MWIR])
def test_brightness_temperature_wide_range(band):
    t = np.geomspace(10.0, 5000.0, 300)
    radiance = planck.band_radiance(t, band)
    assert_allclose(planck.brightness_temperature(radiance, band), t, rtol=1e-10)
    # beyond the internal table (0.5-20000 K) Newton still converges
    for tt in (3e4, 1e5):
        assert_allclose(planck.brightness_temperature(planck.band_radiance(tt, band), band), tt, rtol=1e-10)


def test_brightness_temperature_special_values():
    out = planck.brightness_temperature(np.array([0.0, -1.0, np.nan, np.inf, 54.93346137683966]), LWIR)
    assert out[0] == 0.0 and out[1] == 0.0
    assert np.isnan(out[2]) and np.isposinf(out[3])
    assert_allclose(out[4], 300.0, atol=1e-9)
    assert isinstance(planck.brightness_temperature(54.9, LWIR), float)


@pytest.mark.parametrize("band,response", [(LWIR, None), (MWIR, None), ((7.0, 15.0), RESPONSE)])
def test_band_radiance_derivative_matches_finite_difference(band, response):
    t = np.array([150.0, 250.0, 300.0, 600.0, 1500.0])
    h = 1e-5 * t  # central difference: truncation error ~ 50 (h/T)^2 at 150 K in MWIR
    fd = (planck.band_radiance(t + h, band, response) - planck.band_radiance(t - h, band, response)) / (2 * h)
    assert_allclose(planck.band_radiance_derivative(t, band, response), fd, rtol=1e-8)


def test_brightness_temperature_sensitivity():
    t = np.array([200.0, 300.0, 900.0])
    radiance = planck.band_radiance(t, MWIR)
    tb, slope = planck.brightness_temperature_sensitivity(radiance, MWIR)
    assert_allclose(tb, t, rtol=1e-12)
    assert_allclose(slope, planck.band_radiance_derivative(t, MWIR), rtol=1e-9)


def test_band_emissivity():
    # gray body: the band emissivity is the emissivity
    assert_allclose(planck.band_emissivity([8.0, 14.0], [0.37, 0.37], LWIR), 0.37, rtol=1e-14)
    assert_allclose(planck.band_emissivity([10.0], [0.8], MWIR), 0.8, rtol=1e-14)
    # a spectral table: Planck-weighted mean against adaptive quadrature
    wl, eps = np.array([5.0, 9.0, 11.0, 15.0]), np.array([0.5, 0.95, 0.7, 0.9])

    def num(lam):
        return np.interp(lam, wl, eps) * planck.spectral_radiance(lam, 300.0)

    expected = quad(num, 8.0, 14.0, points=[9.0, 11.0], epsrel=1e-12)[0] / _quad_band(300.0, LWIR)
    assert_allclose(planck.band_emissivity(wl, eps, LWIR), expected, rtol=1e-10)


def test_band_weighted_mean_of_several_tables():
    """The one Planck weighting (issue 24.3): tables (..., W) at once, each row against adaptive
    quadrature (a path transmittance per range); a row equals band_emissivity of that row."""
    wl = np.array([5.0, 9.0, 11.0, 15.0])
    rows = np.array([[0.5, 0.95, 0.7, 0.9], [1.0, 0.2, 0.6, 0.1], [0.3, 0.3, 0.3, 0.3]])
    got = planck.band_weighted_mean(wl, rows.reshape(3, 1, 4), LWIR, temperature_k=260.0)
    assert got.shape == (3, 1)
    for row, value in zip(rows, got[:, 0]):
        expected = quad(
            lambda lam, row=row: np.interp(lam, wl, row) * planck.spectral_radiance(lam, 260.0),
            8.0,
            14.0,
            points=[9.0, 11.0],
            epsrel=1e-12,
        )[0] / _quad_band(260.0, LWIR)
        assert_allclose(value, expected, rtol=1e-10)
        assert value == pytest.approx(planck.band_emissivity(wl, row, LWIR, temperature_k=260.0), rel=1e-14)


@pytest.mark.parametrize(
    "band,response",
    [(LWIR, None), (MWIR, None), ((7.0, 15.0), RESPONSE), ((8.0, 8.375), None), ((3.0, 3.125), None)],
)
def test_tabulated_band_radiance_and_inverse_match_the_exact_quadrature(band, response):
    # the whole table range (0.5 K to 20 000 K) where the band radiance is a normal float, and beyond
    t = np.geomspace(0.5, 3e4, 4001)
    exact = planck.band_radiance(t, band, response)
    t, exact = t[exact > 1e-290], exact[exact > 1e-290]
    assert_allclose(planck.band_radiance_tabulated(t, band, response), exact, rtol=1e-6, atol=0)
    tb, slope = planck.brightness_temperature_tabulated(exact, band, response)
    tb_exact, slope_exact = planck.brightness_temperature_sensitivity(exact, band, response)
    assert np.max(np.abs(tb - tb_exact)) < 1e-4
    assert_allclose(slope, slope_exact, rtol=1e-4, atol=0)
    # the radiances of a frame (between the table's nodes), and the special values
    t = np.random.default_rng(3).uniform(180.0, 420.0, 5000)
    radiance = planck.band_radiance(t, band, response)
    tb, slope = planck.brightness_temperature_tabulated(radiance, band, response)
    assert np.max(np.abs(tb - t)) < 1e-4
    assert_allclose(slope, planck.band_radiance_derivative(t, band, response), rtol=1e-4)
    tb, slope = planck.brightness_temperature_tabulated(np.array([0.0, -1.0, np.nan, np.inf]), band, response)
    assert (
        tb[0] == 0.0 and tb[1] == 0.0 and np.isnan(tb[2]) and np.isposinf(tb[3]) and np.all(np.isnan(slope))
    )
    assert isinstance(planck.brightness_temperature_tabulated(1.0, band, response)[0], float)
