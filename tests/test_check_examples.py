"""Issue 15: check is a trustworthy gate: it never crashes on a stage compose wrote and finds
nothing wrong with one, for every example and every thermal model, single and multi-frame."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.scenario.spec import THERMAL_MODELS
from humv_usd.usd.check import check_stage

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCENARIOS = sorted(p.name for p in EXAMPLES.glob("*.toml") if "sweep" not in tomllib.loads(p.read_text()))


def _compose_and_check(path: Path, out: Path, edit=None) -> list[str]:
    raw = tomllib.loads(path.read_text())
    if edit is not None:
        edit(raw)
    compose(validate(raw, path), out)
    return check_stage(out / "stage.usda")


@pytest.mark.slow
@pytest.mark.parametrize("name", SCENARIOS)
def test_every_example_composes_to_a_clean_stage(name, tmp_path):
    assert _compose_and_check(EXAMPLES / name, tmp_path / "o") == []


@pytest.mark.slow
@pytest.mark.parametrize("frames", [1, 2])
@pytest.mark.parametrize("model", THERMAL_MODELS)
def test_every_thermal_model_single_and_multi_frame(model, frames, tmp_path):
    def edit(raw):
        raw["thermal"]["model"] = model
        raw["general"]["duration_s"] = (frames - 1) / raw["general"]["fps"]

    assert _compose_and_check(EXAMPLES / "humvvex_fixed.toml", tmp_path / "o", edit) == []
