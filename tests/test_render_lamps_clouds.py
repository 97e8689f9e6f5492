"""Cloud shadows on the render's sun (issue 30.4): broken clouds (``[atmosphere] cloud_size_m``,
:mod:`humv_usd.physics.clouds`) take the direct sun off the points under them, as the thermal
tool does on the faces.

Closed forms: a white Lambertian plate under a uniform sky of radiance L and a sun of beam
irradiance E at zenith angle theta has radiance L + E cos(theta) / pi where the sun reaches it
and L (the diffuse sky only) in a cloud's shadow; between the clouds the beam is the clear-sky
one, the layer's mean over Kasten & Czeplak's DNI / DNI_clear.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Usd
from test_render import add_camera
from test_render_eo import reflective
from test_render_radiometry import atmosphere_tables, new_stage, plate, read_exr, sun

from humv_usd.physics import clouds
from humv_usd.physics.sun import cloud_dni_factor
from humv_usd.pipeline.render import render_stage
from humv_usd.render.light import cloud_shadows
from humv_usd.usd import environment as usd_environment
from humv_usd.usd import schemas as S

W, H = 40, 30


def _cloudy(stage, size_m=400.0, cover=0.5, wind_m_s=0.0, wind_from_deg=270.0, seed=11):
    env = usd_environment.define_environment(stage)
    usd_environment.write_site(
        stage,
        usd_environment.Site("t", "", "2024-06-21T12:00:00+00:00", "UTC", 45.0, 0.0, 0.0, seed),
    )
    usd_environment.write_cloud_size(env, size_m)
    env.GetAttribute(S.ENVIRONMENT_CLOUD_COVER).Set(float(cover))
    env.GetAttribute(S.ENVIRONMENT_WIND_SPEED).Set(float(wind_m_s))
    env.GetAttribute(S.ENVIRONMENT_WIND_DIRECTION).Set(float(wind_from_deg))


def test_the_renders_clouds_are_the_thermal_tools_field(tmp_path):
    """The frame's field is physics.clouds' of the seed and size, thresholded at the cover, moved
    by the cloud-level wind (1/7 power law to 1 km) over the frames since frame 0 toward the
    opposite of the wind's direction; the beam between clouds is 1 / (DNI / DNI_clear)."""
    stage = new_stage(tmp_path / "s.usda")
    stage.SetTimeCodesPerSecond(2.0)
    _cloudy(stage, size_m=300.0, cover=0.4, wind_m_s=5.0, wind_from_deg=270.0, seed=3)
    shadows = cloud_shadows(stage, Usd.TimeCode(10.0))
    v = 5.0 * (1000.0 / 10.0) ** (1.0 / 7.0)
    np.testing.assert_allclose(shadows.displacement, [v * 5.0, 0.0], atol=1e-6)  # 5 s east
    x, y = np.meshgrid(np.linspace(-500, 500, 41), np.linspace(-300, 300, 25))
    expected = clouds.cloud_shadow(clouds.cloud_field(3, 300.0), x, y, [[v * 5.0, 0.0]], 0.4)[0]
    got = shadows.sunlit(x, y)
    np.testing.assert_array_equal(got.ravel(), expected)
    assert 0.05 < got.mean() < 0.95  # shadows and gaps both there
    assert shadows.clear_factor == pytest.approx(1.0 / float(cloud_dni_factor(0.4)), rel=1e-6)
    # no clouds without a size, or under a full cover
    _cloudy(stage, size_m=0.0)
    assert cloud_shadows(stage, Usd.TimeCode(0.0)) is None
    _cloudy(stage, size_m=300.0, cover=1.0)
    assert cloud_shadows(stage, Usd.TimeCode(0.0)) is None


def test_a_pixel_in_a_cloud_shadow_gets_the_diffuse_sky_only(tmp_path):
    """A white plate seen from 800 m up (a 580 x 435 m view) under 400 m clouds covering half
    the sky: each pixel whose footprint the field puts wholly in shadow (its neighbours' too,
    sampled at 8 x 8 points each) has the sky's radiance L, each wholly between clouds
    L + E_clear cos(theta) / pi; mixed pixels lie in between by their sunlit share."""
    stage = new_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 3.0], [1.0, 1.0])
    plate(stage, "/World/p", 1e4, 0.0, white, 300.0)
    add_camera(
        stage,
        "eo",
        (0, 0, 800),
        (0, 0, 0),
        fov_x_deg=40.0,
        resolution=(W, H),
        band=(0.4, 0.7),
        band_token="EO",
        up=(0, 1, 0),
    )
    sky_um, sun_um = 100.0, 1500.0  # W m-2 sr-1 um-1, W m-2 um-1: flat
    atmosphere_tables(
        stage, [0.3, 0.9, 4.0], sky=np.full((2, 3), sky_um), zenith=np.array([0.0, 90.0]), solar=[sun_um] * 3
    )
    th = math.radians(30.0)
    sun(stage, (math.sin(th), 0.0, math.cos(th)))
    _cloudy(stage, size_m=400.0, cover=0.5)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    frame = manifest["eo_sensors"][0]["frames"][0]
    assert "broken clouds" in frame["illumination"]["cloud_shadows"]
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    y = ch["Y"]
    shadows = cloud_shadows(Usd.Stage.Open(str(tmp_path / "s.usda")), Usd.TimeCode(0.0))
    # pixel footprints on the plate: the camera looks down -z with +y up, so +x to the right
    half_x = 800.0 * math.tan(math.radians(20.0))
    half_y = half_x * H / W
    sub = (np.arange(8) + 0.5) / 8
    u = ((np.arange(W)[:, None] + sub[None, :]).ravel() / W * 2 - 1) * half_x
    v = (1 - (np.arange(H)[:, None] + sub[None, :]).ravel() / H * 2) * half_y
    lit = shadows.sunlit(u[None, :], v[:, None]).reshape(H, 8, W, 8).mean(axis=(1, 3))
    diffuse = sky_um / 1000.0  # Y of a flat spectral radiance is that radiance [W m-2 sr-1 nm-1]
    direct = sun_um / 1000.0 * shadows.clear_factor * math.cos(th) / math.pi

    # wholly: the pixel and its 8 neighbours (a sliver of sun between samples stays out)
    def wholly(mask):
        out = mask.copy()
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                out[max(dy, 0) : H + min(dy, 0), max(dx, 0) : W + min(dx, 0)] &= mask[
                    max(-dy, 0) : H + min(-dy, 0), max(-dx, 0) : W + min(-dx, 0)
                ]
        return out

    dark, clear = wholly(lit == 0.0), wholly(lit == 1.0)
    assert dark.sum() > 0.2 * lit.size and clear.sum() > 0.2 * lit.size
    np.testing.assert_allclose(y[dark], diffuse, rtol=3e-3)
    np.testing.assert_allclose(y[clear], diffuse + direct, rtol=3e-3)
    # mixed pixels lie in between, in proportion to their sunlit share
    mixed = (lit > 0.0) & (lit < 1.0)
    np.testing.assert_allclose(y[mixed], diffuse + direct * lit[mixed], atol=0.25 * direct)
