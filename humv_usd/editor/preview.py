"""The preview: one small, fast frame of one sensor, coloured by brightness temperature.

Two qualities (:func:`preview_commands`), both rendered into ``OUT/preview`` (``--force``: the
folder holds the previous preview):

* ``fast`` (the default): a preview-quality copy of the scenario (:func:`preview_scenario`:
  every sensor at at most :data:`PREVIEW_WIDTH_PX` columns through its ``render_resolution``,
  frame 0 only, and the thermal layer's costliest knobs lowered to :data:`PREVIEW_THERMAL`)
  written to ``OUT/.editor/preview.toml`` and composed into ``OUT/.editor/preview``: its own
  folder and its own layer cache, never the real layers. The copy does not depend on the
  previewed sensor, so a preview of another sensor and the 3D tab's view reuse its layers.
  After an edit that rebuilds the thermal layer (a person, a pose, the clock, the weather) it
  costs about 40 % less CPU than the real compose (with the page's warm worker,
  :mod:`humv_usd.editor.jobs`, about 70 % less: 5-7 against 19-21 CPU-s on humvvex), and the
  image differs from the full-quality preview by < 0.1 K on the person (``humv-usd bench
  preview`` measures it per edit). The page says that it is a preview and what it lowered
  (:func:`preview_notes`).
* ``full``: the real ``humv-usd compose`` of the scenario into the editor's output folder (the
  same command as the Run tab's Compose and the 3D tab's view: one layer cache), then the
  render of frame 0 binned with ``--resolution`` (:func:`preview_resolution`; the field of view
  stays).

Until 2026-11-27 (morning) the preview composed a binned one-sensor copy at full quality into a
folder of its own: its thermal layer was built twice, at full cost, and every preview after an
edit failed (the render refused a folder rendered from another stage without ``--force``).

This module turns the render's EXR channel ``IR.brightness_temperature`` (logical name
``brightness_temperature``) into a colour image with a colour bar between the render's own
preview levels (1st and 99th percentile, ``preview_levels_k`` in the manifest). EO sensors show
their sRGB PNG as it is.
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps

from humv_usd.editor.fields import all_fields
from humv_usd.images import read_exr, write_png
from humv_usd.scenario.load import Scenario
from humv_usd.scenario.spec import SECTIONS

#: colour map of the temperature preview (perceptually uniform, prints in grey)
COLOUR_MAP = "inferno"
#: render settings of a preview: samples per pixel, sub-bands, annotators (the cheapest one)
PREVIEW_SPP, PREVIEW_SUBBANDS, PREVIEW_ANNOTATORS = 2, 1, "semantic"
#: widest preview image [px]
PREVIEW_WIDTH_PX = 320
#: the qualities of a preview (see the module doc)
QUALITIES = ("fast", "full")
#: the fast preview's thermal knobs: ``(key, value, "max" | "min")``, the value a scenario's own
#: is lowered to (never raised: a scenario already cheaper keeps its value). Measured on humvvex
#: (``humv-usd bench preview``): the thermal layer 11.4 -> 5.2 CPU-s; the person's facets' mean
#: within 0.05 K of full quality (8 rays and a 24 x 24 map change the noise, not the mean); the
#: ground's shadow edges blurred over 0.5 m (21,262 -> 4,936 faces) instead of the cameras'
#: pixel footprint. The ground's 24 h slab spin-up and its exchange with the wall are kept: a 6 h
#: spin-up warmed the ground by 3 K on average, no exchange moved its 95th percentile (by the wall) by 7 K.
PREVIEW_THERMAL = (
    ("radiation_rays", 8, "min"),
    ("radiation_resolution", 24, "min"),
    ("surface_cell_m", 0.5, "max"),
)
#: where a fast preview's scenario and stage live, under the output folder
PREVIEW_STAGE_DIR = Path(".editor") / "preview"
PREVIEW_SCENARIO = Path(".editor") / "preview.toml"


def _sensor_table(scenario: Scenario, sensor: str) -> tuple[int, dict]:
    index = [s["id"] for s in scenario["sensor"]].index(sensor)
    return index, scenario["sensor"][index]


def preview_resolution(scenario: Scenario, sensor: str) -> tuple[int, int]:
    """The preview's pixel count of ``sensor``: its render size (``render_resolution``, else
    ``resolution``) binned by the smallest integer k that brings the width to at most
    :data:`PREVIEW_WIDTH_PX`. The field of view stays (``render --resolution`` and a sensor's
    ``render_resolution`` scale the pitch by the same factor).

    Parameters
    ----------
    scenario : Scenario
        The validated scenario (the sensor's preset values filled in).
    sensor : str
        The sensor's ``id``.
    """
    _, filled = _sensor_table(scenario, sensor)
    width, height = filled.get("render_resolution") or filled["resolution"]
    k = max(1, math.ceil(width / PREVIEW_WIDTH_PX))
    return max(1, width // k), max(1, height // k)


def _absolute_paths(raw: dict, folder: Path) -> None:
    """File keys of ``raw`` made absolute against ``folder`` (the preview's copy lives in the
    output folder, not beside the scenario)."""
    for f in all_fields(raw):
        node = raw
        for part in f.path[:-1]:
            ok = isinstance(node, list) or (isinstance(node, dict) and part in node)
            node = node[part] if ok else None
        value = node.get(f.path[-1]) if isinstance(node, dict) else None
        if f.key.kind == "path" and isinstance(value, str):
            node[f.path[-1]] = str((folder / value).resolve())
        elif f.key.kind == "pathlist" and isinstance(value, list):
            node[f.path[-1]] = [str((folder / v).resolve()) if isinstance(v, str) else v for v in value]


def preview_scenario(raw: dict, scenario: Scenario, folder: Path) -> dict:
    """The scenario document of a fast preview (see the module doc).

    Every sensor rendered at its :func:`preview_resolution` (its ``render_resolution``: the
    field of view, pitch and lens stay those of the scenario); frame 0 only
    (``general.duration_s = 0``); the thermal knobs of :data:`PREVIEW_THERMAL` lowered; file
    keys absolute; the description says it is a preview. Everything else as written. Nothing
    in it depends on which sensor is previewed (one layer cache for all of them and the 3D tab).

    Parameters
    ----------
    raw : dict
        The scenario as written (plain values; not changed).
    scenario : Scenario
        The same, validated (the sensors' preset values filled in).
    folder : Path
        The scenario's folder (relative file keys are relative to it).
    """
    out = copy.deepcopy(raw)
    _absolute_paths(out, folder)
    for table, filled in zip(out.get("sensor", []), scenario["sensor"]):
        table["render_resolution"] = list(preview_resolution(scenario, filled["id"]))
    general = out.setdefault("general", {})
    general["duration_s"] = 0.0
    general["description"] = f"editor preview (fast quality: {'; '.join(preview_notes(scenario))})"
    thermal = out.setdefault("thermal", {})
    for key, own, lowered in _thermal_knobs(scenario):
        if lowered != own:
            thermal[key] = lowered
    return out


def _thermal_knobs(scenario: Scenario) -> list[tuple[str, float | str, float]]:
    """(key, the scenario's value ("auto" when left to the thermal tool), the fast preview's) of
    :data:`PREVIEW_THERMAL`; the radiation
    knobs only where people have a radiation balance (not with the fixed model)."""
    th = scenario["thermal"] or {}
    out = []
    for key, value, how in PREVIEW_THERMAL:
        if key.startswith("radiation_") and th.get("model") == "fixed":
            continue
        own = th.get(key, SECTIONS["thermal"].keys[key].default)
        if own is None:  # automatic (radiation_rays: from the cameras): the preview's value
            out.append((key, "auto", value))
            continue
        out.append((key, own, min(own, value) if how == "min" else max(own, value)))
    return out


def preview_notes(scenario: Scenario) -> list[str]:
    """What a fast preview lowers against ``scenario``, one short phrase each (the page and the
    preview scenario's description show them)."""
    notes = [
        f"thermal.{k} {low:g} (scenario: {own if isinstance(own, str) else format(own, 'g')})"
        for k, own, low in _thermal_knobs(scenario)
        if low != own
    ]
    if scenario.frame_count > 1:
        notes.append(f"frame 0 only (scenario: {scenario.frame_count} frames)")
    notes.append(f"{PREVIEW_SPP} samples per pixel, {PREVIEW_SUBBANDS} sub-band")
    return notes


def preview_commands(
    scenario_file: Path,
    out_dir: Path,
    sensor: str,
    resolution: tuple[int, int],
    quality: str = "fast",
) -> list[list[str]]:
    """The ``humv-usd`` arguments of a preview of ``sensor``'s frame 0 into ``out_dir/preview``.

    ``fast``: ``scenario_file`` is the preview scenario (:func:`preview_scenario`, written by
    the caller to ``out_dir / PREVIEW_SCENARIO``), composed into ``out_dir / PREVIEW_STAGE_DIR``
    and rendered at its own ``render_resolution``. ``full``: ``scenario_file`` is the scenario
    itself, composed into ``out_dir`` (as the Run tab's Compose: the layer cache is shared) and
    rendered at ``resolution``. Both render with ``--force`` (the folder holds the previous
    preview, rendered from the stage before the edit)."""
    if quality not in QUALITIES:
        raise ValueError(f"invalid preview quality {quality!r}; allowed: {', '.join(QUALITIES)}")
    stage_dir = out_dir / PREVIEW_STAGE_DIR if quality == "fast" else out_dir
    size = [] if quality == "fast" else ["--resolution", f"{int(resolution[0])}x{int(resolution[1])}"]
    return [
        ["compose", str(scenario_file), "-o", str(stage_dir)],
        [
            "render",
            str(stage_dir / "stage.usda"),
            "-o",
            str(out_dir / "preview"),
            "--frames",
            "0",
            "--sensor",
            sensor,
            *size,
            "--spp",
            str(PREVIEW_SPP),
            "--subbands",
            str(PREVIEW_SUBBANDS),
            "--annotators",
            PREVIEW_ANNOTATORS,
            "--force",
        ],
    ]


@dataclass(frozen=True)
class Preview:
    """A preview image (PNG) and its colour bar (None for EO)."""

    png: Path
    sensor: str
    levels_k: tuple[float, float] | None
    colour_stops: list[str]


def colour_stops(n: int = 11) -> list[str]:
    """CSS colours of the colour map at n evenly spaced levels (the colour bar's gradient)."""
    cmap = colormaps[COLOUR_MAP]
    rgb = [[int(round(255 * c)) for c in cmap(i / (n - 1))[:3]] for i in range(n)]
    return [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in rgb]


def colourise(temperature_k: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Brightness temperature [K] → uint8 RGB through :data:`COLOUR_MAP`, ``lo``..``hi`` K
    spanning the map (clipped); non-finite pixels black."""
    t = np.asarray(temperature_k, dtype=np.float64)
    scaled = (t - lo) / (hi - lo) if hi > lo else np.full(t.shape, 0.5)
    rgb = colormaps[COLOUR_MAP](np.clip(np.nan_to_num(scaled, nan=0.0), 0.0, 1.0))[..., :3]
    rgb[~np.isfinite(t)] = 0.0
    return np.rint(rgb * 255).astype(np.uint8)


def make_preview(render_dir: Path, sensor: str) -> Preview:
    """The preview of ``sensor``'s frame 0 in a render folder (reads its manifest)."""
    manifest = json.loads((render_dir / "manifest.json").read_text())
    for item in manifest.get("sensors", []):
        if item["name"] == sensor and item["frames"]:
            frame = item["frames"][0]
            lo, hi = frame["preview_levels_k"]
            bt = read_exr(render_dir / frame["exr"])["brightness_temperature"]
            png = render_dir / sensor / "preview_colour.png"
            write_png(png, colourise(bt, lo, hi))
            return Preview(png, sensor, (float(lo), float(hi)), colour_stops())
    for item in manifest.get("eo_sensors", []):
        if item["name"] == sensor and item["frames"]:
            return Preview(render_dir / item["frames"][0]["png"], sensor, None, [])
    reasons = [s.get("reason", "") for s in manifest.get("skipped_sensors", []) if s.get("name") == sensor]
    raise FileNotFoundError(
        f"no frame of sensor {sensor!r} in {render_dir}" + (f": {reasons[0]}" if reasons else "")
    )
