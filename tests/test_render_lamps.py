"""Lamps in the fast estimator (issue 24.4, 30.3): next-event estimation of point lamps, spots and
lit windows in EO and SWIR, against closed forms and Mitsuba's spectral path tracer.

Closed forms: a Lambertian plate of reflectance rho under an isotropic point lamp of luminous
intensity I at height h has, at horizontal distance r from the lamp's foot, illuminance
E = I cos(theta) / d^2 = I h / (h^2 + r^2)^(3/2) and luminance rho E / pi (inverse-square and
cosine laws); a point the lamp cannot see gets none of it (a box's shadow); in a band the lamp's
light is its spectral intensity integrated with the sensor's response.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux
from test_render import add_camera, add_mesh, box, rect_y, rect_z
from test_render_eo import reflective
from test_render_radiometry import atmosphere_tables, new_stage, plate, read_exr, sun

from humv_usd.compat import trapezoid
from humv_usd.physics import nightsky
from humv_usd.pipeline.render import render_stage
from humv_usd.render import estimator as E
from humv_usd.render import lights
from humv_usd.usd import lights as usd_lights

Y_TO_CD = 683.0 * 106.856895  # luminance [cd m-2] of the render's Y
W, H = 24, 18


def _night(stage):
    """No sun (40 deg below the horizon), no sky table, no site (so no moon): only the natural
    night sky (~2e-4 cd m-2) besides the lamps."""
    atmosphere_tables(
        stage, [0.3, 0.9, 4.0], sky=np.zeros((2, 3)), zenith=np.array([0.0, 90.0]), solar=[0.0] * 3
    )
    h = math.radians(-40.0)
    sun(stage, (math.cos(h), 0.0, math.sin(h)))


def _footprint_mean(fn, eye_h, fov_x_deg, w=W, h=H, sub=16):
    """Per pixel (h, w) mean of fn(x, y) over the pixel's footprint on z = 0 of a camera at
    (0, 0, eye_h) looking straight down (a radially symmetric fn: the image's orientation does
    not matter), on sub x sub points per pixel."""
    half_x = eye_h * math.tan(math.radians(fov_x_deg) / 2)
    half_y = half_x * h / w
    u = (np.arange(w * sub) + 0.5) / (w * sub) * 2 - 1
    v = (np.arange(h * sub) + 0.5) / (h * sub) * 2 - 1
    vals = fn(u[None, :] * half_x, v[:, None] * half_y)
    return vals.reshape(h, sub, w, sub).mean(axis=(1, 3))


def _lamp_stage(tmp_path, spectrum="led_4000k", band=(0.4, 0.7), token="EO", occluder=False):
    stage = new_stage(tmp_path / "s.usda")
    grey = reflective(stage, "grey", [0.3, 3.0], [0.5, 0.5])
    plate(stage, "/World/p", 1e3, 0.0, grey, 280.0)
    if occluder:  # a 0.4 m box halfway up, beside the lamp's foot
        add_mesh(stage, "/World/Scene/box", *box((0.8, 0.0, 0.5), 0.4), material=grey, instance_id=2)
    add_camera(
        stage,
        "cam",
        (0, 0, 3),
        (0, 0, 0),
        fov_x_deg=90.0,
        resolution=(W, H),
        band=band,
        band_token=token,
        up=(0, 1, 0),
    )
    _night(stage)
    usd_lights.write_lamp(stage, "/World/Scene/lamp", spectrum, 2000.0, (0.0, 0.0, 1.0))
    stage.Save()
    return tmp_path / "s.usda"


def test_point_lamp_on_a_plate_is_the_inverse_square_and_cosine_law(tmp_path):
    """Every pixel of a grey plate under a 2000 lm bare lamp 1 m up (illuminance from 159 lx at
    its foot to 2.7 lx in the corners) is rho I h / (h^2 + r^2)^1.5 / pi averaged over its
    footprint, within 4 standard errors plus 0.3 % (the visible bins against the CIE y-bar)."""
    manifest = render_stage(_lamp_stage(tmp_path), tmp_path / "out", spp=8)
    [eo] = manifest["eo_sensors"]
    assert eo["estimator"] == "fast" and "led_4000k" in eo["frames"][0]["illumination"]["lamps"]
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    i_cd = 2000.0 / (4 * math.pi)
    expected = _footprint_mean(
        lambda x, y: 0.5 * i_cd * 1.0 / (1.0 + x**2 + y**2) ** 1.5 / math.pi, 3.0, 90.0
    )
    got, err = ch["Y"] * Y_TO_CD, ch["Y_stderr"] * Y_TO_CD
    assert expected.max() / expected.min() > 30  # the test spans the falloff
    # per pixel, relative: 5 standard errors (at least half the image's RMS one: two replicas'
    # spread is now and then far too small) plus the bins' 0.3 %
    rel, rel_err = got / expected - 1, err / expected
    floor = 0.5 * np.sqrt(np.mean(rel_err**2))
    assert np.all(np.abs(rel) <= 5 * np.maximum(rel_err, floor) + 3e-3), np.max(np.abs(rel))
    # the image: 4 standard errors of its sum plus 0.3 %
    sigma = np.sqrt(np.sum(err**2)) / got.size
    assert abs(got.mean() - expected.mean()) <= 4 * sigma + 3e-3 * expected.mean()


def test_a_box_casts_the_lamps_shadow(tmp_path):
    """A box beside the lamp: plate pixels whose whole footprint lies in its geometric shadow
    (the segment to the lamp crosses the box) get no direct lamp light (the night sky and what
    the box's underside reflects from the lit plate: ~4e-3 cd m-2 at 256 spp, ~1e-4 of the lit
    plate), the rest the closed form."""
    render_stage(_lamp_stage(tmp_path, occluder=True), tmp_path / "out", spp=8)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    lit = ch["Y"] * Y_TO_CD
    ids = ch["instance_id"].astype(int)

    def shadowed(x, y):
        # the segment (x, y, 0) -> (0, 0, 1) at height z is at (x, y) (1 - z); inside the box's
        # x, y span [0.6, 1.0] x [-0.2, 0.2] for some z in [0.3, 0.7]?
        z = np.linspace(0.3, 0.7, 41)[:, None, None]
        px, py = x * (1 - z), y * (1 - z)
        return np.any((px >= 0.6) & (px <= 1.0) & (np.abs(py) <= 0.2), axis=0).astype(float)

    full = _footprint_mean(lambda x, y: shadowed(*np.broadcast_arrays(x, y)), 3.0, 90.0)
    # plate pixels whose footprint is all plate (none of the box seen in front of it)
    near_box = np.zeros_like(ids, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near_box |= np.roll(np.roll(ids == 2, dy, axis=0), dx, axis=1)
    plate_px = (ids == 1) & ~near_box
    dark = plate_px & (full == 1.0)
    assert dark.sum() >= 4
    clear = plate_px & (full == 0.0)
    # no direct lamp light: the night sky (rho x ~2e-4 cd m-2) and the box's underside lit by the
    # plate (~1e-3 of the lit plate at 256 spp; the lamp itself would give ~1): each pixel and
    # their mean under 3e-3 of the lit plate within 5 (4) standard errors (at 8 spp a rare path
    # to the box's underside makes a pixel's value)
    dark_err = ch["Y_stderr"][dark] * Y_TO_CD
    bound = 3e-3 * lit[clear].mean()
    assert np.all(lit[dark] < bound + 5 * dark_err), (lit[dark].max(), bound)
    mean_err = np.sqrt(np.sum(dark_err**2)) / dark_err.size
    assert lit[dark].mean() < bound + 4 * mean_err, (lit[dark].mean(), bound, mean_err)
    i_cd = 2000.0 / (4 * math.pi)
    expected = _footprint_mean(lambda x, y: 0.5 * i_cd / (1.0 + x**2 + y**2) ** 1.5 / math.pi, 3.0, 90.0)
    # lit pixels: the lamp plus light the box reflects back (at most a few %)
    err = ch["Y_stderr"][clear] * Y_TO_CD
    sigma = np.sqrt(np.sum(err**2)) / err.size
    ratio = lit[clear].mean() / expected[clear].mean()
    assert 1 - 3e-3 - 4 * sigma / expected[clear].mean() <= ratio <= 1.03, ratio


@pytest.mark.parametrize("spectrum, lit", [("hps", True), ("led_4000k", False)])
def test_swir_sees_the_sodium_lamps_lines_and_not_the_leds(tmp_path, spectrum, lit):
    """SWIR 0.9-1.7 um (flat response) under a 2000 lm lamp: the plate's radiance is the night
    sky's (OH airglow) plus rho I_band cos(theta) / (pi d^2), I_band the lamp's spectral
    intensity integrated over the band (HPS: its 1138 nm line; a white LED has none)."""
    band = (0.9, 1.7)
    render_stage(_lamp_stage(tmp_path, spectrum, band, "SWIR"), tmp_path / "out", spp=8)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    lamp = usd_lights.read_lamps(Usd.Stage.Open(str(tmp_path / "s.usda")), 0.0)[0]
    full = np.linspace(0.36, 2.5, 4281)  # the photometric scale needs the visible
    i_um = lights.spectral_per_nm(lamp, 2000.0 / (4 * math.pi), full * 1000.0) * 1000.0  # W sr-1 um-1
    x = np.linspace(*band, 8001)
    i_band = float(trapezoid(np.interp(x, full, i_um), x))
    airglow = 0.5 * float(trapezoid(nightsky.night_sky_radiance(x), x))
    expected = _footprint_mean(lambda u, v: 0.5 * i_band / (1.0 + u**2 + v**2) ** 1.5 / math.pi, 3.0, 90.0)
    if lit:
        assert i_band > 1e-3  # the line carries light
        assert ch["radiance"].mean() == pytest.approx(expected.mean() + airglow, rel=0.01)
    else:
        assert i_band < 1e-9
        assert ch["radiance"].mean() == pytest.approx(airglow, rel=0.01)


def _street(tmp_path):
    """A tiny lamp-lit street corner: asphalt-grey ground, a wall with a lit window, a box, a
    soft-edged sodium spot and a bare incandescent lamp."""
    stage = new_stage(tmp_path / "s.usda")
    wl = [0.36, 0.45, 0.55, 0.65, 0.83]
    ground = reflective(stage, "ground", wl, [0.08, 0.1, 0.12, 0.14, 0.2])
    wall = reflective(stage, "wall", wl, [0.3, 0.45, 0.5, 0.55, 0.6])
    blue = reflective(stage, "blue", wl, [0.5, 0.6, 0.3, 0.1, 0.3])
    add_mesh(stage, "/World/Scene/ground", *rect_z(-20, 20, -20, 20), material=ground, instance_id=1)
    add_mesh(stage, "/World/Scene/wall", *rect_y(-6, 6, 0, 5, 3.0), material=wall, instance_id=2)
    add_mesh(stage, "/World/Scene/box", *box((0.5, 1.0, 0.5), 1.0), material=blue, instance_id=3)
    add_camera(
        stage,
        "cam",
        (1.0, -6.0, 2.0),
        (0.0, 1.5, 1.0),
        fov_x_deg=60,
        resolution=(32, 24),
        band=(0.4, 0.7),
        band_token="EO",
    )
    _night(stage)
    spot = usd_lights.write_lamp(
        stage, "/World/Scene/spot", "hps", 8000.0, (-2.0, 0.0, 4.0), (-1.0, 1.0, 0.0), 50.0
    )
    UsdLux.ShapingAPI(spot).CreateShapingConeSoftnessAttr(0.4)
    usd_lights.write_lamp(stage, "/World/Scene/bulb", "incandescent", 1500.0, (2.5, -1.0, 2.5))
    window = usd_lights.write_window(stage, "/World/Scene/window", "led_3000k", 60.0, 1.2, 1.4)
    # width along x, emitting along -y (toward the street), 5 mm in front of the wall
    frame = Gf.Matrix4d(1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 2.0, 2.995, 2.0, 1)
    UsdGeom.Xformable(window).AddTransformOp().Set(frame)
    stage.Save()
    return tmp_path / "s.usda"


@pytest.mark.slow
def test_fast_lamps_agree_with_the_spectral_path_tracer(tmp_path):
    """Per labelled region (and the window's pixels) and channel, the fast estimator's X, Y, Z of
    the lamp-lit street agree with Mitsuba's 5-nm spectral path tracer within 4 combined
    standard errors plus 1 % (2 % for Z; the visible bins against 5 nm, with a sodium lamp's
    lines)."""
    stage = _street(tmp_path)
    render_stage(stage, tmp_path / "ref", spp=1024, estimator="path", seed=1)
    render_stage(stage, tmp_path / "fast", spp=64, estimator="fast", seed=2)
    ref = read_exr(tmp_path / "ref" / "cam" / "0000.exr")
    fast = read_exr(tmp_path / "fast" / "cam" / "0000.exr")
    _compare_regions(ref, fast)


def _compare_regions(ref, fast, allowance=1e-2):
    """{(region, channel): (difference in standard errors, relative difference)}; region 0: the
    window's pixels (background in the path tracer's labels, where its emitter shape is no part;
    the wall behind it in the fast one's)."""
    ids, fast_ids = ref["instance_id"].astype(int), fast["instance_id"].astype(int)
    out = {}
    for region in (0, 1, 2, 3):
        m = (ids == region) & (fast_ids == (2 if region == 0 else region))
        assert m.sum() >= 10
        sigma = np.sqrt(np.sum(fast["Y_stderr"][m] ** 2) + np.sum(ref["Y_stderr"][m] ** 2)) / m.sum()
        for c in "XYZ":
            r, f = float(ref[c][m].mean()), float(fast[c][m].mean())
            s = sigma * r / float(ref["Y"][m].mean())
            out[(region, c)] = ((f - r) / s, f / r - 1)
            # Z: a lamp's narrow peaks (an LED's 450 nm blue, sodium lines) integrated on the CIE
            # 5-nm tables here and on Mitsuba's own colour-matching tables there: ~1 % apart
            allow = 2 * allowance if c == "Z" else allowance
            assert abs(f - r) <= 4 * s + allow * r, (region, c, f / r - 1, s / r)
    return out


def test_many_lamps_and_windows_by_one_sampled_light_per_hit(tmp_path):
    """Nine bare lamps on a 1 m ring 1 m over a grey plate (more than MAX_LAMP_RAYS: one lamp per
    hit, chosen by its unoccluded irradiance) and a 2 x 2 m lit window over another plate split
    into four 1 x 1 m windows (one window per hit): the image means are the closed forms (the
    sum of nine inverse-square terms; pi L F with the four corner view factors) within 4
    standard errors plus 0.3 % / 2 %."""
    assert 9 > E.MAX_LAMP_RAYS
    stage = new_stage(tmp_path / "s.usda")
    grey = reflective(stage, "grey", [0.3, 3.0], [0.5, 0.5])
    plate(stage, "/World/p", 1e3, 0.0, grey, 280.0)
    add_camera(
        stage,
        "cam",
        (0, 0, 3),
        (0, 0, 0),
        fov_x_deg=60.0,
        resolution=(W, H),
        band=(0.4, 0.7),
        band_token="EO",
        up=(0, 1, 0),
    )
    _night(stage)
    ring = [(math.cos(a), math.sin(a), 1.0) for a in np.linspace(0, 2 * math.pi, 9, endpoint=False)]
    for i, pos in enumerate(ring):
        usd_lights.write_lamp(stage, f"/World/Scene/lamp{i}", "led_4000k", 200.0 * (1 + i % 3), pos)
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=16)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")

    def lit(x, y):
        return sum(
            0.5 * 200.0 * (1 + i % 3) / (4 * math.pi) / ((x - px) ** 2 + (y - py) ** 2 + 1.0) ** 1.5 / math.pi
            for i, (px, py, _) in enumerate(ring)
        )

    expected = _footprint_mean(lit, 3.0, 60.0)
    got, err = ch["Y"] * Y_TO_CD, ch["Y_stderr"] * Y_TO_CD
    sigma = np.sqrt(np.sum(err**2)) / got.size
    assert abs(got.mean() - expected.mean()) <= 4 * sigma + 3e-3 * expected.mean(), (
        got.mean() / expected.mean() - 1,
        sigma / expected.mean(),
    )

    # four windows making one 2 x 2 m window of 100 cd m-2, 1 m over a white plate
    stage = new_stage(tmp_path / "w.usda")
    white = reflective(stage, "white", [0.3, 3.0], [1.0, 1.0])
    plate(stage, "/World/p", 1e3, 0.0, white, 280.0)
    _night(stage)
    for i, (x, y) in enumerate([(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]):
        window = usd_lights.write_window(stage, f"/World/Scene/window{i}", "incandescent", 100.0, 1.0, 1.0)
        UsdGeom.Xformable(window).AddTranslateOp().Set(Gf.Vec3d(x, y, 1.0))
    add_camera(
        stage,
        "cam",
        (0.0, -2.5, 0.9),
        (0.0, 0.0, 0.0),
        fov_x_deg=1.5,
        resolution=(8, 6),
        band=(0.4, 0.7),
        band_token="EO",
        up=(0, 0, 1),
    )
    stage.Save()
    render_stage(tmp_path / "w.usda", tmp_path / "wout", spp=64)
    ch = read_exr(tmp_path / "wout" / "cam" / "0000.exr")
    a = 1.0 / math.sqrt(2.0)
    f = 4 * (2 * a * math.atan(a)) / (2 * math.pi)  # four 1 x 1 m corner rectangles at 1 m
    got = ch["Y"] * Y_TO_CD
    sigma = np.sqrt(np.sum((ch["Y_stderr"] * Y_TO_CD) ** 2)) / got.size
    assert abs(got.mean() - 100.0 * f) <= 4 * sigma + 0.02 * 100.0 * f, (got.mean() / (100.0 * f) - 1, sigma)
