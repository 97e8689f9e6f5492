"""Garment colours (humv_usd.catalog.dyes, human.clothing_colors): the visible follows the colour,
the infrared stays the fabric's; the scenario key, the materials tool and the pattern rule."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdShade

from humv_usd.avatar.api import avatar_scenario_dict
from humv_usd.catalog.dyes import COLOURS, garment_material, material
from humv_usd.catalog.materials import LIBRARY
from humv_usd.errors import InputError
from humv_usd.materials import layer as materials_layer
from humv_usd.scenario.load import validate
from humv_usd.scenario.spec import GARMENT_COLOURS


@pytest.mark.parametrize("fabric", ["cotton_white", "denim", "wool_knit_thick", "polymer_black"])
@pytest.mark.parametrize("colour", ["red", "navy", "khaki", "white"])
def test_dyed_fabric_is_the_colour_in_the_visible_and_the_fabric_beyond(fabric, colour):
    m, base = material(f"{fabric}__{colour}"), LIBRARY[fabric]
    assert m.display_color == pytest.approx(COLOURS[colour], abs=1e-3)  # 0.65 / 0.55 / 0.45 µm
    nir = np.array([0.8, 1.0, 1.6, 2.2, 3.0, 5.0, 10.0])
    assert m.at(nir) == pytest.approx(base.at(nir), abs=1e-3)
    assert m.at(nir, "emissivity") == pytest.approx(base.at(nir, "emissivity"), abs=1e-3)
    assert (m.conductivity, m.density, m.specific_heat, m.thickness) == (
        base.conductivity,
        base.density,
        base.specific_heat,
        base.thickness,
    )
    assert m.solar_absorptivity == pytest.approx(m.spectral_solar_absorptivity, abs=1e-4)


def test_darker_colours_absorb_more_sunlight():
    alpha = {c: material(f"cotton_white__{c}").solar_absorptivity for c in ("white", "yellow", "red", "navy")}
    assert alpha["white"] < alpha["yellow"] < alpha["red"] < alpha["navy"]


def test_patterns_first_match_wins_and_unknown_names():
    colours = [["tshirt*", "red"], ["*", "black"]]
    assert garment_material("tshirt_white", colours) == "cotton_white__red"
    assert garment_material("tshirt", colours) == "cotton_white__red"  # the alias
    assert garment_material("jeans", colours) == "denim__black"
    assert garment_material("jeans", None) == "denim"
    assert GARMENT_COLOURS == tuple(COLOURS)
    for name in ("denim__mauve", "nothing__red", "denim"[:-1]):
        with pytest.raises(KeyError):
            material(name)


def test_scenario_key_and_materials_layer():
    raw = avatar_scenario_dict()
    raw["human"][0]["clothing"] = ["tshirt_white", "jeans", "shoes"]
    raw["human"][0]["clothing_colors"] = {"tshirt*": "red", "shoes": "brown"}
    scenario = validate(raw)
    names = materials_layer.used_materials(scenario)
    assert {"cotton_white__red", "denim", "leather_black__brown"} <= set(names)
    stage = Usd.Stage.Open(materials_layer.build(scenario))
    red = UsdShade.Material(stage.GetPrimAtPath("/World/Materials/cotton_white__red"))
    assert red
    raw["human"][0]["clothing_colors"] = {"tshirt*": "mauve"}
    with pytest.raises(InputError) as exc:
        validate(raw)
    assert any("clothing_colors" in p and "mauve" in p for p in exc.value.problems)
