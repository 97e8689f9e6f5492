"""Scenario validation: defaults, one line per problem with key, value and range."""

from __future__ import annotations

import datetime as dt

import pytest
from conftest import HUMVVEX

from humv_usd.errors import InputError
from humv_usd.scenario import load_scenario, validate
from humv_usd.scenario.inputs import read_values
from humv_usd.scenario.spec import SECTIONS


def problems(raw) -> list[str]:
    with pytest.raises(InputError) as info:
        validate(raw)
    return info.value.problems


def test_humvvex_loads_with_defaults_filled():
    s = load_scenario(HUMVVEX)
    assert s["general"]["latitude_deg"] == pytest.approx(39.80)
    assert s["general"]["start"] == dt.datetime(2018, 10, 24, 14, 5)
    assert s["sensor"][0]["resolution"] == [1024, 768]
    assert s["sensor"][0]["pixel_pitch_um"] == 17.0
    assert s.frame_count == 1
    # the four HUMVVEX imagers: two LWIR, MWIR (infrared) and EO colour
    assert [x["id"] for x in s.infrared_sensors] == ["atom1024_lwir", "lwir640", "mwir_insb"]
    # sections mirror the editor's six tabs plus the atmosphere and the ground-truth outputs
    assert list(SECTIONS) == [
        "general",
        "human",
        "placement",
        "scene",
        "sensor",
        "thermal",
        "atmosphere",
        "annotations",
    ]


def test_out_of_range_names_key_value_and_range(raw):
    raw["general"]["latitude_deg"] = 95.0
    (line,) = problems(raw)
    assert line == "general.latitude_deg = 95.0: allowed range -90.0..90.0"


def test_unknown_key_suggests(raw):
    raw["sensor"][0]["pixel_pich_um"] = 12.0
    (line,) = problems(raw)
    assert "sensor[0].pixel_pich_um: unknown key (did you mean 'pixel_pitch_um'?)" in line


def test_unknown_section_suggests(raw):
    raw["sensors"] = {}
    (line,) = problems(raw)
    assert "[sensors]: unknown section (did you mean 'sensor'?)" in line


def test_every_problem_reported_once(raw):
    raw["general"]["fps"] = 0
    raw["sensor"][0]["resolution"] = [1024]
    raw["sensor"][0]["band"] = "lwir"
    raw["atmosphere"]["relative_humidity"] = 1.5
    found = problems(raw)
    assert len(found) == 4
    assert any(p.startswith("general.fps = 0") for p in found)
    assert any(p.startswith("sensor[0].resolution = [1024]: expected 2 integers") for p in found)
    assert any("sensor[0].band = 'lwir': allowed values: EO, NIR, SWIR, MWIR, LWIR" in p for p in found)
    assert any(p.startswith("atmosphere.relative_humidity = 1.5") for p in found)


@pytest.mark.parametrize("value", [True, "10", float("nan"), [1, 2]])
def test_wrong_types_rejected(raw, value):
    raw["general"]["elevation_m"] = value
    (line,) = problems(raw)
    assert line.startswith("general.elevation_m = ")


def test_missing_required(raw):
    del raw["general"]["latitude_deg"]
    (line,) = problems(raw)
    assert line.startswith("general.latitude_deg: missing required key")


def test_datetime_must_be_local(raw):
    raw["general"]["start"] = dt.datetime(2018, 10, 24, 14, 5, tzinfo=dt.UTC)
    (line,) = problems(raw)
    assert "expected a TOML local date-time" in line


def test_cross_references(raw):
    raw["placement"][0]["human"] = "p2"
    found = problems(raw)
    assert any("placement[0].human = 'p2'" in p for p in found)
    assert any("human id 'p1': no [[placement]]" in p for p in found)


def test_duplicate_and_bad_ids(raw):
    raw["sensor"].append(dict(raw["sensor"][0]))
    last = len(raw["sensor"]) - 1
    raw["scene"]["object"][0]["id"] = "1wall"
    found = problems(raw)
    assert any(f"sensor[{last}].id = 'atom1024_lwir': must be unique" in p for p in found)
    assert any("scene.object[0].id = '1wall'" in p for p in found)


def test_band_edges_ordered_and_defaulted(raw):
    raw["sensor"][0]["wavelength_um"] = [14.0, 8.0]
    assert any("short < long" in p for p in problems(raw))
    del raw["sensor"][0]["wavelength_um"]
    raw["sensor"][0]["band"] = "MWIR"
    assert validate(raw)["sensor"][0]["wavelength_um"] == [3.0, 5.0]


def test_garments_from_the_catalogue(raw):
    raw["human"][0]["clothing"] = ["tshirt_white", "shrts"]
    (line,) = problems(raw)
    assert line.startswith("human[0].clothing[1] = 'shrts': allowed garments: ")
    assert line.endswith("(did you mean 'shorts'?)")
    raw["human"][0]["clothing"] = ["tshirt", "tshirt_white"]
    (line,) = problems(raw)
    assert "human[0].clothing[1] = 'tshirt_white': listed twice" in line
    raw["human"][0]["clothing"] = ["tshirt_black", "leggings", "cap"]
    assert validate(raw)["human"][0]["clothing"] == ["tshirt_black", "leggings", "cap"]


def test_file_errors(tmp_path):
    with pytest.raises(InputError, match="scenario file not found"):
        load_scenario(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[general\nname = 1")
    with pytest.raises(InputError, match="not valid TOML"):
        load_scenario(bad)


def test_digest_tracks_content(raw):
    a = validate(raw)
    raw["thermal"]["skin_temperature_k"] = 305.0
    b = validate(raw)
    # what a layer reads: the general section is the same, the thermal section not
    assert read_values(a, ["general"]) == read_values(b, ["general"])
    assert read_values(a, ["thermal"]) != read_values(b, ["thermal"])
    assert a.digest() != b.digest()


def test_annotator_names_checked_at_load(raw):
    from humv_usd.groundtruth.annotators import ANNOTATORS
    from humv_usd.scenario.spec import ANNOTATIONS

    assert set(ANNOTATIONS.keys["annotators"].choices) == set(ANNOTATORS)
    raw["annotations"] = {"annotators": ["boxes", "keypionts"]}
    (line,) = problems(raw)
    assert line.startswith("annotations.annotators[1] = 'keypionts': allowed: ")
    assert line.endswith("(did you mean 'keypoints'?)")
    raw["annotations"] = {"annotators": ["boxes", "keypoints"]}
    assert validate(raw)["annotations"]["annotators"] == ["boxes", "keypoints"]


def test_humvvex_fixed_is_humvvex_with_the_closed_form_thermal_model():
    """examples/humvvex.toml (the demo: physiology) and humvvex_fixed.toml (the tests'
    closed-form variant) differ only in [thermal]."""
    import tomllib

    from conftest import HUMVVEX_DEMO

    demo, fixed = (tomllib.loads(p.read_text()) for p in (HUMVVEX_DEMO, HUMVVEX))
    assert demo.pop("thermal")["model"] == "jos3" and fixed.pop("thermal")["model"] == "fixed"
    assert demo == fixed
    assert "shoes" in demo["human"][0]["clothing"]
