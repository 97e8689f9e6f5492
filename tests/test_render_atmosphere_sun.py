"""EO atmospheric path per pixel, the blackbody sun from the DNI, sub-bands from the sensor prim.

Closed forms (small synthetic stages, helpers of test_render_radiometry):
- EO: a white Lambertian plate under a spectrally flat sun seen through an authored spectral
  path: the film's Y is int ybar (tau(l, r) E cos / pi + P(l, r)) dl / int ybar, i.e.
  tau_Y(r) E cos / pi + P_Y(r), per pixel by range (colour-science's CIE 1931 tables, 1 nm);
- EO airlight (Koschmieder 1924): a black plate seen through the path has Y = Y_h (1 - tau_Y(r)),
  Y_h the horizon sky; a white plate's contrast against the horizon is C(r) = C0 tau_Y(r);
- sun without a solar table: E(l) = DNI pi B(l, 5772 K) / (sigma T^4), in MWIR and in the visible;
- sub-band count: the sensor's humv:sensor:subbands, overridden by the render option.
"""

from __future__ import annotations

import colour
import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Sdf
from scipy import constants
from test_render_eo import eo_camera, reflective
from test_render_radiometry import (
    MWIR,
    H,
    W,
    atmosphere_tables,
    camera,
    material,
    new_stage,
    path_table,
    plate,
    read_exr,
    sun,
    within_noise,
)

from humv_usd.compat import trapezoid
from humv_usd.errors import InputError
from humv_usd.physics import planck
from humv_usd.pipeline.render import render_stage
from humv_usd.render import cie, radiometry

SIGMA = constants.Stefan_Boltzmann
#: the Sun's nominal effective temperature, IAU 2015 Resolution B3 [K] (an independent literal)
T_SUN = 5772.0
CMFS = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
LAM_NM = np.asarray(CMFS.wavelengths, dtype=float)
XYZ_BAR = np.asarray(CMFS.values, dtype=float)  # (471, 3), 1 nm


def dni_attr(stage, value):
    stage.GetPrimAtPath("/World/Environment").CreateAttribute(
        "humv:environment:directNormalIrradiance", Sdf.ValueTypeNames.Float
    ).Set(float(value))


def pixel_ranges(depth, eye, target, fov_x_deg):
    """Range [m] of each pixel centre's hit from the depth channel and the camera geometry."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, [0, 0, 1])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tx = np.tan(np.radians(fov_x_deg / 2))
    ty = tx * H / W
    xs, ys = np.meshgrid((np.arange(W) + 0.5) / W * 2 - 1, 1 - (np.arange(H) + 0.5) / H * 2)
    dirs = fwd + xs[..., None] * tx * right + ys[..., None] * ty * up
    return depth * np.linalg.norm(dirs, axis=-1) / (dirs @ fwd)


def silhouette(hit):
    pad = np.pad(hit, 1, mode="edge")
    return (pad[:-2, 1:-1] != hit) | (pad[2:, 1:-1] != hit) | (pad[1:-1, :-2] != hit) | (pad[1:-1, 2:] != hit)


# --- EO atmosphere ---------------------------------------------------------------------------------


def test_cie_tables_are_colour_sciences():
    """The frozen CMFs and sRGB matrix are colour-science's (and the generator is in sync)."""
    assert cie.main(["--check"]) == 0
    for c in range(3):
        assert_allclose(
            cie.CMF_XYZ[:, c], np.interp(cie.CMF_WAVELENGTHS_NM, LAM_NM, XYZ_BAR[:, c]), rtol=0, atol=1e-12
        )
    assert_allclose(cie.XYZ_TO_SRGB, colour.models.RGB_COLOURSPACE_sRGB.matrix_XYZ_to_RGB, atol=1e-12)


