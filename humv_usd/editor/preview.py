"""The preview: one small, fast frame of one sensor, coloured by brightness temperature.

The preview is a real ``humv-usd compose`` (cached layers) and ``humv-usd render`` of frame 0 for
one sensor with few samples and one sub-band (:func:`preview_commands`), on a copy of the scenario
that keeps only that sensor, with at most :data:`PREVIEW_WIDTH_PX` columns (pixels binned: the
pitch grows by the same factor, so the field of view stays; :func:`preview_scenario`); it is
composed into ``OUT/.editor/preview`` so the real output's layers stay as they are. This module turns the
render's EXR channel ``IR.brightness_temperature`` (logical name ``brightness_temperature``) into a colour image with a colour bar between
the render's own preview levels (1st and 99th percentile, ``preview_levels_k`` in the manifest).
EO sensors show their sRGB PNG as it is.
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


def preview_scenario(raw: dict, scenario: Scenario, folder: Path, sensor: str) -> dict:
    """The scenario document of a preview of ``sensor``: only that sensor, binned to at most
    :data:`PREVIEW_WIDTH_PX` columns (pitch × k, resolution // k: same field of view), file keys
    made absolute (the copy lives in the output folder).

    Parameters
    ----------
    raw : dict
        The scenario as written (plain values).
    scenario : Scenario
        The same, validated (the sensor's preset values filled in).
    folder : Path
        The scenario's folder (relative file keys are relative to it).
    """
    out = copy.deepcopy(raw)
    for f in all_fields(raw):
        node = out
        for part in f.path[:-1]:
            node = (
                node[part]
                if isinstance(node, (dict, list)) and (isinstance(node, list) or part in node)
                else None
            )
        value = node.get(f.path[-1]) if isinstance(node, dict) else None
        if f.key.kind == "path" and isinstance(value, str):
            node[f.path[-1]] = str((folder / value).resolve())
        elif f.key.kind == "pathlist" and isinstance(value, list):
            node[f.path[-1]] = [str((folder / v).resolve()) for v in value]
    index = [s["id"] for s in scenario["sensor"]].index(sensor)
    filled = scenario["sensor"][index]
    table = out["sensor"][index]
    width, height = filled["resolution"]
    pitch = filled["pixel_pitch_um"]
    k = max(1, math.ceil(width / PREVIEW_WIDTH_PX))
    k = max(1, min(k, int(SECTIONS["sensor"].keys["pixel_pitch_um"].hi // pitch)))
    if k > 1:
        table["resolution"] = [max(1, width // k), max(1, height // k)]
        table["pixel_pitch_um"] = pitch * k
    out["sensor"] = [table]
    return out


def preview_commands(preview_file: Path, out_dir: Path, sensor: str) -> list[list[str]]:
    """The ``humv-usd`` arguments of a preview: compose the preview scenario (written by the
    caller to ``preview_file``) into ``out_dir/.editor/preview``, render frame 0 of ``sensor``
    into ``out_dir/preview``."""
    stage_dir = out_dir / ".editor" / "preview"
    return [
        ["compose", str(preview_file), "-o", str(stage_dir)],
        [
            "render",
            str(stage_dir / "stage.usda"),
            "-o",
            str(out_dir / "preview"),
            "--frames",
            "0",
            "--sensor",
            sensor,
            "--spp",
            str(PREVIEW_SPP),
            "--subbands",
            str(PREVIEW_SUBBANDS),
            "--annotators",
            PREVIEW_ANNOTATORS,
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
