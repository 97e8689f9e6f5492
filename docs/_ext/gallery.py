"""The manual's gallery: every imager of the example scenes rendered, with a label overlay.

``make gallery`` (``python docs/_ext/gallery.py``) composes each example of :data:`EXAMPLES`
with its cameras at 1/:data:`SCALE` of their pixel count per axis (the pixel pitch scaled up by
the same factor, so each camera keeps its field of view), renders frame 0 at the render's
automatic quality, and writes into ``docs/gallery/``: ``<example>_<sensor>.png`` (the render's
preview: brightness temperature for IR, sRGB for EO), ``<example>_<sensor>_labels.png`` (the
preview with each labelled class tinted and each object's visible 2D box drawn, from the EXR's
``class_id`` and ``<frame>.objects.json``) and ``gallery.json`` (what each image is and how it was
made), which the gallery page lists. The scenes are the examples as committed, so the gallery
shows what ``make demo`` renders, smaller, plus the reflective bands the examples lack
(:data:`REFLECTIVE`): a NIR (``nir_imx273``) and a SWIR (``swir_ingaas640``) camera beside each
example's EO camera, looking where it looks.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import tomlkit
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "out" / "gallery"
GALLERY = ROOT / "docs" / "gallery"
EXAMPLES = ("humvvex", "street")
SCALE = 4
#: reflective-band cameras the examples lack, added beside the EO camera (``eo_rgb``): id, preset,
#: the full-size resolution and pixel pitch [um] before :data:`SCALE` (the NIR camera 2x2 binned,
#: as the IMX273 can, so its gallery image stays small; the field of view is the preset's), and
#: the offset along x [m] from the EO camera (the examples space their cameras 0.6-0.8 m apart)
REFLECTIVE = (
    ("nir", "nir_imx273", (720, 540), 6.9, -0.8),
    ("swir", "swir_ingaas640", (640, 512), 15.0, -1.6),
)
#: label tint per class name (RGB), drawn at 45 % over the preview; classes without one are left
TINT = {
    "person": (230, 40, 40),
    "building": (40, 90, 230),
    "vehicle": (240, 200, 30),
    "prop": (40, 200, 80),
    "panel": (200, 60, 220),
    "vegetation": (60, 160, 60),
    "other": (0, 200, 200),
}


def _absolute_paths(raw: dict, folder: Path) -> None:
    """Rewrite the scenario's file keys (kinds "path" and "pathlist" of the spec) to absolute
    paths, so the copy in ``out/gallery`` finds the example's files."""
    from humv_usd.scenario.spec import SECTIONS

    def walk(table, section):
        for name, key in section.keys.items():
            if name in table and key.kind == "path":
                table[name] = str((folder / table[name]).resolve())
            elif name in table and key.kind == "pathlist":
                table[name] = [str((folder / p).resolve()) for p in table[name]]
        for sub_name, sub in section.subsections.items():
            for entry in table.get(sub_name, []) if sub.array else [table.get(sub_name, {})]:
                walk(entry, sub)

    for name, section in SECTIONS.items():
        for table in raw.get(name, []) if section.array else [raw.get(name, {})]:
            walk(table, section)


def _reflective_cameras(raw: dict) -> None:
    """Add the :data:`REFLECTIVE` cameras beside the example's EO camera (none without one)."""
    eo = next((s for s in raw.get("sensor", []) if s.get("id") == "eo_rgb"), None)
    if eo is None:
        return
    taken = {s.get("id") for s in raw["sensor"]}
    for sid, name, resolution, pitch, dx in REFLECTIVE:
        if sid in taken:
            continue
        x, y, z = eo["position_m"]
        raw["sensor"].append(
            {
                "id": sid,
                "preset": name,
                "resolution": list(resolution),
                "pixel_pitch_um": pitch,
                "position_m": [x + dx, y, z],
                "look_at_m": list(eo["look_at_m"]),
            }
        )


