"""Artificial lights (issue 24.4): lamp spectra, their USD form, and a lamp-lit street rendered.

References: colour-science's CCT (Ohno 2013) for the white lamps' colour temperature; the
inverse-square law E = I cos(theta) / d^2 and the Lambertian plate L = rho E / pi for a lamp;
the view factor of a parallel rectangle (Siegel & Howell, Thermal Radiation Heat Transfer, 4th
ed., 2002, app. C) for a lit window.
"""

from __future__ import annotations

import math

import colour
import numpy as np
import pytest
from pxr import Gf, UsdGeom
from test_render_eo import eo_camera, reflective
from test_render_radiometry import atmosphere_tables, new_stage, plate, read_exr, sun

from humv_usd.catalog.lights import LAMPS, NOMINAL_CCT_K
from humv_usd.errors import InputError
from humv_usd.pipeline.render import render_stage
from humv_usd.usd import lights as usd_lights

Y_TO_CD = 683.0 * 106.856895  # luminance [cd m-2] of the render's Y


@pytest.mark.parametrize("name", sorted(NOMINAL_CCT_K))
def test_white_lamps_have_their_colour_temperature(name):
    wl = np.arange(360.0, 831.0, 1.0)
    sd = colour.SpectralDistribution(dict(zip(wl, LAMPS[name].spd(wl / 1000.0))))
    cct, duv = colour.temperature.XYZ_to_CCT_Ohno2013(colour.sd_to_XYZ(sd))
    assert cct == pytest.approx(NOMINAL_CCT_K[name], rel=0.01) and abs(duv) < 0.005


def test_sodium_lamp_is_self_reversed_and_has_its_nir_lines():
    s = LAMPS["hps"].spd(np.array([0.568, 0.589, 0.615, 0.819, 1.138, 0.45, 1.6]))
    assert s[1] < s[0] and s[1] < s[2]  # the absorbed D-line core
    assert s[3] > 0.2 and s[4] > 0.05 and s[5] < 0.01 and s[6] < 1e-3
    # white LEDs are dark in the SWIR, a filament is not
    assert LAMPS["led_4000k"].spd(1.2) < 1e-6 < LAMPS["halogen"].spd(1.2)


def test_lamp_on_a_moving_parent_reads_back_in_world_space(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    pole = UsdGeom.Xform.Define(stage, "/World/Scene/pole")
    op = pole.AddTranslateOp()
    op.Set(Gf.Vec3d(2.0, 3.0, 0.0), 0.0)
    op.Set(Gf.Vec3d(4.0, 3.0, 0.0), 10.0)
    usd_lights.write_lamp(
        stage, "/World/Scene/pole/head", "led_4000k", 5000.0, (0.0, 0.0, 6.0), cone_angle_deg=70.0
    )
    [lamp] = usd_lights.read_lamps(stage, 5.0)
    np.testing.assert_allclose(lamp.position, [3.0, 3.0, 6.0], atol=1e-9)
    np.testing.assert_allclose(lamp.direction, [0.0, 0.0, -1.0], atol=1e-9)
    assert lamp.cone_angle_deg == pytest.approx(70.0) and lamp.luminous_flux_lm == 5000.0
    stage.GetPrimAtPath("/World/Scene/pole/head").GetAttribute(usd_lights.SPECTRUM).Set("neon")
    with pytest.raises(InputError, match=r"humv:light:spectrum = 'neon': allowed: incandescent"):
        usd_lights.read_lamps(stage, 0.0)


def _night_street(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 3.0], [1.0, 1.0])
    plate(stage, "/World/p", 1e3, 0.0, white, 280.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=4.0)
    atmosphere_tables(
        stage, [0.3, 0.9, 4.0], sky=np.zeros((2, 3)), zenith=np.array([0.0, 90.0]), solar=[0.0] * 3
    )
    h = math.radians(-40.0)
    sun(stage, (math.cos(h), 0.0, math.sin(h)))
    return stage


@pytest.mark.parametrize("cone", [None, 60.0])
def test_lamp_lit_street_is_the_inverse_square_law(tmp_path, cone):
    """A 1000 lm lamp 4 m above a white plate at night: under the lamp E = I / h^2 with
    I = flux / 4 pi (a bare lamp) or flux / (2 pi (1 - cos 60 deg)) (a 60 deg cone), and the
    plate's luminance E / pi; the frame is rendered by the fast estimator."""
    stage = _night_street(tmp_path)
    usd_lights.write_lamp(
        stage, "/World/Scene/lamp", "led_4000k", 1000.0, (0.0, 0.0, 4.0), cone_angle_deg=cone
    )
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=16)
    [eo] = manifest["eo_sensors"]
    assert eo["estimator"] == "fast"  # the lamps by next-event estimation (render.estimator)
    assert "led_4000k" in eo["frames"][0]["illumination"]["lamps"]
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    solid = 4 * math.pi if cone is None else 2 * math.pi * (1 - math.cos(math.radians(cone)))
    # the view is 0.7 m wide: every pixel within 0.5 m of the foot, cos^3 falloff >= 0.988
    x = (np.arange(ch["Y"].shape[1]) + 0.5) / ch["Y"].shape[1] * 2 - 1
    y = (np.arange(ch["Y"].shape[0]) + 0.5) / ch["Y"].shape[0] * 2 - 1
    half = 10.0 * math.tan(math.radians(2.0))
    r2 = (x[None, :] * half) ** 2 + (y[:, None] * half * ch["Y"].shape[0] / ch["Y"].shape[1]) ** 2
    expected = (1000.0 / solid) * 4.0 / (16.0 + r2) ** 1.5 / math.pi  # cd m-2
    # 2e-3: Mitsuba's colour-matching tables against the CIE 5-nm y-bar
    assert (ch["Y"] * Y_TO_CD).mean() == pytest.approx(expected.mean(), rel=5e-3)
    assert ch["R"].mean() > 0 and ch["B"].mean() > 0  # white light renders white, not one channel


def test_lit_window_is_the_view_factor_of_a_rectangle(tmp_path):
    """A 2 x 2 m window of luminance L = 100 cd m-2 facing down 1 m above a white plate: under
    its centre E = pi L F with F four corner view factors of 1 x 1 m rectangles at 1 m,
    F_corner = [X/sqrt(1+X^2) atan(Y/sqrt(1+X^2)) + Y/sqrt(1+Y^2) atan(X/sqrt(1+Y^2))] / (2 pi),
    X = Y = 1; the white plate's luminance is E / pi (seen within 0.1 m of that point: < 1 %
    off the centre value)."""
    stage = _night_street(tmp_path)
    window = usd_lights.write_window(stage, "/World/Scene/window", "incandescent", 100.0, 2.0, 2.0)
    UsdGeom.Xformable(window).AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 1.0))
    stage.RemovePrim("/World/Sensors/eo")  # looking from under the window's edge (its back is black)
    eo_camera(stage, "eo", (0.0, -2.5, 0.9), (0.0, 0.0, 0.0), fov_x_deg=1.5, up=(0, 0, 1))
    stage.GetPrimAtPath("/World/Sensors/eo").GetAttribute("humv:sensor:resolution").Set(Gf.Vec2i(8, 6))
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=64)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    a = 1.0 / math.sqrt(2.0)
    f = 4 * (2 * a * math.atan(a)) / (2 * math.pi)
    expected = math.pi * 100.0 * f / math.pi
    assert (ch["Y"] * Y_TO_CD).mean() == pytest.approx(expected, rel=0.02)
