"""Render radiometry: sub-bands, atmosphere per range, spectral sky, sun, blackbody read-back.

Closed forms: Planck sub-band sums, a plate seen through an authored path table
(tau(r) S + P(r) per pixel), a perfect reflector under a zenith-dependent sky (cosine-weighted
hemispherical mean), a plate lit by the sun (E cos(theta) / pi), and a blackbody panel read back
through the sensor chain after atmospheric correction. Stages are small synthetic ones authored
here with the atmosphere and environment attributes of humv_usd.usd.schemas.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pxr import Gf, Sdf, UsdGeom, UsdShade, Vt
from test_render import add_camera, within_noise
from test_render import add_material as material
from test_render import new_stage as _new_stage
from test_render import read_exr as _read_exr

from humv_usd.compat import trapezoid
from humv_usd.errors import InputError
from humv_usd.physics import planck
from humv_usd.pipeline.render import render_stage
from humv_usd.render import radiometry
from humv_usd.render.radiometry import SubBands

W, H = 32, 24
LWIR = (8.0, 14.0)
MWIR = (3.0, 5.0)


# --- stage helpers ------------------------------------------------------------------------------


def new_stage(path, sky_k=280.0):
    """test_render's stage plus the /World/Environment scope the sun goes on."""
    stage = _new_stage(path, sky_k=sky_k)
    UsdGeom.Scope.Define(stage, "/World/Environment")
    return stage


def farr(prim, name, values):
    prim.CreateAttribute(name, Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray([float(v) for v in np.ravel(values)])
    )


def plate(stage, path, half, z, mat, temperature_k, instance_id=1):
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(
        Vt.Vec3fArray(
            [
                Gf.Vec3f(-half, -half, z),
                Gf.Vec3f(half, -half, z),
                Gf.Vec3f(half, half, z),
                Gf.Vec3f(-half, half, z),
            ]
        )
    )
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
        "humv:thermal:temperature", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform
    ).Set(Vt.FloatArray([temperature_k]))
    mesh.GetPrim().CreateAttribute("humv:label:instanceId", Sdf.ValueTypeNames.Int).Set(instance_id)
    return mesh


def camera(stage, name, eye, target, fov_x_deg=20.0, band=LWIR, up=(0, 1, 0), netd=None):
    return add_camera(
        stage,
        name,
        eye,
        target,
        fov_x_deg=fov_x_deg,
        resolution=(W, H),
        band=band,
        band_token="LWIR" if band[0] >= 7 else "MWIR",
        up=up,
        netd=netd,
    )


def atmosphere_tables(stage, wavelengths, sky=None, zenith=None, solar=None):
    atm = stage.GetPrimAtPath("/World/Atmosphere")
    farr(atm, "humv:atmosphere:wavelengths", wavelengths)
    if sky is not None:
        farr(atm, "humv:atmosphere:skyZenithAngles", zenith)
        farr(atm, "humv:atmosphere:skySpectralRadiance", sky)
    if solar is not None:
        farr(atm, "humv:atmosphere:solarSpectralIrradiance", solar)


def path_table(stage, sensor, ranges, tau, rad):
    p = UsdGeom.Scope.Define(stage, f"/World/Atmosphere/Paths/{sensor.split('/')[-1]}").GetPrim()
    p.CreateAttribute("humv:atmospherePath:sensor", Sdf.ValueTypeNames.String).Set(sensor)
    farr(p, "humv:atmospherePath:ranges", ranges)
    farr(p, "humv:atmospherePath:transmittance", tau)
    farr(p, "humv:atmospherePath:radiance", rad)


def sun(stage, toward):
    d = np.asarray(toward, float) / np.linalg.norm(toward)
    stage.GetPrimAtPath("/World/Environment").CreateAttribute(
        "humv:environment:sunDirection", Sdf.ValueTypeNames.Float3
    ).Set(Gf.Vec3f(*map(float, d)))


def read_exr(path):
    return _read_exr(path)[1]


# --- sub-bands (numpy) -------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 3, 7])
def test_subband_planck_sums_to_band(n):
    response = (np.array([7.5, 9.0, 12.0, 14.0]), np.array([0.2, 1.0, 0.8, 0.0]))
    sub = SubBands(LWIR, response, n)
    t = np.array([250.0, 300.0, 340.0])
    assert_allclose(sub.radiance(t).sum(axis=-1), planck.band_radiance(t, LWIR, response), rtol=1e-9)
    # a constant table integrates to the response integral, a constant has that weighted mean
    x = np.linspace(7.0, 15.0, 9)
    ones = sub.integrate(x, np.ones_like(x))
    r8 = 0.2 + 0.8 * 0.5 / 1.5  # response at the band edge 8 um
    assert_allclose(
        ones.sum(), 0.5 * (r8 + 1.0) * 1.0 + 0.5 * (1.0 + 0.8) * 3.0 + 0.5 * 0.8 * 2.0, rtol=1e-12
    )
    assert_allclose(sub.weighted_mean(x, np.full_like(x, 0.37)), 0.37, rtol=1e-12)


