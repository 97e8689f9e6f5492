"""The people examples (issue 29; docs/user/people.md) are valid scenarios and sweeps: every
scenario under examples/people/ validates, the props example holds the chair, the box and both
held phones, and the crowd sweep draws valid crowds (people of every age, their hair kept, all
steering round each other). Validation only: no compose (cheap)."""

from __future__ import annotations

import tomllib

import pytest
from conftest import ROOT

from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.load import default_hair, validate
from humv_usd.sweep.spec import expand, load_sweep

PEOPLE = ROOT / "examples" / "people"
SCENARIOS = sorted(p for p in PEOPLE.glob("*.toml") if "sweep" not in tomllib.loads(p.read_text()))


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.name)
def test_every_people_scenario_is_valid(path):
    validate(tomllib.loads(path.read_text()), path)


def test_props_example_has_the_chair_the_box_and_the_phones():
    path = PEOPLE / "props.toml"
    scenario = validate(tomllib.loads(path.read_text()), path)
    ids = instance_ids(scenario)
    assert {"prop:sitter:chair", "prop:carrier:box", "prop:sitter:phone_call", "prop:boy:phone"} <= set(ids)
    assert all(h.get("clothing_prints") for h in scenario["human"])


def test_crowd_sweep_draws_valid_crowds():
    variants = expand(load_sweep(PEOPLE / "crowd_sweep.toml"))
    assert len(variants) == 4
    ages = []
    for v in variants:
        scenario = validate(v.raw)
        assert all(p["avoidance"] == "socialForce" for p in scenario["placement"])
        for h in scenario["human"]:
            assert h["activity"] in ("walk", "carry")
            assert h["clothing"][0] in ("hair_short", "hair_long", "hair_tied")
            ages.append(h["age_yr"])
    assert min(ages) < 18.0 and max(ages) > 60.0


HAIR = ("hair_short", "hair_long", "hair_tied")
EXAMPLES = sorted(p for p in ROOT.glob("examples/**/*.toml") if "sweep" not in tomllib.loads(p.read_text()))


def test_every_example_person_and_every_table1_person_wears_head_hair():
    """Issue 25.5 / 29.2: hair on for the examples and the seed's Table 1 (a bald head reads as hot
    as the face); Table 1's women wear the women's default style, its men the men's."""
    people = 0
    for path in EXAMPLES:
        for h in validate(tomllib.loads(path.read_text()), path)["human"]:
            assert any(g in HAIR for g in h["clothing"]), (path.name, h["id"], h["clothing"])
            people += 1
    assert people >= 20
    table1 = load_sweep(ROOT / "examples" / "table1.toml")
    for v in table1.variants:
        h = v.scenario["human"][0]
        assert [g for g in h["clothing"] if g in HAIR] == default_hair(h), (v.id, h["clothing"])


def test_a_person_without_a_clothing_key_wears_hair_by_sex_and_an_empty_list_is_bald(raw):
    man = dict(raw["human"][0], id="man")
    man.pop("clothing")
    woman = dict(man, id="woman", sex="female")
    bald = dict(man, id="bald", clothing=[])
    shirt = dict(man, id="shirt", clothing=["tshirt_white"])
    raw["human"] = [man, woman, bald, shirt]
    raw["placement"] = [
        dict(raw["placement"][0], human=h["id"], position_m=[i, 0.0, 0.0]) for i, h in enumerate(raw["human"])
    ]
    clothing = {h["id"]: h["clothing"] for h in validate(raw)["human"]}
    assert clothing == {"man": ["hair_short"], "woman": ["hair_tied"], "bald": [], "shirt": ["tshirt_white"]}
    assert default_hair({"sex": "female"}) == ["hair_tied"] and default_hair({"sex": "male"}) == [
        "hair_short"
    ]
