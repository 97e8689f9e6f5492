"""Top-down plan of a scenario as SVG: ground, objects, assets, people with their walk paths,
sensors with their horizontal view frusta (aerial: the orbit), a north arrow and the sun's azimuth.

World frame as the stage: x east, y north (up on the plan), metres. Each sensor is a
``<g class="sensor" data-id=ID>`` and each person a ``<g class="person" data-id=ID>``, so a test
(or a browser) can find them.
"""

from __future__ import annotations

import math
from html import escape

import numpy as np

from humv_usd.catalog.sensors import orbit_positions
from humv_usd.physics.sensor import field_of_view_deg
from humv_usd.scenario.load import Scenario

_SENSOR_COLOURS = {"LWIR": "#d62728", "MWIR": "#ff7f0e", "EO": "#1f77b4"}


def horizontal_fov_deg(sensor: dict) -> float:
    """Full horizontal field of view of a pinhole camera [deg]: 2·atan(w·p / 2f)
    (:func:`humv_usd.physics.sensor.field_of_view_deg`)."""
    width_m = sensor["resolution"][0] * sensor["pixel_pitch_um"] * 1e-6
    return field_of_view_deg(width_m, sensor["focal_length_mm"] * 1e-3)


def sensor_position(sensor: dict) -> np.ndarray:
    """Camera position at frame 0 [m] (aerial: on its orbit)."""
    if sensor["platform"] == "aerial":
        return orbit_positions(
            sensor["look_at_m"],
            sensor["altitude_m"],
            sensor["orbit_radius_m"],
            sensor["orbit_speed_m_s"],
            [0.0],
            start_deg=sensor["orbit_start_deg"],
            clockwise=sensor["orbit_clockwise"] == "yes",
        )[0]
    if sensor["platform"] in ("vehicle", "drone"):  # the start of its path
        return np.asarray(sensor["path_m"][0], dtype=float)
    return np.asarray(sensor["position_m"], dtype=float)


def sensor_look_point(sensor: dict, placements: list[dict]) -> np.ndarray:
    """Where the camera looks at frame 0 [m]: look_at_m, else its tracked person's placement,
    the start of its target path, or 10 m along its first path segment (a forward camera)."""
    if sensor.get("look_at_m") is not None:
        return np.asarray(sensor["look_at_m"], dtype=float)
    pos = sensor_position(sensor)
    target = sensor.get("target")
    if target == "human":
        for p in placements:
            if p["human"] == sensor.get("target_human"):
                return np.asarray(p["position_m"], dtype=float)
    if target == "path" and sensor.get("target_path_m"):
        return np.asarray(sensor["target_path_m"][0], dtype=float)
    path = np.asarray(sensor.get("path_m") or [], dtype=float).reshape(-1, 3)
    step = path[1] - path[0] if len(path) > 1 else np.array([0.0, 1.0, 0.0])
    return pos + 10.0 * step / max(float(np.linalg.norm(step)), 1e-9)


def _heading_vector(compass_deg: float) -> np.ndarray:
    a = math.radians(compass_deg)
    return np.array([math.sin(a), math.cos(a)])


def _object_corners(obj: dict) -> np.ndarray:
    w, d = obj["size_m"][0] / 2.0, obj["size_m"][1] / 2.0
    a = math.radians(obj["heading_deg"])  # counter-clockwise about z
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    local = np.array([[-w, -d], [w, -d], [w, d], [-w, d]])
    return local @ rot.T + np.asarray(obj["center_m"][:2])


def _assets(scene: dict) -> list[tuple[str, np.ndarray]]:
    """Scene parts other than the ground and the primitive objects that have a position
    (``[[scene.asset]]`` and the like): (label, xy)."""
    out = []
    for name, value in (scene or {}).items():
        if name in ("ground", "object") or not isinstance(value, list):
            continue
        for i, item in enumerate(value):
            if not isinstance(item, dict):
                continue
            pos = item.get("position_m") or item.get("center_m")
            if isinstance(pos, list) and len(pos) >= 2:
                out.append((str(item.get("id", f"{name}[{i}]")), np.asarray(pos[:2], dtype=float)))
    return out


