"""The sweep's camera sampler: a ``[camera]`` table draws one sensor's pose per variant around a
person (or a point, or a region), the way Replicator's and BlenderProc's camera samplers do.

::

    [camera]
    sensor = 0                              # the [[sensor]] placed (index)
    preset = "kaist"                        # humv_usd.catalog.viewpoints: fills what is not given
    human = 0                               # aim at this [[human]] (its placement at frame 0) ...
    # target_m = [0.0, 0.0, 1.0]            # ... or at a point, or at a point drawn in a region:
    # region_m = [[-10.0, -10.0], [10.0, 10.0]]
    distance_m = { uniform = [5.0, 40.0] }  # horizontal distance to the target
    height_m = { uniform = [1.5, 2.2] }     # camera height above the ground
    azimuth_deg = { uniform = [0.0, 360.0] }  # compass direction of the camera seen from the target
    pitch_deg = { normal = [0.0, 1.0] }     # camera elevation; leave out to aim at the target
    yaw_offset_deg = { uniform = [-15.0, 15.0] }  # horizontal aim off the target
    roll_deg = { normal = [0.0, 0.5] }
    min_height_px = 20                      # the person at least this tall in the image
    max_tries = 500

Constraints (a draw that fails one is redrawn, up to ``max_tries``): the person (a cylinder of
the person's stature and radius :data:`PERSON_RADIUS_M`) lies wholly inside the image and in
front of the camera, its bounding box is at least ``min_height_px`` tall, the camera is above
the ground and not inside a ``[[scene.object]]`` box, and no such box cuts the line of sight to
the person's centre. Draws use ``numpy.random.default_rng([sweep seed, variant, 28])``, so a
variant's pose does not depend on the others. The drawn pose becomes the sensor's ``position_m``,
``look_at_m`` and ``roll_deg`` (a still camera: platform tripod, target point); the variant's
parameters record distance, height, azimuth, pitch, roll and the person's pixel height.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from humv_usd.catalog.viewpoints import VIEWPOINTS
from humv_usd.errors import InputError, bad_value
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.geometry.rig import camera_axes, direction_angles
from humv_usd.physics.sensor import field_of_view_deg
from humv_usd.scenario.spec import SENSOR_PRESET_KEYS

#: radius [m] of the cylinder standing in for a person (shoulder half-width)
PERSON_RADIUS_M = 0.25
CAMERA_KEYS = (
    "sensor",
    "preset",
    "human",
    "target_m",
    "region_m",
    "distance_m",
    "height_m",
    "azimuth_deg",
    "pitch_deg",
    "yaw_offset_deg",
    "roll_deg",
    "min_height_px",
    "max_tries",
)
DISTRIBUTION_KEYS = ("distance_m", "height_m", "azimuth_deg", "pitch_deg", "yaw_offset_deg", "roll_deg")
#: lowest camera height above the ground [m]
MIN_CAMERA_HEIGHT_M = 0.2


@dataclass
class CameraSampler:
    """A parsed ``[camera]`` table (see the module doc); distributions as in
    :mod:`humv_usd.catalog.viewpoints` (``("uniform", lo, hi)``, ``("normal", mean, sd[, clip])``,
    ``("fixed", v)``; ``pitch_deg`` None: aimed at the target; ``distance_m`` None: from the pitch)."""

    sensor: int = 0
    preset: str | None = None
    human: int | None = 0
    target_m: tuple | None = None
    region_m: tuple | None = None
    distance_m: tuple | None = ("uniform", 5.0, 30.0)
    height_m: tuple = ("uniform", 1.5, 2.0)
    azimuth_deg: tuple = ("uniform", 0.0, 360.0)
    pitch_deg: tuple | None = None
    yaw_offset_deg: tuple = ("fixed", 0.0)
    roll_deg: tuple = ("fixed", 0.0)
    min_height_px: float = 10.0
    max_tries: int = 500
    sensor_keys: dict = field(default_factory=dict)


def draw(dist, rng: np.random.Generator) -> float:
    """One value of a distribution tuple."""
    kind = dist[0]
    if kind == "fixed":
        return float(dist[1])
    if kind == "uniform":
        return float(rng.uniform(dist[1], dist[2]))
    if kind == "normal":
        lo, hi = dist[3] if len(dist) > 3 else (-math.inf, math.inf)
        for _ in range(1000):
            v = float(rng.normal(dist[1], dist[2]))
            if lo <= v <= hi:
                return v
        return float(np.clip(dist[1], lo, hi))
    raise ValueError(f"invalid distribution {dist!r}")


def _distribution(where: str, value, problems: list[str]):
    """A sweep-file distribution ({uniform = [lo, hi]}, {normal = [mean, sd]}, a number) -> tuple."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return ("fixed", float(value))
    if isinstance(value, dict) and len(value) == 1:
        ((kind, args),) = value.items()
        ok = isinstance(args, list) and len(args) == 2 and all(isinstance(a, (int, float)) for a in args)
        if kind == "uniform" and ok and args[0] <= args[1]:
            return ("uniform", float(args[0]), float(args[1]))
        if kind == "normal" and ok and args[1] >= 0:
            return ("normal", float(args[0]), float(args[1]))
    problems.append(
        bad_value(
            where, value, "expected a number, { uniform = [lo, hi] } (lo <= hi) or { normal = [mean, sd] }"
        )
    )
    return None


