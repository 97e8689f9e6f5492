"""Sensor tool: cameras with HumvSensorAPI → layers/sensors.usda.

One UsdGeom.Camera per ``[[sensor]]`` with the radiometric model (HumvSensorAPI) from the table
and its preset (:mod:`humv_usd.catalog.sensors`). Where the camera is and where it points comes
from its rig (:mod:`humv_usd.geometry.rig`): the platform (tripod, mast, aerial orbit, vehicle or
drone along ``path_m``, handheld with shake), the target (a point, a person tracked through the
avatar layer's keypoints, a moving point on a path, or the direction of travel) and the gimbal
limits. A camera whose pose changes gets a transform time sample at every frame (all sensors
share the frame times: synchronised, multi-view); a still one gets one transform.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

from humv_usd.catalog.sensors import PRESETS, orbit_positions, preset
from humv_usd.errors import InputError, bad_value
from humv_usd.geometry.rig import (
    Gimbal,
    RigPoses,
    camera_matrix,
    direction_angles,
    polyline_track,
    rig_poses,
    shake_angles,
)
from humv_usd.scenario import Scenario, validate
from humv_usd.scenario.inputs import FRAMES
from humv_usd.usd.avatar import read_keypoints
from humv_usd.usd.layers import SCOPES, finish, library_layer_main, new_layer_stage
from humv_usd.usd.paths import human_path, sensor_path
from humv_usd.usd.sensor import CHAIN_ATTRIBUTES, write_sensor

NAME = "sensors"
READS = (*FRAMES, "sensor", "@netdOrigin")
UPSTREAM = ("avatar_*",)  # a camera tracking a person reads the person's keypoints (upstream_for)
VERSION = "6"  # 3: focusDistance at the look-at point; 4: rigs; 5: a tracked person in metres; 6: NETD origin
#: inputs only the render reads (the image chain after the optics: noise, counts, AGC, FPN, lens
#: stop, codecs): the key the layers built on this one see ignores them (compose's
#: ``LayerState.passed_key``), so a NETD or AGC edit rebuilds this layer and not the thermal layer
#: (which reads the cameras' poses and pixel footprints) or the path tables (positions). Issue 26:
#: an edit of netd_k cost the editor's preview a 25-60 s thermal rebuild.
RENDER_ONLY = (
    "@netdOrigin",
    *(
        f"sensor.*.{k}"
        for k in (
            "f_number",
            "netd_k",
            "bit_depth",
            "gain",
            "offset",
            "agc",
            "agc_percentiles",
            "agc_plateau",
            "agc_max_gain",
            "agc_midpoint",
            "fpn_gain_sigma",
            "fpn_offset_sigma_k",
            "fpn_drift_k_per_s",
            "ffc_interval_s",
            "fpn_seed",
            "vignetting",
            "time_constant_s",
            "jpeg_quality",
            "h264_crf",
            "full_well_e",
            "read_noise_e",
            "subbands",
        )
    ),
)


def upstream_for(scenario: Scenario) -> tuple[str, ...]:
    """The avatar layers this scenario's sensors read: those of the people a camera tracks
    (``target = "human"``); none otherwise, so an avatar edit leaves a still camera cached."""
    ids = sorted({s["target_human"] for s in scenario["sensor"] if (s.get("target") or "point") == "human"})
    return tuple(f"avatar_{i}" for i in ids)


# UsdGeom lens and filmback values are in tenths of a scene unit: on a metre stage 1 mm = 0.01.
_MM_TO_TENTHS_OF_M = 0.01


def camera_positions(s: dict, fps: float, frame_count: int) -> np.ndarray:
    """Platform position [m] per frame, (frame_count, 3): the orbit (aerial), the path
    (vehicle, drone) or position_m (tripod, mast, handheld)."""
    return _platform(s, fps, frame_count)[0]


def _platform(s: dict, fps: float, frame_count: int) -> tuple[np.ndarray, np.ndarray | None]:
    """(positions (T, 3) [m], compass heading of travel (T,) [deg] or None for a still one)."""
    times = np.arange(max(frame_count, 1)) / fps
    if s["platform"] == "aerial":
        orbit = dict(start_deg=s["orbit_start_deg"], clockwise=s["orbit_clockwise"] == "yes")
        args = (s["look_at_m"], s["altitude_m"], s["orbit_radius_m"], s["orbit_speed_m_s"])
        pos = orbit_positions(*args, times, **orbit)
        ahead = orbit_positions(*args, times + 1e-3, **orbit)  # the tangent: direction of travel
        moving = np.linalg.norm(ahead - pos, axis=1) > 0
        return pos, direction_angles(ahead - pos)[0] if moving.all() else None
    if s["platform"] in ("vehicle", "drone"):
        pos, direction = polyline_track(s["path_m"], s["speed_m_s"], times)
        return pos, direction_angles(direction)[0]
    return np.tile(np.asarray(s["position_m"], dtype=float), (times.size, 1)), None


#: COCO keypoints whose mean is a tracked person's body centre: shoulders and hips
_TORSO_KEYPOINTS = (5, 6, 11, 12)


def person_centres(stage, human_id: str, frame_count: int) -> np.ndarray:
    """(T, 3) world centre [m] of a person's torso (mean of the COCO shoulders and hips of the
    avatar layer's keypoints) at each frame; InputError when the stage has no keypoints for them."""
    prim = stage.GetPrimAtPath(human_path(human_id)) if stage is not None else None
    where = f"{human_path(human_id)}.humv:label:cocoKeypoints"
    out = np.empty((max(frame_count, 1), 3))
    # compose's in-memory upstream root authors no metersPerUnit (USD's fallback is centimetres);
    # the layers are in metres
    authored = stage is not None and UsdGeom.StageHasAuthoredMetersPerUnit(stage)
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage)) if authored else 1.0
    for f in range(len(out)):
        pts = read_keypoints(prim, f) if prim and prim.IsValid() else None
        if pts is None or len(pts) < 17:
            raise InputError(
                bad_value(where, None, "a tracked person needs the avatar layer's 17 COCO keypoints")
            )
        m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(f)), dtype=float)
        centre = pts[list(_TORSO_KEYPOINTS)].mean(axis=0)
        out[f] = (centre @ m[:3, :3] + m[3, :3]) * mpu
    return out


