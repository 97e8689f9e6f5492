"""Sensor presets, platforms and the sensor chain (PSF, NETD noise, counts, AGC)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from humv_usd.catalog import sensors as presets
from humv_usd.compat import trapezoid
from humv_usd.errors import InputError
from humv_usd.physics import planck
from humv_usd.physics import sensor as chain
from humv_usd.physics.sensor import SensorModel, apply_chain, psf_kernel
from humv_usd.scenario import validate
from humv_usd.scenario.inputs import read_values
from humv_usd.scenario.spec import DEFAULT_SUBBANDS, SENSOR_PRESETS
from humv_usd.sensors import layer as sensors_layer
from humv_usd.usd import schemas as S
from humv_usd.usd.sensor import read_sensor_model


def model_from_preset(name: str, **over) -> SensorModel:
    p = presets.preset(name)
    gain, offset = presets.calibration(name)
    kw = dict(
        name=name,
        band=p.band,
        wavelength_range_um=p.wavelength_um,
        response_wavelengths_um=np.asarray(p.response_wavelengths_um),
        response=np.asarray(p.response),
        resolution=p.resolution,
        pixel_pitch_m=p.pixel_pitch_um * 1e-6,
        f_number=p.f_number,
        focal_length_m=p.focal_length_mm * 1e-3,
        netd_k=p.netd_k,
        bit_depth=p.bit_depth,
        gain=gain,
        offset=offset,
        agc=p.agc,
        agc_percentiles=p.agc_percentiles,
        channel_response=None if p.channel_response is None else np.asarray(p.channel_response),
        full_well_e=p.full_well_e,
        read_noise_e=p.read_noise_e,
        preset=name,
    )
    kw.update(over)
    return SensorModel(**kw)


def mono(wavelength_um: float, pitch_um: float, f_number: float) -> SensorModel:
    """A sensor with a narrow flat response around one wavelength."""
    return SensorModel(
        name="m",
        band="LWIR",
        wavelength_range_um=(wavelength_um - 0.01, wavelength_um + 0.01),
        response_wavelengths_um=np.array([wavelength_um - 0.01, wavelength_um + 0.01]),
        response=np.array([1.0, 1.0]),
        resolution=(8, 8),
        pixel_pitch_m=pitch_um * 1e-6,
        f_number=f_number,
        focal_length_m=0.025,
    )


# ---------------------------------------------------------------------------- presets
def test_presets_cover_the_humvvex_imagers_with_sources():
    assert set(presets.PRESETS) == set(SENSOR_PRESETS)
    bands = sorted(
        presets.preset(n).band for n in ("atom1024_lwir", "lwir640_12um", "mwir_insb640", "rgb_imx273")
    )
    assert bands == ["EO", "LWIR", "LWIR", "MWIR"]  # the seed's four HUMVVEX imagers
    atom = presets.preset("atom1024_lwir")
    assert atom.resolution == (1024, 768) and atom.pixel_pitch_um == 17.0
    assert atom.wavelength_um == (8.0, 14.0) and atom.netd_k <= 0.05 and atom.bit_depth == 14
    assert presets.preset("lwir640_12um").pixel_pitch_um == 12.0
    mw = presets.preset("mwir_insb640")
    assert mw.resolution == (640, 512) and mw.wavelength_um == (3.0, 5.0) and mw.netd_k == 0.02
    rgb = presets.preset("rgb_imx273")
    assert rgb.bit_depth == 12 and len(rgb.channel_response) == 3
    for p in presets.PRESETS.values():
        assert len(p.source) > 150 and "typical" in p.source, p.name
        wl = np.asarray(p.response_wavelengths_um)
        r = np.asarray(p.response)
        assert np.all(np.diff(wl) > 0) and wl.size == r.size and r.max() == pytest.approx(1.0)
        assert np.all((r >= 0) & (r <= 1))
        # FOV = 2 atan(n p / 2 f)
        w = p.resolution[0] * p.pixel_pitch_um * 1e-3
        assert p.fov_deg[0] == pytest.approx(math.degrees(2 * math.atan(w / 2 / p.focal_length_mm)))
    assert atom.fov_deg[0] == pytest.approx(38.4, abs=0.1)
    # RGB channels peak in the right order: B < G < R
    peaks = [rgb.response_wavelengths_um[int(np.argmax(c))] for c in rgb.channel_response]
    assert peaks[2] < peaks[1] < peaks[0]


def test_ir_preset_calibration_spans_its_temperature_range():
    for name in ("atom1024_lwir", "lwir640_12um", "mwir_insb640"):
        m = model_from_preset(name)
        lo, hi = presets.preset(name).span_k
        assert lo <= 253.15 and hi >= 328.15
        for t, expected in ((lo, 0), (hi, m.max_count)):
            radiance = planck.band_radiance(t, m.wavelength_range_um, m.response_pair)
            assert chain.quantize(radiance, m.gain, m.offset, m.bit_depth) == expected
        # one count is finer than the NETD
        step_k = 1.0 / m.gain / planck.band_radiance_derivative(300.0, m.wavelength_range_um, m.response_pair)
        assert step_k < m.netd_k


# ---------------------------------------------------------------------------- PSF
def test_airy_psf_is_normalised_and_has_closed_form_zero():
    lam, n = 10.0, 1.0
    r = np.linspace(0, 400, 400001)
    h = chain.airy_psf(r, lam, n)
    total = trapezoid(h * 2 * np.pi * r, r)
    assert total == pytest.approx(chain.airy_encircled_energy(400, lam, n), rel=1e-4)
    assert chain.airy_psf(1.21967 * lam * n, lam, n) < 1e-7 * chain.airy_psf(0.0, lam, n)


@pytest.mark.parametrize("wavelength_um, f_number", [(10.0, 1.0), (4.0, 2.5), (0.55, 2.8)])
def test_psf_fwhm_matches_airy_closed_form(wavelength_um, f_number):
    """FWHM of the Airy pattern = 1.029 lambda N (Goodman 2005, §4.4.2)."""
    lam_n = wavelength_um * f_number
    pitch = lam_n / 10.0
    point = psf_kernel(mono(wavelength_um, pitch, f_number), [wavelength_um], pixel_footprint=False)
    assert point.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.allclose(point, point.T) and np.allclose(point, point[::-1, ::-1])
    fwhm = chain.kernel_fwhm_px(point) * pitch
    assert fwhm == pytest.approx(1.029 * lam_n, rel=0.01)
    # integrating over a pixel footprint of lambda N / 10 broadens it by well under 2 %
    box = psf_kernel(mono(wavelength_um, pitch, f_number), [wavelength_um])
    assert box.sum() == pytest.approx(1.0, abs=1e-12)
    assert 1.029 * lam_n <= chain.kernel_fwhm_px(box) * pitch < 1.02 * 1.029 * lam_n


def test_psf_encircled_energy_matches_rayleigh():
    """Energy inside the first dark ring (1.22 lambda N) = 0.838 (Born & Wolf §8.5.2)."""
    lam, n, pitch = 10.0, 1.0, 1.0
    k = psf_kernel(mono(lam, pitch, n), [lam], energy=0.99)
    c = k.shape[0] // 2
    y, x = np.mgrid[-c : c + 1, -c : c + 1] * pitch
    inside = np.hypot(x, y) <= 1.2197 * lam * n
    kept = chain.airy_encircled_energy(c * pitch, lam, n)  # the kernel is renormalised to its extent
    assert k[inside].sum() == pytest.approx(
        chain.airy_encircled_energy(1.2197 * lam * n, lam, n) / kept, abs=0.01
    )


def test_psf_of_big_pixels_is_nearly_a_delta_and_band_average_lies_between():
    m = model_from_preset("atom1024_lwir", f_number=0.01)  # diffraction negligible: pixel box only
    k = psf_kernel(m)
    assert k.shape == (3, 3) and k[1, 1] > 0.99
    fine = model_from_preset("atom1024_lwir", pixel_pitch_m=1e-6)  # resolve the PSF itself
    widths = [chain.kernel_fwhm_px(psf_kernel(fine, [lam], pixel_footprint=False)) for lam in (8.0, 14.0)]
    band = chain.kernel_fwhm_px(psf_kernel(fine, pixel_footprint=False))
    assert widths[0] < band < widths[1]
    m = model_from_preset("atom1024_lwir")
    pitch = m.pixel_pitch_m * 1e6
    w = chain.psf_weights(m, np.linspace(8, 14, 13))
    assert w.sum() == pytest.approx(1.0) and np.all(w > 0)
    assert psf_kernel(m).sum() == pytest.approx(1.0) and pitch == 17.0


def test_psf_convolution_keeps_flat_fields_and_total_power():
    m = model_from_preset("lwir640_12um")
    k = psf_kernel(m)
    flat = np.full((40, 50), 7.5)
    np.testing.assert_allclose(chain.convolve_psf(flat, k), 7.5, rtol=1e-12)
    point = np.zeros((61, 61))
    point[30, 30] = 1.0
    out = chain.convolve_psf(point, k)
    assert out.sum() == pytest.approx(1.0, rel=1e-9)
    np.testing.assert_allclose(
        out[30 - k.shape[0] // 2 : 31 + k.shape[0] // 2, 30 - k.shape[0] // 2 : 31 + k.shape[0] // 2],
        k,
        atol=1e-12,
    )


# ---------------------------------------------------------------------------- noise
@pytest.mark.parametrize("name", ["atom1024_lwir", "mwir_insb640"])
def test_noise_of_a_flat_300k_field_is_the_netd(name):
    """Temporal std of a flat 300 K blackbody, read back as brightness temperature = NETD."""
    m = model_from_preset(name)
    band, resp = m.wavelength_range_um, m.response_pair
    radiance = np.full((32, 32), planck.band_radiance(300.0, band, resp))
    rng = np.random.default_rng(7)
    frames = np.stack([apply_chain(radiance, m, rng, psf=False).counts for _ in range(24)])
    temps = planck.brightness_temperature(chain.counts_to_radiance(frames, m.gain, m.offset), band, resp)
    std = temps.std(axis=0, ddof=1)
    n = frames.shape[0] * frames.shape[1] * frames.shape[2]
    # sampling error of a std from n Gaussian samples: 1/sqrt(2 n) (~0.5 %); the quantizer adds
    # step^2/12 to the variance
    step_k = 1.0 / m.gain / planck.band_radiance_derivative(300.0, band, resp)
    expected = math.sqrt(m.netd_k**2 + step_k**2 / 12)
    assert np.sqrt(np.mean(std**2)) == pytest.approx(expected, rel=4 / math.sqrt(2 * n))
    assert np.mean(temps) == pytest.approx(300.0, abs=0.01)
    assert apply_chain(radiance, m, rng).noise_sigma == pytest.approx(
        m.netd_k * planck.band_radiance_derivative(300.0, band, resp)
    )


def test_noise_uses_the_sensors_reference_temperature():
    """An authored humv:sensor:referenceTemperature sets where the NETD is defined (found in
    review: the render passed a fixed 300 K)."""
    import dataclasses

    m = dataclasses.replace(model_from_preset("atom1024_lwir"), reference_temperature_k=330.0)
    band, resp = m.wavelength_range_um, m.response_pair
    radiance = np.full((8, 8), planck.band_radiance(330.0, band, resp))
    out = apply_chain(radiance, m, np.random.default_rng(0), psf=False)
    assert out.noise_sigma == pytest.approx(m.netd_k * planck.band_radiance_derivative(330.0, band, resp))
    assert out.noise_sigma > 1.2 * m.netd_k * planck.band_radiance_derivative(300.0, band, resp)
    assert out.settings["noise"]["reference_temperature_k"] == 330.0


def test_eo_shot_and_read_noise_follow_the_photon_transfer_curve():
    m = model_from_preset("rgb_imx273", gain=None)
    rgb = np.full((64, 64, 3), 0.3)
    rgb[:, 32:] = 0.05
    out = apply_chain(rgb, m, np.random.default_rng(3), psf=False)
    l_sat = out.settings["noise"]["saturation_input"]
    e_per_unit = m.full_well_e / l_sat
    for half, level in ((np.s_[:, :32], 0.3), (np.s_[:, 32:], 0.05)):
        e = out.radiance[half] * e_per_unit
        mean_e = level * e_per_unit
        # EMVA 1288: variance [e-^2] = mean signal + read noise^2
        assert e.var(ddof=1) == pytest.approx(mean_e + m.read_noise_e**2, rel=0.05)
    # auto exposure: the 99.5th percentile sits at 80 % of full well
    assert 0.3 * e_per_unit == pytest.approx(0.8 * m.full_well_e, rel=1e-9)
    assert out.counts.dtype == np.uint16 and out.counts.max() <= 4095
    assert out.image8.dtype == np.uint8 and out.image8.shape == (64, 64, 3)


def test_colour_matrix_maps_d65_white_to_grey():
    import colour

    m = model_from_preset("rgb_imx273")
    ccm = chain.colour_correction_matrix(m)
    shape = colour.SpectralShape(400, 700, 10)
    d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
    wl = shape.wavelengths / 1000.0
    cam = chain.integrate_response(wl, d65.values[None, :], m)[0]
    srgb = ccm @ cam
    assert srgb.min() == pytest.approx(srgb.max(), rel=0.03)
    # a saturated red patch stays red
    red = np.where(wl > 0.6, 1.0, 0.02)
    cam_red = chain.integrate_response(wl, (red * d65.values)[None, :], m)[0]
    out = ccm @ cam_red
    assert out[0] > 3 * out[1] and out[0] > 3 * out[2]


# ---------------------------------------------------------------------------- counts and AGC
@pytest.mark.parametrize("bits", [8, 14, 16])
def test_quantization_bounds_and_inverse(bits):
    gain, offset = 137.0, -2000.0
    rng = np.random.default_rng(0)
    top = (1 << bits) - 1
    lo, hi = (0 - offset) / gain, (top - offset) / gain
    radiance = rng.uniform(lo, hi, 10000)
    counts = chain.quantize(radiance, gain, offset, bits)
    assert counts.dtype == np.uint16 and counts.min() >= 0 and counts.max() <= top
    back = chain.counts_to_radiance(counts, gain, offset)
    assert np.max(np.abs(back - radiance)) <= 0.5 / gain * (1 + 1e-9)
    extreme = chain.quantize(np.array([-1e9, 1e9, np.nan, np.inf]), gain, offset, bits)
    assert extreme.tolist() == [0, top, 0, top]


def test_agc_modes():
    rng = np.random.default_rng(1)
    counts = rng.normal(8000, 300, (100, 120)).astype(np.uint16)
    lin, info = chain.agc(counts, "linear", (1.0, 99.0), 14)
    lo, hi = np.percentile(counts, [1, 99])
    assert info["black_count"] == lo and info["white_count"] == hi
    assert np.mean(lin == 0) == pytest.approx(0.01, abs=0.005) and np.mean(lin == 255) == pytest.approx(
        0.01, abs=0.005
    )
    eq, _ = chain.agc(counts, "histogram", bit_depth=14)
    hist = np.bincount(eq.ravel() // 32, minlength=8) / eq.size
    np.testing.assert_allclose(hist, 1 / 8, atol=0.02)  # equalised: flat histogram
    fixed, _ = chain.agc(counts, "none", bit_depth=14)
    np.testing.assert_array_equal(fixed, np.rint(counts * 255.0 / 16383).astype(np.uint8))
    with pytest.raises(ValueError, match="invalid AGC mode"):
        chain.agc(counts, "gamma")


def test_apply_chain_records_settings_and_checks_shapes():
    m = model_from_preset("lwir640_12um")
    img = np.full((20, 24), planck.band_radiance(300.0, m.wavelength_range_um, m.response_pair))
    img[5:10, 5:10] = planck.band_radiance(310.0, m.wavelength_range_um, m.response_pair)
    out = apply_chain(img, m, np.random.default_rng(0))
    s = out.settings
    assert s["psf"]["kernel_px"] % 2 == 1 and s["agc"]["mode"] == "plateau"
    assert s["gain"] == m.gain and s["offset"] == m.offset and s["saturated_fraction"] == 0
    assert out.counts.shape == img.shape and out.image8.dtype == np.uint8
    import json

    json.dumps(s)
    with pytest.raises(ValueError, match="must be"):
        apply_chain(np.zeros((4, 4, 3)), m, np.random.default_rng(0))
    holed = img.copy()
    holed[0, 0] = np.nan
    out = apply_chain(holed, m, np.random.default_rng(0))
    assert out.settings["nonfinite_inputs_zeroed"] == 1 and np.isfinite(out.radiance).all()
    # noise and PSF off: counts are exactly the quantized input
    clean = apply_chain(img, m, np.random.default_rng(0), psf=False, noise=False)
    np.testing.assert_array_equal(clean.counts, chain.quantize(img, m.gain, m.offset, m.bit_depth))


# ---------------------------------------------------------------------------- scenario + layer
def test_scenario_preset_fills_and_table_wins(raw):
    s = validate(raw)
    atom, lw, mw, eo = s["sensor"]
    assert atom["resolution"] == [1024, 768] and atom["pixel_pitch_um"] == 17.0
    assert mw["band"] == "MWIR" and mw["wavelength_um"] == [3.0, 5.0] and mw["netd_k"] == 0.02
    assert eo["band"] == "EO" and eo["gain"] is None and eo["bit_depth"] == 12
    assert lw["gain"] == pytest.approx(presets.calibration("lwir640_12um")[0])
    raw["sensor"][1]["resolution"] = [320, 256]
    raw["sensor"][1]["netd_k"] = 0.03
    s = validate(raw)
    assert s["sensor"][1]["resolution"] == [320, 256] and s["sensor"][1]["netd_k"] == 0.03
    assert s["sensor"][1]["pixel_pitch_um"] == 12.0
    bad = copy.deepcopy(raw)
    bad["sensor"][0]["preset"] = "atom2048"
    with pytest.raises(InputError, match=r"sensor\[0\]\.preset = 'atom2048': allowed values"):
        validate(bad)
    other = copy.deepcopy(raw)
    other["sensor"][0]["band"] = "MWIR"  # another band than the preset's: no LWIR edges/counts
    o = validate(other)["sensor"][0]
    assert o["wavelength_um"] == [3.0, 5.0] and o["gain"] == 100.0 and o["resolution"] == [1024, 768]
    eo = copy.deepcopy(raw)
    eo["sensor"][0] = {
        "id": "cam",
        "band": "EO",
        "resolution": [64, 48],
        "focal_length_mm": 8.0,
        "position_m": [0, -5, 1.6],
        "look_at_m": [0, 0, 1],
    }
    assert validate(eo)["sensor"][0]["gain"] is None  # EO: auto exposure
    bare = copy.deepcopy(raw)
    del bare["sensor"][0]["preset"]
    with pytest.raises(InputError, match=r"sensor\[0\]\.resolution: missing required key"):
        validate(bare)


def test_mast_height_is_checked(raw):
    raw["sensor"][0]["platform"] = "mast"
    raw["sensor"][0]["position_m"] = [0.0, -15.0, 1.6]
    with pytest.raises(InputError, match=r"sensor\[0\]\.position_m\[2\] = 1.6: a mast camera's height"):
        validate(raw)
    raw["sensor"][0]["position_m"] = [0.0, -15.0, 12.0]
    assert validate(raw)["sensor"][0]["platform"] == "mast"


def aerial_raw(raw):
    raw["general"]["duration_s"] = 0.2
    raw["general"]["fps"] = 10.0
    s = raw["sensor"][0]
    del s["position_m"]
    s.update(
        platform="aerial",
        look_at_m=[1.0, 2.0, 0.0],
        altitude_m=120.0,
        orbit_radius_m=150.0,
        orbit_speed_m_s=30.0,
        orbit_start_deg=180.0,
    )
    raw["sensor"] = [s]
    return raw


def test_aerial_orbit_is_time_sampled_and_looks_at_the_centre(raw):
    scenario = validate(aerial_raw(copy.deepcopy(raw)))
    stage = Usd.Stage.Open(sensors_layer.build(scenario))
    prim = stage.GetPrimAtPath("/World/Sensors/atom1024_lwir")
    assert prim.GetAttribute(S.SENSOR_PLATFORM).Get() == "aerial"
    samples = UsdGeom.Xformable(prim).GetOrderedXformOps()[0].GetAttr().GetTimeSamples()
    assert samples == [0.0, 1.0, 2.0]
    centre = np.array([1.0, 2.0, 0.0])
    prev = None
    for frame in samples:
        m = UsdGeom.Camera(prim).GetCamera(Usd.TimeCode(frame)).transform
        pos = np.array(m.Transform((0, 0, 0)))
        fwd = np.array(m.TransformDir((0, 0, -1)))
        assert pos[2] == pytest.approx(120.0)
        assert np.hypot(*(pos[:2] - centre[:2])) == pytest.approx(150.0)
        to_centre = (centre - pos) / np.linalg.norm(centre - pos)
        assert np.dot(fwd / np.linalg.norm(fwd), to_centre) == pytest.approx(1.0, abs=1e-9)
        if prev is not None:  # arc length per frame = speed / fps
            chord = np.linalg.norm(pos - prev)
            assert 2 * 150.0 * math.asin(chord / 300.0) == pytest.approx(30.0 / 10.0, rel=1e-6)
        prev = pos
    start = np.array(UsdGeom.Camera(prim).GetCamera(Usd.TimeCode(0)).transform.Transform((0, 0, 0)))
    np.testing.assert_allclose(start[:2], [1.0, 2.0 - 150.0], atol=1e-9)  # 180 deg: south
    bad = aerial_raw(copy.deepcopy(raw))
    bad["sensor"][0]["position_m"] = [0, 0, 1]
    with pytest.raises(InputError, match="not with platform = 'aerial'"):
        validate(bad)


def test_sensors_layer_round_trips_to_the_chain_model(raw):
    scenario = validate(raw)
    stage = Usd.Stage.Open(sensors_layer.build(scenario))
    for s in scenario["sensor"]:
        prim = stage.GetPrimAtPath(f"/World/Sensors/{s['id']}")
        m = read_sensor_model(prim)
        p = presets.preset(s["preset"])
        assert m.preset == p.name and m.band == p.band and m.agc == p.agc
        assert m.resolution == p.resolution and m.bit_depth == p.bit_depth
        assert m.focal_length_m == pytest.approx(p.focal_length_mm * 1e-3)
        assert m.pixel_pitch_m == pytest.approx(p.pixel_pitch_um * 1e-6)
        np.testing.assert_allclose(m.response, p.response, atol=1e-6)
        assert m.fov_deg[0] == pytest.approx(p.fov_deg[0], rel=1e-6)
        if p.band == "EO":
            assert m.gain is None and m.channel_response.shape == (3, len(p.response_wavelengths_um))
        else:
            assert m.gain == pytest.approx(presets.calibration(p.name)[0], rel=1e-6)


def test_presets_file_is_up_to_date():
    """layers/sensors.usda = every preset (regenerate: python -m humv_usd.sensors.layer)."""
    assert sensors_layer.main(["--check"]) == 0
    stage = Usd.Stage.Open(str(sensors_layer.PRESETS_FILE))
    names = {p.GetName() for p in stage.GetPrimAtPath("/World/Sensors").GetChildren()}
    assert names == set(presets.PRESETS)


# ---------------------------------------------------------------------------- NETD vs f-number
def test_netd_scales_with_f_number_when_not_given(raw):
    """A preset's f-number overridden without a netd_k: NETD x (4N^2 + 1)/(4N0^2 + 1) on the prim
    (detector-limited, Dereniak & Boreman 1996 §5.8), recorded in the attribute's customData; a
    netd_k given explicitly (other than the preset's) or the preset's f-number: unchanged."""
    by_id = {s["id"]: s for s in raw["sensor"]}
    by_id["atom1024_lwir"]["f_number"] = 1.4  # preset f/1, 50 mK
    by_id["lwir640"].update(f_number=2.0, netd_k=0.03)  # explicit NETD wins
    by_id["mwir_insb"]["f_number"] = 2.5  # the preset's own f-number
    stage = Usd.Stage.Open(sensors_layer.build(validate(raw)))

    def netd(name):
        return stage.GetPrimAtPath(f"/World/Sensors/{name}").GetAttribute(S.SENSOR_NETD)

    assert netd("atom1024_lwir").Get() == pytest.approx(0.05 * (4 * 1.4**2 + 1) / 5.0, rel=1e-6)
    assert "x (4N^2+1)/(4N0^2+1)" in netd("atom1024_lwir").GetCustomDataByKey("humv:netdOrigin")
    assert netd("lwir640").Get() == pytest.approx(0.03, rel=1e-6)
    assert netd("mwir_insb").Get() == pytest.approx(0.02, rel=1e-6)
    lwir640 = [i for i, s in enumerate(raw["sensor"]) if s["id"] == "lwir640"][0]
    assert netd("lwir640").GetCustomDataByKey("humv:netdOrigin") == f"given: sensor[{lwir640}].netd_k"
    assert netd("mwir_insb").GetCustomDataByKey("humv:netdOrigin") == "preset mwir_insb640"
    # the chain's noise follows: sigma_L = NETD dL/dT
    m = read_sensor_model(stage.GetPrimAtPath("/World/Sensors/atom1024_lwir"))
    assert m.netd_k == pytest.approx(0.0884, rel=1e-5)
    noise = apply_chain(np.full((8, 8), 40.0), m, np.random.default_rng(0), psf=False).settings["noise"]
    assert noise["netd_k"] == m.netd_k and noise["netd_source"].startswith("scaled from preset atom1024_lwir")
    assert presets.netd_for_f_number(0.05, 1.0, 1.0) == 0.05
    # a netd_k given equal to the preset's value is the user's word: not scaled
    by_id["atom1024_lwir"]["netd_k"] = 0.05
    stage = Usd.Stage.Open(sensors_layer.build(validate(raw)))
    assert netd("atom1024_lwir").Get() == pytest.approx(0.05, rel=1e-6)
    assert netd("atom1024_lwir").GetCustomDataByKey("humv:netdOrigin").startswith("given: sensor[")


def test_netd_origin_is_recorded_at_load_and_read_back(raw, tmp_path):
    """Issue 24.2: where a sensor's NETD comes from is recorded when the scenario fills the
    table (not re-derived later by comparing floats), authored with the value, and read back
    by the render's sensor read; a user layer's override without a note is named as such."""
    raw["sensor"] = [
        {"id": "p", "preset": "lwir640_12um", "position_m": [0, -5, 2], "look_at_m": [0, 0, 1]},
        {
            "id": "g",
            "preset": "lwir640_12um",
            "netd_k": 0.05,
            "position_m": [0, -5, 2],
            "look_at_m": [0, 0, 1],
        },
        {
            "id": "s",
            "preset": "lwir640_12um",
            "f_number": 2.0,
            "position_m": [0, -5, 2],
            "look_at_m": [0, 0, 1],
        },
        {
            "id": "d",
            "band": "LWIR",
            "resolution": [64, 48],
            "focal_length_mm": 10.0,
            "position_m": [0, -5, 2],
            "look_at_m": [0, 0, 1],
        },
    ]
    scenario = validate(raw)
    assert scenario.netd_origin[:2] == ("preset lwir640_12um", "given: sensor[1].netd_k")
    assert scenario.netd_origin[2].startswith("scaled from preset lwir640_12um NETD 0.05 K at f/1 to f/2")
    assert scenario.netd_origin[3].startswith("default: 0.05 K")
    # the origin is an input of the sensors layer's cache key (the same value, another note)
    assert read_values(scenario, sensors_layer.READS)["@netdOrigin"] == list(scenario.netd_origin)
    layer = sensors_layer.build(scenario)
    path = tmp_path / "sensors.usda"
    layer.Export(str(path))
    stage = Usd.Stage.Open(str(path))
    models = {n: read_sensor_model(stage.GetPrimAtPath(f"/World/Sensors/{n}")) for n in "pgsd"}
    assert [models[n].netd_note for n in "pgsd"] == list(scenario.netd_origin)
    assert models["s"].netd_k == pytest.approx(0.05 * 17.0 / 5.0, rel=1e-6)  # (4N^2+1)/(4N0^2+1)
    # a user layer that overrides the value: its own file, not the sensors layer's note
    edit = tmp_path / "edit.usda"
    root = Sdf.Layer.CreateNew(str(edit))
    root.subLayerPaths = [str(path)]
    user = Usd.Stage.Open(root)
    user.SetEditTarget(root)
    user.GetPrimAtPath("/World/Sensors/p").GetAttribute(S.SENSOR_NETD).Set(0.08)
    m = read_sensor_model(user.GetPrimAtPath("/World/Sensors/p"))
    assert m.netd_k == pytest.approx(0.08) and m.netd_note.startswith(f"authored in {edit}")
    # nothing authored: the reader's own default, said so
    bare = Usd.Stage.CreateInMemory()
    cam = UsdGeom.Camera.Define(bare, "/c")
    cam.GetPrim().ApplyAPI(S.SENSOR_API)
    assert read_sensor_model(cam.GetPrim()).netd_note.startswith("reader default: 0.05 K")
    # the sensor chain's manifest record carries it
    noise = apply_chain(np.full((8, 8), 40.0), models["g"], np.random.default_rng(0), psf=False).settings[
        "noise"
    ]
    assert noise["netd_source"] == "given: sensor[1].netd_k"


def test_subbands_key_is_authored_for_infrared_sensors(raw):
    from humv_usd.render import radiometry
    from humv_usd.scenario import spec

    assert spec.SENSOR.keys["subbands"].default == radiometry.DEFAULT_SUBBANDS
    by_id = {s["id"]: s for s in raw["sensor"]}
    by_id["lwir640"]["subbands"] = 6
    stage = Usd.Stage.Open(sensors_layer.build(validate(raw)))

    def sub(name):
        return stage.GetPrimAtPath(f"/World/Sensors/{name}").GetAttribute(S.SENSOR_SUBBANDS)

    assert sub("lwir640").Get() == 6 and sub("atom1024_lwir").Get() == radiometry.DEFAULT_SUBBANDS
    assert not sub("eo_rgb").HasAuthoredValue()
    by_id["lwir640"]["subbands"] = 0
    with pytest.raises(InputError, match="subbands"):
        validate(raw)


# ---------------------------------------------------------------------------- the render's read
def _camera(stage, name, **attrs):
    cam = UsdGeom.Camera.Define(stage, f"/World/{name}")
    prim = cam.GetPrim()
    prim.ApplyAPI(S.SENSOR_API)
    for key, value in attrs.items():
        prim.GetAttribute(key).Set(value)
    return prim


def test_read_sensor_is_the_model_with_what_the_render_needs():
    """One sensor model: the render's read (read_sensor) is read_sensor_model plus path,
    sub-bands, skip reason and whether the response is authored."""
    from pxr import Gf, Vt

    from humv_usd.usd.sensor import read_sensor

    stage = Usd.Stage.CreateInMemory()
    res = Gf.Vec2i(64, 48)
    lw = _camera(
        stage,
        "lw",
        **{S.SENSOR_BAND: "LWIR", S.SENSOR_WAVELENGTH_RANGE: Gf.Vec2f(8, 14), S.SENSOR_RESOLUTION: res},
    )
    m = read_sensor(lw)
    assert isinstance(m, SensorModel) and m.path == "/World/lw" and m.kind == "IR" and m.rendered
    assert m.band_response is None and m.subbands == DEFAULT_SUBBANDS  # the schema's fallback
    np.testing.assert_allclose(m.response_pair[0], [8.0, 14.0])  # flat band for the chain
    lw.GetAttribute(S.SENSOR_RESPONSE_WAVELENGTHS).Set(Vt.FloatArray([8.0, 11.0, 14.0]))
    lw.GetAttribute(S.SENSOR_RESPONSE).Set(Vt.FloatArray([0.5, 1.0, 0.25]))
    lw.GetAttribute(S.SENSOR_SUBBANDS).Set(3)
    m = read_sensor(lw)
    np.testing.assert_allclose(m.band_response[1], [0.5, 1.0, 0.25])
    assert m.subbands == 3
    lw.GetAttribute(S.SENSOR_RESPONSE).Set(Vt.FloatArray([0.5, 1.0]))
    with pytest.raises(InputError, match="expected one response value per wavelength"):
        read_sensor(lw)
    eo = _camera(stage, "eo", **{S.SENSOR_WAVELENGTH_RANGE: Gf.Vec2f(0.4, 0.7), S.SENSOR_RESOLUTION: res})
    eo.GetAttribute(S.SENSOR_RESPONSE).Set(Vt.FloatArray([1.0, 1.0]))  # not checked: EO uses the CIE observer
    m = read_sensor(eo)
    assert m.kind == "EO" and m.band_response is None  # by its range below 3 um
    ortho = _camera(
        stage,
        "ortho",
        **{S.SENSOR_BAND: "MWIR", S.SENSOR_WAVELENGTH_RANGE: Gf.Vec2f(3, 5), S.SENSOR_RESOLUTION: res},
    )
    UsdGeom.Camera(ortho).GetProjectionAttr().Set(UsdGeom.Tokens.orthographic)
    m = read_sensor(ortho)
    assert not m.rendered and "only perspective cameras are rendered" in m.skip_reason
