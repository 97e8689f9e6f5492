"""Warm clutter (``[[scene.clutter]]`` and generated places): procedural low-poly meshes and the
held temperatures of their heat-carrying parts.

Each object is an Xform /World/Scene/<id> (HumvLabelAPI: instance id ``clutter:<id>``, class
by kind, :data:`humv_usd.scenario.spec.CLUTTER_CLASSES`) with one mesh per part. A part with
its own heat source carries ``humv:heat:heldTemperature`` (:mod:`humv_usd.usd.heat`), which
the thermal layer holds; the other parts are slabs of their material like any scene surface.

Kinds and parts (local frame: x forward, z up, metres at scale 1):

* vehicle (4.4 x 1.8 x 1.46 m car): Body, Roof (slabs of ``material``), Hood, Grille, Glass
  (cabin), Wheel0-3 (tyre rubber), Exhaust -- :func:`humv_usd.physics.warm_objects.vehicle_part_temperatures`;
  driving along ``path_m`` at ``speed_m_s``: a time-sampled transform, one sample per frame.
* dog, cattle: Trunk, Head, Leg0-3 (fur), all at the coat surface temperature
  (:func:`~humv_usd.physics.warm_objects.coat_surface_temperature`).
* street_lamp: Pole, Arm (slabs), Head (LED housing, held while lit).
* window: Pane (glass on a facade, lit room behind: held at the glazing's outer surface).
* hvac: Casing (slab), Fan (discharge grille, held).
* barbecue: Bowl, Lid (held hot), Leg0-2 (slabs); fire: Embers (held), Log0-2 (held).

Lit lamps and windows, and a running vehicle's low beams at night, get the render's lights
(UsdLux through :mod:`humv_usd.usd.lights`, issue 24.4): /World/Scene/<id>/Light, Headlight*.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Gf, Usd, UsdGeom

from humv_usd.physics import warm_objects as W
from humv_usd.physics.convection import watmuff
from humv_usd.scenario.spec import CLUTTER_CLASSES
from humv_usd.scene.geometry import box
from humv_usd.usd.heat import write_held_temperature
from humv_usd.usd.layers import set_kind
from humv_usd.usd.lights import write_lamp, write_window
from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.paths import material_path, object_path

#: sun elevation below which a photocell switches a lamp on [deg] (civil twilight's start)
PHOTOCELL_SUN_ELEVATION_DEG = -3.0
#: outer film coefficient and U-value of a double-glazed window [W m-2 K-1] (EN 673 / ISO 6946:
#: R_se = 0.04 m2 K/W -> 25; U 2.8 for air-filled double glazing)
WINDOW_OUTER_W_M2K, WINDOW_U_W_M2K = 25.0, 2.8
#: room air behind a lit window [K]
ROOM_AIR_K = 294.15
#: lights (humv_usd.catalog.lights spectra): an LED street luminaire (3000-8000 lm, cone ~70 deg
#: half-angle), a lit window's luminance [cd m-2] (10-100), a halogen low beam per lamp (~1000 lm,
#: ~30 deg, aimed slightly down)
LAMP_SPECTRUM, LAMP_FLUX_LM, LAMP_CONE_DEG = "led_4000k", 6000.0, 70.0
WINDOW_SPECTRUM, WINDOW_LUMINANCE = "led_3000k", 30.0
HEADLIGHT_SPECTRUM, HEADLIGHT_FLUX_LM, HEADLIGHT_CONE_DEG = "halogen", 1000.0, 30.0


# ----------------------------------------------------------------------------- primitives
def _box(x0, x1, y0, y1, z0, z1):
    return box([(x0 + x1) / 2, (y0 + y1) / 2, z0], [x1 - x0, y1 - y0, z1 - z0])


def cylinder(center, axis: str, radius: float, length: float, segments: int = 10):
    """A closed n-gon prism (outward counter-clockwise faces) along ``axis`` ('x', 'y', 'z'),
    centred at ``center``."""
    a = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)
    lo = np.column_stack([ring, np.full(segments, -length / 2)])
    hi = np.column_stack([ring, np.full(segments, length / 2)])
    pts = np.vstack([lo, hi])  # along local z
    n = segments
    sides = [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    faces = [list(range(n - 1, -1, -1)), list(range(n, 2 * n))] + sides
    perm = {"z": [0, 1, 2], "x": [2, 0, 1], "y": [1, 2, 0]}[axis]  # cyclic: keeps handedness
    pts = pts[:, perm] + np.asarray(center, dtype=float)
    return pts, np.array([len(f) for f in faces]), np.concatenate(faces)


def ellipsoid(center, radii, segments: int = 10, rings: int = 6):
    """A closed low-poly ellipsoid (UV sphere scaled by ``radii``, outward counter-clockwise)."""
    th = np.linspace(0.0, np.pi, rings + 1)[1:-1]  # polar angles of the inner rings
    ph = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring_pts = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    pts = np.vstack([[0, 0, 1], ring_pts, [0, 0, -1]]) * np.asarray(radii, dtype=float)
    top, bottom, n = 0, len(pts) - 1, segments

    def v(r, s):
        return 1 + r * n + s % n

    faces = [[top, v(0, s), v(0, s + 1)] for s in range(n)]
    faces += [
        [v(r, s), v(r + 1, s), v(r + 1, s + 1), v(r, s + 1)] for r in range(rings - 2) for s in range(n)
    ]
    faces += [[bottom, v(rings - 2, s + 1), v(rings - 2, s)] for s in range(n)]
    pts = pts + np.asarray(center, dtype=float)
    return pts, np.array([len(f) for f in faces]), np.concatenate(faces)


def _scaled(mesh, s: float):
    pts, counts, idx = mesh
    return pts * s, counts, idx


# ----------------------------------------------------------------------------- parts per kind
def vehicle_parts(body_material: str) -> list[tuple[str, tuple, str, str | None]]:
    """(name, mesh, material, held-temperature key of vehicle_part_temperatures or None)."""
    parts = [
        ("Body", _box(-2.2, 2.2, -0.9, 0.9, 0.30, 0.92), body_material, None),
        ("Hood", _box(0.9, 2.2, -0.85, 0.85, 0.92, 0.95), body_material, "hood"),
        ("Grille", _box(2.2, 2.23, -0.6, 0.6, 0.40, 0.75), "painted_metal", "grille"),
        ("Glass", _box(-1.5, 0.9, -0.8, 0.8, 0.92, 1.42), "glass", "glass"),
        ("Roof", _box(-1.4, 0.7, -0.75, 0.75, 1.42, 1.46), body_material, None),
        ("Exhaust", cylinder([-2.3, 0.5, 0.25], "x", 0.035, 0.3, 8), "painted_metal", "exhaust"),
    ]
    for k, (x, y) in enumerate(((1.35, 0.8), (1.35, -0.8), (-1.35, 0.8), (-1.35, -0.8))):
        parts.append((f"Wheel{k}", cylinder([x, y, 0.32], "y", 0.32, 0.22, 12), "rubber", "tyre"))
    return parts


def animal_parts(name: str) -> list[tuple[str, tuple, str, str | None]]:
    a = W.ANIMALS[name]
    s = a.length_m / 2.3  # proportions of the cattle body, scaled to the animal's length
    leg_len = 0.5 * a.height_m
    rx, ry, rz = 0.42 * a.length_m, a.trunk_diameter_m / 2, 0.55 * a.trunk_diameter_m / 2 + 0.05 * s
    parts = [
        ("Trunk", ellipsoid([0, 0, leg_len + rz * 0.8], [rx, ry, rz]), "fur", "coat"),
        (
            "Head",
            ellipsoid([rx + 0.1 * s, 0, a.height_m - 0.12 * s], [0.3 * s, 0.17 * s, 0.2 * s], 8, 5),
            "fur",
            "coat",
        ),
    ]
    for k, (x, y) in enumerate(((0.7, 0.6), (0.7, -0.6), (-0.7, 0.6), (-0.7, -0.6))):
        parts.append(
            (
                f"Leg{k}",
                cylinder([x * rx, y * ry, leg_len / 2 + 0.1 * rz], "z", 0.2 * ry, leg_len + 0.2 * rz, 6),
                "fur",
                "coat",
            )
        )
    return parts


def lamp_parts(material: str) -> list:
    return [
        ("Pole", cylinder([0, 0, 3.0], "z", 0.07, 6.0, 8), material, None),
        ("Arm", _box(0.0, 1.5, -0.04, 0.04, 5.9, 6.0), material, None),
        ("Head", _box(1.2, 1.9, -0.15, 0.15, 5.82, 5.97), material, "lamp"),
    ]


def window_parts() -> list:
    w, h = 1.2, 1.4
    return [("Pane", _box(0.0, 0.02, -w / 2, w / 2, 0.0, h), "glass", "window")]


def hvac_parts(material: str) -> list:
    return [
        ("Casing", _box(-0.45, 0.45, -0.45, 0.45, 0.0, 0.8), material, None),
        ("Fan", cylinder([0, 0, 0.83], "z", 0.32, 0.06, 12), "painted_metal", "discharge"),
    ]


def barbecue_parts() -> list:
    parts = [
        ("Bowl", cylinder([0, 0, 0.7], "z", 0.3, 0.2, 12), "painted_metal", "lid"),
        ("Lid", ellipsoid([0, 0, 0.8], [0.3, 0.3, 0.22], 12, 5), "painted_metal", "lid"),
    ]
    for k in range(3):
        a = 2 * math.pi * k / 3
        parts.append(
            (
                f"Leg{k}",
                cylinder([0.22 * math.cos(a), 0.22 * math.sin(a), 0.3], "z", 0.015, 0.6, 6),
                "painted_metal",
                None,
            )
        )
    return parts


def fire_parts() -> list:
    parts = [("Embers", cylinder([0, 0, 0.04], "z", 0.45, 0.08, 12), "soil", "embers")]
    for k in range(3):
        a = 2 * math.pi * k / 3
        log = cylinder([0.25 * math.cos(a), 0.25 * math.sin(a), 0.12], "x", 0.06, 0.7, 8)
        rot = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        c = np.array([0.25 * math.cos(a), 0.25 * math.sin(a), 0.12])
        pts = (log[0] - c) @ rot.T + c
        parts.append((f"Log{k}", (pts, log[1], log[2]), "wood", "logs"))
    return parts


def parts_of(entry: dict) -> list:
    kind = entry["kind"]
    if kind == "vehicle":
        return vehicle_parts(entry["material"])
    if kind in W.ANIMALS:
        return animal_parts(kind)
    return {
        "street_lamp": lambda: lamp_parts(entry["material"]),
        "window": window_parts,
        "hvac": lambda: hvac_parts(entry["material"]),
        "barbecue": barbecue_parts,
        "fire": fire_parts,
    }[kind]()


# ----------------------------------------------------------------------------- temperatures
def is_lit(entry: dict, sun_elevation_deg: float) -> bool:
    """Whether a lamp or window is lit at frame 0 ("auto": the sun below the photocell's
    threshold, :data:`PHOTOCELL_SUN_ELEVATION_DEG`)."""
    if entry["lit"] == "auto":
        return sun_elevation_deg < PHOTOCELL_SUN_ELEVATION_DEG
    return entry["lit"] == "on"


def global_irradiance(sun_elevation_deg: float, cloud_cover: float) -> float:
    """Global horizontal irradiance [W m-2]: 910 sin(h) - 30 clear (Kasten & Czeplak 1980,
    Solar Energy 24:177), times 1 - 0.75 c^3.4 for cloud cover c; 0 with the sun down."""
    s = math.sin(math.radians(sun_elevation_deg))
    if s <= 0:
        return 0.0
    return max(910.0 * s - 30.0, 0.0) * (1.0 - 0.75 * cloud_cover**3.4)


def part_temperatures(
    entry: dict, air_k: float, wind_m_s: float, sun_elevation_deg: float, cloud_cover: float
) -> dict:
    """Held temperature [K] per heat key of the entry's parts (see :func:`parts_of`); a key
    missing from the result leaves that part a slab (an unlit lamp, a stopped fan)."""
    kind = entry["kind"]
    run, off = float(entry["run_s"]), float(entry["off_s"])
    if kind == "vehicle":
        state = W.VehicleState(run, off, float(entry["speed_m_s"]) if entry["path_m"] else 0.0)
        t = W.vehicle_part_temperatures(
            air_k, state, wind_m_s, global_irradiance(sun_elevation_deg, cloud_cover)
        )
        return {k: t[k] for k in ("hood", "grille", "glass", "exhaust", "tyre")}
    if kind in W.ANIMALS:
        a = W.ANIMALS[kind]
        return {
            "coat": float(
                W.coat_surface_temperature(a.skin_k, air_k, a.coat_depth_m, a.trunk_diameter_m, wind_m_s)
            )
        }
    if kind in ("street_lamp", "window"):
        if not is_lit(entry, sun_elevation_deg):
            return {}
        if kind == "street_lamp":
            return {
                "lamp": air_k
                + float(
                    W.lumped_response(max(run, 1.0), 0.0, W.LAMP_HOUSING_EXCESS_K, W.LAMP_TAU_S, W.LAMP_TAU_S)
                )
            }
        # glazing's outer surface: T_a + U (T_room - T_a) / h_o (series resistances, ISO 6946)
        h_o = max(WINDOW_OUTER_W_M2K, float(watmuff(wind_m_s)))
        return {"window": air_k + WINDOW_U_W_M2K * (ROOM_AIR_K - air_k) / h_o}
    if kind == "hvac":
        mode = "cooling" if air_k > 291.15 else "heating"
        return {
            "discharge": air_k
            + float(W.lumped_response(run, off, W.HVAC_DISCHARGE_K[mode], W.HVAC_TAU_S, W.HVAC_TAU_S))
        }
    if kind == "barbecue":
        return {"lid": air_k + float(W.lumped_response(run, off, W.GRILL_LID_K - air_k, 600.0, 900.0))}
    if kind == "fire":
        return {
            "embers": air_k + float(W.lumped_response(run, off, W.EMBERS_K - air_k, 300.0, 1800.0)),
            "logs": air_k + float(W.lumped_response(run, off, W.LOGS_K - air_k, 300.0, 1800.0)),
        }
    raise ValueError(f"invalid model selection {kind}")


# ----------------------------------------------------------------------------- motion
def path_poses(entry: dict, times_s) -> tuple[np.ndarray, np.ndarray]:
    """(positions (T, 3), headings (T,) [deg]) along position_m -> path_m at speed_m_s; it
    stops at the path's end. Without a path or speed: the placement at every time."""
    start = np.asarray(entry["position_m"], dtype=float)
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    if not entry["path_m"] or entry["speed_m_s"] <= 0:
        return np.repeat(start[None], len(t), 0), np.full(len(t), float(entry["heading_deg"]))
    pts = np.vstack([start[:2], np.asarray(entry["path_m"], dtype=float)])
    seg = np.diff(pts, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    s = np.clip(entry["speed_m_s"] * t, 0.0, cum[-1])
    k = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = np.where(seg_len[k] > 0, (s - cum[k]) / np.maximum(seg_len[k], 1e-12), 0.0)
    xy = pts[k] + seg[k] * frac[:, None]
    heading = np.degrees(np.arctan2(seg[k, 1], seg[k, 0]))
    return np.column_stack([xy, np.full(len(t), start[2])]), heading


def _matrix(position, heading_deg: float, scale: float) -> Gf.Matrix4d:
    m = Gf.Matrix4d().SetScale(Gf.Vec3d(scale))
    m = m * Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(0, 0, 1), float(heading_deg)))
    return m * Gf.Matrix4d().SetTranslate(Gf.Vec3d(*map(float, position)))


