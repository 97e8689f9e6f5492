"""Band quantities of a material (issue 24): one authority per band for Kirchhoff's law
eps + rho + tau = 1, checked against the stored tables; the cached band emissivity is the
thermal solve's number."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from humv_usd.catalog.materials import LIBRARY
from humv_usd.render import bands
from humv_usd.usd.materials import StageMaterial


def _material(eps, rho, tau=None, wl=(0.4, 1.0, 4.0, 8.0, 14.0)):
    return StageMaterial("/M", np.array(wl), np.array(eps, float), np.array(rho, float), tau)


def test_authority_per_band():
    assert bands.authority((8.0, 14.0)) == "emissivity"
    assert bands.authority((3.0, 5.0)) == "emissivity"
    assert bands.authority((0.4, 0.7)) == "reflectance"
    assert bands.authority((0.9, 1.7)) == "reflectance"  # SWIR: reflected light


def test_closure_error_is_the_largest_departure_in_the_band():
    m = _material([0.1, 0.2, 0.9, 0.95, 0.97], [0.9, 0.8, 0.1, 0.05 + 0.07, 0.03])
    assert bands.closure_error(m, (8.0, 14.0)) == pytest.approx(0.07)  # the 8 um node
    assert bands.closure_error(m, (0.4, 0.7)) == pytest.approx(0.0, abs=1e-12)  # nodes 0.4 and 1.0
    glass = _material(
        [0.0, 0.0, 0.9, 0.9, 0.9], [0.1, 0.1, 0.1, 0.1, 0.1], np.array([0.9, 0.9, 0.0, 0.0, 0.0])
    )
    assert bands.closure_error(glass, (0.4, 0.7)) == pytest.approx(0.0, abs=1e-12)
    assert bands.closure_error(StageMaterial("/N", np.array([8.0]), np.array([0.9])), (8.0, 14.0)) is None


def test_catalog_materials_close_in_every_band():
    """The catalog derives eps = 1 - rho - tau at each node (its authority is the reflectance):
    every library material closes to its 6-decimal rounding."""
    for name, mat in LIBRARY.items():
        m = StageMaterial(
            name,
            np.asarray(mat.spectrum_wavelengths, float),
            np.asarray(mat.spectrum_emissivity, float),
            np.asarray(mat.spectrum_reflectance, float),
            None if mat.spectrum_transmittance is None else np.asarray(mat.spectrum_transmittance, float),
        )
        for band in ((0.4, 0.7), (3.0, 5.0), (8.0, 14.0)):
            err = bands.closure_error(m, band)
            assert err is not None and err <= 1e-6, (name, band, err)


def test_check_closure_flags_and_caches(caplog):
    m = _material([0.1, 0.2, 0.9, 0.95, 0.97], [0.9, 0.8, 0.1, 0.2, 0.03])
    lwir = SimpleNamespace(name="lwir", wavelength_range_um=(8.0, 14.0))
    cache: dict = {}
    rec = bands.check_closure(cache, m, lwir)
    assert rec["authority"] == "emissivity" and rec["max_error"] == pytest.approx(0.15) and not rec["ok"]
    assert "differs from 1 by 0.15" in caplog.text
    assert bands.check_closure(cache, m, lwir) is rec  # once per material and sensor
