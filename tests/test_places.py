"""Generated places and warm clutter (issue 30): seeds, layout, procedural meshes, labels, held
temperatures on the stage as the thermal tool reads them, and input errors. No render, no slab
solve: scene and materials layers only."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import general_toml, place_keys, scene_stage
from pxr import Usd, UsdGeom

from humv_usd.errors import InputError
from humv_usd.groundtruth.labels import CLASSES
from humv_usd.physics import warm_objects as W
from humv_usd.pipeline.compose import compose_in_memory
from humv_usd.scenario import validate
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.places import CAR_LENGTH_M, KIND_MATERIALS, place_items, scene_clutter
from humv_usd.scenario.spec import CLUTTER, CLUTTER_CLASSES, PLACE_KINDS
from humv_usd.scene import layer as scene_layer
from humv_usd.scene.ground import scene_terrain
from humv_usd.scene.objects import part_temperatures, parts_of, path_poses
from humv_usd.sweep.spec import load_sweep
from humv_usd.thermal.surfaces import scene_meshes
from humv_usd.usd import schemas as S
from humv_usd.usd.lights import read_lamps
from humv_usd.usd.mesh import signed_volume

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PLACES = sorted((EXAMPLES / "places").glob("*.toml"))


def _entry(kind: str, **kw) -> dict:
    e = {k: copy.deepcopy(v.default) for k, v in CLUTTER.keys.items()}
    e.update(id="x", kind=kind, **kw)
    return e


@pytest.mark.parametrize("kind", PLACE_KINDS[1:])
def test_a_seed_gives_the_same_place_and_another_seed_another(kind):
    a, b, c = (place_items(place_keys(kind, seed=s, vehicles=8, animals=3)) for s in (1, 1, 2))
    assert a == b
    assert a.clutter != c.clutter
    ids = [o["id"] for o in a.objects] + [x["id"] for x in a.clutter]
    assert len(ids) == len(set(ids)) and all(i.startswith("place_") for i in ids)
    half = place_keys(kind)["length_m"] / 2
    for x in a.clutter:  # inside the place along the road
        assert -half - 1e-6 <= x["position_m"][0] <= half + 1e-6


def test_street_parks_cars_apart_and_counts_add_up():
    p = place_keys("street", seed=4, vehicles=9, driving=1 / 3, lamps=5, animals=2, warm_objects=2)
    items = place_items(p)
    kinds = [c["kind"] for c in items.clutter]
    assert kinds.count("vehicle") == 9 and kinds.count("street_lamp") == 5 and kinds.count("dog") == 2
    assert sum(1 for c in items.clutter if c["kind"] == "vehicle" and c["speed_m_s"] > 0) == 3
    for y in {c["position_m"][1] for c in items.clutter if c["kind"] == "vehicle" and c["speed_m_s"] == 0}:
        xs = sorted(
            c["position_m"][0] for c in items.clutter if c["kind"] == "vehicle" and c["position_m"][1] == y
        )
        assert all(b - a >= CAR_LENGTH_M for a, b in zip(xs, xs[1:]))


@pytest.mark.parametrize("kind", sorted(CLUTTER_CLASSES))
def test_parts_are_closed_outward_meshes_of_the_declared_materials(kind):
    e = _entry(kind)
    for name, (pts, counts, idx), material, _ in parts_of(e):
        assert signed_volume(pts, counts, idx) > 0, name  # closed, faces counter-clockwise outward
        assert material in set(KIND_MATERIALS[kind]) | {e["material"]}, name


def test_box_part_volume_is_its_extent():
    hood = next(p for p in parts_of(_entry("vehicle")) if p[0] == "Hood")[1]
    assert signed_volume(*hood) == pytest.approx(1.3 * 1.7 * 0.03, rel=1e-6)


def test_a_driving_car_follows_its_path_and_stops_at_the_end():
    e = _entry("vehicle", position_m=[0.0, 0.0, 0.0], path_m=[[10.0, 0.0], [10.0, 10.0]], speed_m_s=5.0)
    pos, head = path_poses(e, [0.0, 1.0, 3.0, 10.0])
    assert np.allclose(pos[:, :2], [[0, 0], [5, 0], [10, 5], [10, 10]])
    assert np.allclose(head, [0, 0, 90, 90])


def test_lamps_light_by_the_sun_and_parts_take_their_models():
    lamp = _entry("street_lamp")
    assert part_temperatures(lamp, 285.0, 1.0, 20.0, 0.0) == {}  # day: off, a slab
    night = part_temperatures(lamp, 285.0, 1.0, -10.0, 0.0)["lamp"]
    assert 285.0 < night <= 285.0 + W.LAMP_HOUSING_EXCESS_K
    car = part_temperatures(_entry("vehicle", run_s=1800.0), 290.0, 1.0, -10.0, 0.0)
    ref = W.vehicle_part_temperatures(290.0, W.VehicleState(1800.0), 1.0, 0.0)
    assert car == {k: ref[k] for k in ("hood", "grille", "glass", "exhaust", "tyre")}


SCENARIO = (
    general_toml("t", "2018-10-24T21:00:00", 0.4)
    + """
