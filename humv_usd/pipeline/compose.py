"""``humv-usd compose``: scenario → one USD layer per part + a root stage that sublayers them.

Every layer is built in memory first; only when all of them succeeded is anything written, each
file atomically and only if its text changed (so an unchanged scenario rewrites nothing).
Parts the scenario lacks get no layer; the report says what was skipped and why.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

from pxr import Sdf, Usd

import humv_usd
from humv_usd.atmosphere import layer as atmosphere_layer
from humv_usd.avatar import layer as avatar_layer
from humv_usd.clothing import layer as clothing_layer
from humv_usd.environment import layer as environment_layer
from humv_usd.fileio import write_text_atomic
from humv_usd.groundtruth import annotators
from humv_usd.materials import layer as materials_layer
from humv_usd.scenario import Scenario
from humv_usd.scene import layer as scene_layer
from humv_usd.sensors import layer as sensors_layer
from humv_usd.thermal import layer as thermal_layer
from humv_usd.usd.layers import layer_text, set_layer_metadata

LAYER_DIR = "layers"
ROOT_NAME = "stage.usda"
REPORT_NAME = "compose.json"
# file-name patterns compose owns inside OUT/layers (stale ones are removed)
_OWNED = (
    "environment.usda",
    "atmosphere.usda",
    "materials.usda",
    "scene.usda",
    "sensors.usda",
    "thermal.usda",
    "avatar_*.usda",
    "clothing_*.usda",
)


@dataclass
class ComposeReport:
    stage_path: Path
    layers: list[tuple[str, bool, float]] = field(default_factory=list)  # name, written, seconds
    skipped: list[tuple[str, str]] = field(default_factory=list)  # part, reason
    removed: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def written(self) -> list[str]:
        return [name for name, wrote, _ in self.layers if wrote]


def plan(scenario: Scenario) -> tuple[list[str], list[tuple[str, str]]]:
    """Which layers this scenario needs (weakest first) and which parts are skipped, and why."""
    needed, skipped = ["environment"], []
    has_ir = bool(scenario.infrared_sensors)
    has_meshes = bool(scenario["human"]) or scenario["scene"] is not None
    # EO sensors need the atmosphere too (sun and skylight spectra, paths); it runs LOWTRAN7
    # only for infrared bands (an EO-only scenario gets the analytic/SPCTRL2 tables)
    if has_meshes:
        needed.append("materials")
    else:
        skipped.append(("materials", "no humans and no scene"))
    if scenario["scene"] is not None:
        needed.append("scene")
    else:
        skipped.append(("scene", "no [scene] section"))
    if scenario["human"]:
        needed.extend(f"avatar_{h['id']}" for h in scenario["human"])
        dressed = [h["id"] for h in scenario["human"] if h["clothing"]]
        needed.extend(clothing_layer.layer_name(i) for i in dressed)
        if not dressed:
            skipped.append(("clothing", "nobody wears garments"))
    else:
        skipped.append(("avatar", "no [[human]]"))
    if scenario["sensor"]:
        needed.append("sensors")
    else:
        skipped.append(("sensors", "no [[sensor]]"))
    # after the sensors: the atmosphere reads their camera positions (atmosphere UPSTREAM)
    if scenario["sensor"] or "atmosphere" in scenario.given:
        needed.append("atmosphere")
    else:
        skipped.append(("atmosphere", "no sensor and no [atmosphere] section"))
    if has_meshes and has_ir:
        needed.append("thermal")
    else:
        skipped.append(("thermal", "no infrared sensor" if has_meshes else "no meshes"))
    return needed, skipped


def _build(name: str, scenario: Scenario, upstream: Usd.Stage | None) -> Sdf.Layer:
    if name.startswith("clothing_"):
        human_id = name.removeprefix("clothing_")
        human = next(h for h in scenario["human"] if h["id"] == human_id)
        return clothing_layer.build_one(scenario, human, upstream)
    if name.startswith("avatar_"):
        human_id = name.removeprefix("avatar_")
        human = next(h for h in scenario["human"] if h["id"] == human_id)
        return avatar_layer.build_one(scenario, human)
    tool = {
        "environment": environment_layer,
        "atmosphere": atmosphere_layer,
        "materials": materials_layer,
        "scene": scene_layer,
        "sensors": sensors_layer,
        "thermal": thermal_layer,
    }[name]
    return tool.build(scenario, upstream)


def compose_in_memory(layers: list[Sdf.Layer], fps: float) -> Usd.Stage:
    root = Sdf.Layer.CreateAnonymous(".usda")
    # same time codes per second as the layers, or USD rescales their time samples
    root.timeCodesPerSecond = fps
    root.framesPerSecond = fps
    root.subLayerPaths = [lyr.identifier for lyr in reversed(layers)]  # strongest first
    return Usd.Stage.Open(root)


def root_layer(scenario: Scenario, names: list[str]) -> Sdf.Layer:
    g = scenario["general"]
    root = Sdf.Layer.CreateAnonymous(".usda")
    set_layer_metadata(
        root,
        g["fps"],
        scenario.frame_count,
        f"HumV-USD stage for scenario '{g['name']}' (composed by humv-usd compose)",
    )
    root.subLayerPaths = [f"./{LAYER_DIR}/{n}.usda" for n in reversed(names)]
    root.customLayerData = {
        "humv:scenario": g["name"],
        "humv:scenarioDigest": scenario.digest(),
        "humv:version": humv_usd.__version__,
        **annotators.stage_metadata(scenario),  # [annotations] -> what the render computes
    }
    return root


def compose(scenario: Scenario, out_dir: str | Path) -> ComposeReport:
    """Write OUT/layers/*.usda and OUT/stage.usda for ``scenario``; see the module doc."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    names, skipped = plan(scenario)
    built: list[tuple[str, Sdf.Layer, float]] = []
    for name in names:
        t = time.perf_counter()
        reads_stage = name in ("thermal", "atmosphere") or name.startswith("clothing_")
        upstream = (
            compose_in_memory([lyr for _, lyr, _ in built], scenario["general"]["fps"])
            if reads_stage
            else None
        )
        built.append((name, _build(name, scenario, upstream), time.perf_counter() - t))
    texts = [(name, layer_text(lyr), dt) for name, lyr, dt in built]
    # what each tool ran and skipped (its layer's customLayerData "humv:<tool>:ran"), for compose.json
    ran = {
        name: dict(value)
        for name, lyr, _ in built
        for key, value in dict(lyr.customLayerData).items()
        if key.endswith(":ran")
    }
    root_text = layer_text(root_layer(scenario, names))

    report = ComposeReport(stage_path=out / ROOT_NAME, skipped=skipped)
    layer_dir = out / LAYER_DIR
    for name, text, dt in texts:
        t = time.perf_counter()
        wrote = write_text_atomic(layer_dir / f"{name}.usda", text)
        report.layers.append((name, wrote, dt + time.perf_counter() - t))
    keep = {f"{n}.usda" for n in names}
    if layer_dir.is_dir():
        for pattern in _OWNED:
            for stale in sorted(layer_dir.glob(pattern)):
                if stale.name not in keep:
                    stale.unlink()
                    report.removed.append(stale.name)
    wrote_root = write_text_atomic(out / ROOT_NAME, root_text)
    report.layers.append(("stage", wrote_root, 0.0))
    report.seconds = time.perf_counter() - t0
    # run times (and what ran) for pipelines; error estimates live in the layers themselves
    write_text_atomic(
        out / REPORT_NAME,
        json.dumps(
            {
                "humv_usd": humv_usd.__version__,
                "scenario_digest": scenario.digest(),
                "seconds_total": round(report.seconds, 4),
                "layers": [{"name": n, "written": w, "seconds": round(t, 4)} for n, w, t in report.layers],
                "skipped": [{"part": p, "reason": r} for p, r in report.skipped],
                "ran": ran,
                "removed": report.removed,
            },
            indent=2,
        )
        + "\n",
    )
    return report
