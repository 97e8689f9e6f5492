"""Puddles as calm-water mirrors in the fast estimator (issue 30.4): a camera ray on water
(material ``water``, :mod:`humv_usd.scene.puddles`) sees (1 - R) B(T) + R L(mirror direction),
R water's Fresnel reflectance at the incidence angle (Hale & Querry's index, Born & Wolf).

Closed forms: under a uniform sky of radiance L a cold (visible: non-emitting) mirror has radiance
R(theta) L; in an isothermal enclosure (sky, water and walls at one temperature) everything,
mirror pixels included, is the blackbody radiance (Kirchhoff: emissivity 1 - R, reflectance R).
"""

from __future__ import annotations

import math

import numpy as np
from test_render import add_camera, add_material, add_mesh, box, rect_z
from test_render_eo import reflective
from test_render_radiometry import atmosphere_tables, new_stage, read_exr, sun

from humv_usd.compat import trapezoid
from humv_usd.physics import planck, water_film
from humv_usd.pipeline.render import render_stage
from humv_usd.render.cie import CMF_WAVELENGTHS_NM, CMF_XYZ

LWIR = (8.0, 14.0)


def _view(theta_deg, distance=10.0):
    """A camera at zenith angle theta_deg looking at the origin from ``distance``."""
    t = math.radians(theta_deg)
    return (0.0, -distance * math.sin(t), distance * math.cos(t))


def test_a_puddle_under_a_uniform_sky_is_fresnel_times_the_sky(tmp_path):
    """Visible: water seen at 75 deg from the zenith (a pedestrian's view of a puddle a few
    metres away) under a uniform sky of radiance L has Y = R_Y(75 deg) L, R_Y the y-bar
    weighted Fresnel reflectance (0.21 here against the 0.02 of a Lambertian water table)."""
    stage = new_stage(tmp_path / "s.usda")
    water = reflective(stage, "water", [0.3, 3.0], [0.05, 0.05])
    add_mesh(stage, "/World/Scene/puddle", *rect_z(-50, 50, -50, 50), material=water, instance_id=1)
    add_camera(
        stage,
        "eo",
        _view(75.0),
        (0, 0, 0),
        fov_x_deg=2.0,
        resolution=(8, 6),
        band=(0.4, 0.7),
        band_token="EO",
        up=(0, 0, 1),
    )
    sky_um = 100.0
    atmosphere_tables(
        stage, [0.3, 0.9, 4.0], sky=np.full((2, 3), sky_um), zenith=np.array([0.0, 90.0]), solar=[0.0] * 3
    )
    sun(stage, (0.0, 0.6, 0.8))
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=8)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    ybar = np.asarray(CMF_XYZ, float).reshape(-1, 3)[:, 1]
    wl = CMF_WAVELENGTHS_NM / 1000.0
    r = water_film.fresnel_reflectance(
        math.cos(math.radians(75.0)), water_film.water_refractive_index(np.clip(wl, 0.4, 14))
    )
    r_y = float(np.sum(ybar * r) / np.sum(ybar))
    assert 0.15 < r_y < 0.3
    # the view's rays span 74-76 deg: R varies +-6 % across the image, averages to the centre's
    assert np.mean(ch["Y"]) == np.float32(np.mean(ch["Y"]))
    assert abs(float(np.mean(ch["Y"])) / (r_y * sky_um / 1000.0) - 1) < 0.01


def test_an_isothermal_puddle_scene_is_the_blackbody(tmp_path):
    """LWIR furnace: water, a box and the sky at 300 K: every pixel (the box mirrored in the
    water included) is B(300 K) within 5 standard errors + 1e-4."""
    t = 300.0
    stage = new_stage(tmp_path / "s.usda", sky_k=t)
    water = add_material(stage, "water", 0.98)
    wall = add_material(stage, "wall", 0.6)
    add_mesh(
        stage,
        "/World/Scene/puddle",
        *rect_z(-30, 30, -30, 30),
        material=water,
        temperature_k=t,
        instance_id=1,
    )
    add_mesh(
        stage, "/World/Scene/box", *box((0.0, 4.0, 1.0), 2.0), material=wall, temperature_k=t, instance_id=2
    )
    add_camera(
        stage,
        "cam",
        (0.0, -6.0, 1.0),
        (0.0, 2.0, 0.0),
        fov_x_deg=40.0,
        resolution=(24, 18),
        band=LWIR,
        band_token="LWIR",
    )
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    b = planck.band_radiance(t, LWIR)
    err = ch["radiance_stderr"]
    assert (ch["instance_id"] == 1).sum() > 50  # the water fills the lower image
    assert np.all(np.abs(ch["radiance"] - b) <= 5 * np.nan_to_num(err, nan=0.0) + 1e-4 * b)


def test_a_warm_puddle_mirrors_a_cold_sky_in_lwir(tmp_path):
    """LWIR: water at 290 K under a uniform 250 K sky seen at 80 deg from the zenith (a puddle
    along the street): L = int_band (1 - R) B(290) + R B(250) within 0.5 % (R about 0.35 there:
    the grazing puddle looks 11 K colder than the 0.98-emissivity table said)."""
    stage = new_stage(tmp_path / "s.usda", sky_k=250.0)
    water = add_material(stage, "water", 0.98)
    add_mesh(
        stage,
        "/World/Scene/puddle",
        *rect_z(-200, 200, -200, 200),
        material=water,
        temperature_k=290.0,
        instance_id=1,
    )
    add_camera(
        stage,
        "cam",
        _view(80.0),
        (0, 0, 0),
        fov_x_deg=1.0,
        resolution=(8, 6),
        band=LWIR,
        band_token="LWIR",
        up=(0, 0, 1),
    )
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    wl = np.linspace(*LWIR, 2001)
    r = water_film.fresnel_reflectance(math.cos(math.radians(80.0)), water_film.water_refractive_index(wl))
    expected = float(
        trapezoid((1 - r) * planck.spectral_radiance(wl, 290.0) + r * planck.spectral_radiance(wl, 250.0), wl)
    )
    lambertian = float(
        trapezoid(0.98 * planck.spectral_radiance(wl, 290.0) + 0.02 * planck.spectral_radiance(wl, 250.0), wl)
    )
    assert expected < 0.9 * lambertian  # the mirror is what the test is about
    assert abs(float(np.mean(ch["radiance"])) / expected - 1) < 5e-3
