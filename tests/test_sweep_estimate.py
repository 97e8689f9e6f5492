"""The dry run's compose estimate sees the scene's size (issue 30.6, issue 26.2): the thermal layer's
scene term against the composes it was fitted to, and a place sweep's estimate growing with the
place. Nothing is composed: the scene layers are built in memory (well under a second each)."""

from __future__ import annotations

import math
import tomllib

from conftest import ROOT

from humv_usd.sweep import plan
from humv_usd.sweep.spec import load_sweep

#: examples/random_places.toml's daytime variants composed 2026-11-27 (default cells, one person
#: with model = "fixed", load 2-4): variant, scene meshes, measured thermal-layer seconds
MEASURED_DAY = [
    ("v0014 parking lot 16:36", 23, 8.1),
    ("v0015 parking lot 07:59", 33, 23.6),
    ("v0010 rural road 14:55", 83, 119.7),
    ("v0008 rural road 11:06", 128, 175.4),
    ("v0018 open field 13:42", 93, 89.7),
    ("v0019 open field 15:44", 120, 28.9),
]
#: the same run's night variant (sun down since long before frame 0: no refinement)
MEASURED_NIGHT = ("v0013 parking lot 00:10", 37, 2.8)


def test_scene_term_follows_the_measured_composes():
    """Five of the six daytime composes within a factor 2 of the estimate, all within a factor 3.5
    (the open field at 15:44: 0.29), their geometric mean within 1.5; the night one within 1.2."""
    ratios = [seconds / plan.scene_thermal_seconds(meshes) for _, meshes, seconds in MEASURED_DAY]
    assert all(1 / 3.5 < r < 3.5 for r in ratios), ratios
    assert sum(0.5 < r < 2.0 for r in ratios) >= 5, ratios
    assert 1 / 1.5 < math.exp(sum(math.log(r) for r in ratios) / len(ratios)) < 1.5
    _, meshes, seconds = MEASURED_NIGHT
    assert 1 / 1.2 < seconds / plan.scene_thermal_seconds(meshes, sun=False) < 1.2
    assert plan.scene_thermal_seconds(0) == 0.0


def test_place_sweep_estimate_grows_with_the_place(tmp_path):
    """A street sweep over length_m: the longer street has more buildings (meshes), and its compose
    estimate is larger by the difference of the scene terms."""
    path = ROOT / "examples" / "places" / "street.toml"
    raw = path.read_text(encoding="utf-8")
    assert tomllib.loads(raw)["scene"]["place"]["kind"] == "street"
    (tmp_path / "street.toml").write_text(raw, encoding="utf-8")
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
    assert all(plan.sun_in_memory(v.scenario) for v in sw.variants)
    scene = [plan.scene_thermal_seconds(m) for m in meshes]
    assert alone[1]["compose_s"] > alone[0]["compose_s"] > scene[0]
    assert abs((alone[1]["compose_s"] - alone[0]["compose_s"]) - (scene[1] - scene[0])) < 0.2
