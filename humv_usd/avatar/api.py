"""Python API of the avatar tool: one person → one avatar layer file, without a scenario file.

::

    from humv_usd.avatar.api import author_avatar
    author_avatar("p1.usda", stature_m=1.62, mass_kg=58, sex="female", activity="walk")

:func:`author_avatar` builds the smallest scenario that holds one ``[[human]]`` and its
``[[placement]]``, validates it with :func:`humv_usd.scenario.validate` (so a bad value gets the
same one-line message as in a scenario file, naming the key, e.g.
``human[0].stature_m = 3.0: allowed range 0.7..2.3``) and writes what
:func:`humv_usd.avatar.layer.build_one` builds for that person, atomically. The command
``humv-usd avatar`` and the Blender add-on (``tools/blender_addon/humv_usd_avatar``) call it.

The layer is the same file ``humv-usd compose`` writes as ``layers/avatar_<id>.usda`` for a
scenario with this person alone (instance id 1, no scene). The ``[general]`` section is fixed
and neutral, because an avatar layer does not depend on the site or time of day; only its
frame rate and duration matter (they set the layer's time codes and frame range)::

    name = "avatar_<id>", start = 2000-01-01T12:00:00, utc_offset_h = 0,
    latitude_deg = 0, longitude_deg = 0, elevation_m = 0, seed = 0
"""

from __future__ import annotations

import datetime as dt
import os
from numbers import Number
from pathlib import Path

from humv_usd.avatar.layer import READS, VERSION, build_one
from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import write_text_atomic
from humv_usd.scenario import validate
from humv_usd.scenario.inputs import inputs_key, read_values
from humv_usd.usd.layers import layer_text, set_inputs_key

#: The neutral ``[general]`` values used for a stand-alone avatar (see the module doc).
NEUTRAL_GENERAL = {
    "start": dt.datetime(2000, 1, 1, 12, 0, 0),
    "utc_offset_h": 0.0,
    "latitude_deg": 0.0,
    "longitude_deg": 0.0,
    "elevation_m": 0.0,
    "seed": 0,
}

#: Extensions of the file written (text USD; ``.usd`` files may hold text too).
LAYER_SUFFIXES = (".usda", ".usd")


def _plain(value):
    """numpy scalars (e.g. from a UI or an array) → Python numbers; anything else unchanged."""
    if isinstance(value, Number) and not isinstance(value, (bool, int, float)) and hasattr(value, "item"):
        return value.item()
    return value


def _vector(value):
    """A position given as a tuple, list or array → list (what the validator expects)."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        return value  # the validator reports it: "expected 3 numbers"
    return [_plain(v) for v in value]


def avatar_scenario_dict(
    *,
    id: str = "p1",
    sex: str = "male",
    age_yr: float = 30,
    stature_m: float = 1.75,
    mass_kg: float = 75,
    build: str = "average",
    fitness: str = "average",
    activity: str = "stand",
    position_m=(0.0, 0.0, 0.0),
    heading_deg: float = 0.0,
    fps: float = 30,
    duration_s: float = 0,
) -> dict:
    """The raw scenario document (as parsed TOML) for one person: [general], [[human]],
    [[placement]]. Not validated."""
    general = {
        "name": f"avatar_{id}" if isinstance(id, str) else "avatar",
        "description": "stand-alone avatar (humv_usd.avatar.api.author_avatar)",
        **NEUTRAL_GENERAL,
        "fps": _plain(fps),
        "duration_s": _plain(duration_s),
    }
    human = {
        "id": id,
        "sex": sex,
        "age_yr": _plain(age_yr),
        "stature_m": _plain(stature_m),
        "mass_kg": _plain(mass_kg),
        "build": build,
        "fitness": fitness,
        "activity": activity,
        "clothing": [],
    }
    placement = {"human": id, "position_m": _vector(position_m), "heading_deg": _plain(heading_deg)}
    return {"general": general, "human": [human], "placement": [placement]}


def _check_out_path(out_path) -> Path:
    try:
        path = Path(os.fspath(out_path))
    except TypeError:
        raise InputError(bad_value("out_path", out_path, "expected a file path")) from None
    if path.is_dir():
        raise InputError(bad_value("out_path", str(path), "is a folder; expected a file path"))
    if path.suffix.lower() not in LAYER_SUFFIXES:
        raise InputError(
            bad_value(
                "out_path",
                str(path),
                "expected a USD text layer file ending in " + " or ".join(LAYER_SUFFIXES),
            )
        )
    return path


def author_avatar(
    out_path,
    *,
    id: str = "p1",
    sex: str = "male",
    age_yr: float = 30,
    stature_m: float = 1.75,
    mass_kg: float = 75,
    build: str = "average",
    fitness: str = "average",
    activity: str = "stand",
    position_m=(0.0, 0.0, 0.0),
    heading_deg: float = 0.0,
    fps: float = 30,
    duration_s: float = 0,
) -> Path:
    """Write the avatar layer of one person to ``out_path`` (``.usda``) and return its path.

    Keys, units and ranges are the scenario's (``humv_usd/scenario/spec.py``, sections
    ``human`` and ``placement``; ``fps`` and ``duration_s`` from ``general``). The prim is
    ``/World/Humans/<id>`` (HumvAvatarAPI, HumvLabelAPI with instance id 1).

    Raises :class:`~humv_usd.errors.InputError` (one line per problem, naming the key such as
    ``human[0].mass_kg`` or ``out_path``) before anything is written, and
    :class:`~humv_usd.assets.MissingAssetError` when the MakeHuman data is not fetched. The
    write is atomic, and skipped when the file already holds exactly this layer.
    """

    problems = []
    try:
        path = _check_out_path(out_path)
    except InputError as exc:
        problems += exc.problems
        path = None
    raw = avatar_scenario_dict(
        id=id,
        sex=sex,
        age_yr=age_yr,
        stature_m=stature_m,
        mass_kg=mass_kg,
        build=build,
        fitness=fitness,
        activity=activity,
        position_m=position_m,
        heading_deg=heading_deg,
        fps=fps,
        duration_s=duration_s,
    )
    try:
        scenario = validate(raw)
    except InputError as exc:
        problems += exc.problems
    if problems:
        raise InputError("", problems)

    # imported here: pxr and the avatar code load only when a layer is really built

    human = scenario["human"][0]
    layer = build_one(scenario, human)
    # the key compose gives this layer (the avatar reads no other layer): the file is the one
    # compose writes, and compose takes it as an unchanged avatar layer
    set_inputs_key(layer, inputs_key(VERSION, read_values(scenario, READS, human["id"]), {}))
    try:
        write_text_atomic(path, layer_text(layer))
    except OSError as exc:
        raise InputError(bad_value("out_path", str(path), f"cannot write ({exc.strerror or exc})")) from None
    return path
