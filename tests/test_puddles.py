"""Puddles after rain (issue 30.4): seeded water patches on the ground, clear of what stands on
it, authored by the scene layer only after rain, and solved as free water (no NaN at night)."""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest
from conftest import general_toml, scene_stage
from pxr import Usd

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.materials import layer as materials_layer
from humv_usd.materials.layer import LIBRARY_FILE, PUDDLE_MATERIAL
from humv_usd.physics import evaporation as ev
from humv_usd.scenario import validate
from humv_usd.scenario.ids import instance_ids
from humv_usd.scene.puddles import MATERIAL, PUDDLES, RADIUS_M, puddle_discs
from humv_usd.thermal import surfaces as SF
from humv_usd.usd import schemas as S
from humv_usd.usd.materials import read_material
from humv_usd.usd.paths import material_path


def test_puddles_cover_their_share_clear_of_obstacles():
    keep_out = [(0.0, 0.0, 5.0), (10.0, -8.0, 3.0)]
    discs = puddle_discs(4, 0.1, (40.0, 30.0), keep_out)
    assert discs == puddle_discs(4, 0.1, (40.0, 30.0), keep_out)  # the seed's puddles
    assert discs != puddle_discs(5, 0.1, (40.0, 30.0), keep_out)
    area = sum(np.pi * r * r for _, _, r in discs)
    assert 0.1 * 1200.0 <= area <= 0.1 * 1200.0 + np.pi * RADIUS_M[1] ** 2
    for x, y, r in discs:
        assert RADIUS_M[0] <= r <= RADIUS_M[1]
        assert abs(x) + r <= 20.0 and abs(y) + r <= 15.0
        for cx, cy, cr in keep_out:
            assert np.hypot(x - cx, y - cy) >= cr + r
    assert puddle_discs(4, 0.0, (40.0, 30.0)) == []


SCENARIO = (
    general_toml("puddles", seed=2)
    + """
[scene.ground]
material = "asphalt"
size_m = [30.0, 30.0]
horizon_m = 0.0
puddles = 0.08

[[scene.object]]
id = "wall"
material = "concrete"
center_m = [0.0, 4.0, 0.0]
size_m = [6.0, 1.0, 3.0]

[atmosphere]
rain_mm_h = 3.0
rain_end_h = 1.0
"""
)


@pytest.mark.parametrize("rain", [3.0, 0.0])
def test_scene_layer_authors_puddles_only_after_rain(rain):
    raw = tomllib.loads(SCENARIO)
    raw["atmosphere"]["rain_mm_h"] = rain
    scenario = validate(raw)
    stage = scene_stage(scenario)
    prim = stage.GetPrimAtPath(PUDDLES)
    assert bool(prim) == (rain > 0)
    assert (PUDDLE_MATERIAL in materials_layer.used_materials(scenario)) == (rain > 0)
    if not prim:
        return
    ids = instance_ids(scenario)
    assert prim.GetAttribute(S.LABEL_CLASS).Get() == "ground"
    assert prim.GetAttribute(S.LABEL_INSTANCE_ID).Get() == ids["ground_puddles"] != ids["ground"]
    assert prim.GetCustomDataByKey("humv:groundZone") and MATERIAL == PUDDLE_MATERIAL
    meshes = {m.path: m for m in SF.scene_meshes(stage, scenario)}
    water = meshes[str(PUDDLES)]
    assert water.material.name == "water" and water.is_ground and not water.refinable
    z = water.points[:, 2]
    assert np.all((z > 0.0) & (z < 0.01))  # on the flat ground, just above it
    wall = np.array([0.0, 4.0])
    assert np.min(np.hypot(*(water.points[:, :2] - wall).T)) > 1.0  # none under the wall


def test_a_puddle_at_night_is_free_water_near_the_wet_bulb():
    """Free water has no surface resistance whatever the light or the soil (it gave 0 x inf =
    NaN at night before): under an overcast night sky at the air temperature a puddle sits
    between the psychrometric wet bulb and the air."""
    lib = Usd.Stage.Open(str(LIBRARY_FILE))
    water = read_material(lib.GetPrimAtPath(material_path("water")))
    soil = read_material(lib.GetPrimAtPath(material_path("soil")))
    pts = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    mesh = SF.SceneMesh(
        str(PUDDLES), pts, np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]), 1, water, None, True, soil
    )
    n = 200
    t = np.arange(n) * 600.0 - (n - 1) * 600.0
    one = np.ones(n)
    air, rh = 288.15, 0.7
    f = SF.SurfaceForcing(
        t, air * one, rh * one, 2.0 * one, np.tile([0.0, 0.0, 1.0], (n, 1)), np.zeros(n, bool),
        0 * one, 0 * one, 0 * one, soil_moisture=0.0,
    )  # fmt: skip
    eps_sky = SF.SurfaceForcing.sky_longwave.fget(f) / (SIGMA * air**4)
    f = dataclasses.replace(f, sky_longwave_factor=1.0 / eps_sky, rain_kg_m2_s=np.full(n, 1.0 / 3600.0))
    out, diag = SF.surface_temperatures(None, [mesh], t, 0.0, forcing=f, exchange=False)
    temp = out[str(PUDDLES)][:, 0]
    assert np.all(np.isfinite(temp))
    assert float(ev.wet_bulb_temperature(air, rh)) - 0.3 < temp[-1] < air - 1.0


def test_weather_examples_validate():
    """examples/weather/*.toml (composed by hand, see weather.md: minutes) validate; the rainy
    ones (after_rain; snow.toml is dry) have puddles."""
    from pathlib import Path

    examples = sorted((Path(__file__).resolve().parents[1] / "examples" / "weather").glob("*.toml"))
    assert examples
    rainy = []
    for path in examples:
        scenario = validate(tomllib.loads(path.read_text()), path)
        if scenario["atmosphere"]["rain_mm_h"] > 0:
            rainy.append(path.stem)
            assert scenario["scene"]["ground"]["puddles"] > 0, path.stem
    assert "after_rain" in rainy