def test_reduce_xyz_closed_form():
    """Flat tables reduce to themselves (tau) and to P x int xbar_c / int ybar (P per nm); a
    spectral tau reduces to its CMF-weighted mean (1 nm reference from colour-science)."""
    wl = np.array([0.35, 0.45, 0.55, 0.65, 0.85])
    ranges = np.array([10.0, 50.0])
    tau = np.array([[0.9, 0.8, 0.95, 0.7, 0.6], [0.5, 0.4, 0.6, 0.3, 0.2]])
    rad = np.full((2, wl.size), 2000.0)  # W m-2 sr-1 um-1 = 2 per nm
    red = radiometry.reduce_xyz(radiometry.PathTable("t", ranges, wl, tau, rad))
    assert_allclose(red.ranges_m, [0.0, 10.0, 50.0])
    assert_allclose(red.transmittance[0], 1.0) and assert_allclose(red.radiance[0], 0.0)
    integrals = trapezoid(XYZ_BAR, LAM_NM, axis=0)
    assert_allclose(red.radiance[1:], 2.0 * np.tile(integrals / integrals[1], (2, 1)), rtol=2e-3)
    for j in range(2):
        ref = trapezoid(XYZ_BAR * np.interp(LAM_NM / 1000, wl, tau[j])[:, None], LAM_NM, axis=0) / integrals
        assert_allclose(red.transmittance[j + 1], ref, rtol=2e-3)
    # halfway in range: linear interpolation
    t_mid, p_mid = red.at(np.array([30.0]))
    assert_allclose(t_mid[0], 0.5 * (red.transmittance[1] + red.transmittance[2]))
    assert_allclose(p_mid[0], 0.5 * (red.radiance[1] + red.radiance[2]))


def test_eo_path_per_pixel_closed_form(tmp_path):
    """A white plate under a flat sun at zenith seen obliquely through a non-gray path whose tau
    and P are linear in range: every plate pixel's X, Y, Z is tau_c(r) E / pi + P_c(r) with r its
    range (CMF-weighted closed form, exact for a flat surface radiance); sky pixels stay 0."""
    e_um = 1500.0
    eye, target, fov = (0.0, -30.0, 6.0), (0.0, 0.0, 1.5), 40.0
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 200.0, 0.0, reflective(stage, "white", [0.3, 1.0], [1.0, 1.0]), 300.0)
    cam = eo_camera(stage, "eo", eye, target, fov_x_deg=fov, up=(0, 0, 1))
    wl = np.array([0.3, 0.45, 0.55, 0.65, 0.9])
    atmosphere_tables(stage, wl, solar=np.full(wl.size, e_um))
    sun(stage, (0.0, 0.0, 1.0))
    ranges = np.array([1.0, 100.0])
    a = np.array([2e-3, 6e-3, 3e-3, 5e-3, 1e-3])  # per metre
    tau = np.stack([1.0 - a * r for r in ranges])
    rad = np.stack([np.array([50.0, 150.0, 100.0, 60.0, 20.0]) * r / 100.0 for r in ranges])  # per um
    path_table(stage, str(cam.GetPath()), ranges, tau, rad)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=32)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    depth = ch["depth"].astype(float)
    hit = np.isfinite(depth)
    assert hit.any() and (~hit).any()
    r = np.where(hit, pixel_ranges(depth, eye, target, fov), 0.0)
    # reference: per wavelength (1 nm, colour-science CMFs), tau and P linear in range (0 m: 1, 0;
    # held beyond 100 m)
    rr = np.clip(r, 0.0, 100.0)
    a_l = np.interp(LAM_NM / 1000, wl, a)
    p_l = np.interp(LAM_NM / 1000, wl, rad[1]) / 100.0 / 1000.0  # per m per nm
    f = np.clip(rr / 1.0, 0.0, 1.0)[..., None]  # 0-1 m: from (1, 0) to the first table row
    tau_l = np.where(rr[..., None] >= 1.0, 1.0 - a_l * rr[..., None], 1.0 - f * a_l)
    p_l = p_l * rr[..., None]
    integrals = trapezoid(XYZ_BAR, LAM_NM, axis=0)
    y_int = integrals[1]
    surface = e_um / 1000.0 / np.pi  # W m-2 sr-1 nm-1
    edge = silhouette(hit)
    inner = hit & ~edge
    for c, name in enumerate("XYZ"):
        expected = trapezoid((tau_l * surface + p_l) * XYZ_BAR[:, c], LAM_NM, axis=-1) / y_int
        expected = np.where(hit, expected, 0.0)
        assert (ch[name][~hit & ~edge] == 0).all()
        if name == "Y":  # per pixel against its Monte Carlo error (Mitsuba's CMF tables: 2e-3)
            ok = within_noise(ch[name], ch["Y_stderr"], expected, rel=3e-3) | edge
            assert ok.all(), f"{name}: {(~ok).sum()} pixels off"
        # X and Z carry more spectral-sampling noise than Y_stderr says: the mean relative error
        rel = ch[name][inner] / expected[inner] - 1.0
        assert abs(rel.mean()) < 4 * rel.std() / np.sqrt(rel.size) + 3e-3, name
        # and the path term (~8 % here) is resolved far beyond that tolerance
        assert 4 * rel.std() / np.sqrt(rel.size) + 3e-3 < 0.02
    # the path is visible: far plate pixels lie well below the bare plate
    bare = surface
    assert (ch["Y"][hit & ~edge] < bare * 0.9).any()
    assert np.abs(ch["Y"][hit] - bare).max() > 10 * ch["Y_stderr"][hit].mean()
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    xyz = np.stack([ch["X"], ch["Y"], ch["Z"]], axis=-1).astype(float)
    assert_allclose(rgb, colour.XYZ_to_sRGB(xyz, apply_cctf_encoding=False), rtol=1e-4, atol=1e-6)
    frame = manifest["eo_sensors"][0]["frames"][0]
    assert frame["atmosphere"].startswith("per pixel by range")
    assert "no airlight: no humv:atmosphere:skySpectralRadiance" in frame["atmosphere"]


