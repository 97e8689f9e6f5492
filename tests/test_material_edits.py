"""A stronger layer that edits materials changes the thermal layer and the render alike
(issue 11, deliverable 3a): a fabric's solar absorptivity and a wall's emissivity spectrum,
overridden in a user layer above the composed layers, change the temperatures the thermal tool
solves and the radiance the render draws, and the band emissivity the thermal solve uses is the
one the render uses (Kirchhoff)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from pxr import Sdf, Usd, Vt

from humv_usd import images
from humv_usd.catalog.materials import LIBRARY
from humv_usd.pipeline.compose import LAYER_DIR, compose, compose_in_memory
from humv_usd.pipeline.render import render_stage
from humv_usd.render.bands import band_emissivity as _band_emissivity
from humv_usd.render.export import StageExport
from humv_usd.scenario import validate
from humv_usd.thermal import layer as thermal_layer
from humv_usd.thermal.human import LONGWAVE_BAND_UM, longwave_emissivity
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import layer_text
from humv_usd.usd.materials import bound_material, mesh_material, read_material

pytestmark = pytest.mark.slow

SHIRT = "/World/Humans/p1/Clothing/tshirt_white"
WALL = "/World/Scene/warehouse"
SENSOR = "lwir"
SHIRT_ABSORPTIVITY = 0.95  # the white shirt (0.3) made as dark as a black one
WALL_EMISSIVITY_SCALE = 0.4  # the painted siding (~0.91 in 8-14 um) made shiny


def _scenario(humvvex_raw):
    raw = copy.deepcopy(humvvex_raw)
    raw["thermal"].update(
        model="twoNode",
        radiation_method="fast",
        radiation_rays=8,
        radiation_resolution=24,
        spin_up_s=600.0,
        surface_spin_up_s=6 * 3600.0,
    )
    raw["atmosphere"]["model"] = "analytic"
    # one small LWIR camera with a flat response over the thermal tool's long-wave band
    raw["sensor"] = [
        {
            "id": SENSOR,
            "band": "LWIR",
            "wavelength_um": list(LONGWAVE_BAND_UM),
            "resolution": [160, 120],
            "focal_length_mm": 6.0,
            "position_m": [0.0, -15.0, 1.6],
            "look_at_m": [0.0, 0.0, 1.6],
        }
    ]
    return validate(raw)


def _user_layer(base: Usd.Stage, path) -> Sdf.Layer:
    """OUT/user.usda: overs on the shirt's fabric and the wall's material, as a user writes them."""
    fabric = bound_material(base.GetPrimAtPath(SHIRT)).GetPath()
    paint = bound_material(base.GetPrimAtPath(WALL)).GetPath()
    eps = np.asarray(base.GetPrimAtPath(paint).GetAttribute(S.MATERIAL_EMISSIVITY).Get(), dtype=float)
    layer = Sdf.Layer.CreateNew(str(path))
    stage = Usd.Stage.Open(layer)
    # a darker shirt is a darker spectrum (the thermal solve takes its solar absorptivity from
    # the spectrum the render uses): reflectance 1 - 0.95 up to 5 um, Kirchhoff's emissivity
    fab = base.GetPrimAtPath(fabric)
    wl = np.asarray(fab.GetAttribute(S.MATERIAL_WAVELENGTHS).Get(), dtype=float)
    rho = np.asarray(fab.GetAttribute(S.MATERIAL_REFLECTANCE).Get(), dtype=float)
    rho = np.where(wl <= 5.0, 1.0 - SHIRT_ABSORPTIVITY, rho)
    over = stage.OverridePrim(fabric)
    over.CreateAttribute(S.MATERIAL_REFLECTANCE, Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray(rho.tolist())
    )
    over.CreateAttribute(S.MATERIAL_EMISSIVITY, Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray((1.0 - rho).tolist())
    )
    over.CreateAttribute(S.MATERIAL_SOLAR_ABSORPTIVITY, Sdf.ValueTypeNames.Float).Set(SHIRT_ABSORPTIVITY)
    stage.OverridePrim(paint).CreateAttribute(S.MATERIAL_EMISSIVITY, Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray((WALL_EMISSIVITY_SCALE * eps).tolist())
    )
    layer.Save()
    return layer


def _edited_stage(out, scenario) -> str:
    """OUT/edited.usda: the composed layers, the thermal layer rebuilt over them with the user
    layer, and the user layer strongest."""
    base = Sdf.Layer.FindOrOpen(str(out / "stage.usda"))
    subs = [s for s in base.subLayerPaths if not s.endswith("/thermal.usda")]  # strongest first
    upstream = [Sdf.Layer.FindOrOpen(str(out / s)) for s in reversed(subs)]  # weakest first
    user = _user_layer(Usd.Stage.Open(str(out / "stage.usda")), out / "user.usda")
    thermal = thermal_layer.build(scenario, compose_in_memory([*upstream, user], scenario["general"]["fps"]))
    (out / LAYER_DIR / "thermal_edited.usda").write_text(layer_text(thermal))
    base.Export(str(out / "edited.usda"))
    edited = Sdf.Layer.FindOrOpen(str(out / "edited.usda"))
    edited.subLayerPaths = ["./user.usda", f"./{LAYER_DIR}/thermal_edited.usda", *subs]
    edited.Save()
    return str(out / "edited.usda")


def _render(stage_path, out_dir) -> dict:
    render_stage(stage_path, out_dir, spp=4, sensors=[SENSOR])
    ch = images.read_exr(out_dir / SENSOR / "0000.exr")  # by logical name
    return {n: np.asarray(v).astype(np.float32) for n, v in ch.items()}


@pytest.fixture(scope="module")
def runs(tmp_path_factory, humvvex_raw):
    out = tmp_path_factory.mktemp("edits")
    scenario = _scenario(humvvex_raw)
    compose(scenario, out)
    edited = _edited_stage(out, scenario)
    stages = {"base": out / "stage.usda", "edited": edited}
    return {
        k: (Usd.Stage.Open(str(p)), _render(p, out / f"render_{k}"), StageExport(Usd.Stage.Open(str(p))))
        for k, p in stages.items()
    }


def _temperatures(stage, path):
    return np.asarray(stage.GetPrimAtPath(path).GetAttribute(S.TEMPERATURE_PRIMVAR).Get(0), dtype=float)


def test_the_user_layer_reaches_the_thermal_tool_and_the_render(runs):
    (base, img0, _), (edited, img1, _) = runs["base"], runs["edited"]
    # what every tool reads: the override wins over the materials layer
    assert mesh_material(edited.GetPrimAtPath(SHIRT)).solar_absorptivity == pytest.approx(SHIRT_ABSORPTIVITY)
    assert mesh_material(base.GetPrimAtPath(SHIRT)).solar_absorptivity == pytest.approx(
        LIBRARY["cotton_white"].spectral_solar_absorptivity, abs=1e-6
    )  # the white shirt's spectrum: 0.30
    eps0, eps1 = (longwave_emissivity(mesh_material(s.GetPrimAtPath(WALL))) for s in (base, edited))
    assert eps1 == pytest.approx(WALL_EMISSIVITY_SCALE * eps0, rel=1e-6)
    # thermal: the darker shirt warms in the afternoon sun; the shiny siding, which loses
    # less long wave to the sky, warms where the sun shines on it
    shirt0, shirt1 = _temperatures(base, SHIRT), _temperatures(edited, SHIRT)
    assert shirt1.mean() > shirt0.mean() + 1.0
    wall0, wall1 = _temperatures(base, WALL), _temperatures(edited, WALL)
    assert wall1.max() > wall0.max() + 1.0
    # render: same pixels, same noise (same seed): the wall's emissivity label follows the
    # edit and its radiance changes; the shirt's pixels are brighter
    ids0, ids1 = img0["instance_id"], img1["instance_id"]
    assert np.array_equal(ids0, ids1)
    wall = ids0 == 3
    assert wall.sum() > 500
    np.testing.assert_allclose(
        img1["emissivity"][wall], WALL_EMISSIVITY_SCALE * img0["emissivity"][wall], rtol=1e-5
    )
    assert (
        np.abs(img1["radiance"][wall] - img0["radiance"][wall]).mean() > 0.05 * img0["radiance"][wall].mean()
    )
    person = ids0 == 1
    fabric = person & np.isclose(
        img0["emissivity"], longwave_emissivity(mesh_material(base.GetPrimAtPath(SHIRT)))
    )
    assert fabric.sum() > 50
    assert img1["brightness_temperature"][fabric].mean() > img0["brightness_temperature"][fabric].mean() + 0.5


def test_thermal_and_render_use_one_band_emissivity(runs):
    """Kirchhoff: for the sensor's band (the thermal tool's 8-14 um, flat response) the render's
    band emissivity of every material is the number the thermal solve uses, and the render's
    per-pixel emissivity label carries it."""
    for name in ("base", "edited"):
        stage, img, exporter = runs[name]
        [sensor] = [s for s in exporter.sensors if s.name == SENSOR]
        assert tuple(sensor.wavelength_range_um) == LONGWAVE_BAND_UM and sensor.band_response is None
        for path in (SHIRT, WALL, "/World/Humans/p1/Body", "/World/Scene/Ground"):
            prim = stage.GetPrimAtPath(path)
            thermal_eps = longwave_emissivity(mesh_material(prim))  # what the thermal solve uses
            render_material = exporter.meshes.bound_material(
                prim, path, Usd.TimeCode(0)
            )  # what the render reads
            assert _band_emissivity({}, render_material, sensor) == thermal_eps  # same function, same number
            assert (
                read_material(bound_material(prim)).solar_absorptivity == render_material.solar_absorptivity
            )
        wall = img["instance_id"] == 3
        expected = longwave_emissivity(mesh_material(stage.GetPrimAtPath(WALL)))
        np.testing.assert_allclose(img["emissivity"][wall], expected, rtol=1e-6)