# ----------------------------------------------------------------------------- authoring
def author_clutter(
    stage: Usd.Stage,
    entry: dict,
    instance_id: int,
    air_k: float,
    wind_m_s: float,
    sun_elevation_deg: float,
    cloud_cover: float,
    fps: float,
    frames: int,
    ground_height=None,
) -> Usd.Prim:
    """/World/Scene/<id>: placement (time-sampled when driving), label, one mesh per part.
    ``ground_height(x, y)``: the terrain's height [m], added to the placement's z (None: flat)."""
    root = UsdGeom.Xform.Define(stage, object_path(entry["id"]))
    op = root.AddTransformOp()
    scale = float(entry["scale"])
    pos, head = path_poses(entry, np.arange(frames) / fps)
    if ground_height is not None:
        pos[:, 2] += np.asarray(ground_height(pos[:, 0], pos[:, 1]), dtype=float)
    op.Set(_matrix(pos[0], head[0], scale))
    if entry["kind"] == "vehicle" and entry["path_m"] and entry["speed_m_s"] > 0:
        for f in range(frames):
            op.Set(_matrix(pos[f], head[f], scale), Usd.TimeCode(f))
    label(root.GetPrim(), instance_id, CLUTTER_CLASSES[entry["kind"]])
    set_kind(root.GetPrim(), "component")
    held = part_temperatures(entry, air_k, wind_m_s, sun_elevation_deg, cloud_cover)
    for name, mesh, material, heat in parts_of(entry):
        m = define_mesh(stage, root.GetPath().AppendChild(name), *mesh, material=material_path(material))
        if heat is not None and heat in held:
            write_held_temperature(m.GetPrim(), held[heat])
    _author_lights(stage, root.GetPath(), entry, held, sun_elevation_deg)
    return root.GetPrim()