def test_horizon_sky_rows_near_the_horizon():
    zen = np.array([0.0, 45.0, 85.0, 89.0])
    rad = np.array([[10.0, 20.0], [30.0, 40.0], [100.0, 200.0], [120.0, 220.0]])
    l_h, rule = radiometry.horizon_sky(zen, rad)
    assert_allclose(l_h, [110.0, 210.0]) and "85, 89" in rule
    # no row at 85-90 deg: the cosine-weighted hemispherical mean (the EO render's uniform sky)
    l_h, rule = radiometry.horizon_sky(zen[:2], rad[:2])
    assert_allclose(l_h, [radiometry.hemisphere_mean(zen[:2], rad[:2, j]) for j in range(2)])
    assert "cosine-weighted" in rule


def test_reduce_xyz_airlight_closed_form():
    """P^air_c(r) = int xbar_c L_h (1 - tau(l, r)) dl / int ybar (1 nm colour-science reference);
    a flat L_h gives Y_h (1 - tau_Y(r)) exactly; the thermal part is kept, 0 m has none."""
    wl = np.array([0.35, 0.45, 0.55, 0.65, 0.85])
    ranges = np.array([1000.0, 5000.0])
    tau = np.array([[0.80, 0.84, 0.86, 0.88, 0.9], [0.33, 0.40, 0.45, 0.52, 0.6]])
    thermal = np.full((2, wl.size), 1e-3)  # per um
    table = radiometry.PathTable("t", ranges, wl, tau, thermal)
    bare = radiometry.reduce_xyz(table)
    assert bare.airlight is None and bare.horizon_xyz is None
    l_h = np.array([90.0, 120.0, 100.0, 80.0, 40.0])  # per um
    red = radiometry.reduce_xyz(table, (wl, l_h))
    integrals = trapezoid(XYZ_BAR, LAM_NM, axis=0)
    lh_nm = np.interp(LAM_NM / 1000, wl, l_h) / 1000.0
    assert_allclose(
        red.horizon_xyz, trapezoid(XYZ_BAR * lh_nm[:, None], LAM_NM, axis=0) / integrals[1], rtol=2e-3
    )
    assert_allclose(red.airlight[0], 0.0) and assert_allclose(red.radiance[0], 0.0)
    for j in range(2):
        one_minus = 1.0 - np.interp(LAM_NM / 1000, wl, tau[j])
        ref = trapezoid(XYZ_BAR * (lh_nm * one_minus)[:, None], LAM_NM, axis=0) / integrals[1]
        assert_allclose(red.airlight[j + 1], ref, rtol=2e-3)
        assert_allclose(red.radiance[j + 1], ref + bare.radiance[j + 1], rtol=2e-3)
    # flat horizon: Y = Y_h (1 - tau_Y), so a black object at 5 km is 55 % of the horizon sky
    flat = radiometry.reduce_xyz(table, (wl, np.full(wl.size, 100.0)))
    assert_allclose(flat.horizon_xyz[1], 0.1, rtol=2e-3)
    assert_allclose(flat.airlight[1:, 1], 0.1 * (1.0 - flat.transmittance[1:, 1]), rtol=1e-9)
    assert 0.5 < flat.airlight[2, 1] / flat.horizon_xyz[1] < 0.6


