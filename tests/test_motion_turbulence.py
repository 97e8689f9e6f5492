"""Sensor-chain stages from motion and the atmosphere: motion blur (EO exposure, bolometer
time constant), rolling shutter, turbulence; the image velocity of a moving camera."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from humv_usd.geometry.camera import Camera, CameraPose, image_velocity
from humv_usd.geometry.rig import camera_axes
from humv_usd.physics import sensor as chain
from humv_usd.physics.sensor import SensorModel


def _edge(h=8, w=200, u0=100.0):
    """x = 1 right of the edge at u0 (pixel centres at i + 0.5 in the image, i in the arrays)."""
    return np.tile((np.arange(w) >= u0).astype(float), (h, 1))


def test_motion_blur_of_a_moving_edge_is_the_closed_form():
    """An edge whose image moves right at v: box exposure T gives a linear ramp of length vT
    ending at the edge; a bolometer (tau) gives exp(-(u0 - u)/(v tau)) left of it."""
    v, t = 400.0, 0.05  # 20 px streak
    vel = np.zeros((8, 200, 2))
    vel[..., 0] = v
    u = np.arange(200.0)
    # the sampled edge (bilinear between pixel centres) is a unit ramp centred at 99.5
    box = chain.motion_blur(_edge(), vel, t, "box", samples=256)[4]
    np.testing.assert_allclose(box, np.clip((u - 99.5 + v * t) / (v * t), 0, 1), atol=0.01)
    tau = 0.01  # 4 px
    expo = chain.motion_blur(_edge(), vel, tau, "exponential", samples=256)[4]
    want = np.where(u >= 99.5, 1.0, np.exp(-(99.5 - u) / (v * tau)))
    np.testing.assert_allclose(expo, want, atol=0.06)  # the unit ramp rounds the jump
    assert expo.sum() == pytest.approx(want.sum(), rel=0.01)
    still = chain.motion_blur(_edge(), np.zeros((8, 200, 2)), t, "box")
    np.testing.assert_array_equal(still, _edge())


def test_rolling_shutter_skews_a_vertical_edge_by_the_readout():
    h, w, v, readout = 101, 200, 300.0, 0.1  # 30 px over the frame
    vel = np.zeros((h, w, 2))
    vel[..., 0] = v
    img = chain.rolling_shutter(_edge(h, w), vel, readout)
    for r in (0, 50, 100):
        edge = np.argmax(img[r] >= 0.5)
        assert edge == pytest.approx(100.0 - v * readout * (h - 1 - r) / (h - 1), abs=1.0)


def test_fried_parameter_scaling_and_the_seeing_disc():
    r0 = chain.fried_parameter(10e-6, 1e-14, 1000.0)
    assert chain.fried_parameter(5e-6, 1e-14, 1000.0) == pytest.approx(r0 * 0.5 ** (6 / 5))
    assert chain.fried_parameter(10e-6, 1e-14, 8000.0) == pytest.approx(r0 * 8 ** (-3 / 5))
    assert chain.fried_parameter(10e-6, 1e-14, 1000.0, "plane") == pytest.approx(r0 * (3 / 8) ** (3 / 5))
    assert chain.turbulence_mtf(r0 / 10e-6, 10e-6, r0) == pytest.approx(math.exp(-3.44))
    # a point source: the blurred image keeps its energy and its FWHM is the seeing disc,
    # 0.98 lambda / r0 (the long-exposure PSF of this MTF; Fried 1966, Roddier 1981)
    model = SensorModel(
        name="t",
        band="MWIR",
        wavelength_range_um=(3.9, 4.1),
        response_wavelengths_um=np.array([3.9, 4.1]),
        response=np.array([1.0, 1.0]),
        resolution=(129, 129),
        pixel_pitch_m=15e-6,
        f_number=4.0,
        focal_length_m=1.0,
    )
    img = np.zeros((129, 129))
    img[64, 64] = 1.0
    out, r0, seeing_px = chain.apply_turbulence(img, model, 2e-13, 3000.0)
    assert out.sum() == pytest.approx(1.0, rel=0.005)  # the far wings fold back at the reflected edges
    assert 3.0 < seeing_px < 30.0
    row = out[64] / out[64].max()
    above = np.flatnonzero(row >= 0.5)
    width = above[-1] - above[0] + 1  # pixel-resolution FWHM
    assert width == pytest.approx(0.98 * 4e-6 / r0 / 15e-6, abs=1.5)


def test_image_velocity_of_a_pan_and_of_a_drone_over_flat_ground():
    w, h, f_px = 160, 120, 200.0
    fov = math.degrees(2 * math.atan(w / (2 * f_px)))
    fwd0, up0 = camera_axes(0.0, 0.0)
    a = math.radians(2.0)
    fwd1, up1 = camera_axes(2.0, 0.0)  # panned 2 deg to the east (right)
    c0 = Camera.from_pose(CameraPose(np.zeros(3), fwd0, up0, fov), w, h)
    c1 = Camera.from_pose(CameraPose(np.zeros(3), fwd1, up1, fov), w, h)
    vel = image_velocity(c1, c0, 0.1)
    # the content at the centre now was f tan(a) right of the centre: it moved left
    assert vel[60, 80, 0] == pytest.approx(-f_px * math.tan(a) / 0.1, rel=1e-3)
    # nadir drone at 50 m flying east at 10 m/s: ground content moves left at V f / h everywhere
    fwd, up = camera_axes(0.0, -90.0)
    d0 = Camera.from_pose(CameraPose(np.array([0.0, 0.0, 50.0]), fwd, up, fov), w, h)
    d1 = Camera.from_pose(CameraPose(np.array([1.0, 0.0, 50.0]), fwd, up, fov), w, h)
    vel = image_velocity(d1, d0, 0.1)
    np.testing.assert_allclose(vel[..., 0], -10.0 * f_px / 50.0, rtol=1e-9)
    np.testing.assert_allclose(vel[..., 1], 0.0, atol=1e-9)
    depth = np.full((h, w), 50.0)  # the same with the depth channel
    np.testing.assert_allclose(image_velocity(d1, d0, 0.1, depth=depth), vel, atol=1e-9)


def _lwir(**kw) -> SensorModel:
    return SensorModel(
        name="t",
        band="LWIR",
        wavelength_range_um=(8.0, 14.0),
        response_wavelengths_um=np.array([8.0, 14.0]),
        response=np.array([1.0, 1.0]),
        resolution=(64, 48),
        pixel_pitch_m=17e-6,
        f_number=1.0,
        focal_length_m=0.013,
        **kw,
    )


def test_chain_records_the_stages_and_leaves_the_input_alone():
    model = _lwir(
        time_constant_s=0.01,
        motion_blur="camera",
        turbulence_cn2=1e-14,
        turbulence_path_m=500.0,
    )
    x = np.random.default_rng(0).uniform(10.0, 20.0, (48, 64))
    keep = x.copy()
    vel = np.zeros((48, 64, 2))
    vel[..., 0] = 300.0
    out = chain.apply_chain(x, model, np.random.default_rng(1), velocity_px_s=vel, noise=False)
    np.testing.assert_array_equal(x, keep)
    assert out.settings["motion_blur"]["max_streak_px"] == pytest.approx(3.0)
    assert out.settings["lag"]["applied"] is False
    assert out.settings["turbulence"]["r0_m"] > 0
    off = chain.apply_chain(
        x, dataclasses.replace(model, motion_blur="none"), np.random.default_rng(1), noise=False
    )
    assert off.settings["motion_blur"] is None
    with pytest.raises(ValueError, match="motion_blur"):
        dataclasses.replace(model, motion_blur="yes")


def test_the_spec_offers_the_chain_modes():
    from humv_usd.scenario import spec

    assert spec.MOTION_BLUR_MODES == chain.MOTION_BLUR_MODES


def test_the_render_chain_reads_the_velocity_of_a_drone_from_its_pose(raw):
    """pipeline.chains: a nadir drone 50 m up flying east at 10 m/s, image up along its heading:
    the ground's image moves down at V f / h in every pixel (central difference of the USD pose
    time samples)."""
    from pxr import Usd

    from humv_usd.pipeline.chains import SensorChains
    from humv_usd.scenario import validate
    from humv_usd.sensors import layer as sensors_layer
    from humv_usd.usd.sensor import read_sensor

    raw["general"].update(fps=10.0, duration_s=0.3)
    s = raw["sensor"][0]
    for key in ("position_m", "look_at_m"):
        s.pop(key)
    s.update(
        platform="drone",
        path_m=[[0.0, 0.0, 50.0], [100.0, 0.0, 50.0]],
        speed_m_s=10.0,
        target="forward",
        mount_pitch_deg=-90.0,
        motion_blur="camera",
        render_resolution=[64, 48],
    )
    raw["sensor"] = [s]
    stage = Usd.Stage.Open(sensors_layer.build(validate(raw)))
    prim = stage.GetPrimAtPath("/World/Sensors/" + s["id"])
    model = read_sensor(prim)  # the render's read
    assert model.motion_blur == "camera"
    f_px = model.focal_length_m / model.pixel_pitch_m
    chains = SensorChains(stage, 0, [str(prim.GetPath())])
    for frame in (0, 1, 3):
        vel = chains.velocity(model, frame)
        np.testing.assert_allclose(vel[..., 1], 10.0 * f_px / 50.0, rtol=1e-6)
        np.testing.assert_allclose(vel[..., 0], 0.0, atol=1e-6 * f_px)


def test_h264_clip_predicts_frames_and_leaves_the_counts_alone():
    pytest.importorskip("av")
    rng = np.random.default_rng(0)
    scene = rng.uniform(60, 200, (64, 96)).round()
    scene = (scene + np.roll(scene, 1, 1) + np.roll(scene, 1, 0)) / 3  # some texture
    flat = np.full((48, 64), 117, np.uint8)
    err = {}
    for crf in (10, 40):
        stream = chain.H264Stream(crf, flat.shape)
        assert np.abs(stream.roundtrip(flat).astype(int) - 117).max() <= 1  # flat: nearly exact
        stream = chain.H264Stream(crf, scene.shape)
        errs = [
            np.sqrt(
                np.mean((stream.roundtrip(np.roll(scene, k, 1).astype(np.uint8)) - np.roll(scene, k, 1)) ** 2)
            )
            for k in range(3)
        ]
        assert stream.bytes[2] < stream.bytes[0]  # frames after the first are predicted (P-frames)
        err[crf] = np.mean(errs)
    assert err[10] < err[40]
    model = SensorModel(
        name="t",
        band="LWIR",
        wavelength_range_um=(8.0, 14.0),
        response_wavelengths_um=np.array([8.0, 14.0]),
        response=np.array([1.0, 1.0]),
        resolution=(96, 64),
        pixel_pitch_m=17e-6,
        f_number=1.0,
        focal_length_m=0.013,
        h264_crf=30,
    )
    x = 35.0 + scene / 10.0  # 8-14 um band radiance around 280-320 K [W m-2 sr-1]
    state = chain.ChainState()
    out = chain.apply_chain(x, model, np.random.default_rng(1), state=state, noise=False)
    ref = chain.apply_chain(x, dataclasses.replace(model, h264_crf=0), np.random.default_rng(1), noise=False)
    np.testing.assert_array_equal(out.counts, ref.counts)
    assert out.settings["compression"]["crf"] == 30 and out.settings["compression"]["rms_error_levels"] > 0
    assert not np.array_equal(out.image8, ref.image8)


def test_a_tracked_person_keeps_its_own_image_motion():
    """pipeline.chains: labelled objects move at their mask centroid's velocity between
    frames, not with the background (a tracked person stays sharp)."""
    from pxr import Usd, UsdGeom

    from humv_usd.pipeline.chains import SensorChains

    stage = Usd.Stage.CreateInMemory()
    stage.SetTimeCodesPerSecond(10.0)
    UsdGeom.Camera.Define(stage, "/c")
    model = dataclasses.replace(_lwir(), path="/c", motion_blur="camera")
    chains = SensorChains(stage, 0, ["/c"])
    inst = np.zeros((48, 64), int)
    inst[10:20, 30:34] = 7
    assert chains.velocity(model, 0, instance=inst) is None  # a still camera, the first frame
    inst2 = np.roll(inst, 2, axis=1)  # moved 2 px right in one frame (0.1 s)
    vel = chains.velocity(model, 1, instance=inst2)
    np.testing.assert_allclose(vel[inst2 == 7], [[20.0, 0.0]] * int((inst2 == 7).sum()))
    assert not np.any(vel[inst2 == 0])


def test_only_moving_classes_get_their_own_motion():
    from humv_usd.groundtruth.labels import CLASS_ID
    from humv_usd.pipeline.chains import SensorChains

    cls = np.array([[CLASS_ID["person"], CLASS_ID["ground"], CLASS_ID["building"], CLASS_ID["vehicle"]]])
    inst = np.array([[4, 2, 3, 9]])
    np.testing.assert_array_equal(SensorChains.movers(cls, inst), [[4, 0, 0, 9]])
    assert SensorChains.movers(None, inst) is None