def camera_rig(s: dict, fps: float, frame_count: int, upstream=None) -> RigPoses:
    """The camera poses of sensor table ``s`` at each frame (:func:`humv_usd.geometry.rig.rig_poses`):
    platform (:func:`camera_positions`), target (look_at_m, a person's torso centre read from
    ``upstream``'s avatar layer, a point moving along target_path_m, or none: along the direction
    of travel turned by the mount angles), gimbal limits, roll and hand shake."""
    n = max(frame_count, 1)
    times = np.arange(n) / fps
    origins, heading = _platform(s, fps, frame_count)
    targets = (
        None if (s.get("target") or "point") == "forward" else _target_points(s, fps, frame_count, upstream)
    )
    if heading is None:  # a still platform faces its first target (forward: north)
        heading = np.full(n, direction_angles(targets[0] - origins[0])[0] if targets is not None else 0.0)
    gimbal = Gimbal(
        yaw_range_deg=tuple(s["gimbal_yaw_range_deg"]),
        pitch_range_deg=tuple(s["gimbal_pitch_range_deg"]),
        rate_deg_s=float(s["gimbal_rate_deg_s"]),
    )
    rms = float(s.get("shake_rms_deg") or 0.0)
    try:
        return rig_poses(
            origins,
            heading,
            times,
            targets=targets,
            mount_deg=(s["mount_yaw_deg"], s["mount_pitch_deg"]),
            gimbal=gimbal,
            roll_deg=s["roll_deg"],
            shake_deg=shake_angles(times, rms, s["shake_seed"]) if rms > 0 else None,
        )
    except ValueError as exc:
        raise InputError(f"sensor {s['id']}: {exc}") from None


def _target_points(s: dict, fps: float, frame_count: int, upstream) -> np.ndarray:
    """(T, 3) the points :func:`camera_rig` aims at (target point, person or path)."""
    n = max(frame_count, 1)
    target = s.get("target") or "point"
    if target == "human":
        return person_centres(upstream, s["target_human"], n)
    if target == "path":
        pts = np.asarray(s["target_path_m"], dtype=float).reshape(-1, 3)
        if len(pts) == 1:
            return np.tile(pts[0], (n, 1))
        return polyline_track(pts, s["target_speed_m_s"], np.arange(n) / fps)[0]
    return np.tile(np.asarray(s["look_at_m"], dtype=float), (n, 1))