def quad(stage, path, x0, x1, y0, y1, mat, instance_id):
    mesh = plate(stage, path, 1.0, 0.0, mat, 300.0, instance_id)
    mesh.GetPointsAttr().Set([(x0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (x0, y1, 0.0)])
    return mesh


def test_eo_airlight_black_and_white_plate_closed_form(tmp_path):
    """A black plate (rho = 0) and a white one (rho = 1) under a flat sun at zenith and a sky
    brighter at the horizon (flat spectra), seen through a non-gray path (tau linear in range,
    no thermal path radiance): per pixel, the black plate is Y = Y_h (1 - tau_Y(r)) with Y_h the
    sky table's horizon rows (not its hemispherical mean), and the white plate's contrast against
    the horizon is Koschmieder's C(r) = C0 tau_Y(r), C0 = (E / pi + L_sky - Y_h) / Y_h."""
    e_um, zen, sky_rows = 1500.0, np.array([0.0, 45.0, 85.0, 89.0]), np.array([30.0, 60.0, 120.0, 120.0])
    eye, target, fov = (0.0, -30.0, 6.0), (0.0, 0.0, 1.5), 40.0
    stage = new_stage(tmp_path / "s.usda")
    quad(
        stage,
        "/World/black",
        -200.0,
        0.0,
        -200.0,
        200.0,
        reflective(stage, "black", [0.3, 1.0], [0.0, 0.0]),
        1,
    )
    quad(
        stage,
        "/World/white",
        0.0,
        200.0,
        -200.0,
        200.0,
        reflective(stage, "white", [0.3, 1.0], [1.0, 1.0]),
        2,
    )
    cam = eo_camera(stage, "eo", eye, target, fov_x_deg=fov, up=(0, 0, 1))
    wl = np.array([0.3, 0.45, 0.55, 0.65, 0.9])
    atmosphere_tables(stage, wl, sky=np.repeat(sky_rows, wl.size), zenith=zen, solar=np.full(wl.size, e_um))
    sun(stage, (0.0, 0.0, 1.0))
    ranges = np.array([1.0, 100.0])
    a = np.array([2e-3, 6e-3, 3e-3, 5e-3, 1e-3])  # per metre
    path_table(
        stage, str(cam.GetPath()), ranges, np.stack([1.0 - a * r for r in ranges]), np.zeros((2, wl.size))
    )
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=128)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    depth = ch["depth"].astype(float)
    hit = np.isfinite(depth)
    r = np.clip(np.where(hit, pixel_ranges(depth, eye, target, fov), 0.0), 0.0, 100.0)
    tau_l = np.where(
        r[..., None] >= 1.0,
        1.0 - np.interp(LAM_NM / 1000, wl, a) * r[..., None],
        1.0 - np.clip(r, 0, 1)[..., None] * np.interp(LAM_NM / 1000, wl, a),
    )
    tau_y = trapezoid(tau_l * XYZ_BAR[:, 1], LAM_NM, axis=-1) / trapezoid(XYZ_BAR[:, 1], LAM_NM)
    y_h = 0.12  # flat 120 W m-2 sr-1 um-1 at zenith 85-89 deg
    l_sky = radiometry.hemisphere_mean(zen, sky_rows) / 1000.0  # the uniform sky that lights the plates
    inst = ch["instance_id"]
    edge = silhouette(hit) | silhouette(inst == 1)
    black, white = (inst == 1) & ~edge, (inst == 2) & ~edge
    assert black.sum() > 50 and white.sum() > 50 and (r[black] > 30).any() and (tau_y[black] < 0.85).any()
    # black: pure airlight, no Monte Carlo noise (nothing reflects)
    assert_allclose(ch["Y"][black], y_h * (1.0 - tau_y[black]), rtol=3e-3, atol=1e-9)
    # white: contrast against the horizon, per pixel within noise and as a fitted slope
    s_white = e_um / 1000.0 / np.pi + l_sky
    c0 = (s_white - y_h) / y_h
    expected = tau_y * s_white + y_h * (1.0 - tau_y)
    ok = within_noise(ch["Y"], ch["Y_stderr"], expected, rel=3e-3)
    assert ok[white].all(), f"{(~ok[white]).sum()} white pixels off"
    c = (ch["Y"][white] - y_h) / y_h
    ratio = c / (c0 * tau_y[white])  # Koschmieder: 1 at every range
    tol = 4 * ratio.std() / np.sqrt(ratio.size) + 3e-3
    assert abs(ratio.mean() - 1.0) < tol < 0.02, (ratio.mean(), tol)
    slope = np.sum(c * tau_y[white]) / np.sum(tau_y[white] ** 2)
    assert abs(slope / c0 - 1.0) < tol
    assert np.ptp(tau_y[white]) > 0.1  # the contrast really varies with range
    # without the airlight (Y = tau_Y S, the plate only darkens) the white plate would be darker
    dark = ch["Y"][white] / (tau_y[white] * s_white) - 1.0
    assert dark.mean() > 4 * dark.std() / np.sqrt(dark.size) + 0.02
    frame = manifest["eo_sensors"][0]["frames"][0]
    assert "Koschmieder airlight" in frame["atmosphere"] and "zenith 85, 89 deg" in frame["atmosphere"]
    assert "Y_h = 0.12 W m-2 sr-1 nm-1" in frame["atmosphere"]


