"""Sensor chain of real cores (issue 28): plateau AGC, artefact stages (vignetting, bolometer lag,
fixed-pattern noise and its drift, quantisation, JPEG), the thermal-core presets and the one
field-of-view formula. Expectations are closed forms or hand-worked histograms."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from humv_usd.catalog import sensors as presets
from humv_usd.editor.plan import horizontal_fov_deg
from humv_usd.physics import planck
from humv_usd.physics import sensor as chain
from humv_usd.physics.sensor import SensorModel, apply_chain
from humv_usd.scenario import validate
from humv_usd.sensors import layer as sensors_layer
from humv_usd.usd.sensor import read_camera_pose, read_sensor_model, write_sensor


def lwir(**over) -> SensorModel:
    """The Boson 640 preset as a model at 160 x 128 px (its calibration: 233-373 K on 14 bits)."""
    p = presets.preset("boson640")
    gain, offset = presets.calibration("boson640")
    kw = dict(
        name="t",
        band="LWIR",
        wavelength_range_um=p.wavelength_um,
        response_wavelengths_um=np.asarray(p.response_wavelengths_um),
        response=np.asarray(p.response),
        resolution=(160, 128),
        pixel_pitch_m=12e-6,
        f_number=1.0,
        focal_length_m=0.018,
        netd_k=0.05,
        gain=gain,
        offset=offset,
        agc="plateau",
    )
    kw.update(over)
    return SensorModel(**kw)


def band_l(m: SensorModel, t_k):
    return planck.band_radiance(t_k, m.wavelength_range_um, m.response_pair)


FACE = (slice(20, 30), slice(20, 30))  # 100 px = 0.49 % of 160 x 128
JACKET = (slice(60, 72), slice(100, 110))  # 120 px = 0.59 %
BACKGROUND = (slice(80, 120), slice(20, 80))


def person_scene(m: SensorModel) -> np.ndarray:
    """10 degC surroundings, a 17 degC face and a -1 degC jacket (each under 1 % of the pixels)."""
    img = np.full((128, 160), band_l(m, 283.15))
    img[FACE] = band_l(m, 290.15)
    img[JACKET] = band_l(m, 272.15)
    return img


# ============================================================================ 1. AGC
def test_plateau_agc_keeps_a_face_and_a_jacket_apart_where_the_linear_stretch_saturates():
    m = lwir()
    img = person_scene(m)
    out = {
        mode: apply_chain(img, dataclasses.replace(m, agc=mode), np.random.default_rng(0), psf=False)
        for mode in ("linear", "plateau")
    }
    lin = out["linear"].image8
    # linear 1-99 % stretch: the background noise fills 0..255, face and jacket are clipped to
    # the ends and read like the brightest / darkest 1 % of the noise
    assert np.all(lin[FACE] == 255) and np.all(lin[JACKET] == 0)
    assert np.mean(lin[BACKGROUND] == 255) > 0 and np.mean(lin[BACKGROUND] == 0) > 0
    pl = out["plateau"].image8
    face, jacket, bg = pl[FACE].astype(float), pl[JACKET].astype(float), pl[BACKGROUND].astype(float)
    assert face.mean() - jacket.mean() > 150
    # every face pixel brighter than 99 % of the background, every jacket pixel darker than 99 %
    assert face.min() > np.percentile(bg, 99) and jacket.max() < np.percentile(bg, 1)
    assert len(np.unique(pl[FACE])) > 5  # the face keeps its (noise) texture: not one clipped level
    # the radiometric outputs do not depend on the AGC
    np.testing.assert_array_equal(out["linear"].counts, out["plateau"].counts)
    np.testing.assert_array_equal(out["linear"].radiance, out["plateau"].radiance)


def test_plateau_equalisation_closed_form():
    """10 px at count 10, 1000 at 20, 10 at 30, plateau 10 px: clipped histogram 10/10/10, so
    the levels are 0, 127.5 -> 128, 255; histogram equalisation gives the big bin 1000/1010 of
    the range (252). Plateau 1 (no clipping) is histogram equalisation."""
    counts = np.array([10] * 10 + [20] * 1000 + [30] * 10, dtype=np.uint16).reshape(30, 34)
    img, info = chain.agc(counts, "plateau", bit_depth=14, plateau=10 / counts.size)
    assert {int(img[counts == k][0]) for k in (10, 20, 30)} == {0, 128, 255}
    assert img[counts == 20][0] == 128 and info["clipped_bins"] == 1
    eq, _ = chain.agc(counts, "histogram", bit_depth=14)
    assert eq[counts == 20][0] == round(1000 / 1010 * 255)
    rng = np.random.default_rng(4)
    noisy = rng.normal(8000, 300, (50, 60)).astype(np.uint16)
    np.testing.assert_array_equal(
        chain.agc(noisy, "plateau", bit_depth=14, plateau=1.0)[0],
        chain.agc(noisy, "histogram", bit_depth=14)[0],
    )


def test_plateau_max_gain_limits_the_span_about_the_midpoint():
    counts = np.arange(1000, 1021, dtype=np.uint16).repeat(10).reshape(21, 10)  # 20 counts wide
    img, info = chain.agc(counts, "plateau", bit_depth=14, max_gain=2.0, midpoint=127.0)
    assert info["span_levels"] == 40.0
    assert img.min() == 107 and img.max() == 147  # 127 -+ 20
    free, _ = chain.agc(counts, "plateau", bit_depth=14)
    assert free.min() == 0 and free.max() == 255
    flat, _ = chain.agc(np.full((4, 4), 900, np.uint16), "plateau", bit_depth=14)
    assert np.all(flat == 127)


def test_plateau_is_the_default_for_infrared_and_eo_keeps_linear(raw):
    stage = Usd.Stage.CreateInMemory()
    ir = UsdGeom.Camera.Define(stage, "/Ir").GetPrim()
    ir.CreateAttribute("humv:sensor:band", Sdf.ValueTypeNames.Token).Set("LWIR")
    ir.CreateAttribute("humv:sensor:wavelengthRange", Sdf.ValueTypeNames.Float2).Set((8.0, 14.0))
    eo = UsdGeom.Camera.Define(stage, "/Eo").GetPrim()
    eo.CreateAttribute("humv:sensor:band", Sdf.ValueTypeNames.Token).Set("EO")
    for prim in (ir, eo):
        UsdGeom.Camera(prim).CreateFocalLengthAttr(0.18)
    assert read_sensor_model(ir).agc == "plateau" and read_sensor_model(eo).agc == "linear"
    s = validate(raw)
    by_id = {x["id"]: x for x in s["sensor"]}
    assert {by_id[i]["agc"] for i in ("atom1024_lwir", "lwir640", "mwir_insb")} == {"plateau"}
    assert by_id["eo_rgb"]["agc"] == "linear"
    raw["sensor"] = [
        {
            "id": "bare",
            "resolution": [64, 48],
            "focal_length_mm": 9.0,
            "position_m": [0, -9, 1],
            "look_at_m": [0, 0, 1],
        }
    ]
    assert validate(raw)["sensor"][0]["agc"] == "plateau"


def test_eo_plateau_equalises_luminance():
    p = presets.preset("rgb_imx273")
    m = SensorModel(
        name="e",
        band="EO",
        wavelength_range_um=p.wavelength_um,
        response_wavelengths_um=np.asarray(p.response_wavelengths_um),
        response=np.asarray(p.response),
        resolution=(40, 30),
        pixel_pitch_m=3.45e-6,
        f_number=2.8,
        focal_length_m=0.012,
        bit_depth=12,
        agc="plateau",
    )
    rgb = np.full((30, 40, 3), 0.2)
    rgb[5:8, 5:8] = 0.9
    out = apply_chain(rgb, m, np.random.default_rng(0), psf=False, eo_space="srgb")
    assert out.settings["agc"]["mode"] == "plateau" and out.image8[6, 6].mean() > out.image8[20, 20].mean()


# ============================================================================ 2. artefacts
def test_vignetting_is_cos4_of_the_field_angle():
    m = lwir(vignetting="cos4", resolution=(9, 7), focal_length_m=0.004)
    falloff = chain.vignetting(m.resolution, m.pixel_pitch_m, m.focal_length_m)
    r_corner = math.hypot(4 * 12e-6, 3 * 12e-6)
    assert falloff[0, 0] == pytest.approx(math.cos(math.atan(r_corner / 0.004)) ** 4, rel=1e-12)
    assert falloff[3, 4] == 1.0 and falloff[3, 0] == pytest.approx(math.cos(math.atan(48e-6 / 0.004)) ** 4)
    flat = np.full((7, 9), 5.0)
    out = apply_chain(flat, m, np.random.default_rng(0), psf=False, noise=False)
    np.testing.assert_allclose(out.radiance, 5.0 * falloff, rtol=1e-12)
    assert out.settings["vignetting"]["corner"] == pytest.approx(falloff[0, 0])
    np.testing.assert_array_equal(flat, 5.0)  # the input (the render's radiance) is untouched
    off = apply_chain(flat, lwir(resolution=(9, 7)), np.random.default_rng(0), psf=False, noise=False)
    np.testing.assert_allclose(off.radiance, 5.0) and off.settings["vignetting"] is None


def test_bolometer_lag_matches_the_first_order_solution_over_frames():
    """tau dy/dt = x - y. A ramp x = s t from rest: y = s (t - tau (1 - exp(-t/tau))); a
    constant x after y0: y = x + (y0 - x) exp(-t/tau). Frames at 100 Hz, tau 10 ms."""
    tau, fps, s = 0.010, 100.0, 3.0
    m = lwir(time_constant_s=tau, resolution=(4, 3))
    state = chain.ChainState()
    for n in range(8):
        t = n / fps
        out = apply_chain(
            np.full((3, 4), s * t), m, np.random.default_rng(0), psf=False, noise=False, time_s=t, state=state
        )
        expected = s * (t - tau * (1 - math.exp(-t / tau)))
        np.testing.assert_allclose(out.radiance, expected, rtol=1e-12, atol=1e-15)
    y0, x = state.output[0, 0], 1.0
    t0 = state.time_s
    # a constant input: the ramp would continue into x over the step; restart from a held input
    state.signal = np.full((3, 4), x)
    for k in range(1, 4):
        out = apply_chain(
            np.full((3, 4), x),
            m,
            np.random.default_rng(0),
            psf=False,
            noise=False,
            time_s=t0 + k / fps,
            state=state,
        )
        np.testing.assert_allclose(out.radiance, x + (y0 - x) * math.exp(-k / fps / tau), rtol=1e-12)
    assert out.settings["lag"]["carry_over"] == pytest.approx(math.exp(-1 / fps / tau))
    # no state: the detector is settled (y = x), and says why
    lone = apply_chain(np.full((3, 4), 2.0), m, np.random.default_rng(0), psf=False, noise=False)
    np.testing.assert_allclose(lone.radiance, 2.0) and not lone.settings["lag"]["applied"]


def test_fixed_pattern_noise_and_drift_since_the_last_ffc():
    m = lwir(
        resolution=(128, 96),
        fpn_gain_sigma=0.01,
        fpn_offset_sigma_k=0.08,
        fpn_drift_k_per_s=0.001,
        ffc_interval_s=180.0,
        fpn_seed=7,
    )
    per_k = planck.band_radiance_derivative(300.0, m.wavelength_range_um, m.response_pair)
    l_ref = band_l(m, 300.0)
    zg, zo, zr = chain.fixed_pattern((96, 128), 7)

    def run(img, t):
        return apply_chain(img, m, np.random.default_rng(1), psf=False, noise=False, time_s=t).radiance

    at_ref = np.full((96, 128), l_ref)
    # at the shutter's temperature only the offset residual: sigma_o z_o, in kelvin
    dk = (run(at_ref, 0.0) - l_ref) / per_k
    np.testing.assert_allclose(dk, 0.08 * zo, atol=1e-9)
    assert np.std(dk) == pytest.approx(0.08, rel=0.05)
    # a warmer scene adds the gain residual sigma_g z_g (L - L_ref)
    warm = band_l(m, 320.0)
    np.testing.assert_allclose(
        run(np.full((96, 128), warm), 0.0), warm + 0.01 * zg * (warm - l_ref) + per_k * 0.08 * zo, rtol=1e-12
    )
    # drift grows linearly since the FFC, restarts after one: t = 250 s is 70 s after the FFC at 180 s
    np.testing.assert_allclose((run(at_ref, 60.0) - l_ref) / per_k, 0.08 * zo + 0.001 * zr * 60.0, atol=1e-9)
    np.testing.assert_allclose(run(at_ref, 250.0), run(at_ref, 70.0), rtol=1e-15)
    assert (
        chain.time_since_ffc(250.0, 180.0) == pytest.approx(70.0)
        and chain.time_since_ffc(250.0, 0.0) == 250.0
    )
    # fixed: the same pattern in every frame; another seed, another pattern
    other = dataclasses.replace(m, fpn_seed=8)
    b = apply_chain(at_ref, other, np.random.default_rng(1), psf=False, noise=False, time_s=0.0).radiance
    assert abs(np.corrcoef((b - l_ref).ravel(), dk.ravel())[0, 1]) < 0.1
    # off by default: nothing added
    np.testing.assert_array_equal(
        apply_chain(
            at_ref, lwir(resolution=(128, 96)), np.random.default_rng(1), psf=False, noise=False
        ).radiance,
        at_ref,
    )


def test_quantisation_error_is_uniform_over_one_count():
    """An ideal ADC's error on a dense ramp: uniform in [-1/2, 1/2] LSB, RMS 1/sqrt(12) LSB."""
    gain, offset = 1000.0, 0.0
    ramp = np.linspace(0.0, 10.0, 200001)  # 0..10000 counts, 20 samples per count
    err = chain.quantize(ramp, gain, offset, 14).astype(float) - gain * ramp
    assert np.abs(err).max() <= 0.5 + 1e-9
    assert np.sqrt(np.mean(err**2)) == pytest.approx(1 / math.sqrt(12), rel=0.01)