def test_subbands_drop_zero_response():
    sub = SubBands(MWIR, (np.array([3.0, 3.9, 4.0, 5.0]), np.array([0.0, 0.0, 1.0, 1.0])), 4)
    assert sub.bands == [(3.5, 4.0), (4.0, 4.5), (4.5, 5.0)]


def test_subband_error_gray_exact_and_falls_for_nongray():
    wl = np.array([8.0, 9.0, 9.5, 10.0, 14.0])
    gray = np.full(wl.size, 0.8)
    sky = (np.linspace(8, 14, 50), planck.spectral_radiance(np.linspace(8, 14, 50), 250.0))
    t = np.array([280.0, 320.0])
    for n in (1, 4):
        assert np.abs(radiometry.subband_error(LWIR, None, wl, gray, t, n, sky=sky)).max() < 1e-6
    quartz = np.array([0.95, 0.6, 0.7, 0.95, 0.95])  # reststrahlen-like dip near 9 um
    tau = (np.linspace(8, 14, 61), 0.6 + 0.3 * np.sin(np.linspace(0, 6, 61)) ** 2, np.linspace(0.1, 2.0, 61))
    errs = [
        np.abs(radiometry.subband_error(LWIR, None, wl, quartz, t, n, sky=sky, path=tau)).max()
        for n in (1, 4, 16, 64)
    ]
    assert errs[0] > 0.05 and errs[-1] < 0.02 * errs[0] and errs[2] < errs[0]


def test_subbands_option_validated(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 5.0, 0.0, material(stage, "m", 0.9), 300.0)
    camera(stage, "ir", (0, 0, 5), (0, 0, 0))
    stage.Save()
    with pytest.raises(InputError, match="subbands"):
        render_stage(tmp_path / "s.usda", tmp_path / "out", subbands=0)


# --- atmosphere per pixel by range -------------------------------------------------------------


def test_path_radiance_and_transmittance_per_pixel(tmp_path):
    """A plate seen obliquely through a path whose tau and P are linear in range and non-gray:
    every pixel is sum_k tau_k(r) S_k + P_k(r) with r the pixel's range (closed form), and the
    sky pixels carry the sky radiance unchanged."""
    eps, t_plate, t_sky = 0.9, 310.0, 260.0
    stage = new_stage(tmp_path / "s.usda", sky_k=t_sky)
    plate(stage, "/World/p", 200.0, 0.0, material(stage, "m", eps), t_plate)
    eye = np.array([0.0, -30.0, 6.0])
    cam = camera(stage, "ir", tuple(eye), (0.0, 0.0, 1.5), fov_x_deg=40.0, up=(0, 0, 1))
    wl = np.array([7.0, 9.0, 11.0, 13.0, 15.0])
    ranges = np.array([1.0, 100.0])
    a = np.array([2e-3, 6e-3, 4e-3, 7e-3, 8e-3])  # per metre, so tau linear in range (held beyond 100 m)
    tau = np.stack([1.0 - a * r for r in ranges])
    rad = np.stack([np.array([0.5, 1.0, 0.8, 1.5, 2.0]) * r / 10.0 for r in ranges])
    atmosphere_tables(stage, wl)
    path_table(stage, str(cam.GetPath()), ranges, tau, rad)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=32, subbands=2)
    ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    sub = SubBands(LWIR, None, 2)
    surface = eps * sub.radiance(t_plate) + (1 - eps) * sub.radiance(t_sky)  # per sub-band
    reduced = radiometry.PathTable("t", ranges, wl, tau, rad).reduce(sub)
    # ranges of the pixel centres on the plate (z = 0) from the camera geometry
    depth = ch["depth"].astype(float)
    hit = np.isfinite(depth)
    assert hit.any() and (~hit).any()
    fwd = (np.array([0.0, 0.0, 1.5]) - eye) / np.linalg.norm(np.array([0.0, 0.0, 1.5]) - eye)
    right = np.cross(fwd, [0, 0, 1])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tx = np.tan(np.radians(20.0))
    ty = tx * H / W
    xs, ys = np.meshgrid((np.arange(W) + 0.5) / W * 2 - 1, 1 - (np.arange(H) + 0.5) / H * 2)
    dirs = fwd + xs[..., None] * tx * right + ys[..., None] * ty * up
    r = depth * np.linalg.norm(dirs, axis=-1) / (dirs @ fwd)
    expected = np.zeros((H, W))
    for k in range(len(sub)):
        tk, pk = reduced.at(np.where(hit, r, 0.0), k)
        expected += np.where(hit, tk * surface[k] + pk, sub.radiance(t_sky)[k])
    # pixels straddling the plate's far edge mix plate and sky samples but take the path of
    # their centre ray (documented approximation): leave them out
    pad = np.pad(hit, 1, mode="edge")
    edge = (pad[:-2, 1:-1] != hit) | (pad[2:, 1:-1] != hit) | (pad[1:-1, :-2] != hit) | (pad[1:-1, 2:] != hit)
    assert edge.sum() < 3 * W
    ok = within_noise(ch["radiance"], ch["radiance_stderr"], expected) | edge
    assert ok.all(), f"{(~ok).sum()} pixels off"
    # the path term is visible: far plate pixels differ from the bare surface by more than noise
    assert np.abs(expected[hit] - surface.sum()).max() > 10 * ch["radiance_stderr"][hit].mean()
    ran = manifest["sensors"][0]["frames"][0]["radiometry"]
    assert ran["atmosphere"].startswith("per pixel by range") and "skipped" in ran["sun"]