def plan_svg(
    scenario: Scenario,
    sun_azimuth_deg: float | None = None,
    sun_zenith_deg: float | None = None,
    width_px: int = 720,
) -> str:
    """The plan of ``scenario`` as an SVG document (text)."""
    d = scenario.data
    places = {p["human"]: p for p in d["placement"]}
    scene = d.get("scene") or {}
    pts: list[np.ndarray] = []
    for p in d["placement"]:
        pts.append(np.asarray(p["position_m"][:2], dtype=float))
        pts += [np.asarray(w, dtype=float) for w in p["waypoints_m"]]
    for obj in scene.get("object", []) if scene else []:
        pts += list(_object_corners(obj))
    pts += [xy for _, xy in _assets(scene)]
    sensors = []
    for s in d["sensor"]:
        s = dict(s, look_at_m=sensor_look_point(s, d.get("placement") or []))  # noqa: PLW2901
        pos = sensor_position(s)
        sensors.append((s, pos))
        pts.append(pos[:2])
        pts.append(np.asarray(s["look_at_m"][:2], dtype=float))
        if s["platform"] == "aerial":
            c, r = np.asarray(s["look_at_m"][:2]), s["orbit_radius_m"]
            pts += [c - r, c + r]
    if not pts:
        pts = [np.zeros(2)]
    arr = np.array(pts)
    lo, hi = arr.min(axis=0), arr.max(axis=0)
    span = max(float((hi - lo).max()), 4.0)
    centre = (lo + hi) / 2.0
    half = span * 0.65
    x0, y0 = centre[0] - half, centre[1] - half  # world lower-left
    size = 2 * half
    scale = width_px / size

    def xy(p) -> tuple[float, float]:
        return (float(p[0]) - x0) * scale, (y0 + size - float(p[1])) * scale

    def poly(points, **attrs) -> str:
        text = " ".join(f"{a:.1f},{b:.1f}" for a, b in (xy(p) for p in points))
        extra = " ".join(f'{k.replace("_", "-")}="{v}"' for k, v in attrs.items())
        return f'<polygon points="{text}" {extra}/>'

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" class="humv-plan" width="{width_px}" height="{width_px}" '
        f'viewBox="0 0 {width_px} {width_px}" font-family="sans-serif" font-size="12">',
        f'<rect width="{width_px}" height="{width_px}" fill="#f4f4f0"/>',
    ]
    ground = scene.get("ground") if scene else None
    if ground:
        gx, gy = ground["size_m"][0] / 2.0, ground["size_m"][1] / 2.0
        corners = [(-gx, -gy), (gx, -gy), (gx, gy), (-gx, gy)]
        out.append(poly(corners, fill="#dcdcd2", stroke="#aaa", class_="ground"))
        out.append(
            f'<text x="6" y="{width_px - 6}" fill="#666">ground: {escape(ground["material"])} '
            f"{gx * 2:g} × {gy * 2:g} m</text>"
        )
    out.append(_grid(x0, y0, size, xy, width_px))
    for obj in scene.get("object", []) if scene else []:
        c = _object_corners(obj)
        out.append(
            f'<g class="object" data-id="{escape(obj["id"])}">'
            + poly(c, fill="#b9b2a0", stroke="#555", fill_opacity="0.8")
            + _label(xy(c.mean(axis=0)), obj["id"], "#333")
            + "</g>"
        )
    for label, pos in _assets(scene):
        cx, cy = xy(pos)
        out.append(
            f'<g class="asset" data-id="{escape(label)}"><path d="M{cx:.1f},{cy - 7:.1f} l7,7 l-7,7 l-7,-7 z" '
            f'fill="#8c564b"/>' + _label((cx, cy - 10), label, "#8c564b") + "</g>"
        )
    for h in d["human"]:
        p = places.get(h["id"])
        if p is None:
            continue
        start = np.asarray(p["position_m"][:2], dtype=float)
        path = [start] + [np.asarray(w, dtype=float) for w in p["waypoints_m"]]
        g = [f'<g class="person" data-id="{escape(h["id"])}">']
        if len(path) > 1:
            line = " ".join(f"{a:.1f},{b:.1f}" for a, b in (xy(q) for q in path))
            g.append(
                f'<polyline class="walk" points="{line}" fill="none" stroke="#2ca02c" stroke-width="2" '
                'stroke-dasharray="6 4"/>'
            )
        elif h["activity"] in ("walk", "run"):
            speed = h["speed_m_s"] or (1.4 if h["activity"] == "walk" else 3.5)
            end = start + _heading_vector(p["heading_deg"]) * speed * max(d["general"]["duration_s"], 1.0)
            (a, b), (c, e) = xy(start), xy(end)
            g.append(
                f'<line class="walk" x1="{a:.1f}" y1="{b:.1f}" x2="{c:.1f}" y2="{e:.1f}" stroke="#2ca02c" '
                'stroke-width="2" stroke-dasharray="6 4"/>'
            )
        cx, cy = xy(start)
        hx, hy = _heading_vector(p["heading_deg"]) * 14
        g.append(f'<circle cx="{cx:.1f}" cy="{cy:.1f}" r="6" fill="#2ca02c"/>')
        g.append(
            f'<line x1="{cx:.1f}" y1="{cy:.1f}" x2="{cx + hx:.1f}" y2="{cy - hy:.1f}" stroke="#2ca02c" '
            'stroke-width="3"/>'
        )
        g.append(_label((cx + 8, cy + 16), h["id"], "#1b6e1b"))
        out.append("".join(g) + "</g>")
    for i, (s, pos) in enumerate(sensors):
        out.append(_sensor(s, pos, xy, scale, span, label_row=i % 4))
    out.append(_north_arrow(width_px))
    if sun_azimuth_deg is not None:
        out.append(_sun(width_px, sun_azimuth_deg, sun_zenith_deg))
    out.append("</svg>")
    return "\n".join(out)