[scene.ground]
material = "asphalt"
size_m = [40.0, 40.0]

[scene.place]
kind = "street"
seed = 2
length_m = 20.0
vehicles = 2
driving = 0.5
lamps = 1
buildings = 1
animals = 1
warm_objects = 1

[[scene.clutter]]
id = "rex"
kind = "dog"
position_m = [1.0, 2.0, 0.0]

[[scene.clutter]]
id = "grill"
kind = "barbecue"
position_m = [3.0, 2.0, 0.0]

[atmosphere]
air_temperature_k = 284.0
wind_speed_m_s = 2.0
"""
)


@pytest.fixture(scope="module")
def composed():
    scenario = validate(tomllib.loads(SCENARIO))
    return scenario, scene_stage(scenario)


def test_every_clutter_object_is_labelled_with_its_class_and_id(composed):
    scenario, stage = composed
    ids = instance_ids(scenario)
    clutter = scene_clutter(scenario["scene"])
    assert {c["id"] for c in clutter} >= {"rex", "grill"} and len(clutter) > 2
    for c in clutter:
        prim = stage.GetPrimAtPath(f"/World/Scene/{c['id']}")
        assert prim.GetAttribute(S.LABEL_CLASS).Get() == CLUTTER_CLASSES[c["kind"]]
        assert prim.GetAttribute(S.LABEL_CLASS).Get() in CLASSES
        assert prim.GetAttribute(S.LABEL_INSTANCE_ID).Get() == ids[f"clutter:{c['id']}"]
    assert len(set(ids.values())) == len(ids)


def test_held_parts_reach_the_thermal_tool_and_lit_lamps_are_lights(composed):
    scenario, stage = composed
    meshes = {m.path: m for m in scene_meshes(stage, scenario)}
    coat = W.coat_surface_temperature(308.15, 284.0, 0.012, 0.28, 2.0)
    assert meshes["/World/Scene/rex/Trunk"].held_k == pytest.approx(coat, abs=1e-3)
    assert meshes["/World/Scene/grill/Lid"].held_k > 400.0
    assert meshes["/World/Scene/grill/Leg0"].held_k is None  # a slab of its material
    lamps = read_lamps(stage, Usd.TimeCode(0))  # 21:00 in October: the sun is down, lamps lit
    lamp = next(c["id"] for c in scene_clutter(scenario["scene"]) if c["kind"] == "street_lamp")
    light = next(x for x in lamps if x.path == f"/World/Scene/{lamp}/Light")
    assert light.kind == "sphere" and light.direction[2] == pytest.approx(-1.0)  # shines down
    windows = [x for x in lamps if x.kind == "rect"]
    assert windows  # lit windows shine out of their facade, towards the road (y = 0)
    for w in windows:
        assert w.direction[1] == pytest.approx(-np.sign(w.position[1])) and abs(w.direction[2]) < 1e-9


def test_a_driving_car_moves_on_the_stage(composed):
    scenario, stage = composed
    c = next(c for c in scene_clutter(scenario["scene"]) if c["speed_m_s"] > 0)
    xf = UsdGeom.Xformable(stage.GetPrimAtPath(f"/World/Scene/{c['id']}"))
    p0 = np.asarray(xf.ComputeLocalToWorldTransform(Usd.TimeCode(0)))[3, :2]
    p2 = np.asarray(xf.ComputeLocalToWorldTransform(Usd.TimeCode(2)))[3, :2]
    end = np.asarray(c["path_m"][-1])  # straight along the road; it stops at the path's end
    expected = min(c["speed_m_s"] * 2 / 5.0, float(np.linalg.norm(end - np.asarray(c["position_m"][:2]))))
    assert expected > 0.5 and np.linalg.norm(p2 - p0) == pytest.approx(expected, rel=1e-5)


@pytest.mark.parametrize(
    "edit,needle",
    [
        (lambda r: r["scene"]["clutter"].append({"id": "rex", "kind": "dog"}), "scene.clutter[2].id"),
        (lambda r: r["scene"]["clutter"].append({"id": "place_x", "kind": "dog"}), "starts with place_"),
        (lambda r: r["scene"]["clutter"][0].update(kind="horse"), "scene.clutter[0].kind"),
        (lambda r: r["scene"]["place"].update(kind="moon"), "scene.place.kind"),
        (lambda r: r["scene"]["place"].update(vehicles=-1), "scene.place.vehicles"),
    ],
)
def test_bad_keys_are_one_line_errors(edit, needle):
    raw = tomllib.loads(SCENARIO)
    edit(raw)
    with pytest.raises(InputError) as e:
        validate(raw)
    assert needle in str(e.value)


@pytest.mark.parametrize("path", PLACES, ids=[p.stem for p in PLACES])
def test_place_examples_validate(path):
    scenario = validate(tomllib.loads(path.read_text()), path)
    assert scenario["scene"]["place"]["kind"] == path.stem


def test_random_places_sweep_spans_kinds_times_and_seeds():
    sweep = load_sweep(EXAMPLES / "random_places.toml")
    kinds = [v.scenario["scene"]["place"]["kind"] for v in sweep.variants]
    assert sorted(set(kinds)) == sorted(PLACE_KINDS[1:]) and len(kinds) == 24
    hours = [v.scenario["general"]["start"].hour for v in sweep.variants]
    assert min(hours) < 6 and max(hours) >= 19  # night and day
    assert len({v.scenario["scene"]["place"]["seed"] for v in sweep.variants}) == 24


def test_bench_scales_the_place_and_refuses_bad_factors():
    from click.testing import CliRunner

    from humv_usd.bench.places import scaled_place
    from humv_usd.cli.main import main

    raw = tomllib.loads((EXAMPLES / "places" / "street.toml").read_text())
    big = scaled_place(raw, 2.0)
    assert big["scene"]["place"]["vehicles"] == 2 * raw["scene"]["place"]["vehicles"]
    assert big["scene"]["place"]["length_m"] == 2 * raw["scene"]["place"]["length_m"] and "human" not in big
    validate(big, EXAMPLES / "places" / "street.toml")
    result = CliRunner().invoke(main, ["bench", "places", "--factors", "0,x"])
    assert result.exit_code == 2 and "--factors" in result.output


def test_clutter_stands_on_the_terrain():
    raw = tomllib.loads(SCENARIO)
    raw["scene"]["terrain"] = {"slope_deg": [0.0, 5.0]}
    raw["scene"]["place"]["kind"] = "none"
    scenario = validate(raw)
    stage = compose_in_memory([scene_layer.build(scenario)], 5.0)
    terrain = scene_terrain(scenario["scene"])
    xf = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Scene/rex"))
    z = np.asarray(xf.ComputeLocalToWorldTransform(Usd.TimeCode(0)))[3, 2]
    assert abs(float(terrain.height(1.0, 2.0))) > 0.05 and z == pytest.approx(
        float(terrain.height(1.0, 2.0)), abs=1e-5
    )


@pytest.mark.extended
@pytest.mark.parametrize("path", PLACES, ids=[p.stem for p in PLACES])
def test_place_examples_compose_to_clean_stages(path, tmp_path):
    """End to end (1.5-12 min each on 2 busy cores: the thermal tool refines and solves every
    generated surface): compose, then ``humv-usd check`` finds nothing."""
    from humv_usd.pipeline.compose import compose
    from humv_usd.usd.check import check_stage

    compose(validate(tomllib.loads(path.read_text()), path), tmp_path / "o")
    assert check_stage(tmp_path / "o" / "stage.usda") == []