def test_jpeg_stage_changes_only_the_8_bit_image():
    m = lwir()
    img = person_scene(m)
    ref = apply_chain(img, m, np.random.default_rng(0), psf=False)
    errors = []
    for q in (10, 50, 95):
        out = apply_chain(img, dataclasses.replace(m, jpeg_quality=q), np.random.default_rng(0), psf=False)
        np.testing.assert_array_equal(out.counts, ref.counts)  # raw counts and radiance untouched
        np.testing.assert_array_equal(out.radiance, ref.radiance)
        errors.append(np.sqrt(np.mean((out.image8.astype(float) - ref.image8) ** 2)))
        assert out.settings["compression"]["rms_error_levels"] == pytest.approx(errors[-1])
    assert errors[0] > errors[1] > errors[2] > 0
    # a flat 8 x 8-aligned image is one DC coefficient per block (ITU-T T.81 A.3.3: DC = 8 (v - 128)),
    # quantised with the IJG table's DC step Q = (16 S + 50) // 100, S = 5000 / quality (< 50)
    # or 200 - 2 quality: the decoded level is 128 + round(8 (v - 128) / Q) Q / 8
    for v, q in ((70, 5), (77, 5), (77, 10), (70, 50), (77, 95)):
        scale = 5000 // q if q < 50 else 200 - 2 * q
        step = min(max((16 * scale + 50) // 100, 1), 255)
        expected = 128 + round(8 * (v - 128) / step) * step / 8
        flat = np.full((16, 24), v, np.uint8)
        np.testing.assert_array_equal(chain.jpeg_roundtrip(flat, q), np.full((16, 24), round(expected)))
    assert ref.settings["compression"] is None


def test_every_artefact_leaves_the_input_untouched_and_is_recorded():
    m = lwir(
        vignetting="cos4",
        time_constant_s=0.01,
        fpn_gain_sigma=0.01,
        fpn_offset_sigma_k=0.05,
        fpn_drift_k_per_s=0.001,
        jpeg_quality=75,
    )
    img = person_scene(m)
    keep = img.copy()
    state = chain.ChainState()
    for n in range(3):
        out = apply_chain(img, m, np.random.default_rng(n), time_s=n / 30, state=state)
    np.testing.assert_array_equal(img, keep)
    import json

    json.dumps(out.settings)
    for key in ("vignetting", "lag", "fixed_pattern", "compression"):
        assert out.settings[key], key


def test_chain_settings_round_trip_through_the_scenario_and_the_prim(raw):
    by_id = {s["id"]: s for s in raw["sensor"]}
    by_id["lwir640"].update(
        agc_plateau=0.002,
        agc_max_gain=4.0,
        agc_midpoint=100.0,
        fpn_gain_sigma=0.005,
        fpn_offset_sigma_k=0.04,
        fpn_drift_k_per_s=0.0005,
        ffc_interval_s=120.0,
        fpn_seed=3,
        vignetting="cos4",
        time_constant_s=0.011,
        jpeg_quality=80,
    )
    stage = Usd.Stage.Open(sensors_layer.build(validate(raw)))
    m = read_sensor_model(stage.GetPrimAtPath("/World/Sensors/lwir640"))
    assert (m.agc_plateau, m.agc_max_gain, m.agc_midpoint) == pytest.approx((0.002, 4.0, 100.0))
    assert (m.fpn_gain_sigma, m.fpn_offset_sigma_k, m.fpn_drift_k_per_s, m.ffc_interval_s) == pytest.approx(
        (0.005, 0.04, 0.0005, 120.0)
    )
    assert (m.fpn_seed, m.vignetting, m.jpeg_quality) == (3, "cos4", 80)
    assert m.time_constant_s == pytest.approx(0.011)
    plain = read_sensor_model(stage.GetPrimAtPath("/World/Sensors/atom1024_lwir"))
    assert (plain.vignetting, plain.time_constant_s, plain.jpeg_quality, plain.fpn_offset_sigma_k) == (
        "none",
        0,
        0,
        0,
    )
    by_id["lwir640"]["jpeg_quality"] = 101
    with pytest.raises(Exception, match="jpeg_quality"):
        validate(raw)


def test_bad_chain_settings_name_the_key():
    with pytest.raises(ValueError, match="vignetting = 'cos3'"):
        lwir(vignetting="cos3")
    with pytest.raises(ValueError, match="time_constant_s = -1"):
        lwir(time_constant_s=-1)
    with pytest.raises(ValueError, match="jpeg_quality = 200"):
        lwir(jpeg_quality=200)


# ============================================================================ 3. presets and FOV
NEW_PRESETS = ("boson320", "boson640", "tau2_640", "lepton35", "h20t_thermal")


@pytest.mark.parametrize("name", [n for n, p in presets.PRESETS.items() if p.stated_fov_deg is not None])
def test_preset_field_of_view_matches_the_data_sheet_within_1_deg(name):
    p = presets.preset(name)
    w, h = p.resolution
    n = w if p.stated_fov_axis == "horizontal" else math.hypot(w, h)
    fov = math.degrees(2 * math.atan(n * p.pixel_pitch_um * 1e-3 / (2 * p.focal_length_mm)))
    assert fov == pytest.approx(p.stated_fov_deg, abs=1.0)
    got = p.fov_deg[0] if p.stated_fov_axis == "horizontal" else p.diagonal_fov_deg
    assert got == pytest.approx(fov, rel=1e-12)


def test_thermal_core_presets_carry_their_data_sheet_values():
    assert set(NEW_PRESETS) <= set(presets.PRESETS)
    tau2 = presets.preset("tau2_640")
    assert (tau2.resolution, tau2.pixel_pitch_um) == ((640, 512), 17.0)
    assert tau2.fov_deg == pytest.approx((45.0, 37.0), abs=0.5)  # FLIR ADAS: 45 x 37 deg
    assert presets.preset("lepton35").resolution == (160, 120)
    assert presets.preset("boson320").resolution == (320, 256)
    h20t = presets.preset("h20t_thermal")
    assert (h20t.resolution, h20t.pixel_pitch_um, h20t.focal_length_mm) == ((640, 512), 12.0, 13.5)
    for name in NEW_PRESETS:
        p = presets.preset(name)
        assert p.band == "LWIR" and p.netd_k <= 0.05 and p.agc == "plateau" and p.frame_rate_hz > 0
        assert p.stated_fov_deg is not None and len(p.source) > 150


def test_every_field_of_view_reader_agrees(raw):
    """Presets, the sensor model, the camera prim (aperture / focal length) and the editor's plan
    all give 2 atan(n p / 2 f) for each preset."""
    raw["sensor"] = [
        {"id": name, "preset": name, "position_m": [0.0, -15.0, 1.6], "look_at_m": [0.0, 0.0, 1.0]}
        for name in presets.PRESETS
    ]
    scenario = validate(raw)
    stage = Usd.Stage.Open(sensors_layer.build(scenario))
    for s in scenario["sensor"]:
        p = presets.preset(s["preset"])
        expected = math.degrees(2 * math.atan(p.resolution[0] * p.pixel_pitch_um / (2e3 * p.focal_length_mm)))
        prim = stage.GetPrimAtPath(f"/World/Sensors/{s['id']}")
        assert p.fov_deg[0] == pytest.approx(expected, rel=1e-9)
        assert read_sensor_model(prim).fov_deg[0] == pytest.approx(expected, rel=1e-6)
        assert read_camera_pose(prim, Usd.TimeCode.Default()).fov_x_deg == pytest.approx(expected, rel=1e-6)
        assert horizontal_fov_deg(s) == pytest.approx(expected, rel=1e-9)


def test_write_sensor_authors_chain_settings_only_when_given():
    stage = Usd.Stage.CreateInMemory()
    prim = UsdGeom.Camera.Define(stage, "/C").GetPrim()
    UsdGeom.Camera(prim).CreateFocalLengthAttr(0.18)
    common = dict(
        band="LWIR",
        wavelength_range_um=(8.0, 14.0),
        resolution=(64, 48),
        pixel_pitch_m=12e-6,
        f_number=1.0,
        netd_k=0.05,
        bit_depth=14,
        offset=0.0,
        preset="",
        platform="tripod",
        agc="plateau",
        agc_percentiles=(1.0, 99.0),
    )
    write_sensor(prim, **common, chain_settings={"vignetting": "cos4", "jpeg_quality": None})
    assert prim.GetAttribute("humv:sensor:vignetting").HasAuthoredValue()
    assert not prim.GetAttribute("humv:sensor:jpegQuality").HasAuthoredValue()
    assert read_sensor_model(prim).vignetting == "cos4"


def test_scenario_choices_match_the_chain():
    """The spec's copies of the chain's token sets (scenario sits above physics but keeps its own
    tuples for the docs) are the chain's."""
    from humv_usd.scenario import spec

    assert spec.AGC_MODES == chain.AGC_MODES and spec.VIGNETTING_MODES == chain.VIGNETTING_MODES
    assert set(spec.SENSOR_PRESETS) == set(presets.PRESETS)
