"""EO (visible) render: Mitsuba spectral variant, reflectance spectra, sun and sky, colour.

Closed form: a white Lambertian plate under a sun beam of spectral irradiance E at incidence
theta has radiance E rho cos(theta) / pi; Mitsuba's XYZ film gives Y = that radiance per nm for a
flat spectrum. Colour: linear sRGB must be colour-science's XYZ_to_sRGB of the XYZ channels.
"""

from __future__ import annotations

import colour
import numpy as np
import OpenImageIO as oiio
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, UsdGeom
from test_render_radiometry import H, W, atmosphere_tables, farr, material, new_stage, plate, read_exr, sun

from humv_usd.pipeline.render import render_stage
from humv_usd.render.eo import EO_WAVELENGTHS_NM, reflectance_spectrum
from humv_usd.render.scene_export import Material


def eo_camera(stage, name, eye, target, fov_x_deg=20.0, up=(0, 1, 0)):
    cam = UsdGeom.Camera.Define(stage, f"/World/Sensors/{name}")
    view = Gf.Matrix4d().SetLookAt(Gf.Vec3d(*eye), Gf.Vec3d(*target), Gf.Vec3d(*up))
    cam.AddTransformOp().Set(view.GetInverse())
    h_ap = 2 * 0.25 * np.tan(np.radians(fov_x_deg) / 2)
    cam.CreateFocalLengthAttr(0.25)
    cam.CreateHorizontalApertureAttr(float(h_ap))
    cam.CreateVerticalApertureAttr(float(h_ap * H / W))
    p = cam.GetPrim()
    p.CreateAttribute("humv:sensor:band", Sdf.ValueTypeNames.Token).Set("EO")
    p.CreateAttribute("humv:sensor:wavelengthRange", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(0.4, 0.7))
    p.CreateAttribute("humv:sensor:resolution", Sdf.ValueTypeNames.Int2).Set(Gf.Vec2i(W, H))
    return cam


def reflective(stage, name, wavelengths, reflectance):
    m = material(stage, name, 1.0 - np.asarray(reflectance, float), wavelengths=wavelengths)
    farr(m.GetPrim(), "humv:material:reflectance", reflectance)
    return m


def test_reflectance_spectrum_sampling():
    m = Material("/m", np.array([0.4, 0.5, 0.7]), np.array([0.9, 0.5, 0.1]), np.array([0.1, 0.5, 0.9]))
    rho = reflectance_spectrum(m)
    assert_allclose(rho[EO_WAVELENGTHS_NM == 450.0], 0.3)
    assert_allclose(rho[EO_WAVELENGTHS_NM == 360.0], 0.1)  # held below the table
    assert_allclose(rho[EO_WAVELENGTHS_NM == 800.0], 0.9)  # and above


@pytest.mark.parametrize("estimator", ["fast", "path"])
@pytest.mark.parametrize("zenith_deg", [0.0, 50.0])
def test_white_plate_under_sun_closed_form(tmp_path, zenith_deg, estimator):
    e_um = 1500.0  # W m-2 um-1, flat
    stage = new_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 1.0], [1.0, 1.0])
    plate(stage, "/World/p", 1e3, 0.0, white, 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    atmosphere_tables(stage, [0.3, 0.9, 4.0], solar=[e_um, e_um, e_um])
    th = np.radians(zenith_deg)
    sun(stage, (np.sin(th), 0.0, np.cos(th)))
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=32, estimator=estimator)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    expected = e_um / 1000.0 * np.cos(th) / np.pi  # W m-2 sr-1 nm-1
    sigma = np.sqrt(np.mean(ch["Y_stderr"] ** 2) / ch["Y"].size)
    # 2e-3: Mitsuba's own colour-matching tables integrate a flat spectrum to Y = 1.0012
    assert abs(ch["Y"].mean() - expected) < 4 * sigma + 2e-3 * expected
    assert sigma < 3e-3 * expected
    xyz = np.stack([ch["X"], ch["Y"], ch["Z"]], axis=-1)
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    assert_allclose(
        rgb, colour.XYZ_to_sRGB(xyz.astype(float), apply_cctf_encoding=False), rtol=1e-4, atol=1e-6
    )
    # flat spectrum: X, Y and Z agree to the CIE integrals (equal-energy white)
    assert_allclose(ch["X"].mean() / ch["Y"].mean(), 1.0, atol=2e-3)
    [eo] = manifest["eo_sensors"]
    assert eo["frames"][0]["illumination"]["sun"].startswith("directional")
    # EO gets the same ground truth as IR: labels at pixel centres, the plate fills the view
    assert (ch["material_kind"] == 4).all() and (ch["instance_id"] > 0).all()
    assert_allclose(ch["surface_temperature"], 300.0, rtol=1e-6)
    assert_allclose(ch["normal_z"], 1.0, atol=1e-6)
    assert (tmp_path / "out" / "eo" / "0000.instance.png").is_file()
    assert (tmp_path / "out" / "coco.json").is_file()
    png = oiio.ImageInput.open(str(tmp_path / "out" / "eo" / "0000.png"))
    assert png.spec().nchannels == 3 and str(png.spec().format) == "uint8"
    png.close()


