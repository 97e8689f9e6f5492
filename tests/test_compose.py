"""compose: one layer per part, conventions, idempotence, nothing written on bad input."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import HUMVVEX, HUMVVEX_LAYERS, ROOT
from pxr import Usd, UsdGeom, UsdShade

from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.usd import schemas as S
from humv_usd.usd.check import check_stage
from humv_usd.usd.mesh import triangle_areas

ALL_LAYERS = set(HUMVVEX_LAYERS)
GARMENTS = ("hair_short", "tshirt_white", "shorts", "cap", "shoes")  # humvvex: hair by default


def layer_names(out):
    return {p.stem for p in (out / "layers").glob("*.usda")}


@pytest.fixture(scope="module")
def composed(tmp_path_factory, humvvex_raw):
    out = tmp_path_factory.mktemp("humvvex")
    report = compose(validate(humvvex_raw), out)
    return out, report, Usd.Stage.Open(str(out / "stage.usda"))


def test_one_layer_per_part_and_clean(composed):
    out, report, stage = composed
    assert layer_names(out) == ALL_LAYERS
    assert not list((out / "layers").glob(".*"))  # no temp files left: staged, held (hold_layer)
    assert set(report.written) == ALL_LAYERS | {"stage"}
    assert check_stage(out / "stage.usda") == []
    assert UsdGeom.GetStageUpAxis(stage) == "Z"
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert len(stage.GetRootLayer().rootPrims) == 0  # sublayers + metadata only
    assert stage.GetTimeCodesPerSecond() == 30
    ran = json.loads((out / "compose.json").read_text())["ran"]
    assert set(ran) == {
        "environment",
        "atmosphere",
        "atmosphere_paths",
    }  # each tool says what it ran and skipped
    assert "sun up at 1 of 1" in ran["environment"]["sun"]


def test_each_layer_stands_alone(composed):
    out, _, _ = composed
    for path in (out / "layers").glob("*.usda"):
        layer_stage = Usd.Stage.Open(str(path))
        assert layer_stage.GetDefaultPrim().GetPath() == "/World"
        assert UsdGeom.GetStageUpAxis(layer_stage) == "Z"


def _area_median(mesh, values):
    """Median of per-face values weighted by face area."""
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
    area = triangle_areas(np.asarray(mesh.GetPointsAttr().Get(), dtype=float), counts, indices)
    order = np.argsort(values)
    cum = np.cumsum(area[order])
    return float(np.asarray(values)[order][np.searchsorted(cum, 0.5 * cum[-1])])


def test_every_mesh_has_material_and_one_temperature_per_face(composed):
    _, _, stage = composed
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    garments = {f"/World/Humans/p1/Clothing/{g}" for g in GARMENTS}
    assert {str(p.GetPath()) for p in meshes} == {
        "/World/Scene/Ground",
        "/World/Scene/warehouse",
        "/World/Humans/p1/Body",
    } | garments
    # fixed model: skin as given, garments at the air temperature; the scene (no temperature_k in
    # humvvex) from the slab model in the afternoon sun: the sunlit pad warmer than the 289 K air,
    # the pad in the warehouse's shadow colder than the sunlit pad
    expected = {"/World/Humans/p1/Body": 306.15} | {g: 289.0 for g in garments}
    for prim in meshes:
        assert prim.HasAPI(S.THERMAL_API)
        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("humv:thermal:temperature")
        assert pv.GetInterpolation() == "uniform"
        temps = np.asarray(pv.Get())
        assert len(temps) == len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get())
        path = str(prim.GetPath())
        if path in expected:
            np.testing.assert_allclose(temps, expected[path], rtol=1e-6)
        else:
            assert np.isfinite(temps).all() and (temps > 275.0).all() and (temps < 330.0).all()
        if path == "/World/Scene/Ground":
            # median by area: the thermal layer re-tessellates the ground finely along shadows
            median = _area_median(UsdGeom.Mesh(prim), temps)
            assert median > 289.0 + 3.0 and temps.min() < median - 3.0
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        assert material.GetPrim().HasAPI(S.MATERIAL_API)


def test_meshes_closed_and_outward(composed):
    """Mitsuba area emitters emit on the front side only: boxes must wind outward."""
    from humv_usd.usd.mesh import signed_volume

    _, _, stage = composed
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Scene/warehouse"))
    pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
    vol = signed_volume(pts, mesh.GetFaceVertexCountsAttr().Get(), mesh.GetFaceVertexIndicesAttr().Get())
    assert vol == pytest.approx(40.0 * 15.0 * 8.0, rel=1e-6)
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Humans/p1/Body"))
    pts = np.asarray(body.GetPointsAttr().Get(), dtype=float)
    assert (
        signed_volume(pts, body.GetFaceVertexCountsAttr().Get(), body.GetFaceVertexIndicesAttr().Get()) > 0.03
    )  # ~0.07 m^3 body


def test_avatar_stature_heading_and_attributes(composed):
    _, _, stage = composed
    human = stage.GetPrimAtPath("/World/Humans/p1")
    body = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Humans/p1/Body"))
    bbox = (
        UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["default"])
        .ComputeWorldBound(body.GetPrim())
        .ComputeAlignedRange()
    )
    assert bbox.GetSize()[2] == pytest.approx(1.78, rel=1e-5)
    assert bbox.GetMin()[2] == pytest.approx(0.0, abs=1e-6)
    assert human.GetAttribute(S.AVATAR_STATURE).Get() == pytest.approx(1.78)
    assert human.GetAttribute(S.AVATAR_MASS).Get() == pytest.approx(80.0)
    assert 1.4 < human.GetAttribute(S.AVATAR_BODY_SURFACE_AREA).Get() < 2.6
    # heading 180 deg (facing south, -y): the toes point to -y
    pts = np.asarray(body.GetPointsAttr().Get())
    feet = pts[pts[:, 2] < 0.03]
    assert feet[:, 1].mean() < pts[:, 1].mean()


def test_camera_matches_sensor_geometry(composed):
    _, _, stage = composed
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/World/Sensors/atom1024_lwir"))
    gf = cam.GetCamera(Usd.TimeCode.Default())
    hfov = gf.GetFieldOfView(gf.FOVHorizontal)
    assert hfov == pytest.approx(math.degrees(2 * math.atan(1024 * 17e-6 / 2 / 25e-3)), rel=1e-5)
    m = gf.transform
    assert tuple(m.ExtractTranslation()) == pytest.approx((0.0, -15.0, 1.6))
    forward = -np.asarray(m.TransformDir((0, 0, 1)))
    assert forward == pytest.approx((0.0, 1.0, 0.0), abs=1e-9)  # looks north at the person
    prim = cam.GetPrim()
    assert tuple(prim.GetAttribute(S.SENSOR_RESOLUTION).Get()) == (1024, 768)
    assert prim.GetAttribute(S.SENSOR_PIXEL_PITCH).Get() == pytest.approx(17e-6)


def test_sky_below_air_temperature(composed):
    _, _, stage = composed
    atm = stage.GetPrimAtPath("/World/Atmosphere")
    t_sky = atm.GetAttribute(S.ATMOSPHERE_SKY_TEMPERATURE).Get()
    assert 230.0 < t_sky < 289.0


def test_rerun_rewrites_nothing_and_change_rewrites_one(tmp_path, raw):
    out = tmp_path / "o"
    compose(validate(raw), out)
    files = sorted(out.rglob("*.usda"))
    mtimes = [f.stat().st_mtime_ns for f in files]
    again = compose(validate(raw), out)
    assert again.written == []
    assert [f.stat().st_mtime_ns for f in files] == mtimes
    raw["thermal"]["skin_temperature_k"] = 305.0
    changed = compose(validate(raw), out)
    # the root changes too: it records the digest of the scenario it was composed from
    assert changed.written == ["thermal", "stage"]


def test_parts_the_scenario_lacks_get_no_layer(tmp_path, raw):
    out = tmp_path / "o"
    compose(validate(raw), out)
    del raw["sensor"]
    del raw["atmosphere"]
    report = compose(validate(raw), out)
    assert layer_names(out) == {"environment", "materials", "scene", "avatar_p1", "clothing_p1"}
    assert set(report.removed) == {"atmosphere.usda", "atmosphere_paths.usda", "sensors.usda", "thermal.usda"}
    assert {part for part, _ in report.skipped} == {"atmosphere", "atmosphere_paths", "sensors", "thermal"}
    skipped = json.loads((out / "compose.json").read_text())["skipped"]
    assert {"part": "atmosphere_paths", "reason": "no [[sensor]]"} in skipped
    assert check_stage(out / "stage.usda") == []


def cli(*args, cwd=ROOT):
    return subprocess.run(
        [sys.executable, "-m", "humv_usd.cli.main", *args], cwd=cwd, capture_output=True, text=True
    )


@pytest.mark.slow
def test_cli_bad_input_one_line_per_problem_exit_2_nothing_written(tmp_path):
    bad = tmp_path / "bad.toml"
    text = HUMVVEX.read_text()
    bad.write_text(
        text.replace("latitude_deg = 39.80", "latitude_deg = 139.8").replace(
            "bit_depth = 14", "bit_depth = 40"
        )
    )
    out = tmp_path / "out"
    r = cli("compose", str(bad), "-o", str(out))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 2 and "Traceback" not in r.stderr
    assert "general.latitude_deg = 139.8: allowed range -90.0..90.0" in lines[0]
    assert "sensor[0].bit_depth = 40: allowed range 8..16" in lines[1]
    assert not out.exists()


@pytest.mark.slow
def test_cli_compose_then_check(tmp_path):
    out = tmp_path / "out"
    r = cli("compose", str(HUMVVEX), "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert "thermal" in r.stdout and "written" in r.stdout
    r = cli("check", str(out / "stage.usda"))
    assert r.returncode == 0 and r.stdout.strip().endswith("ok")
    r = cli("check", str(tmp_path / "missing.usda"))
    assert r.returncode == 2 and "stage file not found" in r.stderr
    garbage = tmp_path / "garbage.usda"
    garbage.write_text("this is not usd")
    r = cli("check", str(garbage))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_usd_tools_see_schemas_without_humv(tmp_path):
    """A plain USD process loads the stage's schemas through PXR_PLUGINPATH_NAME."""
    out = tmp_path / "out"
    compose(validate(__import__("tomllib").loads(HUMVVEX.read_text())), out)
    code = (
        f"from pxr import Usd; s = Usd.Stage.Open({str(out / 'stage.usda')!r}); "
        "p = s.GetPrimAtPath('/World/Sensors/atom1024_lwir'); "
        "print(p.HasAPI('HumvSensorAPI'), p.GetAttribute('humv:sensor:netd').Get())"
    )
    env = dict(os.environ, PXR_PLUGINPATH_NAME=str(ROOT / "schemas"))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    has_api, netd = r.stdout.split()
    assert has_api == "True" and float(netd) == pytest.approx(0.05), r.stderr


def test_solved_meshes_are_the_drawn_meshes(composed, humvvex_raw):
    """The thermal tool solves the scene meshes the render draws (one reader,
    humv_usd.usd.mesh.scene_mesh_prims), and every drawn mesh has face temperatures."""
    from humv_usd.render.scene_export import SceneMeshes
    from humv_usd.thermal.surfaces import scene_meshes
    from humv_usd.usd.layers import SCOPES
    from humv_usd.usd.thermal import has_face_temperatures

    _, _, stage = composed
    drawn = [p for p in SceneMeshes(stage).prims]
    humans = str(SCOPES["humans"])
    solved = {m.path for m in scene_meshes(stage, validate(humvvex_raw))}
    assert solved == {str(p.GetPath()) for p in drawn if not str(p.GetPath()).startswith(humans)}
    assert all(has_face_temperatures(p) for p in drawn)
