"""Valid but suspicious scenes: one line each, logged by compose (issue 15).

A scenario can pass every range check and still describe a scene nobody means: a person
50 m above the ground or off its edge, a camera under the ground (it renders the ground's
back face) or inside a box, a person standing inside a box, a camera that sees nobody, keys
the activity ignores. These are warnings, not errors: compose goes on.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

#: how far [m] the feet may be above or below the ground before a person counts as off it
GROUND_TOLERANCE_M = 0.05
#: radius [m] of the cylinder standing in for a person (shoulder half-width)
PERSON_RADIUS_M = 0.25
#: the point [m] above the feet a camera must see (about the chest)
PERSON_CENTRE_M = 1.0
#: space [m] between two people's cylinders below which they overlap (none: they touch)
PERSONAL_GAP_M = 0.0
#: sensor keys only an aerial platform reads
ORBIT_KEYS = ("altitude_m", "orbit_radius_m", "orbit_speed_m_s", "orbit_start_deg", "orbit_clockwise")
#: sensor keys only a vehicle or drone platform reads
PATH_KEYS = ("path_m", "speed_m_s")
#: thermal keys only the radiation balance (jos3, twoNode) reads
RADIATION_KEYS = ("radiation_method", "radiation_rays", "radiation_step_s")


def _inside_box(point, obj, margin: float = 0.0) -> bool:
    """Whether ``point`` lies inside a ``[[scene.object]]`` box (centre of the base, size,
    heading about +z), grown by ``margin`` sideways."""
    c, s = np.asarray(obj["center_m"], float), np.asarray(obj["size_m"], float)
    h = math.radians(obj.get("heading_deg") or 0.0)
    d = np.asarray(point, float) - c
    local_x = math.cos(h) * d[0] + math.sin(h) * d[1]
    local_y = -math.sin(h) * d[0] + math.cos(h) * d[1]
    return bool(abs(local_x) < s[0] / 2 + margin and abs(local_y) < s[1] / 2 + margin and 0.0 < d[2] < s[2])


def _sees(sensor: dict, point) -> bool:
    """Whether ``point`` is in the sensor's field of view (pinhole; pitch, focal length,
    resolution), ignoring occlusion."""
    eye, target = np.asarray(sensor["position_m"], float), np.asarray(sensor["look_at_m"], float)
    forward = target - eye
    if np.linalg.norm(forward) == 0:
        return True
    forward /= np.linalg.norm(forward)
    up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.999 else np.array([0.0, 1.0, 0.0])
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, forward)
    d = np.asarray(point, float) - eye
    depth = float(d @ forward)
    if depth <= 0:
        return False
    f_px = sensor["focal_length_mm"] * 1e-3 / (sensor["pixel_pitch_um"] * 1e-6)
    w, h = sensor["resolution"]
    return abs(d @ right) / depth * f_px <= w / 2 and abs(d @ cam_up) / depth * f_px <= h / 2


def _keys_that_do_nothing(scenario, given: frozenset[str]) -> list[str]:
    """Keys the user wrote that have no effect where they stand (issue 26)."""
    out = []
    for i, s in enumerate(scenario["sensor"]):
        platform = s.get("platform", "tripod")
        if platform != "aerial":
            for key in ORBIT_KEYS:
                if f"sensor[{i}].{key}" in given:
                    out.append(f"sensor[{i}].{key}: ignored on a {platform} camera (for platform = 'aerial')")
        if platform not in ("vehicle", "drone"):
            for key in PATH_KEYS:
                if f"sensor[{i}].{key}" in given:
                    out.append(f"sensor[{i}].{key}: ignored on a {platform} camera (for vehicle or drone)")
    thermal = scenario["thermal"] or {}
    if thermal.get("model") == "fixed":
        for key in RADIATION_KEYS:
            if f"thermal.{key}" in given:
                out.append(f"thermal.{key}: ignored with thermal.model = 'fixed' (no radiation balance)")
    if scenario["scene"] is None and "scene" not in scenario.given:
        out.append("[scene]: not given: no ground and no objects (the people stand in empty space)")
    return out


def suspicious(scenario) -> list[str]:
    """One line per suspicious thing in a validated scenario (empty when none)."""
    out: list[str] = []
    scene = scenario["scene"]
    ground = scene["ground"] if scene is not None else None
    objects = scene["object"] if scene is not None else []
    people = {p["human"]: (i, p) for i, p in enumerate(scenario["placement"])}
    for hum in scenario["human"]:
        where = people.get(hum["id"])
        if where is None:
            continue
        k, place = where
        pos = np.asarray(place["position_m"], float)
        key = f"placement[{k}].position_m = {list(place['position_m'])}"
        if ground is not None:
            if abs(pos[2]) > GROUND_TOLERANCE_M:
                out.append(f"{key}: the feet are {pos[2]:+.2f} m from the ground (z = 0); intended?")
            half = np.asarray(ground["size_m"], float) / 2
            if abs(pos[0]) > half[0] or abs(pos[1]) > half[1]:
                out.append(
                    f"{key}: off the ground, whose extent is x, y within +-{half[0]:g}, +-{half[1]:g} m "
                    "(scene.ground.size_m)"
                )
        for obj in objects:
            if _inside_box(pos + [0, 0, PERSON_CENTRE_M], obj, margin=PERSON_RADIUS_M):
                out.append(f"{key}: person {hum['id']} intersects scene object {obj['id']!r}")
        if hum.get("segment") and place.get("avoidance", "none") != "none":
            out.append(
                f"placement[{k}].avoidance = {place['avoidance']!r}: ignored with human.segment "
                "(a person with segments keeps to the path)"
            )
        walks = {hum.get("activity")} | {seg.get("activity") for seg in hum.get("segment") or ()}
        if place.get("waypoints_m") and not walks & {"walk", "run", "carry"} and not hum.get("bvh"):
            out.append(
                f"placement[{k}].waypoints_m: ignored with activity {hum.get('activity')!r} "
                "(waypoints are for walk and run)"
            )
    centres = [
        (h["id"], np.asarray(people[h["id"]][1]["position_m"], float) + [0, 0, PERSON_CENTRE_M])
        for h in scenario["human"]
        if h["id"] in people
    ]
    given = getattr(scenario, "given_keys", frozenset())
    out += _keys_that_do_nothing(scenario, given)
    for (a, ca), (b, cb) in itertools.combinations(centres, 2):
        gap = float(np.hypot(*(ca - cb)[:2]))
        if gap < 2 * PERSON_RADIUS_M + PERSONAL_GAP_M:
            out.append(
                f"human {a!r} and human {b!r} stand {gap:.2f} m apart (centre to centre): their bodies "
                f"overlap below {2 * PERSON_RADIUS_M + PERSONAL_GAP_M:g} m (placement.position_m)"
            )
    for i, s in enumerate(scenario["sensor"]):
        if s.get("platform", "tripod") != "tripod" or (s.get("target") or "point") != "point":
            continue  # a moving platform or a tracking camera: its path or target, not position_m
        eye = np.asarray(s["position_m"], float)
        key = f"sensor[{i}].position_m = {list(s['position_m'])}"
        if ground is not None and eye[2] < 0:
            out.append(f"{key}: below the ground (z < 0); it would see the ground's back face")
        for obj in objects:
            if _inside_box(eye, obj):
                out.append(f"{key}: inside scene object {obj['id']!r}")
        if centres and not any(_sees(s, c) for _, c in centres):
            out.append(
                f"sensor[{i}] ({s['id']}): no person is in its field of view (look_at_m, focal_length_mm)"
            )
    return out
