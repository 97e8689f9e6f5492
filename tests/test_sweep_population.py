"""A sweep draws whole people from the population (``{ population = {...} }`` on ``human.N``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import ROOT

from humv_usd.errors import InputError
from humv_usd.human.population import bmi_range
from humv_usd.scenario.load import validate
from humv_usd.sweep.spec import expand, load_sweep

BASE = """
[general]
name = "people"
start = 2018-10-24T14:05:00
utc_offset_h = -4.0
latitude_deg = 39.8
longitude_deg = -84.03
fps = 4.0
duration_s = 0.25

[[human]]
id = "p1"
clothing = ["hair_short", "tshirt_white", "jeans", "shoes"]

[[placement]]
human = "p1"
position_m = [0.0, 0.0, 0.0]

[[sensor]]
id = "cam"
band = "LWIR"
resolution = [32, 24]
focal_length_mm = 10.0
position_m = [0.0, -8.0, 1.6]
look_at_m = [0.0, 0.0, 1.0]
"""


def _sweep(tmp_path: Path, draw: str, count: int = 12) -> Path:
    (tmp_path / "base.toml").write_text(BASE)
    path = tmp_path / "sweep.toml"
    path.write_text(
        f'[sweep]\nname = "p"\nbase = "base.toml"\ncount = {count}\nseed = 5\n\n[random]\n{draw}\n'
    )
    return path


def test_population_draws_valid_people(tmp_path):
    path = _sweep(tmp_path, '"human.0" = { population = { age_yr = [2.0, 90.0], skin_tones = ["IV", "V"] } }')
    variants = expand(load_sweep(path))
    humans = [validate(v.raw)["human"][0] for v in variants]  # each a valid scenario
    assert len({h["stature_m"] for h in humans}) == len(humans)
    for h in humans:
        assert 2.0 <= h["age_yr"] <= 90.0 and h["skin_tone"] in ("IV", "V")
        lo, hi = bmi_range(h["age_yr"])
        assert lo - 0.01 <= h["mass_kg"] / h["stature_m"] ** 2 <= hi + 0.01
        # the sampled hair replaces the base's, the rest of the outfit is kept
        assert h["clothing"][0].startswith("hair_") and "hair_short" not in h["clothing"][1:]
        assert h["clothing"][-3:] == ["tshirt_white", "jeans", "shoes"]
    assert variants[3].params["human.0.sex"] == humans[3]["sex"]
    again = expand(load_sweep(path))
    assert [v.raw["human"][0] for v in again] == [v.raw["human"][0] for v in variants]


@pytest.mark.parametrize(
    "draw, expected",
    [
        ('"human.1" = { population = {} }', "has 1 [[human]]"),
        ('"human.0.sex" = { population = {} }', "draws a whole person"),
        ('"human.0" = { population = { age_yr = [1.0, 30.0] } }', "age_yr"),
        ('"human.0" = { population = { height = 2 } }', "expected a table of"),
    ],
)
def test_bad_population_draw_is_one_line_naming_it(tmp_path, draw, expected):
    with pytest.raises(InputError) as exc:
        load_sweep(_sweep(tmp_path, draw))
    assert any(expected in p for p in exc.value.problems), exc.value.problems


def test_drawn_person_keeps_their_hair_under_a_drawn_or_grid_outfit(tmp_path):
    outfits = '[["hoodie", "skirt", "shoes"], ["hair_long", "winter_coat", "boots"]]'
    path = _sweep(
        tmp_path, f'"human.0" = {{ population = {{}} }}\n"human.0.clothing" = {{ choice = {outfits} }}', 8
    )
    path.write_text(
        path.read_text() + '\n[grid.coat]\nnone = {}\ncoat = { "human.0.clothing" = ["jacket", "jeans"] }\n'
    )
    variants = expand(load_sweep(path))
    assert len(variants) == 16
    for v in variants:
        sampled = [g for g in v.raw["human"][0]["clothing"] if g.startswith("hair_") or g == "beard"]
        assert 1 <= len(sampled) <= 2 and "hair_long" not in v.raw["human"][0]["clothing"][len(sampled) :]
        rest = v.raw["human"][0]["clothing"][len(sampled) :]
        assert rest in (["hoodie", "skirt", "shoes"], ["winter_coat", "boots"], ["jacket", "jeans"])
        assert json.loads(v.params["human.0.clothing"]) == v.raw["human"][0]["clothing"]


def test_people_sweep_example_draws_valid_people_in_every_motion():
    variants = expand(load_sweep(ROOT / "examples" / "people_sweep.toml"))
    humans = [validate(v.raw)["human"][0] for v in variants]
    assert {h["activity"] for h in humans} == {
        "walk",
        "carry",
        "wave",
        "sit",
        "crouch",
        "kneel",
        "lieSide",
        "fall",
    }
    assert all(h["clothing"][0] in ("hair_short", "hair_long", "hair_tied") for h in humans)
    assert min(h["age_yr"] for h in humans) < 20.0 < max(h["age_yr"] for h in humans)
