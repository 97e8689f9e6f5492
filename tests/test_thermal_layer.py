"""Thermal layer with physiology: radiation -> MRT -> JOS-3 / two-node -> skin; garment balance."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from humv_usd.human import labels as L
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.thermal.human import auto_radiation_rays
from humv_usd.usd import avatar as UA
from humv_usd.usd import schemas as S
from humv_usd.usd.check import check_stage
from humv_usd.usd.thermal import read_face_temperature_noise

pytestmark = pytest.mark.slow


def face_normals(stage, path, frame=0):
    """Unit normals of the authored faces of a (skinned) mesh at a frame, world space."""
    from humv_usd.human.usdskel import skinned_points

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(path))
    pts = skinned_points(stage, path, Usd.TimeCode(frame), space="world")
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    a, b, c = pts[idx[starts]], pts[idx[starts + 1]], pts[idx[starts + 2]]
    n = np.cross(b - a, c - a)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def temperatures(stage, path, frame=0):
    prim = stage.GetPrimAtPath(path)
    return np.asarray(prim.GetAttribute(S.TEMPERATURE_PRIMVAR).Get(frame), dtype=float)


@pytest.fixture(scope="module")
def jos3_stage(tmp_path_factory, humvvex_raw):
    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"]["model"] = "jos3"
    raw["thermal"]["skin_detail"] = "segment"  # the physiology's segments (facets: below)
    raw["human"][0]["clothing"] = ["tshirt_white", "shorts", "cap"]  # barefoot: cold feet
    raw["scene"]["ground"]["temperature_k"] = 297.0  # held surfaces (the slab: below)
    raw["scene"]["object"][0]["temperature_k"] = 293.0
    raw["thermal"]["radiation_rays"] = 192  # given: the physiology under test, not the rays (below)
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
    seg = L.jos3_segments(np.asarray(body.GetAttribute(UA.BODY_REGION_PRIMVAR).Get()))
    names = list(L.JOS3_SEGMENTS)
    # a person standing in shorts at 16 degC: hands and feet colder than the chest and head
    by = {n: skin[seg == names.index(n)].mean() for n in ("Head", "Chest", "LHand", "RFoot")}
    assert by["LHand"] < by["Chest"] - 2.0 and by["RFoot"] < by["Chest"] - 2.0
    assert by["Head"] > 303.0
    sun = np.asarray(
        stage.GetPrimAtPath("/World/Environment").GetAttribute("humv:environment:sunDirection").Get(0),
        dtype=float,
    )
    assert sun[2] > 0.5  # 14:05 EDT in October: the sun is up in the south-south-west
    for garment in ("tshirt_white", "shorts", "cap"):
        path = f"/World/Humans/p1/Clothing/{garment}"
        assert stage.GetPrimAtPath(path).GetAttribute(S.THERMAL_MODEL).Get() == "balance"
        t = temperatures(stage, path)
        assert np.all((t > air - 10.0) & (t < air + 40.0))
        # the sunlit side of the fabric is warmer than the side facing away from the sun
        n = face_normals(stage, path)
        lit, away = n @ sun > 0.5, n @ sun < -0.5
        assert t[lit].mean() > t[away].mean() + 2.0
    # the shaded side of the shirt: between the cold air and the skin, colder than the chest
    shirt = temperatures(stage, "/World/Humans/p1/Clothing/tshirt_white")
    n = face_normals(stage, "/World/Humans/p1/Clothing/tshirt_white")
    assert shirt[n @ sun < -0.3].mean() < by["Chest"] - 3.0
    # scene surfaces keep the scenario's temperatures (held)
    for path, key in (
        ("/World/Scene/Ground", raw["scene"]["ground"]),
        ("/World/Scene/warehouse", raw["scene"]["object"][0]),
    ):
        prim = stage.GetPrimAtPath(path)
        assert prim.GetAttribute(S.THERMAL_MODEL).Get() == "fixed"
        assert np.all(temperatures(stage, path) == np.float32(key["temperature_k"]))
    # the layer carries its error estimates; compose.json the run times
    report = Sdf.Layer.FindOrOpen(str(out / "layers" / "thermal.usda")).customLayerData
    diag = report["humv:thermal"]["p1"]
    assert 0.0 < diag["qradRmsRelErrorEstimate"] < 0.1
    assert diag["garmentMaxResidual_W_m2"] <= 1e-6
    # the rays' face-temperature noise per mesh (visible faces): bare skin and each garment;
    # the person's is their area-weighted mean, so it lies between the meshes'
    by_mesh = diag["faceTemperatureNoiseRmsByMesh_K"]
    assert set(by_mesh) == {"/World/Humans/p1/Body"} | {
        f"/World/Humans/p1/Clothing/{g}" for g in ("tshirt_white", "shorts", "cap")
    }
    assert all(0.0 < v < 0.5 for v in by_mesh.values())
    assert min(by_mesh.values()) <= diag["faceTemperatureNoiseRms_K"] <= max(by_mesh.values())
    # and per face on each of them (the render propagates it through its smooth shading): one
    # value per authored face, the mesh's RMS within the faces' range
    for path, rms in by_mesh.items():
        prim = stage.GetPrimAtPath(path)
        sigma = read_face_temperature_noise(prim)
        assert sigma is not None and len(sigma) == len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get())
        assert np.all(np.isfinite(sigma) & (sigma >= 0.0)) and sigma.min() <= rms <= sigma.max()
    timings = json.loads((out / "compose.json").read_text())
    assert {x["name"] for x in timings["layers"]} >= {"thermal", "clothing_p1"}


def test_two_node_at_night_with_slab_surfaces(humvvex_raw, tmp_path):
    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"]["model"] = "twoNode"
    raw["thermal"]["skin_detail"] = "segment"  # one skin node, on every facet
    raw["thermal"]["surface_spin_up_s"] = 43200.0
    raw["human"][0]["clothing"] = []
    raw["general"]["start"] = raw["general"]["start"].replace(hour=2)  # 02:05 local
    raw["scene"]["ground"].pop("temperature_k", None)  # -> slab
    raw["scene"]["object"][0]["temperature_k"] = 310.0  # held
    compose(validate(raw), tmp_path)
    stage = Usd.Stage.Open(str(tmp_path / "stage.usda"))
    skin = temperatures(stage, "/World/Humans/p1/Body")
    # Gagge: one mean skin node; naked at 16 degC in a 3 m/s wind for an hour: cold skin
    assert np.ptp(skin) == 0.0 and 290.0 < skin[0] < 303.0
    report = Sdf.Layer.FindOrOpen(str(tmp_path / "layers" / "thermal.usda")).customLayerData
    assert report["humv:thermal"]["p1"]["absorbedShortwaveMean_W_m2"] == 0.0  # no sun at night
    assert report["humv:thermal"]["surfaces"]["slabMaxResidual_W_m2"] < 1e-6
    # radiation_rays left out: the rays of the most demanding thermal camera (the cooled MWIR's
    # NETD 20 mK), as the rule gives them for this stage's sensors
    rays, netd = auto_radiation_rays(stage)
    assert netd == pytest.approx(0.02) and report["humv:thermal"]["qradRays"] == rays > 192
    assert "0.02 K" in report["humv:thermal"]["qradRaysRule"]
    ground = stage.GetPrimAtPath("/World/Scene/Ground")
    assert ground.GetAttribute(S.THERMAL_MODEL).Get() == "slab"
    t_ground = temperatures(stage, "/World/Scene/Ground")
    # a clear night: the open pad radiates to the cold sky and ends up below the 16 degC air
    # (faces the building shaded the afternoon before keep that history: not all equal)
    assert 279.0 < np.median(t_ground) < 289.0
    wall = temperatures(stage, "/World/Scene/warehouse")
    assert np.all(wall == np.float32(310.0))


def _night_jos3(humvvex_raw, out, cloud):
    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"]["model"] = "jos3"
    raw["thermal"]["radiation_rays"] = 16
    raw["general"]["start"] = raw["general"]["start"].replace(hour=2)  # night: no sun
    raw["scene"]["ground"]["temperature_k"] = 286.0  # held surfaces
    raw["scene"]["object"][0]["temperature_k"] = 287.0
    raw["atmosphere"]["cloud_cover"] = cloud
    raw["atmosphere"]["model"] = "analytic"
    raw["sensor"] = raw["sensor"][:1]
    compose(validate(raw), out)
    stage = Usd.Stage.Open(str(out / "stage.usda"))
    report = Sdf.Layer.FindOrOpen(str(out / "layers" / "thermal.usda")).customLayerData
    return stage, dict(report["humv:thermal"]["sky"])


def test_overcast_night_sky_warms_skin_and_garments(humvvex_raw, tmp_path):
    """The thermal layer reads the atmosphere layer's sky: at night (only the long-wave sky
    changes with the clouds) an overcast sky warms the skin and the garments."""
    from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
    from humv_usd.thermal.sky import hemispherical_irradiance, stage_longwave_table

    result = {c: _night_jos3(humvvex_raw, tmp_path / f"c{c}", c) for c in (0.0, 1.0)}
    for c, (stage, sky) in result.items():
        assert sky["source"].startswith("atmosphere layer") and sky["cloudCover"] == c
        table = stage_longwave_table(stage)
        assert sky["longwaveIrradiance_W_m2"] == pytest.approx(hemispherical_irradiance(*table), rel=1e-6)
    t_air = humvvex_raw["atmosphere"]["air_temperature_k"]
    assert result[1.0][1]["longwaveIrradiance_W_m2"] == pytest.approx(SIGMA * t_air**4, rel=1e-5)
    assert result[1.0][1]["longwaveIrradiance_W_m2"] > result[0.0][1]["longwaveIrradiance_W_m2"] + 80
    (clear, _), (cloudy, _) = result[0.0], result[1.0]
    skin_c, skin_o = (temperatures(s, "/World/Humans/p1/Body") for s in (clear, cloudy))
    assert skin_o.mean() > skin_c.mean() + 0.3
    for garment in ("tshirt_white", "shorts", "cap"):
        path = f"/World/Humans/p1/Clothing/{garment}"
        t_c, t_o = temperatures(clear, path), temperatures(cloudy, path)
        assert t_o.mean() > t_c.mean() + 0.1  # shorts: mostly facing the (held) ground
        # upward-facing fabric (shoulders, cap crown) sees the most sky: the largest change
        up = face_normals(clear, path)[:, 2] > 0.7
        if up.sum() >= 10:
            assert (t_o - t_c)[up].mean() > max(1.0, (t_o - t_c)[~up].mean())


@pytest.fixture(scope="module")
def demo_stage(tmp_path_factory):
    """examples/humvvex.toml as shipped: JOS-3, skin per facet, coupled garments, shoes."""
    import tomllib

    from conftest import HUMVVEX_DEMO

    out = tmp_path_factory.mktemp("demo")
    compose(validate(tomllib.loads(HUMVVEX_DEMO.read_text())), out)
    return out, Usd.Stage.Open(str(out / "stage.usda"))


def test_skin_per_facet_sunlit_warmer_than_shaded(demo_stage):
    """Within a segment the sunlit facets are warmer than the shaded ones (their own balance),
    while the segment's area-weighted mean stays the physiology's."""
    out, stage = demo_stage
    body = stage.GetPrimAtPath("/World/Humans/p1/Body")
    skin = temperatures(stage, "/World/Humans/p1/Body")
    seg = L.jos3_segments(np.asarray(body.GetAttribute(UA.BODY_REGION_PRIMVAR).Get()))
    sun = np.asarray(
        stage.GetPrimAtPath("/World/Environment").GetAttribute("humv:environment:sunDirection").Get(0),
        dtype=float,
    )
    n = face_normals(stage, "/World/Humans/p1/Body") @ sun
    names = list(L.JOS3_SEGMENTS)
    for name in ("Head", "LArm", "RArm", "LLeg", "RLeg", "LThigh"):
        m = seg == names.index(name)
        assert skin[m & (n > 0.5)].mean() > skin[m & (n < -0.3)].mean() + 2.0, name
    assert 295.0 < skin.min() and skin.max() < 316.0
    report = Sdf.Layer.FindOrOpen(str(out / "layers" / "thermal.usda")).customLayerData["humv:thermal"]["p1"]
    # two-way coupling: per segment, skin-side garment / bare-skin flux = physiology sensible loss
    assert report["couplingMaxResidual_W_m2"] < 1.0 and report["couplingIterations"] >= 2
    assert report["garmentMaxResidual_W_m2"] <= 1e-6
    shoes = stage.GetPrimAtPath("/World/Humans/p1/Clothing/shoes")
    assert shoes.GetAttribute(S.THERMAL_MODEL).Get() == "balance"
    t_shoes = temperatures(stage, "/World/Humans/p1/Clothing/shoes")
    feet = skin[np.isin(seg, [names.index("LFoot"), names.index("RFoot")])]
    assert 285.0 < t_shoes.mean() < feet.mean()  # leather between skin and the 16 degC air


def test_coupling_converges_over_frames_while_walking(humvvex_raw, tmp_path):
    """Several frames of a walking person: per frame and segment the skin-side flux meets the
    physiology's sensible loss (the physiology reports each output under that output's own
    inputs, so the effective radiant temperature of frame i sets the exchange at frame i)."""
    raw = copy.deepcopy(humvvex_raw)
    raw["general"].update(duration_s=0.4, fps=10.0)
    raw["human"][0].update(activity="walk", clothing=["tshirt_black", "shorts"])
    raw["thermal"].update(model="jos3", radiation_rays=8, radiation_resolution=32, radiation_step_s=0.2)
    raw["scene"]["ground"]["temperature_k"] = 297.0
    raw["scene"]["object"][0]["temperature_k"] = 293.0
    raw["atmosphere"]["model"] = "analytic"
    raw["sensor"] = raw["sensor"][:1]
    compose(validate(raw), tmp_path)
    report = Sdf.Layer.FindOrOpen(str(tmp_path / "layers" / "thermal.usda")).customLayerData["humv:thermal"]
    assert report["p1"]["couplingMaxResidual_W_m2"] < 1.0
    assert report["p1"]["couplingIterations"] <= 8
    stage = Usd.Stage.Open(str(tmp_path / "stage.usda"))
    skin = [temperatures(stage, "/World/Humans/p1/Body", f) for f in range(5)]
    assert all(np.isfinite(s).all() and 290.0 < s.mean() < 310.0 for s in skin)
