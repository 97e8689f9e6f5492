"""Garment colours (humv_usd.catalog.dyes, human.clothing_colors): the visible follows the colour,
the infrared stays the fabric's; the scenario key, the materials tool and the pattern rule."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdShade

from humv_usd.avatar.api import avatar_scenario_dict
from humv_usd.catalog.dyes import COLOURS, PRINTS, garment_material, garment_materials, material, print_faces
from humv_usd.catalog.materials import LIBRARY
from humv_usd.errors import InputError
from humv_usd.materials import layer as materials_layer
from humv_usd.scenario.load import validate
from humv_usd.scenario.spec import GARMENT_COLOURS, GARMENT_PRINTS


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


# ---------------------------------------------------------------------------- prints
def _cylinder(radius=0.15, height=0.6, n_around=96, n_up=120):
    """A vertical open cylinder of quads (about 1 x 0.5 cm faces), z from 0 to ``height``."""
    a = 2 * np.pi * np.arange(n_around) / n_around
    z = np.linspace(0.0, height, n_up + 1)
    pts = np.array([(radius * np.cos(t), radius * np.sin(t), h) for h in z for t in a])
    quads = [
        (
            i * n_around + j,
            i * n_around + (j + 1) % n_around,
            (i + 1) * n_around + (j + 1) % n_around,
            (i + 1) * n_around + j,
        )
        for i in range(n_up)
        for j in range(n_around)
    ]
    return pts, np.full(len(quads), 4), np.array(quads).ravel()


def test_print_kinds_match_the_scenario_key():
    assert GARMENT_PRINTS == tuple(PRINTS)


def test_stripes_are_bands_of_half_the_period():
    pts, counts, idx = _cylinder()
    b = print_faces("stripes", pts, counts, idx)
    z = pts[idx.reshape(-1, 4)].mean(axis=1)[:, 2]
    half = PRINTS["stripes"] / 2
    assert not b[(z % (2 * half)) < half - 1e-9].any() and b[(z % (2 * half)) > half + 1e-9].all()


@pytest.mark.parametrize("kind", ["stripes", "checks", "blobs"])
def test_prints_cover_about_half_the_area_with_each_dye(kind):
    pts, counts, idx = _cylinder()
    b = print_faces(kind, pts, counts, idx, seed=3)
    share = b.mean()  # equal-area faces
    assert 0.3 < share < 0.7
    assert (print_faces(kind, pts, counts, idx, seed=3) == b).all()  # deterministic
    if kind == "blobs":
        assert (print_faces(kind, pts, counts, idx, seed=4) != b).any()  # the seed moves the blobs


def test_print_mix_is_the_mean_of_its_dyes_and_keeps_the_fabric_infrared():
    names = garment_materials(
        "tshirt_white", {"tshirt*": "navy"}, None, {"tshirt*": "stripes"}, {"t*": "yellow"}
    )
    a, b, mix = (material(n) for n in names)
    assert (a.name, b.name) == ("cotton_white__navy", "cotton_white__yellow")
    w = np.array([0.45, 0.55, 0.65, 1.0, 2.2])
    assert mix.at(w) == pytest.approx(0.5 * (a.at(w) + b.at(w)), abs=2e-4)
    ir = np.array([3.0, 5.0, 10.0])
    base = LIBRARY["cotton_white"]
    for m in (a, b, mix):
        assert m.at(ir, "emissivity") == pytest.approx(base.at(ir, "emissivity"), abs=1e-3)
    assert a.solar_absorptivity > mix.solar_absorptivity > b.solar_absorptivity
    # undyed garment: the first dye is the fabric itself; no print: one material
    assert garment_materials("jeans", None, None, {"jeans": "checks"})[:2] == ("denim", "denim__black")
    assert garment_materials("jeans") == ("denim",)


def test_clothing_layer_binds_a_print_per_face():
    """The clothing tool authors a printed garment as two GeomSubsets (every face in exactly one)
    bound to the two dyes, the mesh bound to their mix (what the thermal tool reads)."""
    from humv_usd.clothing.layer import build_for_human, garment_path
    from humv_usd.human.body import build_body

    human = {
        "id": "p0",
        "clothing_colors": [["tshirt*", "navy"]],
        "clothing_prints": [["tshirt*", "blobs"]],
        "clothing_print_colors": [["*", "khaki"]],
    }
    layer = build_for_human(
        human, build_body("female", 9.0, 1.33, 28.0), None, None, ["tshirt_white"], 30.0, 1
    )
    stage = Usd.Stage.Open(layer)
    prim = stage.GetPrimAtPath(garment_path("p0", "tshirt_white"))
    faces = len(prim.GetAttribute("faceVertexCounts").Get())
    binding = UsdShade.MaterialBindingAPI(prim)
    assert [str(t.name) for t in binding.GetDirectBindingRel().GetTargets()] == [
        "cotton_white__print_navy_khaki"
    ]
    subsets = {s.GetPath().name: s for s in binding.GetMaterialBindSubsets()}
    assert set(subsets) == {"PrintA", "PrintB"}
    a, b = (np.asarray(subsets[k].GetIndicesAttr().Get()) for k in ("PrintA", "PrintB"))
    assert np.array_equal(np.sort(np.concatenate([a, b])), np.arange(faces))
    dyes = [
        str(UsdShade.MaterialBindingAPI(subsets[k].GetPrim()).GetDirectBindingRel().GetTargets()[0].name)
        for k in ("PrintA", "PrintB")
    ]
    assert dyes == ["cotton_white__navy", "cotton_white__khaki"]
    assert 0.2 < prim.GetCustomDataByKey("humv:print")["shareB"] < 0.8
