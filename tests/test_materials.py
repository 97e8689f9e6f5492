"""Material library: sources, spectra, Kirchhoff, literature band emissivities; materials layer."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from pxr import Usd

from humv_usd.catalog.materials import FABRICS, LIBRARY, WAVELENGTHS_UM
from humv_usd.errors import InputError
from humv_usd.materials import layer as materials_layer
from humv_usd.physics.planck import band_emissivity
from humv_usd.scenario import validate
from humv_usd.scenario.spec import MATERIALS
from humv_usd.usd import schemas as S
from humv_usd.usd.materials import read_material, substrate

REQUIRED = {
    "skin",
    "cotton_white",
    "cotton_black",
    "nylon",
    "polyester",
    "wool",
    "camouflage_nyco",
    "concrete",
    "asphalt",
    "grass",
    "soil",
    "painted_metal",
    "wood",
    "glass",
    "blackbody",
}


def lwir(m) -> float:
    """Planck-weighted 8-14 µm emissivity at 300 K."""
    return band_emissivity(m.spectrum_wavelengths, m.spectrum_emissivity, (8.0, 14.0))


def test_library_has_every_required_material_and_scenario_choices_exist():
    assert REQUIRED <= set(LIBRARY)
    assert len(FABRICS) >= 6
    assert set(MATERIALS) <= set(LIBRARY)


@pytest.mark.parametrize("name", sorted(LIBRARY))
def test_spectra_are_physical_and_sourced(name):
    m = LIBRARY[name]
    assert len(m.source) > 150 and any(ch.isdigit() for ch in m.source), name  # cites a year/table
    wl = np.asarray(m.spectrum_wavelengths)
    assert np.all(np.diff(wl) > 0) and wl[0] <= 0.4 and wl[-1] >= 14.0
    r = np.asarray(m.spectrum_reflectance)
    e = np.asarray(m.spectrum_emissivity)
    t = np.zeros_like(r) if m.opaque else np.asarray(m.spectrum_transmittance)
    for values in (r, e, t):
        assert values.size == wl.size and np.all((values >= 0) & (values <= 1))
    np.testing.assert_allclose(e + r + t, 1.0, atol=1e-6)  # Kirchhoff / energy balance
    if m.opaque:
        np.testing.assert_allclose(e, 1.0 - r, atol=1e-6)
    # the common-grid values the thermal tools use are the same spectrum
    np.testing.assert_allclose(m.emissivity, m.at(WAVELENGTHS_UM, "emissivity"), atol=1e-6)
    assert 0 < m.conductivity and 0 < m.density and 0 < m.specific_heat and 0 < m.thickness
    assert 0 <= m.solar_absorptivity <= 1


@pytest.mark.parametrize(
    "name, lo, hi",
    [
        ("skin", 0.97, 0.99),  # Steketee 1973: 0.98 +- 0.01
        ("grass", 0.97, 0.99),  # Salisbury & D'Aria 1992: green foliage
        ("soil", 0.93, 0.97),
        ("concrete", 0.93, 0.97),
        ("asphalt", 0.93, 0.97),
        ("wood", 0.90, 0.96),
        ("painted_metal", 0.88, 0.94),
        ("glass", 0.84, 0.92),
        ("blackbody", 0.965, 0.975),
    ],
)
def test_lwir_band_emissivity_matches_literature(name, lo, hi):
    assert lo <= lwir(LIBRARY[name]) <= hi


def test_spectral_features_are_on_the_fine_grid():
    at = lambda name, w: float(LIBRARY[name].at(w))  # noqa: E731
    # water bands of skin and leaves
    for name in ("skin", "grass"):
        assert at(name, 1.45) < 0.5 * at(name, 1.2) and at(name, 1.94) < 0.5 * at(name, 1.65)
    # chlorophyll: green peak, red absorption, red edge
    assert at("grass", 0.55) > at("grass", 0.65) and at("grass", 0.8) > 3 * at("grass", 0.65)
    # silicate reststrahlen: reflectance peak at 8.5-9.3 µm over the 11 µm level
    for name in ("soil", "concrete", "glass"):
        assert max(at(name, 8.5), at(name, 9.0), at(name, 9.3)) > 2 * at(name, 11.0), name
    # skin reflects far more in the NIR than beyond 3 µm
    assert at("skin", 0.8) > 0.5 > 0.03 >= at("skin", 10.0)


def test_glass_is_transparent_in_the_visible_and_opaque_in_the_lwir():
    g = LIBRARY["glass"]
    assert not g.opaque
    assert np.all(g.at([0.45, 0.55, 0.65], "transmittance") > 0.85)
    assert np.all(g.at(np.linspace(5.0, 14.0, 10), "transmittance") == 0.0)
    assert float(g.at(9.3, "emissivity")) < 0.75 < float(g.at(12.0, "emissivity"))


def scenario_with(raw, ground: str, objects: list[str], humans: bool, ground_k=None):
    raw = copy.deepcopy(raw)
    raw["scene"]["ground"]["material"] = ground
    if ground_k is not None:  # held ground: no slab, so no substrate under it
        raw["scene"]["ground"]["temperature_k"] = ground_k
    base = raw["scene"]["object"][0]
    raw["scene"]["object"] = [dict(base, id=f"o{i}", material=m) for i, m in enumerate(objects)]
    if not humans:
        raw.pop("human")
        raw.pop("placement")
    return validate(raw)


def test_materials_layer_authors_only_what_the_scenario_uses(raw):
    scenario = scenario_with(raw, "grass", ["glass", "glass", "wood"], humans=False, ground_k=290.0)
    assert materials_layer.used_materials(scenario) == ["glass", "grass", "wood"]
    stage = Usd.Stage.Open(materials_layer.build(scenario))
    prims = stage.GetPrimAtPath("/World/Materials").GetChildren()
    assert sorted(p.GetName() for p in prims) == ["glass", "grass", "wood"]
    glass = stage.GetPrimAtPath("/World/Materials/glass")
    wl = np.asarray(glass.GetAttribute(S.MATERIAL_WAVELENGTHS).Get())
    assert wl.size == len(LIBRARY["glass"].spectrum_wavelengths) > len(WAVELENGTHS_UM)
    t = np.asarray(glass.GetAttribute(S.MATERIAL_TRANSMITTANCE).Get())
    e = np.asarray(glass.GetAttribute(S.MATERIAL_EMISSIVITY).Get())
    r = np.asarray(glass.GetAttribute(S.MATERIAL_REFLECTANCE).Get())
    np.testing.assert_allclose(e + r + t, 1.0, atol=1e-6)
    grass = stage.GetPrimAtPath("/World/Materials/grass")
    assert not grass.GetAttribute(S.MATERIAL_TRANSMITTANCE).HasAuthoredValue()
    assert "Salisbury" in grass.GetAttribute(S.MATERIAL_SOURCE).Get()
    # people bring skin and their garments' fabrics
    people = scenario_with(raw, "soil", [], humans=True)
    used = materials_layer.used_materials(people)
    assert {"skin", "soil", "cotton_white"} <= set(used) and "glass" not in used


def test_slab_ground_gets_its_substrate_from_the_materials_layer(raw):
    """A ground without temperature_k is a slab over soil: the materials layer authors the soil
    and points the ground material at it; the thermal tool reads it from there."""
    slab = scenario_with(raw, "grass", ["wood"], humans=False)
    assert materials_layer.used_materials(slab) == ["grass", "soil", "wood"]
    stage = Usd.Stage.Open(materials_layer.build(slab))
    grass = read_material(stage.GetPrimAtPath("/World/Materials/grass"))
    soil = substrate(grass, stage, "/World/Scene/Ground")
    assert soil.path == "/World/Materials/soil"
    assert soil.conductivity == pytest.approx(LIBRARY["soil"].conductivity, rel=1e-6)
    assert soil.thickness == pytest.approx(LIBRARY["soil"].thickness, rel=1e-6)
    held = Usd.Stage.Open(materials_layer.build(scenario_with(raw, "grass", ["wood"], False, ground_k=290.0)))
    assert not held.GetPrimAtPath("/World/Materials/soil")
    with pytest.raises(
        InputError, match=r"/World/Materials/grass\.humv:material:substrate.*/World/Scene/Ground"
    ):
        substrate(read_material(held.GetPrimAtPath("/World/Materials/grass")), held, "/World/Scene/Ground")


def test_library_file_is_up_to_date():
    """layers/materials.usda = every library material (regenerate: python -m humv_usd.materials.layer)."""
    assert materials_layer.main(["--check"]) == 0
    stage = Usd.Stage.Open(str(materials_layer.LIBRARY_FILE))
    assert {p.GetName() for p in stage.GetPrimAtPath("/World/Materials").GetChildren()} == set(LIBRARY)