def focus_distances(poses: RigPoses, targets_or_none) -> np.ndarray:
    """(T,) focus distance [m]: to the target, else to where the axis meets the ground z = 0
    (looking down), else 100 m."""
    if targets_or_none is not None:
        return np.linalg.norm(np.asarray(targets_or_none) - poses.origin, axis=1)
    down = -poses.forward[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(down > 1e-3, poses.origin[:, 2] / down, 100.0)
    return np.clip(d, 0.05, 1.0e5)


def render_geometry(s: dict) -> tuple[int, int, float]:
    """(width, height [px], pixel pitch [um]) the camera is authored with: ``resolution`` and
    ``pixel_pitch_um``, or with ``render_resolution`` that pixel count at the same horizontal
    field of view (pitch x resolution[0] / render_resolution[0]; square pixels)."""
    w0, h0 = (int(v) for v in s["resolution"])
    if not s.get("render_resolution"):
        return w0, h0, float(s["pixel_pitch_um"])
    w, h = (int(v) for v in s["render_resolution"])
    return w, h, float(s["pixel_pitch_um"]) * w0 / w


def _response(s: dict):
    """Response curve and EO channel responses authored for the sensor: the preset's when the
    band is the preset's, clipped to the sensor's band edges; none (flat) otherwise."""
    if not s.get("preset"):
        return None, None, None
    p = preset(s["preset"])
    if p.band != s["band"]:
        return None, None, None
    wl = np.asarray(p.response_wavelengths_um, dtype=float)
    lo, hi = s["wavelength_um"]
    if not np.any((wl >= lo) & (wl <= hi)):
        return None, None, None
    channels = None if p.channel_response is None else np.asarray(p.channel_response, dtype=float)
    return wl, np.asarray(p.response, dtype=float), channels


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    frames = scenario.frame_count
    stage = new_layer_stage(g["fps"], frames, "HumV-USD sensors layer")
    UsdGeom.Scope.Define(stage, SCOPES["sensors"])
    for i, s in enumerate(scenario["sensor"]):
        cam = UsdGeom.Camera.Define(stage, sensor_path(s["id"]))
        op = cam.AddTransformOp()
        poses = camera_rig(s, g["fps"], frames, upstream)
        target = (
            None
            if (s.get("target") or "point") == "forward"
            else _target_points(s, g["fps"], frames, upstream)
        )
        # focused where it looks (HumV renders a pinhole; a viewer honouring fStop without a
        # focusDistance focuses at 0 m: Blender rendered a uniform blur)
        focus = cam.CreateFocusDistanceAttr()
        dist = focus_distances(poses, target)
        mats = [
            Gf.Matrix4d(camera_matrix(o, f, u).tolist())
            for o, f, u in zip(poses.origin, poses.forward, poses.up)
        ]
        still = all(m == mats[0] for m in mats) and np.ptp(dist) == 0
        if still:
            op.Set(mats[0])
            focus.Set(float(dist[0]))
        else:
            for frame, (m, d) in enumerate(zip(mats, dist)):
                op.Set(m, Usd.TimeCode(frame))
                focus.Set(float(d), Usd.TimeCode(frame))
        width, height, pitch_um = render_geometry(s)
        pitch_mm = pitch_um * 1e-3
        cam.CreateProjectionAttr(UsdGeom.Tokens.perspective)
        cam.CreateFocalLengthAttr(s["focal_length_mm"] * _MM_TO_TENTHS_OF_M)
        cam.CreateHorizontalApertureAttr(width * pitch_mm * _MM_TO_TENTHS_OF_M)
        cam.CreateVerticalApertureAttr(height * pitch_mm * _MM_TO_TENTHS_OF_M)
        cam.CreateFStopAttr(s["f_number"])
        cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, 1.0e5))
        wl, response, channels = _response(s)
        eo = s["band"] == "EO"
        write_sensor(
            cam.GetPrim(),
            band=s["band"],
            wavelength_range_um=s["wavelength_um"],
            resolution=(width, height),
            pixel_pitch_m=pitch_um * 1e-6,
            f_number=s["f_number"],
            netd_k=s["netd_k"],
            netd_origin=scenario.netd_origin[i] if i < len(scenario.netd_origin) else "",
            bit_depth=s["bit_depth"],
            offset=s["offset"],
            preset=s.get("preset") or "",
            platform=s["platform"],
            agc=s["agc"],
            agc_percentiles=s["agc_percentiles"],
            gain=s["gain"],  # EO presets: no gain = auto exposure
            subbands=None if eo else s["subbands"],  # the render's sub-band count (--subbands overrides)
            full_well_e=s["full_well_e"] if eo or s["band"] in ("NIR", "SWIR") else None,
            read_noise_e=s["read_noise_e"] if eo or s["band"] in ("NIR", "SWIR") else None,
            response_wavelengths_um=wl,
            response=response,
            channel_response=channels,
            chain_settings={k: s.get(k) for k in CHAIN_ATTRIBUTES},
        )
    return finish(stage)


# ---------------------------------------------------------------------------- presets file
PRESETS_FILE = Path(__file__).resolve().parents[2] / "layers" / "sensors.usda"


def build_presets() -> Sdf.Layer:
    """Every sensor preset as a camera /World/Sensors/<preset> (the reusable layers/sensors.usda):
    on a tripod 1.6 m above the origin's south, 15 m away, looking north (as in humvvex)."""
    raw = {
        "general": {
            "name": "sensor_presets",
            "start": _dt.datetime(2018, 10, 24, 14, 5),
            "utc_offset_h": 0.0,
            "latitude_deg": 0.0,
            "longitude_deg": 0.0,
            "fps": 1.0,
        },
        "sensor": [
            {"id": name, "preset": name, "position_m": [0.0, -15.0, 1.6], "look_at_m": [0.0, 0.0, 1.6]}
            for name in PRESETS
        ],
    }
    layer = build(validate(raw))
    layer.documentation = (
        "HumV-USD sensor presets (humv_usd.catalog.sensors), one camera each. "
        "Generated: python -m humv_usd.sensors.layer"
    )
    return layer


def main(argv=None) -> int:
    """Write layers/sensors.usda (``--check``: exit 1 if it is out of date)."""
    return library_layer_main(PRESETS_FILE, build_presets, main.__doc__, argv)


if __name__ == "__main__":
    raise SystemExit(main())
