"""The people examples (issue 29; docs/user/people.md) are valid scenarios and sweeps: every
scenario under examples/people/ validates, the props example holds the chair, the box and both
held phones, and the crowd sweep draws valid crowds (people of every age, their hair kept, all
steering round each other). Validation only: no compose (cheap)."""

from __future__ import annotations

import tomllib

import pytest
from conftest import ROOT

from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.load import validate
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