def _smaller_cameras(raw: dict) -> None:
    from humv_usd.catalog.sensors import PRESETS

    for sensor in raw.get("sensor", []):
        preset = PRESETS.get(sensor.get("preset", ""))
        width, height = sensor.get("resolution") or preset.resolution
        pitch = sensor.get("pixel_pitch_um") or preset.pixel_pitch_um
        sensor["resolution"] = [width // SCALE, height // SCALE]
        sensor["pixel_pitch_um"] = pitch * SCALE


def _overlay(render: Path, sensor: str, out: Path) -> None:
    from humv_usd.groundtruth.labels import CLASSES
    from humv_usd.images import read_exr

    preview = Image.open(render / sensor / "0000.png").convert("RGB")
    base = np.asarray(preview, dtype=np.float32)
    class_id = read_exr(render / sensor / "0000.exr")["class_id"]
    tinted = base.copy()
    for cid, name in enumerate(CLASSES):
        if name in TINT:
            mask = class_id == cid
            tinted[mask] = 0.55 * base[mask] + 0.45 * np.array(TINT[name], dtype=np.float32)
    image = Image.fromarray(tinted.clip(0, 255).astype(np.uint8))
    draw = ImageDraw.Draw(image)
    objects = json.loads((render / sensor / "0000.objects.json").read_text())["objects"]
    for o in objects:
        if o["class"] in TINT and o.get("visible_pixels", 0) > 0:
            x0, y0, x1, y1 = o["box_visible"]
            draw.rectangle([x0, y0, x1 - 1, y1 - 1], outline=TINT[o["class"]], width=1)
    image.save(out)


def make(examples=EXAMPLES) -> list[dict]:
    GALLERY.mkdir(parents=True, exist_ok=True)
    exe = Path(sys.executable).parent / "humv-usd"
    entries = []
    for example in examples:
        source = ROOT / "examples" / f"{example}.toml"
        raw = tomllib.loads(source.read_text())
        _absolute_paths(raw, source.parent)
        _reflective_cameras(raw)
        _smaller_cameras(raw)
        folder = OUT / example
        folder.mkdir(parents=True, exist_ok=True)
        scenario = folder / f"{example}.toml"
        scenario.write_text(tomlkit.dumps(raw))
        subprocess.run([str(exe), "compose", str(scenario), "-o", str(folder / "stage")], check=True)
        render = folder / "render"
        start = time.perf_counter()
        subprocess.run(
            [
                str(exe),
                "render",
                str(folder / "stage" / "stage.usda"),
                "-o",
                str(render),
                "--frames",
                "0",
                "--force",
                "-q",
            ],
            check=True,
        )
        seconds = time.perf_counter() - start
        manifest = json.loads((render / "manifest.json").read_text())
        for sensor in raw["sensor"]:
            sid = sensor["id"]
            if not (render / sid / "0000.png").is_file():
                continue
            image, labels = f"{example}_{sid}.png", f"{example}_{sid}_labels.png"
            Image.open(render / sid / "0000.png").save(GALLERY / image)
            _overlay(render, sid, GALLERY / labels)
            listed = [*manifest.get("sensors", []), *manifest.get("eo_sensors", [])]
            info = next((s for s in listed if isinstance(s, dict) and s.get("name") == sid), {})
            entries.append(
                {
                    "example": example,
                    "sensor": sid,
                    "preset": sensor.get("preset", ""),
                    "band": info.get("band") or sensor.get("band", ""),
                    "resolution": sensor["resolution"],
                    "image": image,
                    "labels": labels,
                    "render_seconds_all_sensors": round(seconds, 1),
                }
            )
    (GALLERY / "gallery.json").write_text(json.dumps(entries, indent=1) + "\n")
    return entries


if __name__ == "__main__":
    for entry in make(sys.argv[1:] or EXAMPLES):
        sys.stdout.write(f"docs/gallery/{entry['image']}  docs/gallery/{entry['labels']}\n")