def test_missing_path_table_is_listed_as_skipped(tmp_path):
    stage = new_stage(tmp_path / "s.usda", sky_k=300.0)
    plate(stage, "/World/p", 50.0, 0.0, material(stage, "m", 0.5), 300.0)
    camera(stage, "ir", (0, 0, 5), (0, 0, 0))
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=8)
    ran = manifest["sensors"][0]["frames"][0]["radiometry"]
    assert ran["atmosphere"].startswith("skipped") and ran["sky"].startswith("uniform blackbody")
    assert len(manifest["sensors"][0]["subbands_um"]) == radiometry.DEFAULT_SUBBANDS


def test_bad_path_table_is_input_error(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 5.0, 0.0, material(stage, "m", 0.9), 300.0)
    cam = camera(stage, "ir", (0, 0, 5), (0, 0, 0))
    atmosphere_tables(stage, [7.0, 15.0])
    path_table(stage, str(cam.GetPath()), [1.0, 100.0], [1.0, 1.0, 0.9], [0, 0, 0, 0])
    stage.Save()
    with pytest.raises(InputError, match="humv:atmospherePath:transmittance"):
        render_stage(tmp_path / "s.usda", tmp_path / "out", spp=2)


# --- sky and sun -------------------------------------------------------------------------------


def test_sky_map_rows_match_mitsuba_envmap_lookup():
    """The lat-long map's rows sit where Mitsuba's envmap looks zenith angles up."""
    from humv_usd import mode
    from humv_usd.render.radiometry import sky_latlong

    mi = mode.mitsuba()
    zen = np.array([0.0, 90.0])
    bitmap = sky_latlong(zen, [0.0, 90.0])  # radiance = zenith angle in degrees
    scene = mi.load_dict(
        {
            "type": "scene",
            "sky": {
                "type": "envmap",
                "bitmap": mi.Bitmap(bitmap),
                "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90),
            },
        }
    )
    emitter = scene.emitters()[0]
    # On CUDA the envmap is a hardware texture, whose linear filtering weights are 9-bit fixed
    # point with 8 fractional bits (NVIDIA, CUDA C++ Programming Guide, "Texture Fetching",
    # linear filtering): a lerp between rows 90 apart is good to 90 / 256 there. A row in the
    # wrong place is off by tens of degrees on either backend.
    tolerance = 1e-3 + (90.0 / 256 if mi.variant().startswith("cuda") else 0.0)
    for z in (0.0, 0.3, 17.0, 63.4, 89.0, 89.9):
        th = np.radians(z)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(float(-np.sin(th)), 0.0, float(-np.cos(th)))
        value = float(np.asarray(emitter.eval(si)).ravel()[0])
        assert value == pytest.approx(z, abs=tolerance)


