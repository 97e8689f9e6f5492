"""Camera rigs (humv_usd.geometry.rig, the sensors layer): platforms on paths, tracking,
gimbal limits, hand shake; the per-frame pose is what the render and the labels read."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from humv_usd.cli.main import parse_resolution
from humv_usd.editor.plan import plan_svg, sensor_look_point, sensor_position
from humv_usd.errors import InputError
from humv_usd.geometry import rig
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.pipeline import graph
from humv_usd.pipeline.compose import compose_in_memory, plan
from humv_usd.render.export import StageExport
from humv_usd.scenario import validate
from humv_usd.sensors import layer as sensors_layer
from humv_usd.thermal.surfaces import FOOTPRINT_FRAMES, _footprint_poses
from humv_usd.usd.avatar import write_keypoints
from humv_usd.usd.paths import human_path
from humv_usd.usd.sensor import override_resolution, read_camera_pose, read_sensor_model


def _poses(stage, prim_path, frames):
    prim = stage.GetPrimAtPath(prim_path)
    return [read_camera_pose(prim, Usd.TimeCode(f)) for f in frames]


def _rig_raw(raw, fps=10.0, duration=0.4, **sensor):
    raw["general"]["fps"] = fps
    raw["general"]["duration_s"] = duration
    s = raw["sensor"][0]
    for key in ("position_m", "look_at_m"):
        s.pop(key, None)
    s.update(sensor)
    raw["sensor"] = [s]
    return raw


def test_polyline_track_closed_form():
    pts = [[0, 0, 1.5], [30, 0, 1.5], [30, 40, 1.5]]
    pos, d = rig.polyline_track(pts, 10.0, [0.0, 1.0, 3.5, 5.0, 100.0])
    np.testing.assert_allclose(pos, [[0, 0, 1.5], [10, 0, 1.5], [30, 5, 1.5], [30, 20, 1.5], [30, 40, 1.5]])
    np.testing.assert_allclose(d, [[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0]])


def test_camera_axes_are_orthonormal_and_roll_turns_up_about_the_axis():
    fwd, up = rig.camera_axes([0.0, 90.0, 200.0, 45.0], [0.0, -30.0, -90.0, 89.0], [0.0, 0.0, 0.0, 30.0])
    np.testing.assert_allclose(np.einsum("ij,ij->i", fwd, up), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(up, axis=1), 1.0)
    np.testing.assert_allclose(fwd[1], [math.cos(math.radians(30)), 0, -0.5], atol=1e-12)  # east, down 30
    # nadir keeps the heading: image up points along azimuth 200 deg
    np.testing.assert_allclose(
        up[2], [math.sin(math.radians(200)), math.cos(math.radians(200)), 0], atol=1e-12
    )
    f0, u0 = rig.camera_axes(45.0, 89.0, 0.0)
    right = np.cross(f0, u0)
    assert np.dot(up[3], u0) == pytest.approx(math.cos(math.radians(30)))
    assert np.dot(up[3], right) == pytest.approx(math.sin(math.radians(30)))


def test_gimbal_clamps_angles_and_limits_the_slew_rate():
    t = np.arange(6) / 10.0
    g = rig.Gimbal(yaw_range_deg=(-180, 180), pitch_range_deg=(-90.0, 30.0), rate_deg_s=50.0)
    # the command jumps 90 deg in azimuth at frame 1; elevation asks for 60 (above the limit)
    az, el = g.follow(np.zeros(6), [0, 90, 90, 90, 90, 90], [60.0] * 6, t)
    np.testing.assert_allclose(el, 30.0)
    np.testing.assert_allclose(az, [0, 5, 10, 15, 20, 25])  # 50 deg/s x 0.1 s per frame
    # pan limits are relative to the platform heading (here 100 deg)
    g2 = rig.Gimbal(yaw_range_deg=(-30.0, 30.0))
    az2, _ = g2.follow(np.full(2, 100.0), [0.0, 170.0], [0.0, 0.0], t[:2])
    np.testing.assert_allclose(az2, [70.0, 130.0])


def test_hand_shake_rms_spectrum_and_repeatability():
    t = np.arange(0, 50.0, 1 / 60.0)
    s = rig.shake_angles(t, 0.2, seed=3)
    np.testing.assert_allclose(np.sqrt(np.mean(s**2, axis=0)), [0.2, 0.2, 0.1], rtol=0.02)
    spec = np.abs(np.fft.rfft(s[:, 0])) ** 2
    f = np.fft.rfftfreq(len(t), 1 / 60.0)
    band = lambda lo, hi: spec[(f >= lo) & (f < hi)].sum()  # noqa: E731
    # the synthesised angle's power per band is the model spectrum's (Lorentzian lines at 2, 4, 10 Hz)
    fine = np.linspace(0.0, 25.0, 250001)
    psd = rig.shake_psd(fine)
    for lo, hi in ((0, 1), (1, 5), (9, 11)):
        share = psd[(fine >= lo) & (fine < hi)].sum() / psd.sum()
        assert band(lo, hi) / spec.sum() == pytest.approx(share, rel=0.03)
    assert rig.shake_psd(4.0) > 5 * rig.shake_psd(10.0)
    t30 = np.arange(0, 2.0, 1 / 30.0)
    np.testing.assert_allclose(rig.shake_angles(t30, 0.2, 3), s[: 2 * 60 : 2], atol=1e-12)  # rate-free
    assert not np.allclose(rig.shake_angles(t30, 0.2, 4), rig.shake_angles(t30, 0.2, 3))


def test_vehicle_camera_rides_its_path_and_looks_ahead_and_down(raw):
    raw = _rig_raw(
        raw,
        platform="vehicle",
        path_m=[[-20.0, -30.0, 1.8], [-20.0, 30.0, 1.8]],
        speed_m_s=15.0,
        target="forward",
        mount_pitch_deg=-5.0,
    )
    stage = Usd.Stage.Open(sensors_layer.build(validate(raw)))
    path = "/World/Sensors/" + raw["sensor"][0]["id"]
    for f, pose in enumerate(_poses(stage, path, range(5))):
        np.testing.assert_allclose(pose.origin, [-20.0, -30.0 + 1.5 * f, 1.8], atol=1e-9)  # 15 m/s at 10 fps
        az, el = rig.direction_angles(pose.forward)
        assert az == pytest.approx(0.0, abs=1e-9) and el == pytest.approx(-5.0)
        assert pose.up[2] > 0


def test_drone_tracks_a_moving_point_and_the_labels_camera_follows(raw):
    raw = _rig_raw(
        raw,
        platform="drone",
        path_m=[[0.0, -80.0, 90.0], [0.0, 80.0, 90.0]],
        speed_m_s=12.0,
        target="path",
        target_path_m=[[5.0, 0.0, 1.0], [5.0, 10.0, 1.0]],
        target_speed_m_s=1.5,
    )
    scenario = validate(raw)
    stage = Usd.Stage.Open(sensors_layer.build(scenario))
    name = raw["sensor"][0]["id"]
    poses = _poses(stage, f"/World/Sensors/{name}", range(5))
    export = StageExport(stage)
    eo = [
        dataclasses.replace(x, band="EO", wavelength_range_um=(0.4, 0.7)) for x in export.sensors
    ]  # no sky needed
    states = [export.frame_state(f, eo) for f in (0, 4)]
    for f, pose in enumerate(poses):
        target = np.array([5.0, 0.15 * f, 1.0])
        to_t = (target - pose.origin) / np.linalg.norm(target - pose.origin)
        assert np.dot(pose.forward, to_t) == pytest.approx(1.0, abs=1e-12)
        cam = Camera.from_pose(pose, 64, 48)
        uv, _ = cam.project(target)
        np.testing.assert_allclose(uv, [32.0, 24.0], atol=1e-6)  # the target stays at the centre
    # the render's frame state (labels, camera.json and the Mitsuba sensor read it) is the rig's pose
    for state, f in zip(states, (0, 4)):
        np.testing.assert_allclose(state.cameras[name].origin, poses[f].origin)
        np.testing.assert_allclose(state.cameras[name].forward, poses[f].forward)


def test_tripod_camera_tracks_a_person_from_the_avatar_keypoints(raw):
    raw = _rig_raw(raw, position_m=[0.0, -15.0, 1.6], target="human", target_human=raw["human"][0]["id"])
    scenario = validate(raw)
    hid = raw["human"][0]["id"]
    avatar = Usd.Stage.CreateInMemory()  # the avatar layer: metres, a walker's keypoints
    UsdGeom.SetStageMetersPerUnit(avatar, 1.0)
    avatar.SetTimeCodesPerSecond(scenario["general"]["fps"])
    root = UsdGeom.Xform.Define(avatar, human_path(hid))
    op = root.AddTranslateOp()
    kp = np.zeros((5, 17, 3))
    kp[:, [5, 6], 2], kp[:, [11, 12], 2] = 1.4, 0.9  # shoulders, hips
    kp[:, [5, 11], 0], kp[:, [6, 12], 0] = -0.2, 0.2
    write_keypoints(root.GetPrim(), kp, [f"k{i}" for i in range(17)])
    for f in range(5):
        op.Set((2.0 * f, 3.0, 0.0), Usd.TimeCode(f))  # walks east 2 m per frame
    # as compose hands it over: an in-memory root over the layer (no metersPerUnit of its own)
    up = compose_in_memory([avatar.GetRootLayer()], scenario["general"]["fps"])
    stage = Usd.Stage.Open(sensors_layer.build(scenario, up))
    for f, pose in enumerate(_poses(stage, "/World/Sensors/" + raw["sensor"][0]["id"], range(5))):
        centre = np.array([2.0 * f, 3.0, 1.15])
        d = (centre - pose.origin) / np.linalg.norm(centre - pose.origin)
        assert np.dot(pose.forward, d) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(pose.origin, [0.0, -15.0, 1.6])
    with pytest.raises(InputError, match="cocoKeypoints"):
        sensors_layer.build(scenario, Usd.Stage.CreateInMemory())


def test_handheld_shakes_by_default_and_a_still_tripod_has_one_transform(raw):
    still = validate(copy.deepcopy(raw))
    still_stage = Usd.Stage.Open(sensors_layer.build(still))
    ops = still_stage.GetPrimAtPath("/World/Sensors/" + raw["sensor"][0]["id"])
    assert UsdGeom.Xformable(ops).GetOrderedXformOps()[0].GetAttr().GetTimeSamples() == []
    hand = _rig_raw(copy.deepcopy(raw), fps=30.0, duration=1.0, platform="handheld")
    hand["sensor"][0].update(position_m=[0.0, -15.0, 1.6], look_at_m=[0.0, 0.0, 1.0])
    scenario = validate(hand)
    assert scenario["sensor"][0]["shake_rms_deg"] == rig.HANDHELD_SHAKE_RMS_DEG
    stage = Usd.Stage.Open(sensors_layer.build(scenario))
    poses = _poses(stage, "/World/Sensors/" + raw["sensor"][0]["id"], range(31))
    az = np.array([rig.direction_angles(p.forward)[0] for p in poses])
    nominal = rig.direction_angles(np.array([0.0, 15.0, -0.6]))[0]
    shake = rig.shake_angles(np.arange(31) / 30.0, rig.HANDHELD_SHAKE_RMS_DEG, 0)
    np.testing.assert_allclose(az - nominal, shake[:, 0], atol=1e-9)


@pytest.mark.parametrize(
    "sensor, message",
    [
        (
            {"platform": "vehicle", "path_m": [[0, 0, 1.5]], "target": "forward"},
            r"path_m.*two distinct points",
        ),
        ({"position_m": [0, -15, 1.6], "target": "human", "target_human": "nobody"}, "target_human"),
        ({"position_m": [0, -15, 1.6]}, r"look_at_m: missing required key"),
        (
            {"position_m": [0, -15, 1.6], "look_at_m": [0, 0, 1], "gimbal_pitch_range_deg": [30, -90]},
            "gimbal_pitch_range_deg",
        ),
        ({"platform": "drone", "position_m": [0, 0, 50], "path_m": [[0, 0, 50], [10, 0, 50]]}, "not with"),
    ],
)
def test_bad_rig_keys_are_named(raw, sensor, message):
    with pytest.raises(InputError, match=message):
        validate(_rig_raw(raw, **sensor))


def test_sensors_layer_reads_an_avatar_only_for_a_tracked_person(raw):
    still = validate(copy.deepcopy(raw))
    assert graph.layer_graph(still, plan(still)[0])["sensors"].upstream == ()
    hid = raw["human"][0]["id"]
    tracking = _rig_raw(raw, position_m=[0.0, -15.0, 1.6], target="human", target_human=hid)
    scenario = validate(tracking)
    nodes = graph.layer_graph(scenario, plan(scenario)[0])
    assert nodes["sensors"].upstream == (f"avatar_{hid}",)
    order = graph.build_order(nodes)
    assert order.index(f"avatar_{hid}") < order.index("sensors")


def test_ground_refinement_keeps_a_passing_cameras_closest_pose():
    """thermal.surfaces: a car camera 1.8 m up passing a ground point at 0.5 m: the kept poses
    come within the documented 3 % of the closest distance over the clip (every pose read)."""
    xs = np.linspace(-15.0, 15.0, 301)  # 0.1 m per frame
    poses = [
        CameraPose(np.array([x, 0.0, 1.8]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]), 45.0)
        for x in xs
    ]
    kept = _footprint_poses(poses)
    assert 2 < len(kept) <= FOOTPRINT_FRAMES
    for x in np.linspace(-14.0, 14.0, 57):
        cell = np.array([x, 0.5, 0.0])
        closest = min(np.linalg.norm(p.origin - cell) for p in poses)
        assert min(np.linalg.norm(p.origin - cell) for p in kept) <= 1.03 * closest


def test_render_resolution_keeps_the_field_of_view(raw):
    """sensor.render_resolution and render --resolution: another pixel count, the same view: a
    world point lands at the same fraction of the image width and height."""
    raw["sensor"] = raw["sensor"][:1]  # atom1024_lwir: 1024x768, 17 um
    full = Usd.Stage.Open(sensors_layer.build(validate(copy.deepcopy(raw))))
    cli = Usd.Stage.Open(sensors_layer.build(validate(copy.deepcopy(raw))))
    assert override_resolution(cli, (128, 96)) == ["atom1024_lwir: 1024x768 -> 128x96, pitch 17 -> 136 um"]
    assert "136" not in cli.GetRootLayer().ExportToString()  # the session layer only
    raw["sensor"][0]["render_resolution"] = [256, 192]
    small = Usd.Stage.Open(sensors_layer.build(validate(raw)))
    path = "/World/Sensors/" + raw["sensor"][0]["id"]
    point = np.array([1.3, 0.4, 2.1])
    frac = []
    for stage, (w, h), pitch in (
        (full, (1024, 768), 17e-6),
        (small, (256, 192), 68e-6),
        (cli, (128, 96), 136e-6),
    ):
        prim = stage.GetPrimAtPath(path)
        model = read_sensor_model(prim)
        assert model.resolution == (w, h) and model.pixel_pitch_m == pytest.approx(pitch)
        uv, _ = Camera.from_pose(read_camera_pose(prim, Usd.TimeCode(0)), w, h).project(point)
        frac.append(uv / [w, h])
    np.testing.assert_allclose(frac[1], frac[0], atol=1e-12)
    np.testing.assert_allclose(frac[2], frac[0], atol=1e-12)
    assert parse_resolution("160x128") == (160, 128)
    with pytest.raises(InputError, match="WIDTHxHEIGHT"):
        parse_resolution("160")


def test_the_editor_plan_draws_moving_and_tracking_cameras(raw):
    """editor.plan: a drone on a path, a car looking ahead and a tracker without look_at_m are
    drawn from their first pose toward what they look at."""
    hid = raw["human"][0]["id"]
    base = {k: v for k, v in raw["sensor"][0].items() if k not in ("position_m", "look_at_m")}
    raw["sensor"] = [
        {
            **base,
            "id": "drone",
            "platform": "drone",
            "path_m": [[0, -40, 60], [30, -40, 60]],
            "target": "human",
            "target_human": hid,
        },
        {
            **base,
            "id": "car",
            "platform": "vehicle",
            "path_m": [[-4, -30, 1.6], [-4, 30, 1.6]],
            "target": "forward",
        },
        {
            **base,
            "id": "mast",
            "platform": "mast",
            "position_m": [6, -12, 4],
            "target": "human",
            "target_human": hid,
        },
    ]
    scenario = validate(raw)
    svg = plan_svg(scenario)
    assert all(f'data-id="{i}"' in svg for i in ("drone", "car", "mast"))
    drone, car, _ = scenario["sensor"]
    np.testing.assert_allclose(sensor_position(drone), [0, -40, 60])
    np.testing.assert_allclose(sensor_look_point(car, []), [-4, -20, 1.6])  # 10 m ahead
    place = scenario["placement"][0]
    np.testing.assert_allclose(sensor_look_point(drone, scenario["placement"]), place["position_m"])
