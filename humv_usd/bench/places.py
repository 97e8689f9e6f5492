"""Cost of generated places against their size (issue 30.6): compose time per layer and render
time against the number of scene objects and triangles.

:func:`place_scaling` composes a place example (``examples/places/<kind>.toml``) at growing
counts of vehicles, animals, lamps and warm objects (and a length that keeps their density),
with its sensors at a small resolution and the person left out (the cost of the place alone),
then renders every sensor once. One row per size: objects (instance ids under /World/Scene),
meshes, triangles (as drawn, after the thermal tool's refinement), seconds of the scene and
thermal layers and of the whole compose, render seconds, peak RSS [MB].
"""

from __future__ import annotations

import copy
import resource
import time
import tomllib
from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.bench.memory import small_sensors
from humv_usd.pipeline.compose import compose
from humv_usd.pipeline.render import render_stage
from humv_usd.scenario import validate

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "places"


def scaled_place(raw: dict, factor: float) -> dict:
    """The scenario document with the place's counts and length times ``factor`` (counts at
    least 0, length at least 10 m) and no people."""
    out = copy.deepcopy(raw)
    place = out["scene"]["place"]
    for key in ("vehicles", "lamps", "animals", "warm_objects", "buildings"):
        if key in place:
            place[key] = int(round(place[key] * factor))
    place["length_m"] = max(10.0, float(place.get("length_m", 60.0)) * factor)
    out.pop("human", None)
    out.pop("placement", None)
    return out


def stage_size(stage_path: Path) -> dict:
    """Objects (labelled prims under /World/Scene), meshes and drawn triangles of a stage."""
    stage = Usd.Stage.Open(str(stage_path))
    objects = meshes = triangles = 0
    for prim in stage.Traverse():
        if not str(prim.GetPath()).startswith("/World/Scene"):
            continue
        if prim.GetParent().GetPath() == "/World/Scene":
            objects += 1
        if prim.IsA(UsdGeom.Mesh):
            meshes += 1
            counts = np.asarray(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [], dtype=np.int64)
            triangles += int(np.sum(np.maximum(counts - 2, 0)))
    return {"objects": objects, "meshes": meshes, "triangles": triangles}


def place_scaling(
    kind: str,
    factors=(0.5, 1.0, 2.0),
    width: int = 64,
    height: int = 48,
    spp: int = 2,
    work: Path | None = None,
) -> list[dict]:
    """One row per size factor (see the module doc); ``work``: folder for the stages."""
    import tempfile

    raw = tomllib.loads((EXAMPLES / f"{kind}.toml").read_text(encoding="utf-8"))
    raw = small_sensors(raw, width, height)
    work = Path(work or tempfile.mkdtemp(prefix="humv-bench-places-"))
    rows = []
    for factor in factors:
        doc = scaled_place(raw, factor)
        out = work / f"{kind}_{factor:g}"
        t = time.perf_counter()
        report = compose(validate(doc, EXAMPLES / f"{kind}.toml"), out)
        t_compose = time.perf_counter() - t
        layer_s = {name: seconds for name, _, seconds in report.layers}
        t = time.perf_counter()
        render_stage(out / "stage.usda", out / "render", frames=[0], spp=spp, annotators=[], force=True)
        t_render = time.perf_counter() - t
        rows.append(
            {
                "kind": kind,
                "factor": factor,
                **stage_size(out / "stage.usda"),
                "scene_s": round(layer_s.get("scene", 0.0), 3),
                "thermal_s": round(layer_s.get("thermal", 0.0), 3),
                "compose_s": round(t_compose, 2),
                "render_s": round(t_render, 2),
                "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1),
            }
        )
    return rows