def parse_camera(table, problems: list[str]) -> CameraSampler | None:
    """The ``[camera]`` table of a sweep file; problems are appended, one line each."""
    if not isinstance(table, dict):
        problems.append(bad_value("[camera]", table, "expected a table"))
        return None
    for key in table:
        if key not in CAMERA_KEYS:
            problems.append(f"camera.{key}: unknown key; allowed: {', '.join(CAMERA_KEYS)}")
    sampler = CameraSampler()
    name = table.get("preset")
    if name is not None:
        if name not in VIEWPOINTS:
            problems.append(bad_value("camera.preset", name, f"expected one of {', '.join(VIEWPOINTS)}"))
        else:
            p = VIEWPOINTS[name]
            sampler.preset = name
            sampler.sensor_keys = dict(p.sensor)
            for key in DISTRIBUTION_KEYS:
                setattr(sampler, key, getattr(p, key))
            sampler.min_height_px = p.min_height_px
    for key in DISTRIBUTION_KEYS:
        if key in table:
            setattr(sampler, key, _distribution(f"camera.{key}", table[key], problems))
    for key, lo, hi in (("sensor", 0, 999), ("max_tries", 1, 100000)):
        if key in table:
            v = table[key]
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                problems.append(bad_value(f"camera.{key}", v, f"expected an integer in {lo}..{hi}"))
            else:
                setattr(sampler, key, v)
    if "min_height_px" in table:
        v = table["min_height_px"]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 16384:
            problems.append(bad_value("camera.min_height_px", v, "expected a number in 0..16384 [px]"))
        else:
            sampler.min_height_px = float(v)
    targets = [k for k in ("human", "target_m", "region_m") if k in table]
    if len(targets) > 1:
        problems.append(f"camera: give one of human, target_m, region_m (got {', '.join(targets)})")
    if "target_m" in table:
        v = table["target_m"]
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(a, (int, float)) for a in v)):
            problems.append(bad_value("camera.target_m", v, "expected [x, y, z] [m]"))
        else:
            sampler.human, sampler.target_m = None, tuple(float(a) for a in v)
    if "region_m" in table:
        v = table["region_m"]
        ok = isinstance(v, list) and len(v) == 2 and all(isinstance(c, list) and len(c) == 2 for c in v)
        if not ok or not all(v[0][i] < v[1][i] for i in range(2)):
            problems.append(bad_value("camera.region_m", v, "expected [[x_min, y_min], [x_max, y_max]] [m]"))
        else:
            sampler.human, sampler.region_m = None, tuple(tuple(float(a) for a in c) for c in v)
    if "human" in table:
        v = table["human"]
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            problems.append(bad_value("camera.human", v, "expected the index of a [[human]]"))
        else:
            sampler.human = v
    if sampler.distance_m is None and sampler.pitch_deg is None and "distance_m" not in table:
        problems.append("camera.distance_m: needed when camera.pitch_deg is not given")
    return sampler