def _author_lights(stage: Usd.Stage, root, entry: dict, held: dict, sun_elevation_deg: float) -> None:
    """The render's lights (UsdLux through :mod:`humv_usd.usd.lights`, issue 24.4): a lit
    lamp's LED under its head, a lit window's pane, a running vehicle's low beams at night."""
    kind = entry["kind"]
    if kind == "street_lamp" and "lamp" in held:
        write_lamp(
            stage,
            str(root.AppendChild("Light")),
            LAMP_SPECTRUM,
            LAMP_FLUX_LM,
            (1.55, 0.0, 5.80),
            None,
            LAMP_CONE_DEG,
        )
    elif kind == "window" and "window" in held:
        light = write_window(
            stage, str(root.AppendChild("Light")), WINDOW_SPECTRUM, WINDOW_LUMINANCE, 1.2, 1.4
        )
        # rows x, y, z of the light's frame: width along the facade (y), emitting along -Z = +x
        frame = Gf.Matrix4d(0, 1, 0, 0, 0, 0, -1, 0, -1, 0, 0, 0, 0.025, 0, 0.7, 1)
        UsdGeom.Xformable(light).AddTransformOp().Set(frame)
    elif (
        kind == "vehicle"
        and entry["off_s"] <= 0.0
        and entry["run_s"] > 0.0
        and is_lit(entry, sun_elevation_deg)
    ):
        for side, y in (("Left", 0.6), ("Right", -0.6)):
            write_lamp(
                stage,
                str(root.AppendChild(f"Headlight{side}")),
                HEADLIGHT_SPECTRUM,
                HEADLIGHT_FLUX_LM,
                (2.25, y, 0.65),
                (15.0, y, 0.0),
                HEADLIGHT_CONE_DEG,
            )