def _label(at, text: str, colour: str) -> str:
    return f'<text x="{at[0]:.1f}" y="{at[1]:.1f}" fill="{colour}" text-anchor="middle">{escape(str(text))}</text>'


def _grid(x0, y0, size, xy, width_px) -> str:
    step = 10 ** math.floor(math.log10(size / 4))
    if size / step > 12:
        step *= 5 if size / step > 40 else 2
    lines = []
    k = math.ceil(x0 / step)
    while k * step <= x0 + size:
        a, _ = xy((k * step, 0))
        lines.append(f'<line x1="{a:.1f}" y1="0" x2="{a:.1f}" y2="{width_px}" stroke="#e4e4de"/>')
        k += 1
    k = math.ceil(y0 / step)
    while k * step <= y0 + size:
        _, b = xy((0, k * step))
        lines.append(f'<line x1="0" y1="{b:.1f}" x2="{width_px}" y2="{b:.1f}" stroke="#e4e4de"/>')
        k += 1
    lines.append(
        f'<text x="{width_px - 6}" y="{width_px - 6}" fill="#666" text-anchor="end">grid {step:g} m</text>'
    )
    return '<g class="grid">' + "".join(lines) + "</g>"


def _sensor(s: dict, pos, xy, scale: float, span: float, label_row: int = 0) -> str:
    colour = _SENSOR_COLOURS.get(s["band"], "#9467bd")
    look = np.asarray(s["look_at_m"], dtype=float)
    g = [f'<g class="sensor" data-id="{escape(s["id"])}" data-band="{escape(s["band"])}">']
    if s["platform"] == "aerial":
        cx, cy = xy(look[:2])
        g.append(
            f'<circle class="orbit" cx="{cx:.1f}" cy="{cy:.1f}" r="{s["orbit_radius_m"] * scale:.1f}" '
            f'fill="none" stroke="{colour}" stroke-dasharray="4 4"/>'
        )
    dx, dy = look[0] - pos[0], look[1] - pos[1]
    ground_range = math.hypot(dx, dy)
    if ground_range > 1e-6:
        azimuth = math.atan2(dy, dx)
        half = math.radians(horizontal_fov_deg(s)) / 2.0
        reach = max(ground_range * 1.4, span * 0.35)
        left = pos[:2] + reach * np.array([math.cos(azimuth + half), math.sin(azimuth + half)])
        right = pos[:2] + reach * np.array([math.cos(azimuth - half), math.sin(azimuth - half)])
        text = " ".join(f"{a:.1f},{b:.1f}" for a, b in (xy(q) for q in (pos[:2], left, right)))
        g.append(
            f'<polygon class="frustum" points="{text}" fill="{colour}" fill-opacity="0.12" stroke="{colour}" '
            'stroke-opacity="0.6"/>'
        )
    cx, cy = xy(pos[:2])
    g.append(f'<rect x="{cx - 5:.1f}" y="{cy - 5:.1f}" width="10" height="10" fill="{colour}"/>')
    g.append(
        f'<text x="{cx:.1f}" y="{cy + 18 + 13 * label_row:.1f}" fill="{colour}" text-anchor="middle" font-size="11">'
        f"{escape(s['id'])}</text>"
    )
    return "".join(g) + "</g>"


def _north_arrow(width_px: int) -> str:
    return (
        '<g class="north" transform="translate(30,50)">'
        '<path d="M0,-30 L9,0 L0,-7 L-9,0 Z" fill="#222"/>'
        '<text x="0" y="16" text-anchor="middle" font-weight="bold">N</text></g>'
    )


def _sun(width_px: int, azimuth_deg: float, zenith_deg: float | None) -> str:
    """An arrow from the plan's edge toward the sun (compass azimuth), with its elevation."""
    cx, cy, r = width_px - 60, 60, 34
    a = math.radians(azimuth_deg)
    sx, sy = cx + r * math.sin(a), cy - r * math.cos(a)
    elev = "" if zenith_deg is None else f", elevation {90 - zenith_deg:.0f}°"
    return (
        f'<g class="sun" data-azimuth="{azimuth_deg:.2f}">'
        f'<circle cx="{cx}" cy="{cy}" r="{r}" fill="none" stroke="#ccc"/>'
        f'<line x1="{cx}" y1="{cy}" x2="{sx:.1f}" y2="{sy:.1f}" stroke="#e6a700" stroke-width="2"/>'
        f'<circle cx="{sx:.1f}" cy="{sy:.1f}" r="7" fill="#ffcc00" stroke="#e6a700"/>'
        f'<text x="{width_px - 6}" y="{cy + r + 16}" text-anchor="end" fill="#8a6500" font-size="11">'
        f"sun azimuth {azimuth_deg:.0f}°{elev}</text></g>"
    )