def _box_hits_segment(obj: dict, a, b) -> bool:
    """Whether the segment a-b passes through a ``[[scene.object]]`` box (slab test in the box's
    frame: centre of the base, size, heading about +z)."""
    c, s = np.asarray(obj["center_m"], float), np.asarray(obj["size_m"], float)
    h = math.radians(obj.get("heading_deg") or 0.0)
    rot = np.array([[math.cos(h), math.sin(h), 0.0], [-math.sin(h), math.cos(h), 0.0], [0.0, 0.0, 1.0]])
    p, d = rot @ (np.asarray(a, float) - c), rot @ (np.asarray(b, float) - np.asarray(a, float))
    lo, hi = np.array([-s[0] / 2, -s[1] / 2, 0.0]), np.array([s[0] / 2, s[1] / 2, s[2]])
    t0, t1 = 0.0, 1.0
    for i in range(3):
        if abs(d[i]) < 1e-12:
            if not lo[i] < p[i] < hi[i]:
                return False
            continue
        ta, tb = sorted(((lo[i] - p[i]) / d[i], (hi[i] - p[i]) / d[i]))
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            return False
    return True


def _inside(obj: dict, point) -> bool:
    return _box_hits_segment(obj, point, np.asarray(point, float) + 1e-9)


def person_box_px(camera: Camera, feet, stature_m: float) -> tuple[float, float, bool]:
    """(height, width) [px] of the bounding box of a person's cylinder (feet position, stature,
    radius :data:`PERSON_RADIUS_M`) and whether it lies wholly inside the image, in front."""
    ang = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1) * PERSON_RADIUS_M
    pts = np.concatenate([np.asarray(feet, float) + ring, np.asarray(feet, float) + ring + [0, 0, stature_m]])
    uv, z = camera.project(pts)
    if np.any(z <= 0) or not np.all(np.isfinite(uv)):
        return 0.0, 0.0, False
    inside = bool(
        np.all((uv[:, 0] >= 0) & (uv[:, 0] <= camera.width) & (uv[:, 1] >= 0) & (uv[:, 1] <= camera.height))
    )
    return float(np.ptp(uv[:, 1])), float(np.ptp(uv[:, 0])), inside