@pytest.mark.parametrize("estimator", ["fast", "path"])
def test_colour_follows_reflectance_and_sky(tmp_path, estimator):
    """A red plate (reflective above 600 nm) lit by the sky only is red in sRGB; its Y is the
    closed form rho_Y * L_sky for a uniform sky over a Lambertian plate."""
    stage = new_stage(tmp_path / "s.usda")
    wl = [0.38, 0.59, 0.61, 0.9]
    red = reflective(stage, "red", wl, [0.05, 0.05, 0.8, 0.8])
    plate(stage, "/World/p", 1e4, 0.0, red, 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    zen = np.array([0.0, 90.0])
    sky = np.full((2, 2), 200.0)  # W m-2 sr-1 um-1, uniform
    atmosphere_tables(stage, [0.3, 1.0], sky=sky, zenith=zen, solar=[1000.0, 1000.0])
    sun(stage, (0.0, 0.3, -1.0))  # the sun is below the horizon; the sky still lights
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=32, estimator=estimator)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    assert ch["R"].mean() > 5 * ch["G"].mean() and ch["R"].mean() > 5 * ch["B"].mean()
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    lam = np.arange(360, 831)
    ybar = cmfs.values[(cmfs.wavelengths >= 360) & (cmfs.wavelengths <= 830), 1]
    rho = np.interp(lam / 1000.0, wl, [0.05, 0.05, 0.8, 0.8])
    rho_y = float((rho * ybar).sum() / ybar.sum())
    assert_allclose(ch["Y"].mean(), rho_y * 0.2, rtol=0.02)
    assert (
        manifest["eo_sensors"][0]["frames"][0]["illumination"]["sun"]
        == "skipped: sun below the horizon (night)"
    )


def test_eo_skipped_without_reflectance_or_light(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 10.0, 0.0, material(stage, "gray", 0.5), 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0))
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=2)
    [skipped] = manifest["skipped_sensors"]
    assert skipped["name"] == "eo" and "no visible illumination" in skipped["reason"]
    atmosphere_tables(stage, [0.3, 1.0], solar=[1000.0, 1000.0])
    sun(stage, (0.0, 0.0, 1.0))
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out2", spp=2)
    [skipped] = manifest["skipped_sensors"]
    assert "/World/Materials/gray has no humv:material:reflectance" in skipped["reason"]
    assert manifest["eo_sensors"] == []


@pytest.mark.slow
def test_eo_only_scenario_composes_and_renders(raw, tmp_path):
    """A scenario whose only sensor is EO (no [atmosphere] section): compose writes the
    atmosphere (sun and skylight spectra, paths; no LOWTRAN, no thermal layer) and the render
    needs no temperatures (regression: it asked for the sky temperature)."""
    from humv_usd.pipeline.compose import compose
    from humv_usd.scenario import validate

    raw["sensor"] = [
        dict(s, resolution=[64, 48], pixel_pitch_um=80.0)
        for s in raw["sensor"]
        if s.get("preset") == "rgb_imx273"
    ]
    assert len(raw["sensor"]) == 1
    raw.pop("atmosphere", None)
    report = compose(validate(raw), tmp_path / "c")
    names = {p.stem for p in (tmp_path / "c" / "layers").glob("*.usda")}
    assert {"atmosphere", "atmosphere_paths"} <= names and "thermal" not in names
    manifest = render_stage(tmp_path / "c" / "stage.usda", tmp_path / "r", spp=4)
    [eo] = manifest["eo_sensors"]
    frame = eo["frames"][0]
    assert frame["illumination"]["sun"].startswith("directional, spectral irradiance")
    assert "skipped" not in frame["illumination"]["sky"]
    assert frame["atmosphere"].startswith("per pixel by range")  # found the atmosphere_paths layer's table
    ch = read_exr(tmp_path / "r" / eo["name"] / "0000.exr")
    person = ch["instance_id"] == 1
    assert person.any() and np.isnan(ch["surface_temperature"][person]).all()
    assert np.isfinite(ch["Y"]).all() and ch["Y"].mean() > 0
    assert any(name == "thermal" for name, _ in report.skipped)