def test_eo_path_skipped_without_visible_table(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 1e3, 0.0, reflective(stage, "white", [0.3, 1.0], [1.0, 1.0]), 300.0)
    cam = eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    wl = np.array([0.3, 0.9, 4.0])
    atmosphere_tables(stage, wl, solar=np.full(3, 1500.0))
    sun(stage, (0.0, 0.0, 1.0))
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    assert manifest["eo_sensors"][0]["frames"][0]["atmosphere"].startswith("skipped: no path table")
    # a table is there but misses the visible: skipped, named
    path_table(stage, str(cam.GetPath()), [1.0, 10.0], np.ones((2, 3)), np.zeros((2, 3)))
    stage.GetPrimAtPath("/World/Atmosphere").GetAttribute("humv:atmosphere:wavelengths").Set([0.5, 0.9, 4.0])
    dni_attr(stage, 800.0)  # the solar table misses the visible now too: the sun from the DNI
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out2", spp=4)
    assert "does not cover 0.40-0.70 um" in manifest["eo_sensors"][0]["frames"][0]["atmosphere"]


# --- sun from the broadband DNI -----------------------------------------------------------------------


def blackbody_sun_band(dni, band):
    """In-band irradiance of a 5772 K blackbody spectrum scaled to the DNI (fine trapezoid)."""
    x = np.linspace(band[0], band[1], 20001)
    return dni * trapezoid(planck.spectral_radiance(x, T_SUN), x) * np.pi / (SIGMA * T_SUN**4)


def test_blackbody_sun_integrates_to_the_dni():
    x = np.geomspace(0.05, 1000.0, 200001)
    assert_allclose(trapezoid(radiometry.blackbody_sun(x, 850.0), x), 850.0, rtol=1e-4)


def mwir_white_plate(tmp_path, toward, dni=800.0):
    eps, t, t_sky = 0.1, 300.0, 270.0
    stage = new_stage(tmp_path / "s.usda", sky_k=t_sky)
    stage.GetPrimAtPath("/World/Atmosphere").CreateAttribute(
        "humv:atmosphere:model", Sdf.ValueTypeNames.Token
    ).Set("analytic")
    plate(stage, "/World/p", 1e4, 0.0, material(stage, "white", eps), t)
    camera(stage, "ir", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0, band=MWIR)
    sun(stage, toward)
    dni_attr(stage, dni)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=256)  # 64 per sub-band
    ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    base = eps * planck.band_radiance(t, MWIR) + (1 - eps) * planck.band_radiance(t_sky, MWIR)
    return manifest, ch, base, eps


