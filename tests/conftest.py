"""Shared fixtures. ``import humv_usd`` first: the schemas must register before any stage."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

import humv_usd  # noqa: F401

ROOT = Path(__file__).resolve().parents[1]
#: humvvex with the closed-form "fixed" thermal model: what the render, label and compose tests
#: compare against (the demo, examples/humvvex.toml, runs the physiology: HUMVVEX_DEMO)
HUMVVEX = ROOT / "examples" / "humvvex_fixed.toml"
HUMVVEX_DEMO = ROOT / "examples" / "humvvex.toml"
#: the layers compose writes for examples/humvvex.toml
HUMVVEX_LAYERS = (
    "environment",
    "atmosphere",
    "atmosphere_paths",
    "materials",
    "scene",
    "avatar_p1",
    "clothing_p1",
    "sensors",
    "thermal",
)


def _upstream_layers(scenario) -> list:
    """Environment, sensors and, when the scenario has one, scene layers (weakest first)."""
    from humv_usd.environment import layer as environment_layer
    from humv_usd.scene import layer as scene_layer
    from humv_usd.sensors import layer as sensors_layer

    layers = [environment_layer.build(scenario), sensors_layer.build(scenario)]
    if scenario["scene"] is not None:
        layers.append(scene_layer.build(scenario))
    return layers


def upstream_of(scenario):
    """The stage the atmosphere tools read (environment, sensors and, when the scenario has
    one, scene layers), composed in memory."""
    from humv_usd.pipeline.compose import compose_in_memory

    return compose_in_memory(_upstream_layers(scenario), scenario["general"]["fps"])


def atmosphere_layer_of(scenario):
    """The atmosphere layer of ``scenario`` built on :func:`upstream_of`."""
    from humv_usd.atmosphere import layer as atmosphere_layer

    return atmosphere_layer.build(scenario, upstream_of(scenario))


def atmosphere_layers_of(scenario):
    """(atmosphere layer, atmosphere paths layer) of ``scenario``: the sky on
    :func:`upstream_of`, the paths on that stage plus the sky."""
    from humv_usd.atmosphere import layer as atmosphere_layer
    from humv_usd.atmosphere import paths as paths_layer
    from humv_usd.pipeline.compose import compose_in_memory

    fps = scenario["general"]["fps"]
    layers = _upstream_layers(scenario)
    sky = atmosphere_layer.build(scenario, compose_in_memory(layers, fps))
    return sky, paths_layer.build(scenario, compose_in_memory([*layers, sky], fps))


def general_toml(name: str, start: str = "2018-07-14T13:00:00", duration_s: float = 0.0, **extra) -> str:
    """The ``[general]`` table (TOML text) of the small scene tests' scenarios: Dayton, Ohio
    (39.8° N, 84.0° W, UTC-4), 5 fps; ``extra`` adds keys with number values (``seed=2``)."""
    lines = [
        "[general]",
        f'name = "{name}"',
        f"start = {start}",
        "utc_offset_h = -4.0",
        'time_zone = "America/New_York"',
        "latitude_deg = 39.8",
        "longitude_deg = -84.0",
        "fps = 5.0",
        f"duration_s = {duration_s}",
        *(f"{key} = {value}" for key, value in extra.items()),
    ]
    return "\n".join(lines) + "\n"


def place_keys(kind: str, **keys) -> dict:
    """A ``[scene.place]`` table: the spec's defaults, then ``kind`` and ``keys``."""
    from humv_usd.scenario.spec import PLACE

    place = {k: copy.deepcopy(v.default) for k, v in PLACE.keys.items()}
    place.update(kind=kind, **keys)
    return place


def scene_stage(scenario):
    """The scene and materials layers of a validated scenario composed in memory (no slab
    solve, no render)."""
    from humv_usd.materials import layer as materials_layer
    from humv_usd.pipeline.compose import compose_in_memory
    from humv_usd.scene import layer as scene_layer

    layers = [scene_layer.build(scenario), materials_layer.build(scenario)]
    return compose_in_memory(layers, scenario["general"]["fps"])


@pytest.fixture(scope="session")
def humvvex_raw() -> dict:
    return tomllib.loads(HUMVVEX.read_text())


@pytest.fixture
def raw(humvvex_raw) -> dict:
    """A fresh, mutable copy of the humvvex scenario document."""
    return copy.deepcopy(humvvex_raw)


def quat_x(deg: float):
    """Unit quaternion (w, x, y, z) of a rotation by ``deg`` degrees about X."""
    import numpy as np

    from humv_usd.human.gait import axis_angle_quat

    return axis_angle_quat((1.0, 0.0, 0.0), np.radians(deg))


def ramp_pose(scenario, human, end_deg: dict):
    """(skeleton, Pose) of the person's fitted body: the joints of ``end_deg`` bend about X
    linearly from rest at frame 0 to their angle [deg] at the scenario's last frame."""
    import numpy as np

    from humv_usd.human.body import build_body
    from humv_usd.human.skeleton import skeleton_for
    from humv_usd.human.usdskel import Pose

    body = build_body(human["sex"], human["age_yr"], human["stature_m"], human["mass_kg"], human["build"])
    sk = skeleton_for(body.points, body.groups)
    frames = scenario.frame_count
    q = np.zeros((frames, len(sk.names), 4))
    q[..., 0] = 1.0
    for f in range(frames):
        for joint, deg in end_deg.items():
            q[f, sk.index(joint)] = quat_x(deg * f / (frames - 1))
    return sk, Pose(np.repeat(sk.rest_positions[:1], frames, axis=0), q)
