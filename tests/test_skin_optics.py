"""Skin reflectance model (humv_usd.physics.skin_optics) and the skin-tone materials
(humv_usd.catalog.skin): limits, the melanin ordering, and IR emissivity left unchanged."""

import numpy as np
import pytest

from humv_usd.catalog.materials import LIBRARY
from humv_usd.catalog.skin import SKIN_TONES, skin_material_name
from humv_usd.physics import skin_optics as S
from humv_usd.physics.water_film import WATER_OPTICAL_CONSTANTS

VIS_NIR = np.array([0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.8, 0.9, 1.0])


def test_diffuse_reflectance_limits():
    # no absorption: all light comes back; strong absorption: none
    assert S.diffuse_reflectance(0.0, 20.0) == pytest.approx(1.0, abs=1e-12)
    assert S.diffuse_reflectance(1e6, 20.0) < 1e-3
    r = S.diffuse_reflectance(np.array([0.01, 0.1, 1.0, 10.0]), 20.0)
    assert np.all(np.diff(r) < 0)
    # small absorption, first order in x = sqrt(3 (1 - a')): R = (1/2)(2 - 4A/3 x)(1 - x), so
    # 1 - R = (1 + 2A/3) x (Farrell et al. 1992 with A from Groenhuis et al. 1983 at n = 1.4)
    x = np.sqrt(3 * 1e-6 / (1e-6 + 1.0))
    n = 1.4
    r_id = -1.440 / n**2 + 0.710 / n + 0.668 + 0.0636 * n
    big_a = (1 + r_id) / (1 - r_id)
    slope = 1 + 2 * big_a / 3
    assert (1 - S.diffuse_reflectance(1e-6, 1.0)) == pytest.approx(slope * x, rel=2e-2)


def test_melanin_and_scattering_laws():
    assert S.melanin_absorption(0.5) == pytest.approx(519.0)
    assert S.melanin_absorption(1.0) == pytest.approx(519.0 * 2**-3.5)
    assert S.reduced_scattering(0.5) == pytest.approx(46.0)


def test_darker_types_reflect_less_in_the_visible_and_alike_in_the_swir():
    r = np.array([S.fitzpatrick_reflectance(VIS_NIR, t) for t in S.FITZPATRICK_MELANIN])
    assert np.all(np.diff(r, axis=0) < 0)  # I > II > ... > VI at every visible/NIR wavelength
    swir = np.array([1.45, 1.65, 1.94, 2.2])
    s = np.array([S.fitzpatrick_reflectance(swir, t) for t in S.FITZPATRICK_MELANIN])
    assert np.ptp(s, axis=0).max() < 0.015  # melanin absorbs < 1 % of the SWIR light
    # the contrast shrinks with wavelength (melanin ~ lambda^-3.5)
    assert r[0, 2] / r[-1, 2] > 3 * r[0, -1] / r[-1, -1]


def test_bad_input():
    with pytest.raises(ValueError, match="wavelength"):
        S.skin_reflectance([3.0], 0.1)
    with pytest.raises(ValueError, match="melanin_fraction"):
        S.skin_reflectance([0.5], 1.5)
    with pytest.raises(ValueError, match="skin_type"):
        S.fitzpatrick_reflectance([0.5], "VII")
    with pytest.raises(ValueError, match="skin_tone"):
        skin_material_name("7")


def test_tone_materials():
    skin = LIBRARY["skin"]
    assert skin_material_name(None) == "skin"
    ir = np.asarray(skin.spectrum_wavelengths) >= 2.8
    for tone in SKIN_TONES:
        m = LIBRARY[skin_material_name(tone)]
        assert m.spectrum_wavelengths == skin.spectrum_wavelengths
        # infrared emissivity unchanged (Steketee 1973: 0.98 for every pigmentation)
        assert np.array_equal(np.asarray(m.spectrum_emissivity)[ir], np.asarray(skin.spectrum_emissivity)[ir])
        assert (m.conductivity, m.density, m.specific_heat) == (
            skin.conductivity,
            skin.density,
            skin.specific_heat,
        )
    # type II is the measured spectrum itself
    assert LIBRARY["skin_II"].spectrum_reflectance == pytest.approx(skin.spectrum_reflectance, abs=1e-3)
    # heavily pigmented skin: dark in the visible, bright in the NIR (Anderson & Parrish 1981, Fig. 2)
    vi = LIBRARY["skin_VI"]
    assert vi.at(0.55) < 0.10 and vi.at(0.8) > 0.3
    # solar absorptivity grows with pigmentation
    alphas = [LIBRARY[skin_material_name(t)].solar_absorptivity for t in SKIN_TONES]
    assert np.all(np.diff(alphas) > 0)


def test_absorption_tables_match_their_sources():
    """Blood at Prahl's (1999, omlc.org/spectra/hemoglobin/summary.html) tabulated molar
    extinction (mu_a = 2.303 e 150 g/L / 64 500 g/mol, plus 80 % water), and water at 4 pi k /
    lambda from Hale & Querry's k as tabulated independently in physics.water_film."""
    prahl = {0.5: (20932.8, 20862.0), 0.576: (55540.0, 40092.0), 0.8: (816.0, 761.72), 1.0: (1024.0, 206.784)}
    for w, (hbo2, hb) in prahl.items():
        water = 0.8 * S.water_absorption(w)
        for sat, eps in ((1.0, hbo2), (0.0, hb)):
            expected = 2.303 * eps * 150.0 / 64500.0 + water
            assert S.blood_absorption(w, oxygen_saturation=sat) == pytest.approx(expected, rel=1e-6)
    w, _, k = WATER_OPTICAL_CONSTANTS[WATER_OPTICAL_CONSTANTS[:, 0] <= 2.5].T
    np.testing.assert_allclose(S.water_absorption(w), 4.0 * np.pi * k / (w * 1e-4), rtol=0.06)
