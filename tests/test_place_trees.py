"""Trees in generated places (issue 30.5): rural_road and open_field build their trees with the
vegetation tool's plants, labelled, with their materials, standing clear of the warm objects.
Scene and materials layers in memory only (no slab solve, no render)."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest
from conftest import general_toml, place_keys, scene_stage

from humv_usd.scenario import validate
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.places import (
    CROWN_WIDTH_PER_HEIGHT,
    TREE_CLEARANCE_M,
    TRUNK_MATERIAL,
    place_items,
    scene_materials,
)
from humv_usd.scene.vegetation import TRUNK_MATERIAL as VEGETATION_TRUNK
from humv_usd.thermal.surfaces import scene_meshes
from humv_usd.usd import schemas as S


@pytest.mark.parametrize("kind", ["rural_road", "open_field"])
def test_places_build_their_trees_clear_of_the_warm_objects(kind):
    p = place_keys(kind, seed=5, vegetation_density=1.0, animals=4, vehicles=6, warm_objects=3)
    items = place_items(p)
    trees = [o for o in items.objects if o["kind"] == "tree"]
    assert len(trees) >= 5 and len(trees) <= len(items.trees)
    where = {(round(x, 9), round(y, 9)): h for x, y, h in items.trees}
    warm = np.array([c["position_m"][:2] for c in items.clutter])
    for o in trees:
        x, y, _ = o["center_m"]
        h = where[(round(x, 9), round(y, 9))]  # a tree of the place's list, at its height
        assert o["size_m"] == pytest.approx([CROWN_WIDTH_PER_HEIGHT * h, CROWN_WIDTH_PER_HEIGHT * h, h])
        assert 4.0 <= h <= 12.0 and (o["material"], o["class"]) == ("leaf", "vegetation")
        assert np.min(np.hypot(*(warm - [x, y]).T)) >= TREE_CLEARANCE_M
        if kind == "rural_road":  # in the fields, off the road and its verges
            assert abs(y) > p["road_width_m"] / 2 + 2.0
    assert {"leaf", TRUNK_MATERIAL} <= scene_materials({"place": p})
    assert TRUNK_MATERIAL == VEGETATION_TRUNK
    assert not any(
        o["kind"] == "tree" for o in place_items(place_keys(kind, seed=5, vegetation_density=0.0)).objects
    )


#: an open field at noon in July: one car, no animals, lamps or warm objects
SCENARIO = {
    **tomllib.loads(general_toml("trees")),
    "scene": {
        "ground": {"material": "soil", "size_m": [60.0, 60.0]},
        "place": {
            "kind": "open_field",
            "seed": 3,
            "length_m": 30.0,
            "vehicles": 1,
            "animals": 0,
            "warm_objects": 0,
            "lamps": 0,
            "vegetation_density": 0.6,
        },
    },
}


def test_generated_trees_are_plants_on_the_stage():
    """Each built tree is the vegetation tool's plant: an Xform labelled vegetation with its
    instance id, a leaf Crown and a wood Trunk whose materials the materials layer authors,
    and meshes the thermal tool solves (crown as leaves) and does not re-tessellate."""
    scenario = validate(copy.deepcopy(SCENARIO))
    trees = [o for o in place_items(scenario["scene"]["place"]).objects if o["kind"] == "tree"]
    assert trees
    stage = scene_stage(scenario)
    ids = instance_ids(scenario)
    meshes = {m.path: m for m in scene_meshes(stage, scenario)}
    for o in trees:
        root = stage.GetPrimAtPath(f"/World/Scene/{o['id']}")
        assert root.GetAttribute(S.LABEL_CLASS).Get() == "vegetation"
        assert root.GetAttribute(S.LABEL_INSTANCE_ID).Get() == ids[f"object:{o['id']}"]
        crown, trunk = meshes[f"{root.GetPath()}/Crown"], meshes[f"{root.GetPath()}/Trunk"]
        assert (crown.material.name, trunk.material.name) == ("leaf", "wood")
        assert crown.held_k is None and not crown.refinable
        top = crown.points[:, 2].max()
        assert top == pytest.approx(o["size_m"][2], rel=0.2)  # as tall as the place said
