"""The preview: one small, fast frame of one sensor, coloured by brightness temperature.

The preview is the real ``humv-usd compose`` of the scenario into the editor's output folder
(the same command as the Run tab's Compose and the 3D tab's view: one layer cache, so a preview
after a compose, a 3D view after a preview, and a preview after an edit rebuild only the layers
the edit invalidates) and a ``humv-usd render`` of frame 0 for one sensor with few samples, one
sub-band and at most :data:`PREVIEW_WIDTH_PX` columns (``--resolution``: pixels binned, the
pitch grows by the same factor, so the field of view stays; :func:`preview_resolution`) into
``OUT/preview`` (:func:`preview_commands`). Until 2026-11-27 the preview composed a binned
one-sensor copy of the scenario into a folder of its own: its sensors layer differed from the
real one, so the thermal layer (which refines the ground's shadow edges to the cameras' pixel
footprints) was built twice, and every preview after an edit failed (the render refused a
folder rendered from another stage without ``--force``). This module turns the render's EXR
channel ``IR.brightness_temperature`` (logical name ``brightness_temperature``) into a colour
image with a colour bar between the render's own preview levels (1st and 99th percentile,
``preview_levels_k`` in the manifest). EO sensors show their sRGB PNG as it is.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps

from humv_usd.images import read_exr, write_png
from humv_usd.scenario.load import Scenario
from humv_usd.scenario.spec import SECTIONS

#: colour map of the temperature preview (perceptually uniform, prints in grey)
COLOUR_MAP = "inferno"
#: render settings of a preview: samples per pixel, sub-bands, annotators (the cheapest one)
PREVIEW_SPP, PREVIEW_SUBBANDS, PREVIEW_ANNOTATORS = 2, 1, "semantic"
#: widest preview image [px]
PREVIEW_WIDTH_PX = 320


def preview_resolution(scenario: Scenario, sensor: str) -> tuple[int, int]:
    """The preview's pixel count of ``sensor``: its resolution binned by the smallest integer k
    that brings the width to at most :data:`PREVIEW_WIDTH_PX` (k also bounded so that the binned
    pitch stays inside the spec's ``pixel_pitch_um`` range). ``render --resolution`` keeps the
    field of view (the pitch grows by the same factor).

    Parameters
    ----------
    scenario : Scenario
        The validated scenario (the sensor's preset values filled in).
    sensor : str
        The sensor's ``id``.
    """
    filled = next(s for s in scenario["sensor"] if s["id"] == sensor)
    width, height = filled["resolution"]
    k = max(1, math.ceil(width / PREVIEW_WIDTH_PX))
    k = max(1, min(k, int(SECTIONS["sensor"].keys["pixel_pitch_um"].hi // filled["pixel_pitch_um"])))
    return max(1, width // k), max(1, height // k)


def preview_commands(
    scenario_file: Path, out_dir: Path, sensor: str, resolution: tuple[int, int]
) -> list[list[str]]:
    """The ``humv-usd`` arguments of a preview: compose the scenario into ``out_dir`` (as the
    Run tab's Compose does: the layer cache is shared), render frame 0 of ``sensor`` at
    ``resolution`` into ``out_dir/preview`` (``--force``: the folder holds the previous
    preview, rendered from the stage before the edit)."""
    return [
        ["compose", str(scenario_file), "-o", str(out_dir)],
        [
            "render",
            str(out_dir / "stage.usda"),
            "-o",
            str(out_dir / "preview"),
            "--frames",
            "0",
            "--sensor",
            sensor,
            "--resolution",
            f"{int(resolution[0])}x{int(resolution[1])}",
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