def test_spectral_sky_envmap_on_a_mirror_plate(tmp_path):
    """A perfect Lambertian reflector (eps 0) under a sky bright at the zenith and dim at the
    horizon reflects its cosine-weighted hemispherical mean; looking up sees L(zenith ~ 0)."""
    wl = np.array([7.0, 15.0])
    zen = np.array([0.0, 30.0, 60.0, 90.0])
    base = np.array([4.0, 3.5, 2.5, 1.0])  # W m-2 sr-1 um-1, same at every wavelength
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 1e4, 0.0, material(stage, "mirror", 0.0), 300.0)
    camera(stage, "down", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    camera(stage, "up", (0, 0, 1), (0, 0, 2), fov_x_deg=4.0)
    atmosphere_tables(stage, wl, sky=np.repeat(base[:, None], 2, axis=1), zenith=zen)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=48, subbands=3)
    width = LWIR[1] - LWIR[0]
    down = read_exr(tmp_path / "out" / "down" / "0000.exr")
    expected = radiometry.hemisphere_mean(zen, base) * width
    sigma_mean = np.sqrt(np.mean(np.square(down["radiance_stderr"])) / down["radiance"].size)
    assert abs(down["radiance"].mean() - expected) < 4 * sigma_mean + 1e-3 * expected
    assert sigma_mean < 2e-3 * expected
    up = read_exr(tmp_path / "out" / "up" / "0000.exr")
    # the 4 deg x 3 deg view spans zenith 0-2.5 deg (mean ~1.2 deg), where the table is linear
    assert_allclose(up["radiance"].mean(), np.interp(1.2, zen, base) * width, rtol=1e-3)
    assert "envmap" in manifest["sensors"][0]["frames"][0]["radiometry"]["sky"]


@pytest.mark.parametrize("toward,lit", [((0.5, 0.0, 1.0), True), ((0.5, 0.0, -0.2), False)])
def test_sun_reflected_in_mwir(tmp_path, toward, lit):
    """A gray plate (eps 0.6) under a blackbody sky and a sun of spectral irradiance E at
    zenith theta: L = eps B(T) + (1 - eps) (B(T_sky) + E cos(theta) / pi) in band; no sun at night."""
    eps, t, t_sky = 0.6, 300.0, 270.0
    wl = np.linspace(2.5, 5.5, 7)
    e_solar = np.linspace(12.0, 4.0, 7)  # W m-2 um-1, beam-normal
    stage = new_stage(tmp_path / "s.usda", sky_k=t_sky)
    plate(stage, "/World/p", 1e4, 0.0, material(stage, "m", eps), t)
    camera(stage, "ir", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0, band=MWIR)
    atmosphere_tables(stage, wl, solar=e_solar)
    sun(stage, toward)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=256)  # 64 per sub-band
    ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    d = np.asarray(toward, float) / np.linalg.norm(toward)
    x = np.linspace(*MWIR, 2001)
    e_band = trapezoid(np.interp(x, wl, e_solar), x)
    expected = eps * planck.band_radiance(t, MWIR) + (1 - eps) * planck.band_radiance(t_sky, MWIR)
    if lit:
        expected += (1 - eps) * e_band * d[2] / np.pi
    ok = within_noise(ch["radiance"], ch["radiance_stderr"], expected)
    assert ok.all(), f"{(~ok).sum()} pixels off"
    assert abs(ch["radiance"].mean() / expected - 1) < 2e-3
    ran = manifest["sensors"][0]["frames"][0]["radiometry"]["sun"]
    assert ran.startswith("directional") if lit else ran == "skipped: sun below the horizon (night)"


def test_glass_reflects_only_its_reflectance(tmp_path):
    """A see-through material (eps 0.3, transmittance 0.6, so R 0.1) under a blackbody sky
    reflects R, not 1 - eps (found in review: a window in MWIR mirrored ~50 %); what it
    transmits is not traced (the render's surfaces are opaque, documented)."""
    eps, trans, t, t_sky = 0.3, 0.6, 300.0, 250.0
    stage = new_stage(tmp_path / "s.usda", sky_k=t_sky)
    glass = material(stage, "glass", eps)
    farr(glass.GetPrim(), "humv:material:transmittance", [trans, trans])
    plate(stage, "/World/p", 1e4, 0.0, glass, t)
    camera(stage, "ir", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0, band=MWIR)
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=64)
    ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    expected = eps * planck.band_radiance(t, MWIR) + (1 - eps - trans) * planck.band_radiance(t_sky, MWIR)
    assert abs(ch["radiance"].mean() / expected - 1) < 2e-3
    # a transmittance that leaves no room for the emissivity is one clear error
    farr(glass.GetPrim(), "humv:material:transmittance", [0.9, 0.9])
    stage.Save()
    with pytest.raises(InputError, match="transmittance"):
        render_stage(tmp_path / "s.usda", tmp_path / "out2", spp=4)


# --- blackbody read-back through the sensor chain ----------------------------------------------


