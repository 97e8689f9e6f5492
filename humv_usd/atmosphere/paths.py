"""Atmosphere paths tool: one slant-path table per sensor → layers/atmosphere_paths.usda.

Its own layer so that moving a sensor rebuilds the sensors layer and this one, not the sky
(which the thermal tool reads) nor the thermal layer. Reads the upstream stage (:data:`UPSTREAM`):
weather and sun from the environment layer (:mod:`humv_usd.usd.environment`), the wavelength grid
from the atmosphere layer (the render pairs the tables with it, :func:`humv_usd.usd.atmosphere.path_table`),
camera positions from the sensors layer (:func:`humv_usd.usd.sensor.camera_positions`) and the
scene's extent from the scene layer (:func:`scene_points`; a scenario may have none).

The tables come from :func:`humv_usd.atmosphere.model.atmosphere_for` (LOWTRAN7 homogeneous
weather paths times the visibility's aerosol, or the analytic model, as the sky layer ran; the
LOWTRAN runs come from the disk cache the sky layer filled), without the sun terms
(``solar=False``: the paths do not depend on them, and a sensor move then costs ~0.04 s on a warm
cache instead of ~0.5 s of importing pvlib). Under /World/Atmosphere/Paths one
table per sensor, with ranges from 1 m to beyond the scene. When the weather varies
(:func:`humv_usd.atmosphere.model.weather_varies`) the tables get time samples at the weather
nodes' frames (USD interpolates them linearly) and keep the frame-0 values as their defaults.
Clouds do not change the paths (:func:`humv_usd.atmosphere.model.with_cloud_cover`). What ran is
recorded in the layer's customLayerData ``humv:atmospherePaths:ran``. The tables are authored
through :func:`humv_usd.usd.atmosphere.define_path_table` and
:func:`humv_usd.usd.atmosphere.write_path_spectra` (this module names no attribute).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf

from humv_usd.atmosphere.model import PATH_RANGES_M, atmosphere_for
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import CLOCK
from humv_usd.usd.atmosphere import define_path_table, define_paths, require_wavelengths, write_path_spectra
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage
from humv_usd.usd.mesh import bound_corners
from humv_usd.usd.paths import sensor_path
from humv_usd.usd.sensor import camera_positions

NAME = "atmosphere_paths"
READS = (
    *CLOCK,
    "atmosphere",  # model, profile, visibility; weather_csv: its hours are the weather nodes
    "sensor.*.id",
    "sensor.*.wavelength_um",
    "sensor.*.look_at_m",
    "placement.*.position_m",
    "placement.*.waypoints_m",
)
#: layers read from the upstream stage: weather and sun (environment), the wavelength grid
#: (atmosphere), camera positions (sensors) and the scene's extent for the ranges (scene)
UPSTREAM = ("environment", "atmosphere", "sensors", "scene")
VERSION = "2"  # 2: tables named <sensor>_path


def scene_points(scenario: Scenario, upstream) -> np.ndarray:
    """Points bounding what the sensors look at [m]: the corners of every scene mesh's bounding
    box on the upstream stage (the scene layer: ground, objects, hand-made meshes), and the
    people's placements and waypoints up to 2 m (from ``[[placement]]``: their skinned extents
    over every frame would cost more than the range table needs)."""
    pts = [bound_corners(upstream, SCOPES["scene"])]
    for p in scenario["placement"]:
        x, y, z = p["position_m"]
        people = [(x, y, z), (x, y, z + 2.0)] + [(wx, wy, z) for wx, wy in p.get("waypoints_m") or []]
        pts.append(np.asarray(people, dtype=float))
    return np.vstack([np.zeros((0, 3))] + pts)


def sensor_ranges(sensor: dict, cams: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Ranges [m] of a sensor's path table: the table's nodes up to the farthest scene point
    (x 1.5, at least twice the look-at distance and 100 m), that range included; ``cams``
    the camera positions per frame (n, 3) [m] of the sensors layer, ``points`` the
    :func:`scene_points`."""

    # a camera tracking a person or a path, or looking along its travel, has no look_at_m
    look_at = sensor.get("look_at_m")
    targets = points if look_at is None else np.vstack([points, np.asarray(look_at, float)[None]])
    far = max(float(np.max(np.linalg.norm(cams[:, None, :] - targets[None], axis=-1))), 1.0)
    look = (
        0.0 if look_at is None else float(np.max(np.linalg.norm(cams - np.asarray(look_at, float), axis=-1)))
    )
    r_max = min(max(1.5 * far, 2.0 * look, 100.0), float(PATH_RANGES_M[-1]))
    return np.unique(np.append(PATH_RANGES_M[PATH_RANGES_M < r_max], r_max))


def build(scenario: Scenario, upstream) -> Sdf.Layer:
    """The atmosphere paths layer; ``upstream``: a stage with the :data:`UPSTREAM` layers."""
    g = scenario["general"]
    full = atmosphere_for(scenario, upstream, solar=False)  # paths only: no sun, no pvlib
    require_wavelengths(upstream, full.wavelengths_um)
    sensors = scenario["sensor"]
    stage = new_layer_stage(
        g["fps"],
        scenario.frame_count,
        f"HumV-USD atmosphere paths layer: {full.source} slant paths of {len(sensors)} sensors",
    )
    define_paths(stage)
    nodes = [0] if full.node_times_s is None else range(full.node_times_s.size)
    node_codes = [] if full.node_times_s is None else np.round(full.node_times_s * float(g["fps"]), 6)
    points = scene_points(scenario, upstream)
    for s in sensors:
        cams = camera_positions(upstream, sensor_path(s["id"]), np.arange(max(scenario.frame_count, 1)))
        ranges = sensor_ranges(s, cams, points)
        # "<sensor>_path", not the sensor's own name: importers that flatten prim names (Blender)
        # otherwise give the camera the table's name and rename the camera "<sensor>.001"
        table = define_path_table(stage, f"{s['id']}_path", sensor_path(s["id"]), ranges)
        for k in nodes:  # defaults = frame 0 (node 0), plus samples at the weather nodes
            tau, rad = full.at_node(k).path(cams[0], ranges)
            if k == 0:
                write_path_spectra(table, tau, rad)
            if len(node_codes):
                write_path_spectra(table, tau, rad, float(node_codes[k]))
    ran = {
        "model": full.source,
        "paths": full.ran.get("paths", "no path model") + f"; tables for {len(sensors)} sensors",
    }
    if len(node_codes):
        ran["paths"] += "; time samples at frames " + ", ".join(f"{c:g}" for c in node_codes)
    stage.GetRootLayer().customLayerData = {"humv:atmospherePaths:ran": ran}
    return finish(stage)