def test_mwir_sun_from_dni_without_solar_table(tmp_path):
    """Analytic atmosphere, no solar spectral table, the sun up with a DNI: the white plate is
    eps B(T) + (1 - eps)(B(T_sky) + E_band cos / pi) with the blackbody sun, brighter than the
    same plate at night (sun below the horizon, same DNI authored)."""
    toward = np.array([0.5, 0.0, 1.0]) / np.linalg.norm([0.5, 0.0, 1.0])
    day_m, day, base, eps = mwir_white_plate(tmp_path / "day", toward)
    night_m, night, _, _ = mwir_white_plate(tmp_path / "night", (0.5, 0.0, -0.2))
    expected = base + (1 - eps) * blackbody_sun_band(800.0, MWIR) * toward[2] / np.pi
    ok = within_noise(day["radiance"], day["radiance_stderr"], expected)
    assert ok.all(), f"{(~ok).sum()} pixels off"
    assert abs(day["radiance"].mean() / expected - 1) < 2e-3
    ok = within_noise(night["radiance"], night["radiance_stderr"], base)
    assert ok.all(), f"night: {(~ok).sum()} pixels off"
    assert day["radiance"].mean() - night["radiance"].mean() > 20 * day["radiance_stderr"].mean()
    ran = day_m["sensors"][0]["frames"][0]["radiometry"]["sun"]
    assert ran.startswith("directional") and "blackbody 5772 K" in ran and "DNI 800" in ran
    assert "blackbody 5772 K" in day_m["radiometry"]["sun_source"]
    assert night_m["sensors"][0]["frames"][0]["radiometry"]["sun"] == "skipped: sun below the horizon (night)"


def test_eo_sun_from_dni_without_solar_table(tmp_path):
    """No spectral tables at all, only the sun direction and DNI: the EO white plate's Y is the
    CIE-weighted blackbody sun irradiance x cos / pi (not skipped)."""
    th = np.radians(30.0)
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 1e3, 0.0, reflective(stage, "white", [0.3, 1.0], [1.0, 1.0]), 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    sun(stage, (np.sin(th), 0.0, np.cos(th)))
    dni_attr(stage, 700.0)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=16)
    assert not manifest["skipped_sensors"]
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    e_nm = 700.0 * np.pi * planck.spectral_radiance(LAM_NM / 1000, T_SUN) / (SIGMA * T_SUN**4) / 1000.0
    expected = trapezoid(e_nm * XYZ_BAR[:, 1], LAM_NM) / trapezoid(XYZ_BAR[:, 1], LAM_NM) * np.cos(th) / np.pi
    sigma = np.sqrt(np.mean(ch["Y_stderr"] ** 2) / ch["Y"].size)
    assert abs(ch["Y"].mean() - expected) < 4 * sigma + 3e-3 * expected
    assert "blackbody 5772 K" in manifest["eo_sensors"][0]["frames"][0]["illumination"]["sun"]


# --- sub-band count from the sensor prim ------------------------------------------------------------


def subbands_stage(tmp_path, value):
    stage = new_stage(tmp_path / "s.usda", sky_k=290.0)
    plate(stage, "/World/p", 50.0, 0.0, material(stage, "m", 0.9), 300.0)
    cam = camera(stage, "ir", (0, 0, 5), (0, 0, 0))
    cam.GetPrim().CreateAttribute("humv:sensor:subbands", Sdf.ValueTypeNames.Int).Set(value)
    stage.Save()
    return tmp_path / "s.usda"


def test_subbands_from_sensor_prim_and_option_overrides(tmp_path):
    path = subbands_stage(tmp_path, 3)
    m = render_stage(path, tmp_path / "a", spp=4)
    s = m["sensors"][0]
    assert len(s["subbands_um"]) == 3 and s["subbands_source"] == "humv:sensor:subbands"
    m = render_stage(path, tmp_path / "b", spp=4, subbands=2)
    s = m["sensors"][0]
    assert len(s["subbands_um"]) == 2 and s["subbands_source"] == "render option subbands"


def test_bad_subbands_on_prim_is_input_error(tmp_path):
    path = subbands_stage(tmp_path, 0)
    with pytest.raises(InputError, match="humv:sensor:subbands"):
        render_stage(path, tmp_path / "a", spp=4)
