"""Thermal layer with physiology: radiation -> MRT -> JOS-3 / two-node -> skin; garment balance."""
from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from humv_usd.avatar import labels as L
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.usd import schemas as S
from humv_usd.usd.check import check_stage

pytestmark = pytest.mark.slow


def temperatures(stage, path, frame=0):
    prim = stage.GetPrimAtPath(path)
    return np.asarray(prim.GetAttribute(S.TEMPERATURE_PRIMVAR).Get(frame), dtype=float)


@pytest.fixture(scope="module")
def jos3_stage(tmp_path_factory, humvvex_raw):
    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"]["model"] = "jos3"
    out = tmp_path_factory.mktemp("jos3")
    compose(validate(raw), out)
    return out, Usd.Stage.Open(str(out / "stage.usda")), raw


def test_jos3_skin_and_garments(jos3_stage):
    out, stage, raw = jos3_stage
    assert check_stage(out / "stage.usda") == []
    air = raw["atmosphere"]["air_temperature_k"]
    body = stage.GetPrimAtPath("/World/Humans/p1/Body")
    assert body.GetAttribute(S.THERMAL_MODEL).Get() == "jos3"
    skin = temperatures(stage, "/World/Humans/p1/Body")
    assert np.all((skin > air - 5.0) & (skin < 310.0))
    seg = L.jos3_segments(np.asarray(body.GetAttribute(L.BODY_REGION_PRIMVAR).Get()))
    names = list(L.JOS3_SEGMENTS)
    # a person standing in shorts at 16 degC: hands and feet colder than the chest and head
    by = {n: skin[seg == names.index(n)].mean() for n in ("Head", "Chest", "LHand", "RFoot")}
    assert by["LHand"] < by["Chest"] - 2.0 and by["RFoot"] < by["Chest"] - 2.0
    assert by["Head"] > 303.0
    for garment in ("tshirt_white", "shorts", "cap"):
        path = f"/World/Humans/p1/Clothing/{garment}"
        assert stage.GetPrimAtPath(path).GetAttribute(S.THERMAL_MODEL).Get() == "balance"
        t = temperatures(stage, path)
        # fabric between the cold surroundings and the skin, colder than the torso's skin
        assert np.all((t > air - 10.0) & (t < 306.0))
    shirt = temperatures(stage, "/World/Humans/p1/Clothing/tshirt_white").mean()
    assert shirt < by["Chest"] - 3.0
    # the layer carries its error estimates; compose.json the run times
    report = Sdf.Layer.FindOrOpen(str(out / "layers" / "thermal.usda")).customLayerData
    diag = report["humv:thermal"]["p1"]
    assert 0.0 < diag["qradRmsRelErrorEstimate"] < 0.1
    assert diag["garmentMaxResidual_W_m2"] <= 1e-6
    timings = json.loads((out / "compose.json").read_text())
    assert {x["name"] for x in timings["layers"]} >= {"thermal", "clothing_p1"}


def test_two_node_uniform_skin(humvvex_raw, tmp_path):
    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"]["model"] = "twoNode"
    raw["human"][0]["clothing"] = []
    compose(validate(raw), tmp_path)
    stage = Usd.Stage.Open(str(tmp_path / "stage.usda"))
    skin = temperatures(stage, "/World/Humans/p1/Body")
    # Gagge: one mean skin node; naked at 16 degC in a 3 m/s wind for an hour: cold skin
    assert np.ptp(skin) == 0.0 and 290.0 < skin[0] < 303.0
