"""The typed writers of humv_usd.usd (the only code that writes HumV attributes by name): what
each writes, the readers give back, and a time-varying value is time-sampled only when it
varies."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from humv_usd.catalog.materials import LIBRARY
from humv_usd.errors import InputError
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
        netd_note="scaled from f/1.0",
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