def sample_view(sampler: CameraSampler, scenario, rng: np.random.Generator) -> dict:
    """One camera pose for ``scenario`` (a validated :class:`humv_usd.scenario.Scenario`, the
    sensor's intrinsics filled) meeting the constraints; InputError when ``max_tries`` draws fail
    (naming the constraint that failed most)."""
    s = scenario["sensor"][sampler.sensor]
    w, h = (int(v) for v in s["resolution"])
    fov_x = field_of_view_deg(w * s["pixel_pitch_um"] * 1e-6, s["focal_length_mm"] * 1e-3)
    vfov = field_of_view_deg(h * s["pixel_pitch_um"] * 1e-6, s["focal_length_mm"] * 1e-3)
    objects = (scenario["scene"] or {}).get("object", []) if scenario["scene"] is not None else []
    stature = None
    if sampler.human is not None:
        hum = scenario["human"][sampler.human]
        place = next(p for p in scenario["placement"] if p["human"] == hum["id"])
        feet = np.asarray(place["position_m"], float)
        stature = float(hum["stature_m"])
    failed: dict[str, int] = {}
    for tries in range(1, sampler.max_tries + 1):
        if sampler.region_m is not None:
            (x0, y0), (x1, y1) = sampler.region_m
            feet = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1), 0.0])
        elif sampler.target_m is not None:
            feet = np.asarray(sampler.target_m, float) - [0.0, 0.0, 1.0]
        centre = feet + [0.0, 0.0, 0.5 * stature if stature else 1.0]
        height = draw(sampler.height_m, rng)
        azimuth = draw(sampler.azimuth_deg, rng)
        pitch = None if sampler.pitch_deg is None else draw(sampler.pitch_deg, rng)
        if sampler.distance_m is None:  # the target at a drawn offset within the central 80 % of the VFOV
            elevation = pitch + rng.uniform(-0.4, 0.4) * vfov
            if elevation > -1.0:
                failed["below the horizon"] = failed.get("below the horizon", 0) + 1
                continue
            distance = (height - centre[2]) / math.tan(math.radians(-elevation))
        else:
            distance = draw(sampler.distance_m, rng)
        a = math.radians(azimuth)
        eye = np.array([centre[0] + distance * math.sin(a), centre[1] + distance * math.cos(a), height])
        if height < MIN_CAMERA_HEIGHT_M:
            failed["above the ground"] = failed.get("above the ground", 0) + 1
            continue
        if any(_inside(o, eye) for o in objects):
            failed["not inside an object"] = failed.get("not inside an object", 0) + 1
            continue
        look_az, look_el = direction_angles(centre - eye)
        look_az = float(look_az) + draw(sampler.yaw_offset_deg, rng)
        el = float(look_el) if pitch is None else pitch
        roll = draw(sampler.roll_deg, rng)
        fwd, up = camera_axes(look_az, el, roll)
        camera = Camera.from_pose(CameraPose(eye, fwd, up, fov_x), w, h)
        if stature is not None:
            px, _, inside = person_box_px(camera, feet, stature)
            if not inside:
                failed["person wholly in view"] = failed.get("person wholly in view", 0) + 1
                continue
            if px < sampler.min_height_px:
                failed[f"at least {sampler.min_height_px:g} px tall"] = (
                    failed.get(f"at least {sampler.min_height_px:g} px tall", 0) + 1
                )
                continue
        else:
            uv, z = camera.project(centre)
            px = float("nan")
            if not (z > 0 and 0 <= uv[0] <= w and 0 <= uv[1] <= h):
                failed["target in view"] = failed.get("target in view", 0) + 1
                continue
        if any(_box_hits_segment(o, eye, centre) for o in objects):
            failed["line of sight"] = failed.get("line of sight", 0) + 1
            continue
        return {
            "position_m": [round(float(v), 6) for v in eye],
            "look_at_m": [round(float(v), 6) for v in eye + 10.0 * fwd],
            "roll_deg": round(roll, 6),
            "distance_m": round(distance, 4),
            "height_m": round(height, 4),
            "azimuth_deg": round(azimuth, 4),
            "pitch_deg": round(el, 4),
            "person_height_px": round(px, 3),
            "tries": tries,
        }
    worst = max(failed, key=failed.get) if failed else "?"
    raise InputError(
        f"camera sampler: no pose in {sampler.max_tries} draws meets the constraints "
        f"(most often failed: {worst}, {failed.get(worst, 0)} times); widen the distributions or lower min_height_px"
    )


def apply_view(raw: dict, sampler: CameraSampler, view: dict) -> None:
    """Set the drawn pose on the variant's sensor table (a still camera)."""
    s = raw["sensor"][sampler.sensor]
    for key in ("path_m", "target_human", "target_path_m"):
        s.pop(key, None)
    s.update(
        platform="tripod" if view["position_m"][2] < 2.0 or view["position_m"][2] > 100.0 else "mast",
        target="point",
        position_m=view["position_m"],
        look_at_m=view["look_at_m"],
        roll_deg=view["roll_deg"],
    )


def with_sensor_keys(raw: dict, sampler: CameraSampler) -> dict:
    """``raw`` with the preset's sensor keys set on the sampled sensor (a copy)."""
    raw = copy.deepcopy(raw)
    if sampler.sensor_keys:
        table = raw["sensor"][sampler.sensor]
        if "preset" in sampler.sensor_keys:  # the dataset's camera: the base's intrinsics go
            for key in SENSOR_PRESET_KEYS:
                table.pop(key, None)
        table.update(copy.deepcopy(sampler.sensor_keys))
    return raw
