"""Crops (issue 30.2): a crop field as a plant of rows (closed-form volume and row count), its
faces solved by the leaf balance near the air by day, and a rural road with ``crop`` growing one
beside the road while the place without it is unchanged. Scene layers in memory only."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest
from conftest import general_toml, place_keys, scene_stage

from humv_usd.errors import InputError
from humv_usd.scenario import validate
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.places import place_items, scene_materials
from humv_usd.scenario.spec import CROPS
from humv_usd.scene.vegetation import CROP_ROW_FILL, PLANT_KINDS, plant_parts
from humv_usd.thermal import surfaces as SF
from humv_usd.thermal.surfaces import scene_meshes
from humv_usd.usd import schemas as S


@pytest.mark.parametrize("crop", sorted(CROPS))
def test_crop_rows_are_closed_and_fill_their_closed_form_volume(crop):
    spacing, height = CROPS[crop]
    size = (12.0, 6.0, height)
    points, tris = plant_parts("crop", size, row_spacing_m=spacing)["Crown"]
    v = points[tris]
    vol = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    assert np.all(np.unique(edges, axis=0, return_counts=True)[1] == 2)  # closed
    rows = int(6.0 // spacing)
    # the row profile: a 1 x 0.6 rectangle under a trapezoid (1 + 0.5) / 2 x 0.4 = area 0.9
    assert vol == pytest.approx(rows * 0.9 * CROP_ROW_FILL * spacing * height * 12.0, rel=1e-9)
    assert points[:, 2].max() == pytest.approx(height) and points[:, 2].min() == 0.0
    assert np.ptp(points[:, 0]) == pytest.approx(12.0)
    assert np.ptp(points[:, 1]) == pytest.approx((rows - 1 + CROP_ROW_FILL) * spacing)
    assert "crop" in PLANT_KINDS and set(CROPS) == {"maize", "wheat"}
    assert CROPS["maize"][0] == pytest.approx(0.76) and 0.15 <= CROPS["wheat"][0] <= 0.2


SCENARIO = {
    **tomllib.loads(general_toml("crops")),
    "scene": {
        "ground": {"material": "soil", "size_m": [60.0, 60.0]},
        "object": [
            {
                "id": "maize",
                "kind": "crop",
                "material": "leaf",
                "class": "vegetation",
                "center_m": [0.0, 0.0, 0.0],
                "size_m": [8.0, 4.0, 2.0],
            },
        ],  # fmt: skip
    },
}


def test_a_crop_object_composes_labelled_and_its_faces_are_leaves_near_the_air():
    scenario = validate(copy.deepcopy(SCENARIO))
    stage = scene_stage(scenario)
    root = stage.GetPrimAtPath("/World/Scene/maize")
    assert root.GetAttribute(S.LABEL_CLASS).Get() == "vegetation"
    assert root.GetAttribute(S.LABEL_INSTANCE_ID).Get() == instance_ids(scenario)["object:maize"]
    meshes = {m.path: m for m in scene_meshes(stage, scenario)}
    crown = meshes["/World/Scene/maize/Crown"]
    assert crown.material.name == "leaf" and crown.held_k is None and not crown.refinable
    assert crown.points[:, 2].max() == pytest.approx(2.0 - 0.05)  # sunk 5 cm like every plant
    # 5 rows of 0.76 m in 4 m, each profile at 4 distinct y (half-width and quarter-width sides)
    assert len(np.unique(np.round(crown.points[:, 1], 4))) == 5 * 4
    # noon sun on the rows: every face a transpiring leaf within a few K of the air (as
    # tests/test_vegetation.py bounds a sunlit leaf in a 2 m/s breeze, Jones 2014 ch. 9); a clear
    # night: every face below the air (radiative cooling), by less than 4 K
    for sw, air in ((900.0, 300.15), (0.0, 288.15)):
        temps = _crop_faces(crown, sw, air)
        if sw:
            assert np.all(np.abs(temps - air) < 4.0)
            assert np.ptp(temps) > 0.1  # sunlit tops and shaded ends differ
        else:
            assert np.all((temps - air > -4.0) & (temps - air < 0.0))


def _crop_faces(crown, sw, air, n=12):
    """The crop's face temperatures [K] after 2 h of held weather: the sun at 72 deg elevation
    (direct 8/9 of ``sw``), RH 0.4, wind 2 m/s, an isotropic clear sky, no exchange."""
    t = np.arange(n) * 600.0 - (n - 1) * 600.0
    one = np.ones(n)
    f = SF.SurfaceForcing(
        t, air * one, 0.4 * one, 2.0 * one, np.tile([0.3, 0.0, 0.95], (n, 1)), np.full(n, sw > 0),
        sw * 8 / 9 * one, sw / 9 * one, 0.95 * sw * one, sky_shape=(np.array([0.0, 90.0]), np.ones(2)),
    )  # fmt: skip
    out, _ = SF.surface_temperatures(None, [crown], f.times_s, 0.0, forcing=f, exchange=False)
    return out[crown.path][-1]


@pytest.mark.parametrize(("kind", "clear"), [("rural_road", 1.0), ("open_field", 3.0)])
def test_places_grow_a_crop_field_clear_of_trees_and_clutter_and_are_otherwise_unchanged(kind, clear):
    keys = dict(seed=5, vegetation_density=0.3, animals=6, vehicles=4, warm_objects=3)
    plain = place_items(place_keys(kind, **keys))
    p = place_keys(kind, crop="wheat", **keys)
    items = place_items(p)
    (c,) = [o for o in items.objects if o["kind"] == "crop"]
    assert (c["material"], c["class"], c["row_spacing_m"]) == ("leaf", "vegetation", CROPS["wheat"][0])
    assert c["size_m"][2] == CROPS["wheat"][1]
    y0, y1 = c["center_m"][1] - c["size_m"][1] / 2, c["center_m"][1] + c["size_m"][1] / 2
    if kind == "rural_road":
        assert y1 < -p["road_width_m"] / 2 - 2.0  # beside the road, in the south field
    else:
        assert y0 >= 3.0 and y1 <= p["length_m"] / 2
    for o in items.objects:  # no tree stands in it
        assert o["kind"] != "tree" or not (y0 - clear <= o["center_m"][1] <= y1 + clear)
    for k in items.clutter:  # nor a warm object
        assert not (y0 - clear <= k["position_m"][1] <= y1 + clear)
    moved = sum(a["position_m"] != b["position_m"] for a, b in zip(items.clutter, plain.clutter))
    assert moved > 0  # some animals or cars had to move out of the field
    assert items.trees == plain.trees  # the same draws
    assert [k["id"] for k in items.clutter] == [k["id"] for k in plain.clutter]
    assert [o for o in plain.objects if o["kind"] == "crop"] == []
    assert place_keys(kind)["crop"] == "none"
    assert {"leaf", "soil"} <= scene_materials({"place": p})


def test_an_unknown_crop_is_a_one_line_error():
    raw = {**copy.deepcopy(SCENARIO), "scene": {"ground": {"material": "soil", "size_m": [60.0, 60.0]}}}
    raw["scene"]["place"] = {"kind": "rural_road", "crop": "rice"}
    with pytest.raises(InputError) as e:
        validate(raw)
    assert str(e.value) == "scene.place.crop = 'rice': allowed values: none, maize, wheat"
