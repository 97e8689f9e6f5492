"""Plants (issue 30.2): leaf temperatures of a crown face in the thermal tool's surface solve
against the closed-form leaf energy balance (Campbell & Norman 1998, eq. 14.6) and field
behaviour (near the air by day, below it on a clear night), and the generated plant meshes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Usd
from scipy.optimize import brentq

from humv_usd.catalog.materials import surface_water
from humv_usd.materials.layer import LIBRARY_FILE
from humv_usd.physics import evaporation as ev
from humv_usd.physics import vegetation as veg
from humv_usd.scene.vegetation import PLANT_KINDS, plant_parts
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.human import longwave_emissivity
from humv_usd.usd.materials import read_material
from humv_usd.usd.paths import material_path

_LIBRARY = Usd.Stage.Open(str(LIBRARY_FILE))
ISOTROPIC_SKY = (np.array([0.0, 90.0]), np.ones(2))
CROWN = "/World/Scene/tree/Crown"


def _leaf_face():
    m = read_material(_LIBRARY.GetPrimAtPath(material_path("leaf")))
    pts = np.array([[0, 0, 5], [1, 0, 5], [1, 1, 5], [0, 1, 5]], dtype=float)
    return SF.SceneMesh(CROWN, pts, np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]), 1, m, None, False)


def _forcing(n, dni, dhi, air, rh, wind):
    t = np.arange(n) * 600.0 - (n - 1) * 600.0
    one = np.ones(n)
    up = dni > 0 or dhi > 0
    return SF.SurfaceForcing(
        t, air * one, rh * one, wind * one, np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, up),
        dni * one, dhi * one, (dni + dhi) * one, sky_shape=ISOTROPIC_SKY,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("dni", "dhi", "air", "rh", "wind"),
    [(800.0, 100.0, 300.15, 0.4, 2.0), (600.0, 150.0, 288.15, 0.7, 0.5), (0.0, 0.0, 283.15, 0.8, 1.0)],
)
def test_leaf_face_matches_the_leaf_energy_balance(dni, dhi, air, rh, wind):
    leaf = _leaf_face()
    f = _forcing(12, dni, dhi, air, rh, wind)
    out, diag = SF.surface_temperatures(None, [leaf], f.times_s, 0.0, forcing=f, exchange=False)
    t_leaf = float(out[CROWN][-1, 0])
    eps = longwave_emissivity(leaf.material)
    alpha = leaf.material.solar_absorptivity
    sw = dni + dhi  # the sun at the zenith, a horizontal face
    absorbed = alpha * sw + eps * float(f.sky_longwave[-1])
    water = surface_water("leaf")
    h = veg.leaf_heat_transfer_coefficient(wind, water.leaf_dimension_m, 2, 101325.0, air)
    rs = ev.surface_resistance(water.minimum_resistance_s_m, sw, 1.0, water.leaf_area_index)
    closed = veg.leaf_temperature(absorbed, air, rh, h, rs, eps)
    assert t_leaf == pytest.approx(float(closed), abs=0.6)  # the linearization's error only
    beta = ev.evaporation_efficiency(h, rs, 101325.0, air)
    gamma = ev.psychrometric_constant(101325.0, air)
    e_a = rh * ev.saturation_vapour_pressure(air)

    def balance(t):  # the same balance without linearizing (one radiating side)
        le = beta * h / gamma * (ev.saturation_vapour_pressure(t) - e_a)
        return absorbed - eps * 5.670374419e-8 * t**4 + h * (air - t) - le

    assert t_leaf == pytest.approx(brentq(balance, 200.0, 400.0), abs=0.02)  # a thin leaf: no storage
    if sw > 0:  # a transpiring sunlit leaf stays within a few K of the air in a breeze, more
        # in calm air (Jones 2014, ch. 9: sunlit leaves 2-10 K above the air at low wind)
        assert abs(t_leaf - air) < (4.0 if wind >= 1.0 else 8.0)
    else:  # a clear night: radiative cooling below the air, by 1-4 K
        assert -4.0 < t_leaf - air < -0.5
    assert diag["slabMaxResidual_W_m2"] < 1e-5


def test_leaf_is_cooler_than_a_dry_slab_in_sun():
    f = _forcing(12, 800.0, 100.0, 300.15, 0.4, 2.0)
    leaf = _leaf_face()
    wood = dataclasses.replace(leaf, material=read_material(_LIBRARY.GetPrimAtPath(material_path("wood"))))
    t_leaf = SF.surface_temperatures(None, [leaf], f.times_s, 0.0, forcing=f, exchange=False)[0][CROWN][-1, 0]
    t_wood = SF.surface_temperatures(None, [wood], f.times_s, 0.0, forcing=f, exchange=False)[0][CROWN][-1, 0]
    assert t_wood > t_leaf + 10.0


def test_leaf_conductance_closed_form():
    # Campbell & Norman eq. 7.30: g = 1.4 x 0.135 sqrt(u/d) mol/m2/s, h = c_p g per side
    h = veg.leaf_heat_transfer_coefficient(2.0, 0.05, 1)
    assert_allclose(h, 29.3 * 1.4 * 0.135 * np.sqrt(2.0 / 0.05), rtol=1e-12)
    assert veg.leaf_heat_transfer_coefficient(2.0, 0.05, 2) == pytest.approx(2 * h)


@pytest.mark.parametrize("kind", [k for k in PLANT_KINDS if k != "crop"])  # crops: test_crops.py
def test_plants_are_closed_outward_meshes(kind):
    size = (10.0, 1.2, 1.8) if kind == "hedge" else (4.0, 3.0, 8.0)
    parts = plant_parts(kind, size, seed=3)
    for points, tris in parts.values():
        v = points[tris]
        # closed and outward: the signed volume is positive and every edge is shared twice
        vol = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0
        assert vol > 0.0
        edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        assert np.all(counts == 2)
    crown = parts["Crown"][0]
    lo, hi = crown.min(axis=0), crown.max(axis=0)
    assert hi[2] == pytest.approx(size[2], rel=0.15) and lo[2] < 0.6 * size[2]
    assert (hi - lo)[0] == pytest.approx(size[0], rel=0.15) and (hi - lo)[1] == pytest.approx(
        size[1], rel=0.15
    )
    assert ("Trunk" in parts) == (kind == "tree")
    other = plant_parts(kind, size, seed=4)["Crown"][0]
    assert not np.allclose(other, crown)  # another seed, another plant