def test_blackbody_panel_reads_back_within_netd(tmp_path):
    """Issue 6 check: a blackbody panel (eps 1) at 308 K, 40 m away, through a non-gray path
    (LWIR, tau 0.55-0.95, path radiance of a 285 K air column), rendered, passed through the
    sensor chain (PSF, NETD noise, 14-bit counts), corrected with the band-effective path
    ((L - L_path) / tau) and converted to brightness temperature: the panel's mean reads back
    within the NETD, and its pixel scatter is about the NETD."""
    chain = pytest.importorskip("humv_usd.physics.sensor")
    t_panel, rng_m, netd = 308.0, 40.0, 0.05
    stage = new_stage(tmp_path / "s.usda", sky_k=250.0)
    bb = material(stage, "blackbody", 1.0)
    mesh = UsdGeom.Mesh.Define(stage, "/World/panel")  # 8 m x 8 m, facing -y, centre 40 m away
    mesh.CreatePointsAttr(
        Vt.Vec3fArray(
            [Gf.Vec3f(-4, rng_m, -4), Gf.Vec3f(4, rng_m, -4), Gf.Vec3f(4, rng_m, 4), Gf.Vec3f(-4, rng_m, 4)]
        )
    )
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(bb)
    UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
        "humv:thermal:temperature", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform
    ).Set(Vt.FloatArray([t_panel]))
    cam = camera(stage, "ir", (0, 0, 0), (0, 1, 0), fov_x_deg=8.0, up=(0, 0, 1), netd=netd)
    wl = np.linspace(7.0, 15.0, 17)
    ranges = np.array([1.0, 20.0, 60.0, 200.0])
    k_ext = 0.004 + 0.008 * np.abs(np.sin(wl))  # per metre: spectral transmittance
    tau = np.exp(-np.outer(ranges, k_ext))
    rad = (1.0 - tau) * planck.spectral_radiance(wl, 285.0)  # isothermal path (Kirchhoff)
    atmosphere_tables(stage, wl)
    path_table(stage, str(cam.GetPath()), ranges, tau, rad)
    stage.Save()
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=16, seed=3)
    ch = read_exr(tmp_path / "out" / "ir" / "0000.exr")
    settings = manifest["sensors"][0]["frames"][0]["sensor_chain"]["settings"]
    l_meas = chain.counts_to_radiance(ch["counts"].astype(float), settings["gain"], settings["offset"])
    # atmospheric correction with the band-effective path at the panel's range (a user's view:
    # the sensor-response-weighted, 300 K Planck-weighted transmittance and the band path radiance)
    whole = radiometry.PathTable("p", ranges, wl, tau, rad).reduce(SubBands(LWIR, None, 1))
    r_px = float(np.nanmedian(ch["depth"][H // 2 - 3 : H // 2 + 3, W // 2 - 3 : W // 2 + 3]))
    tau_b, lp_b = whole.at(r_px, 0)
    bt = planck.brightness_temperature((l_meas - lp_b) / tau_b, LWIR)
    centre = bt[4:-4, 6:-6]  # away from the PSF-blurred panel edges (the panel fills the view)
    assert np.isfinite(ch["depth"]).all()
    raw = planck.brightness_temperature(l_meas, LWIR)[4:-4, 6:-6]
    assert abs(raw.mean() - t_panel) > 5 * netd  # the atmosphere matters ...
    assert abs(centre.mean() - t_panel) < netd  # ... and is corrected within the NETD
    # NETD noise (sigma_L = NETD dL/dT at 300 K), divided by tau and dL/dT at the panel by the
    # correction; Monte Carlo noise and the PSF's averaging change it by a few per cent
    expected_std = (
        netd
        * planck.band_radiance_derivative(300.0, LWIR)
        / planck.band_radiance_derivative(t_panel, LWIR)
        / tau_b
    )
    assert 0.75 * expected_std < centre.std() < 1.25 * expected_std
    on_disk = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert on_disk["sensor_chain"].startswith("ran")


@pytest.mark.parametrize(
    "band,response",
    [(LWIR, (np.array([7.5, 9.0, 12.0, 14.0]), np.array([0.2, 1.0, 0.8, 0.0]))), (MWIR, None)],
)
def test_subband_radiance_tables_match_the_exact_band_integral(band, response):
    sub = SubBands(band, response, 16)
    t = np.concatenate(
        [np.geomspace(150.0, 2000.0, 401), [5772.0], np.random.default_rng(1).uniform(250, 330, 200)]
    )
    exact = np.stack([planck.band_radiance(t, b, response) for b in sub.bands], axis=-1)
    assert_allclose(sub.radiance(t), exact, rtol=1e-6, atol=0)
    assert sub.radiance(300.0).shape == (len(sub),)
