"""The dome light's sky texture (issue 27.4): a lat-long image of the atmosphere layer's visible
sky, written beside the layer at compose and referenced from the dome by a relative path, its
luminance normalised so that the dome keeps the environment layer's photometric scale."""

from __future__ import annotations

import datetime as dt
import os

import numpy as np
import OpenImageIO as oiio
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from humv_usd.atmosphere import layer as atmosphere_layer
from humv_usd.atmosphere.texture import hemisphere_luminance, row_zenith_deg, sky_texture
from humv_usd.physics.cie import XYZ_TO_SRGB
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.usd import atmosphere as A
from humv_usd.usd import environment as E
from humv_usd.usd import schemas as S

WL = np.linspace(0.36, 0.83, 48)
ZEN = np.array([0.0, 30.0, 60.0, 75.0, 90.0])


def test_an_equal_energy_sky_has_the_white_point_of_illuminant_e():
    # the CIE 1931 functions have equal areas (illuminant E: x = y = z = 1/3, CIE 015:2018), so
    # a flat spectrum's linear sRGB is the row sums of the sRGB matrix, whatever the table's scale
    tex, how = sky_texture(ZEN, WL, np.full((ZEN.size, WL.size), 7.0))
    rgb = tex[0, 0] / tex[0, 0, 1]
    row_sums = np.array([3.2406 - 1.5372 - 0.4986, -0.9689 + 1.8758 + 0.0415, 0.0557 - 0.2040 + 1.0570])
    assert_allclose(rgb, row_sums / row_sums[1], rtol=5e-3)
    assert_allclose(XYZ_TO_SRGB.sum(axis=1), row_sums, atol=1e-12)  # the matrix is IEC 61966-2-1's
    assert tex.shape == (64, 128, 3) and tex.dtype == np.float32 and "CIE 1931" in how


def test_zenith_to_horizon_ratio_follows_the_table_and_the_mean_luminance_is_one():
    # radiance (1 + z / 45) x a flat spectrum: the luminance grows 3x from zenith to horizon,
    # linear in zenith between table rows, held below the horizon
    rad = (1.0 + ZEN / 45.0)[:, None] * np.ones(WL.size)[None, :]
    tex, _ = sky_texture(ZEN, WL, rad)
    lum = tex[:, 0, :] @ np.array([0.2126, 0.7152, 0.0722])
    z = np.minimum(row_zenith_deg(), 90.0)
    assert_allclose(lum / lum[0], (1.0 + z / 45.0) / (1.0 + z[0] / 45.0), rtol=1e-5)
    assert_allclose(lum[-1], lum[tex.shape[0] // 2], rtol=1e-6)  # below the horizon: the horizon's
    assert hemisphere_luminance(tex) == pytest.approx(1.0, rel=1e-6)
    # the closed form of the mean: 2 int_0^pi/2 (1 + z/45) cos z sin z dz / norm, with
    # int_0^pi/2 z sin 2z dz = pi/4 (z in radians, 1/45 deg = 4/pi rad^-1)
    mean_raw = 1.0 + (4.0 / np.pi) * (np.pi / 4.0)  # = 2
    top = (1.0 + z[0] / 45.0) / mean_raw
    assert lum[0] == pytest.approx(top, rel=2e-3)  # the rows' band weights vs the integral


def test_uniform_neutral_without_a_visible_sky():
    lwir = np.linspace(7.5, 14.0, 20)
    tex, how = sky_texture(ZEN, lwir, np.ones((ZEN.size, lwir.size)))
    assert (tex == 1.0).all() and "no visible spectrum" in how
    tex, how = sky_texture(ZEN, WL, np.zeros((ZEN.size, WL.size)))
    assert (tex == 1.0).all() and "dark" in how
    assert (sky_texture(None, None, None)[0] == 1.0).all()
    assert hemisphere_luminance(tex) == pytest.approx(1.0, rel=1e-12)  # the band weights sum to 1


RAW = {
    "general": {
        "name": "sky",
        "start": dt.datetime(2026, 6, 21, 12, 0),
        "utc_offset_h": 2.0,
        "latitude_deg": 52.37,
        "longitude_deg": 4.90,
        "fps": 1.0,
    },
    "sensor": [
        {
            "id": "eo",
            "preset": "rgb_imx273",
            "position_m": [0.0, -8.0, 1.6],
            "look_at_m": [0.0, 6.0, 1.0],
            "resolution": [32, 24],
        }
    ],
}


@pytest.fixture(scope="module")
def stage_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sky") / "c"
    compose(validate(RAW), out)
    return out


def test_compose_writes_the_texture_and_the_dome_points_at_it(stage_dir):
    stage = Usd.Stage.Open(str(stage_dir / "stage.usda"))
    dome = UsdLux.DomeLight(stage.GetPrimAtPath(str(E.SKY_LIGHT_PATH)))
    asset = dome.GetTextureFileAttr().Get()
    assert asset.path == f"./{atmosphere_layer.SKY_TEXTURE}"  # relative: the folder can move
    assert os.path.samefile(asset.resolvedPath, stage_dir / "layers" / atmosphere_layer.SKY_TEXTURE)
    assert dome.GetTextureFormatAttr().Get() == "latlong"
    # the dome's pole (+Y, OpenEXR's lat-long layout) turned to the stage's up axis (+Z)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    m = UsdGeom.Xformable(dome).ComputeLocalToWorldTransform(0)
    assert_allclose(m.TransformDir(Gf.Vec3d(0, 1, 0)), (0, 0, 1), atol=1e-12)
    tex = oiio.ImageBuf(asset.resolvedPath).get_pixels(oiio.FLOAT)
    assert tex.shape == (64, 128, 3)
    # the photometric scale stays the environment's: pi x intensity x mean luminance = E_d
    env = stage.GetPrimAtPath(str(E.ENVIRONMENT_PATH))
    dhi = env.GetAttribute(S.ENVIRONMENT_DIFFUSE_HORIZONTAL_IRRADIANCE).Get(0)
    e_d = np.pi * dome.GetIntensityAttr().Get(0) * hemisphere_luminance(tex)
    assert e_d == pytest.approx(dhi * E.DIFFUSE_EFFICACY_LM_W, rel=1e-5)
    # zenith/horizon as the atmosphere layer's visible sky (SPCTRL2's isotropic diffuse light)
    spectra = A.atmosphere_spectra(stage, 0.0)
    vis = (spectra.wavelengths_um > 0.38) & (spectra.wavelengths_um < 0.78)
    table = spectra.sky_radiance[:, vis].mean(axis=1)
    lum = tex[:, 0, :] @ np.array([0.2126, 0.7152, 0.0722])
    assert_allclose(lum[0] / lum[tex.shape[0] // 2 - 1], table[0] / table[-1], rtol=1e-4)
    assert tex[0, 0, 2] > tex[0, 0, 1] > tex[0, 0, 0]  # a clear day's diffuse skylight is blue


def test_an_unchanged_compose_rewrites_no_texture(stage_dir):
    path = stage_dir / "layers" / atmosphere_layer.SKY_TEXTURE
    before = path.stat().st_mtime_ns
    ran = Sdf.Layer.FindOrOpen(str(stage_dir / "layers" / "atmosphere.usda")).customLayerData
    assert ran["humv:atmosphere:ran"]["sky texture"].startswith(atmosphere_layer.SKY_TEXTURE)
    assert compose(validate(RAW), stage_dir).written == []
    assert path.stat().st_mtime_ns == before
