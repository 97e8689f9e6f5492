"""Hair colours from melanin (physics/hair_optics.py, catalog/hair.py) and their binding."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from humv_usd.catalog.dyes import garment_material
from humv_usd.catalog.hair import hair_material_name
from humv_usd.catalog.materials import LIBRARY
from humv_usd.physics import hair_optics as H
from humv_usd.scenario import spec


def test_diffuse_fresnel_of_glass():
    """Diffuse external reflectance of a smooth n = 1.5 surface: 0.092 (e.g. Judd 1942, the
    value used in Saunderson's correction); none for n = 1."""
    assert H.diffuse_fresnel(1.5) == pytest.approx(0.0918, abs=0.001)
    assert H.diffuse_fresnel(1.0) == pytest.approx(0.0, abs=1e-9)


def test_melanin_spectra_match_chiang_rgb():
    """Donner & Jensen's exponents through Chiang et al.'s red value reproduce their green and
    blue coefficients (0.697, 1.37 eumelanin; 0.4, 1.05 pheomelanin) within 6 %."""
    w = np.array([0.65, 0.55, 0.45])
    assert_allclose(H.melanin_absorption(w, 1.0, 0.0), [0.419, 0.697, 1.37], rtol=0.06)
    assert_allclose(H.melanin_absorption(w, 0.0, 1.0), [0.187, 0.4, 1.05], rtol=0.06)


def test_hapke_layer_limits():
    assert H.layer_reflectance(1.0) == pytest.approx(1.0)
    assert H.layer_reflectance(0.0) == pytest.approx(0.0)
    omega = np.linspace(0, 1, 51)
    assert np.all(np.diff(H.layer_reflectance(omega)) > 0)
    # omega = 0.75: gamma = 1/2, R = 1/3
    assert H.layer_reflectance(0.75) == pytest.approx(1 / 3)


def test_colours_order_and_hue():
    w = np.array([0.45, 0.55, 0.65, 1.0])
    r = {c: H.colour_reflectance(w, c) for c in H.HAIR_COLOURS}
    assert r["blond"][1] > r["grey"][1] > r["brown"][1] > r["dark_brown"][1] > r["black"][1]
    for c, v in r.items():
        assert np.all((v > 0) & (v < 1)) and np.all(np.diff(v) > 0), c  # melanin: brighter to the red
    hue = {c: r[c][2] / r[c][0] for c in r}
    assert hue["red"] > hue["brown"] > hue["blond"]  # pheomelanin reddens, less melanin whitens
    with pytest.raises(ValueError, match="hair colour"):
        H.colour_reflectance(w, "green")


def test_other_absorption_inverts_the_model():
    w = np.linspace(0.4, 2.5, 30)
    target = 0.5 * H.hair_reflectance(w, 1.0)  # darker than melanin alone gives
    other = H.other_absorption(w, target, 1.0)
    assert np.all(other > 0)
    assert_allclose(H.hair_reflectance(w, 1.0, other_absorption=other), target, rtol=1e-9)
    # brighter than the melanin allows: nothing to add
    assert np.all(H.other_absorption(w, np.full_like(w, 0.99), 1.0) == 0.0)


def test_catalogue_colours_share_hair_dark_ir_and_swir():
    dark = LIBRARY["hair_dark"]
    w = np.asarray(dark.spectrum_wavelengths)
    black = LIBRARY["hair_black"]
    assert_allclose(black.at(w), dark.at(w), atol=1e-3)  # black hair = the measured dark hair
    for colour in H.HAIR_COLOURS:
        m = LIBRARY[hair_material_name(colour)]
        assert_allclose(m.at([3.0, 5.0, 8.0, 11.0, 14.0]), dark.at([3.0, 5.0, 8.0, 11.0, 14.0]))
        assert m.conductivity == dark.conductivity and m.thickness == dark.thickness
        swir = [1.45, 1.94, 2.3]
        assert np.all(np.abs(m.at(swir) - dark.at(swir)) < 0.05), colour  # the shared SWIR bands
    assert (
        LIBRARY["hair_blond"].at(0.55) > 0.3 > LIBRARY["hair_brown"].at(0.55) > LIBRARY["hair_dark"].at(0.55)
    )
    assert LIBRARY["hair_blond"].solar_absorptivity < LIBRARY["hair_black"].solar_absorptivity


def test_hair_garments_take_the_hair_colour():
    assert garment_material("hair_short", None, "blond") == "hair_blond"
    assert garment_material("beard", None, "grey") == "hair_grey"
    assert garment_material("hair_long") == "hair_dark"  # unset: as before
    assert garment_material("tshirt_white", None, "blond") == "cotton_white"
    assert garment_material("hair_tied", {"hair*": "red"}, "blond") == "hair_dark__red"  # explicit dye wins
    assert spec.HAIR_COLOURS == tuple(H.HAIR_COLOURS)
    assert spec.HUMAN.keys["hair_color"].choices == spec.HAIR_COLOURS
