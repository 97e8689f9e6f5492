"""The dry run's compose estimate sees the scene's size (issue 30.6, issue 26.2): the thermal layer's
scene term against the composes it was fitted to, and a place sweep's estimate growing with the
place. Nothing is composed: the scene layers are built in memory (well under a second each)."""

from __future__ import annotations

import math
import tomllib

import pytest
from conftest import ROOT

from humv_usd.scenario import validate
from humv_usd.sweep import plan
from humv_usd.sweep.spec import load_sweep

#: the 2026-11-27 audit of issue 30 (/work/notes/s5/audit-30/cost_table.json and its sweep):
#: place, scene meshes, measured thermal-layer seconds with ``surface_cell_m = 0.5`` (one person)
MEASURED = [
    ("open_field", 33, 11.2),
    ("open_field", 33, 10.4),
    ("rural_road", 61, 60.3),
    ("rural_road", 61, 14.5),
    ("parking_lot", 92, 71.9),
    ("parking_lot", 92, 118.2),
    ("street", 94, 149.3),
    ("street", 94, 117.4),
    ("street_after_rain", 95, 233.8),
    ("sweep_parking_lot", 42, 63.4),
    ("sweep_open_field_after_rain", 50, 121.8),
]
#: `humv-usd bench places --kind street --factors 0.25,0.5` (cells to the camera footprints, no person)
MEASURED_FOOTPRINT = [(43, 110.4), (76, 450.7)]
PERSON_S = sum(plan.COMPOSE_SECONDS["thermal"])  # the people terms: one person, one frame


def test_scene_term_follows_the_measured_composes():
    """Each audit place's measured mean (day and night) within a factor 2 of the estimate, every single
    compose within a factor 4 (the mesh count does not see the weather: the open field after rain
    is 3.1 x, the rural road at night 0.26 x), and the footprint cells' rows within a factor 1.2."""
    by_place: dict[str, list[float]] = {}
    for place, meshes, seconds in MEASURED:
        ratio = seconds / (PERSON_S + plan.scene_thermal_seconds(meshes, 0.5))
        assert 0.25 < ratio < 4.0, (place, meshes, seconds, ratio)
        by_place.setdefault(place, []).append(math.log(ratio))
    for place in ("open_field", "rural_road", "parking_lot", "street"):  # day and night
        logs = by_place[place]
        assert 0.5 < math.exp(sum(logs) / len(logs)) < 2.0, place
    for meshes, seconds in MEASURED_FOOTPRINT:
        assert seconds / plan.scene_thermal_seconds(meshes, 0.0) == pytest.approx(1.0, rel=0.2)
    assert plan.scene_thermal_seconds(0, 0.5) == 0.0


def test_place_sweep_estimate_grows_with_the_place(tmp_path):
    """A street sweep over length_m: the longer street has more buildings (meshes), its compose
    estimate is larger, and both are above the people-only estimate by the scene term."""
    path = ROOT / "examples" / "places" / "street.toml"
    raw = tomllib.loads(path.read_text(encoding="utf-8"))
    base = tmp_path / "street.toml"
    base.write_text(path.read_text(encoding="utf-8"), encoding="utf-8")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        '[sweep]\nname = "lengths"\nbase = "street.toml"\n[grid]\n"scene.place.length_m" = [20.0, 40.0]\n'
        "[render]\nframes = [0]\n",
        encoding="utf-8",
    )
    sw = load_sweep(sweep)
    keys = {v.id: plan.layer_keys(v.scenario) for v in sw.variants}
    alone = [plan.estimate(sw, {u: keys[u] if u == v.id else {} for u in keys}, 1) for v in sw.variants]
    meshes = [plan.scene_meshes(v.scenario) for v in sw.variants]
    assert meshes[1] > meshes[0] > 0
    assert alone[1]["compose_s"] > alone[0]["compose_s"]
    cell = float(validate(raw, path)["thermal"].get("surface_cell_m") or 0.0)
    scene = [plan.scene_thermal_seconds(m, cell) for m in meshes]
    assert alone[1]["compose_s"] - alone[0]["compose_s"] == pytest.approx(scene[1] - scene[0], abs=0.2)
