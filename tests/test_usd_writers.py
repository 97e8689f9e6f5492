"""The typed writers of humv_usd.usd (the only code that writes HumV attributes by name): what
each writes, the readers give back, and a time-varying value is time-sampled only when it
varies."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from humv_usd.catalog.materials import LIBRARY
from humv_usd.errors import InputError
from humv_usd.usd import atmosphere as UA_ATM
from humv_usd.usd import avatar as UA
from humv_usd.usd import schemas as S
from humv_usd.usd.labels import nearest_class, nearest_instance_id, read_face_label
from humv_usd.usd.materials import read_material, write_material
from humv_usd.usd.mesh import label, write_class
from humv_usd.usd.sensor import read_sensor_model, write_sensor
from humv_usd.usd.thermal import write_surface_temperature


@pytest.fixture
def stage():
    return Usd.Stage.CreateInMemory()


@pytest.mark.parametrize("name", ["cotton_white", "glass"])
def test_material_round_trip(stage, name):
    ref = LIBRARY[name]
    write_material(stage, "/M/" + name, ref)
    m = read_material(stage.GetPrimAtPath("/M/" + name))
    np.testing.assert_allclose(m.wavelengths_um, ref.spectrum_wavelengths, rtol=1e-6)
    np.testing.assert_allclose(m.emissivity, ref.spectrum_emissivity, atol=1e-6)
    assert m.opaque == ref.opaque
    if not ref.opaque:
        np.testing.assert_allclose(m.transmittance, ref.spectrum_transmittance, atol=1e-6)
    assert m.conductivity == pytest.approx(ref.conductivity, rel=1e-6)
    assert m.source == ref.source
    assert stage.GetPrimAtPath(f"/M/{name}/PreviewSurface").IsValid()


def test_sensor_round_trip(stage):
    prim = UsdGeom.Camera.Define(stage, "/Cam").GetPrim()
    wl = np.array([8.0, 10.0, 12.0])
    write_sensor(
        prim,
        band="LWIR",
        wavelength_range_um=(8.0, 12.0),
        resolution=(320, 256),
        pixel_pitch_m=17e-6,
        f_number=1.2,
        netd_k=0.04,
        netd_origin="scaled from f/1.0",
        bit_depth=14,
        offset=100.0,
        preset="x",
        platform="tripod",
        agc="linear",
        agc_percentiles=(2.0, 98.0),
        subbands=3,
        response_wavelengths_um=wl,
        response=np.array([0.5, 1.0, 0.5]),
    )
    m = read_sensor_model(prim)
    assert (m.band, m.resolution, m.bit_depth, m.preset, m.agc) == ("LWIR", (320, 256), 14, "x", "linear")
    assert m.wavelength_range_um == (8.0, 12.0) and m.agc_percentiles == (2.0, 98.0)
    assert m.pixel_pitch_m == pytest.approx(17e-6) and m.f_number == pytest.approx(1.2)
    assert m.netd_k == pytest.approx(0.04) and m.netd_note == "scaled from f/1.0"
    assert m.gain is None and m.offset == 100.0
    np.testing.assert_allclose(m.response, [0.5, 1.0, 0.5])
    assert prim.GetAttribute(S.SENSOR_SUBBANDS).Get() == 3
    # what is not given is not authored (the schema's fallbacks apply)
    assert not prim.GetAttribute(S.SENSOR_GAIN).HasAuthoredValue()
    assert not prim.GetAttribute(S.SENSOR_FULL_WELL).HasAuthoredValue()


def _samples(attr):
    return attr.GetTimeSamples(), attr.Get()


def test_surface_temperature_default_or_time_samples(stage):
    constant = stage.DefinePrim("/A")
    write_surface_temperature(constant, "slab", np.array([[300.0, 301.0], [300.0, 301.0]]))
    attr = constant.GetAttribute(S.TEMPERATURE_PRIMVAR)
    assert _samples(attr)[0] == [] and list(attr.Get()) == [300.0, 301.0]
    assert constant.GetAttribute(S.THERMAL_MODEL).Get() == "slab" and constant.HasAPI(S.THERMAL_API)
    varying = stage.DefinePrim("/B")
    write_surface_temperature(varying, "balance", np.array([[300.0], [302.5]]))
    attr = varying.GetAttribute(S.TEMPERATURE_PRIMVAR)
    assert attr.GetTimeSamples() == [0.0, 1.0] and list(attr.Get(1)) == [302.5]
    assert UsdGeom.Primvar(attr).GetInterpolation() == UsdGeom.Tokens.uniform
    held = stage.DefinePrim("/C")
    write_surface_temperature(held, "fixed", np.full(3, 290.0))
    assert list(held.GetAttribute(S.TEMPERATURE_PRIMVAR).Get()) == [290.0] * 3


def test_metabolic_rate_round_trip(stage):
    walk, stand, bare = (stage.DefinePrim(p) for p in ("/Walk", "/Stand", "/Bare"))
    with pytest.raises(InputError, match="HumvAvatarAPI"):
        UA.write_metabolic_rate(walk, [150.0])
    person = UA.AvatarParameters("p", "male", 30.0, 1.8, 80.0, 0.5, "average", "walk")
    for prim in (walk, stand):
        UA.write_avatar(prim, person, 1.9)
    UA.write_metabolic_rate(walk, [150.0, 160.0, 170.0])
    UA.write_metabolic_rate(stand, [105.0, 105.0])
    assert walk.GetAttribute(S.AVATAR_METABOLIC_RATE).GetTimeSamples() == [0.0, 1.0, 2.0]
    assert stand.GetAttribute(S.AVATAR_METABOLIC_RATE).GetTimeSamples() == []
    np.testing.assert_allclose(UA.read_metabolic_rate(walk, 3), [150.0, 160.0, 170.0])
    np.testing.assert_allclose(UA.read_metabolic_rate(stand, 3), [105.0] * 3)
    np.testing.assert_allclose(UA.read_metabolic_rate(bare, 2, default_w=99.0), [99.0, 99.0])


def test_avatar_parameters_round_trip(stage):
    prim = stage.DefinePrim("/World/Humans/p1")
    person = UA.AvatarParameters("p1", "female", 41.0, 1.65, 60.5, 0.25, "fit", "walk")
    UA.write_avatar(prim, person, 1.7)
    assert UA.read_avatar(stage, "p1") == person
    assert prim.GetAttribute(S.AVATAR_BODY_SURFACE_AREA).Get() == pytest.approx(1.7)


def test_garment_and_air_gap_round_trip(stage):
    shirt, skin = stage.DefinePrim("/Shirt"), stage.DefinePrim("/Skin")
    UA.write_garment(shirt, "tshirt_white", 0.02, 0.003)
    UA.write_air_gap(shirt, np.array([[0.01, 0.02], [0.03, 0.04]]), time_sampled=True)
    assert UA.read_garment(shirt) == "tshirt_white" and UA.is_garment(shirt)
    assert UA.read_garment(skin) is None and not UA.is_garment(skin)
    np.testing.assert_allclose(UA.read_air_gap(shirt, 1), [0.03, 0.04], rtol=1e-6)
    still = stage.DefinePrim("/Still")
    UA.write_air_gap(still, np.array([[0.01, 0.02]]), time_sampled=False)
    assert still.GetAttribute(S.AIR_GAP_PRIMVAR).GetTimeSamples() == []
    np.testing.assert_allclose(UA.read_air_gap(still, 5), [0.01, 0.02], rtol=1e-6)
    with pytest.raises(InputError, match="airGap"):
        UA.read_air_gap(skin, 0)


def test_face_labels_keypoints_and_classes(stage):
    body = stage.DefinePrim("/P/Body")
    UA.write_body_labels(body, [0, 2, 1], ["none", "a", "b"], [0, 16, 3], [f"s{i}" for i in range(17)])
    np.testing.assert_array_equal(UA.read_body_regions(body), [0, 2, 1])
    np.testing.assert_array_equal(read_face_label(body, "jos3_segment", 3, 0, 16), [0, 16, 3])
    assert read_face_label(body, "body_region", 3, 0, 2).dtype == np.int32
    with pytest.raises(InputError, match="expected 4 values"):
        read_face_label(body, "body_region", 4, 0, 2)
    with pytest.raises(InputError, match="ids in 0..1"):
        read_face_label(body, "body_region", 3, 0, 1)
    assert read_face_label(stage.DefinePrim("/Q"), "body_region", 3, 0, 2) is None
    root = stage.GetPrimAtPath("/P")
    kp = np.arange(12, dtype=float).reshape(2, 2, 3)
    UA.write_keypoints(root, kp, ["nose", "left_eye"])
    assert UA.has_keypoints(root) and not UA.has_keypoints(body)
    np.testing.assert_allclose(UA.read_keypoints(root, 1), kp[1])
    label(root, 7, "person")
    write_class(body, "prop")
    assert nearest_instance_id(body) == (root, 7)
    assert nearest_class(body) == (body, "prop") and nearest_class(root) == (root, "person")
    assert nearest_class(stage.DefinePrim("/Z")) == (None, None)


# --- atmosphere layers ---------------------------------------------------------------------------
ZENITH = np.array([0.0, 30.0, 60.0, 89.0])
WL = np.array([8.0, 10.0, 12.0])


def _atmosphere(stage):
    prim = UA_ATM.define_atmosphere(stage, "analytic", "midlatitudeWinter", 23000.0)
    UA_ATM.write_broadband_sky(prim, 0.73414321, 267.5118234, [70.0, 80.0, 100.0, 120.0], ZENITH)
    UA_ATM.write_spectral_grid(prim, WL, ZENITH)
    return prim


def test_atmosphere_round_trip_defaults(stage):
    prim = _atmosphere(stage)
    sky = np.arange(ZENITH.size * WL.size, dtype=float).reshape(ZENITH.size, WL.size) + 0.5
    UA_ATM.write_spectral_sky(prim, sky)
    UA_ATM.write_solar_spectrum(prim, [1.0, 2.0, 3.0])
    assert prim.HasAPI(S.ATMOSPHERE_API) and UA_ATM.model_name(stage) == "analytic"
    assert prim.GetAttribute(S.ATMOSPHERE_PROFILE).Get() == "midlatitudeWinter"
    assert prim.GetAttribute(S.ATMOSPHERE_VISIBILITY).Get() == pytest.approx(23000.0)
    # stored rounded: emissivity to 1e-6, temperature to 1e-4 K (float32)
    assert prim.GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY).Get() == pytest.approx(0.734143, abs=1e-7)
    assert UA_ATM.sky_temperature(stage, UA_ATM.DEFAULT) == pytest.approx(267.5118, abs=2e-5)
    zen, lw = UA_ATM.longwave_sky(stage)
    np.testing.assert_array_equal(zen, ZENITH)
    np.testing.assert_array_equal(lw, [70.0, 80.0, 100.0, 120.0])
    spectra = UA_ATM.atmosphere_spectra(stage, UA_ATM.DEFAULT)
    np.testing.assert_array_equal(spectra.wavelengths_um, WL)
    np.testing.assert_array_equal(spectra.sky_zenith_deg, ZENITH)
    np.testing.assert_array_equal(spectra.sky_radiance, sky)  # (Z, W) row-major back
    np.testing.assert_array_equal(spectra.solar_irradiance, [1.0, 2.0, 3.0])
    for name in (S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE, S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE):
        assert prim.GetAttribute(name).GetTimeSamples() == []


def test_atmosphere_time_samples_interpolate(stage):
    prim = _atmosphere(stage)  # defaults: what a reader without a time gets
    for code, scale in ((0.0, 1.0), (10.0, 2.0)):
        UA_ATM.write_broadband_sky(prim, 0.7 * scale / 2, 260.0 + scale, np.full(4, 50.0 * scale), time=code)
        UA_ATM.write_spectral_sky(prim, np.full((ZENITH.size, WL.size), scale), code)
        UA_ATM.write_solar_spectrum(prim, np.full(WL.size, 10.0 * scale), code)
    for name in (S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE, S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE):
        assert prim.GetAttribute(name).GetTimeSamples() == [0.0, 10.0]
    assert prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).GetTimeSamples() == []  # the grid holds
    # USD interpolates linearly between the samples; the defaults stay
    np.testing.assert_allclose(UA_ATM.longwave_sky(stage, 5.0)[1], 75.0)
    assert UA_ATM.sky_temperature(stage, 5.0) == pytest.approx(261.5)
    assert prim.GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY).Get(10.0) == pytest.approx(0.7)
    spectra = UA_ATM.atmosphere_spectra(stage, 2.5)
    np.testing.assert_allclose(spectra.sky_radiance, 1.25)
    np.testing.assert_allclose(spectra.solar_irradiance, 12.5)
    np.testing.assert_array_equal(UA_ATM.longwave_sky(stage)[1], [70.0, 80.0, 100.0, 120.0])
    assert UA_ATM.sky_temperature(stage, UA_ATM.DEFAULT) == pytest.approx(267.5118, abs=2e-5)


def test_path_table_round_trip(stage):
    _atmosphere(stage)
    UA_ATM.define_paths(stage)
    ranges = np.array([1.0, 10.0])
    # named unlike the sensor: the reader finds it by its sensor attribute
    table = UA_ATM.define_path_table(stage, "table0", "/World/Sensors/cam", ranges)
    tau = np.array([[1.2, 0.9, 0.8], [0.5, -0.1, 0.3]])
    rad = np.array([[0.0, 1.0, -2.0], [3.0, 4.0, 5.0]])
    UA_ATM.write_path_spectra(table, tau, rad)
    assert table.HasAPI(S.ATMOSPHERE_PATH_API)
    assert str(table.GetPath()) == "/World/Atmosphere/Paths/table0"
    got = UA_ATM.path_table(stage, "/World/Sensors/cam", "cam", UA_ATM.DEFAULT)
    assert got.prim == "/World/Atmosphere/Paths/table0"
    np.testing.assert_array_equal(got.ranges_m, ranges)
    np.testing.assert_array_equal(got.wavelengths_um, WL)
    np.testing.assert_allclose(got.transmittance, [[1.0, 0.9, 0.8], [0.5, 0.0, 0.3]], rtol=1e-6)
    np.testing.assert_array_equal(got.radiance, [[0.0, 1.0, 0.0], [3.0, 4.0, 5.0]])
    # time samples at two weather nodes: linear between them, the default as written
    UA_ATM.write_path_spectra(table, np.full((2, 3), 0.8), np.full((2, 3), 2.0), 0.0)
    UA_ATM.write_path_spectra(table, np.full((2, 3), 0.4), np.full((2, 3), 6.0), 20.0)
    half = UA_ATM.path_table(stage, "/World/Sensors/cam", "cam", 10.0)
    np.testing.assert_allclose(half.transmittance, 0.6, rtol=1e-6)
    np.testing.assert_allclose(half.radiance, 4.0, rtol=1e-6)
    assert table.GetAttribute(S.ATMOSPHERE_PATH_RANGES).GetTimeSamples() == []
    assert UA_ATM.path_table(stage, "/World/Sensors/other", "other", 0.0) is None


def test_require_wavelengths(stage):
    with pytest.raises(InputError, match="wavelengths"):
        UA_ATM.require_wavelengths(stage, WL)  # no atmosphere layer
    _atmosphere(stage)
    UA_ATM.require_wavelengths(stage, WL * (1 + 1e-8))
    with pytest.raises(InputError, match="path tables are computed on"):
        UA_ATM.require_wavelengths(stage, np.array([8.0, 10.0, 12.5]))
