"""What a sweep runs: each variant's layer cache keys (compose shares equal keys between
variants), the tasks (one compose per variant, one render per variant and frame chunk) and an
estimate of the cost."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pvlib
from pxr import Usd, UsdGeom

from humv_usd.errors import InputError
from humv_usd.pipeline import compose as compose_mod
from humv_usd.pipeline.budget import free_disk, size_text
from humv_usd.pipeline.graph import build_order, layer_graph
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import inputs_key, read_values
from humv_usd.scenario.times import utc_times
from humv_usd.scene import layer as scene_layer
from humv_usd.sweep import store
from humv_usd.sweep.spec import Sweep, Variant

#: camera samples per second of one worker with the fast infrared estimator (4 reflection
#: directions per camera sample, 16 sub-bands), with :data:`SECONDS_PER_IMAGE`: `humv-usd bench
#: sweep examples/walk.toml --variants 4 --frames 16 --resolution 1024x768` measured a median task
#: of 12.8 s for 4 images per worker with 2 workers on this 2-core machine (2026-11-24, idle),
#: i.e. 3.19 s per 1024x768 image at 2 spp = (786,432 x 2) / 0.72e6 + 1 s
SAMPLES_PER_SECOND_PER_WORKER = 0.72e6
#: fixed cost per rendered image (stage export, ground truth, conversions, writes) [s]
SECONDS_PER_IMAGE = 1.0
#: compose seconds of a layer that is built (not shared): (fixed, per frame) by tool, for the people
#: (the scene's own thermal term: :data:`SCENE_THERMAL`). Per frame from the compose.json of
#: `humv-usd bench sweep` (walk, 16 frames) and examples/table1.toml's variants (31 frames); the fixed
#: parts raised 2026-11-27 to today's whole composes (`humv-usd bench compose --scenario ...`, CPU-s
#: of a fresh child, after the garment-stack speed-up 08d73d8, /work/notes/s5/compose-speed.md): walk
#: (31 frames) 27.9, Table 1 v0025 22.9, v0066 35.1, the one-frame demo 19.1, against which these
#: constants give 27.3, 27.3, 27.3 and 16.2 (the rest: the child's start and imports); others 0.1 s.
#: Thermal lowered 2026-11-27 (s6, 80569a7, 973f1fe: the local skin of all frames in one call, the
#: slope's stacks in the same calls, JOS-3 imported alone) by the measured saving, the same bench
#: before/after back to back at load 8-14: v0066 43.6 -> 41.0, v0025 24.8 -> 23.0, walk 30.2 ->
#: 28.8, demo 19.7 -> 17.4 CPU-s (0.6 s of it the import, fixed; about 0.04 s per frame)
COMPOSE_SECONDS = {
    "avatar": (0.5, 0.0),
    "clothing": (7.0, 0.15),
    "thermal": (6.4, 0.18),
    "environment": (0.7, 0.0),
}
#: thermal seconds of a scene's surfaces (slab balance, refinement at shadow edges, the exchange
#: between faces), added to the thermal layer's people terms above: a * M**b with M the meshes of
#: the scene layer (ground, horizon rings, objects, each clutter part, plants, puddles), counted
#: from the scene layer built in memory (0.05-0.4 s; :func:`scene_meshes`). Least-squares fit of
#: log(thermal s) on log M over six composes of examples/random_places.toml's daytime variants
#: (default cells: down to the cameras' pixel footprints; one person, ``model = "fixed"``;
#: 2026-11-27, the shared 2-core machine at load 2-4, wall s of compose.json), (M, thermal s):
#: parking lot v0014 (23, 8.1), v0015 (33, 23.6), rural road v0010 (83, 119.7), v0008 (128,
#: 175.4), open field v0018 (93, 89.7), v0019 (120, 28.9): a = 0.190, b = 1.31; measured /
#: estimated 0.70, 1.28, 1.93, 1.61, 1.25 and 0.29 (the open field's many animal and vehicle meshes
#: are cheap at 15:44 in October). The mesh count is a proxy for the refined faces the cost follows
#: (the refinement needs the sun and the shadows, i.e. the thermal layer itself); the drawn
#: triangles do no better (v0018 126 k -> 89.7 s, v0019 129 k -> 28.9 s). The issue-30 audit's
#: composes (surface_cell_m 0.5, load 11-15, /work/notes/s5/audit-30/cost_table.json) run 0.35-3.8
#: x this (the loaded machine), `humv-usd bench places --kind street` 4.2 and 8.2 x
SCENE_THERMAL = (0.190, 1.31)
#: factor on the scene term when the sun is down from :data:`SUN_MEMORY_S` before frame 0 to the
#: last frame: the thermal tool then refines no face (its sun dose weights are all 0,
#: :func:`humv_usd.thermal.surfaces.refine_meshes`), so only the coarse faces' balance is left:
#: examples/random_places.toml's v0013 (parking lot at 00:10 in October, 37 meshes, the same run)
#: took 2.8 s of thermal layer where the day term gives 21.5 s (one row)
NIGHT_THERMAL_FACTOR = 0.13
#: how long before frame 0 the thermal tool's refinement still counts the sun: weights exp(t / 1 h)
#: below 0.01 are dropped (:data:`humv_usd.thermal.surfaces.REFINE_MEMORY_S`, ``_recent_weights``)
SUN_MEMORY_S = 3600.0 * math.log(100.0)


def sun_in_memory(scenario: Scenario) -> bool:
    """Whether the sun is above the horizon at some time from :data:`SUN_MEMORY_S` before frame 0
    to the last frame (15 min steps; NREL SPA through pvlib, as the scene layer)."""
    g = scenario["general"]
    end = float(g["duration_s"])
    times = np.append(np.arange(-SUN_MEMORY_S, end, 900.0), end)
    pos = pvlib.solarposition.get_solarposition(
        utc_times(scenario, times), g["latitude_deg"], g["longitude_deg"], g["elevation_m"]
    )
    return bool((pos["apparent_elevation"].to_numpy() > 0.0).any())


def scene_meshes(scenario: Scenario) -> int:
    """Meshes of ``scenario``'s scene layer (0 without a scene), built in memory: the size
    :func:`scene_thermal_seconds` costs."""
    if not scenario["scene"]:
        return 0
    stage = Usd.Stage.Open(scene_layer.build(scenario))
    return sum(1 for prim in stage.Traverse() if prim.IsA(UsdGeom.Mesh))


def scene_thermal_seconds(meshes: int, sun: bool = True) -> float:
    """Estimated thermal-layer seconds of a scene of ``meshes`` meshes (:data:`SCENE_THERMAL`, times
    :data:`NIGHT_THERMAL_FACTOR` without ``sun`` in the refinement's memory: :func:`sun_in_memory`)."""
    a, b = SCENE_THERMAL
    return (1.0 if sun else NIGHT_THERMAL_FACTOR) * a * meshes**b if meshes > 0 else 0.0


#: the thermal layer's people terms (fixed, per frame) with ``[thermal] model = "fixed"`` (the skin
#: at one temperature: no JOS-3, no garment stacks; the thermal tool solves no person): 0, the
#: scene term's fit (:data:`SCENE_THERMAL`) was measured with such people and holds their cost
FIXED_SKIN_THERMAL_SECONDS = (0.0, 0.0)
#: seconds per 1024x768 infrared image of one GPU worker, render only (estimator, labels, queued
#: writes): `python tools/gpu_check.py render out/walk/stage.usda --frames 0:3 --backend cuda` on one
#: NVIDIA H100 with `cuda_ad_mono`, the walk's LWIR camera (atom1024_lwir) at automatic quality,
#: measured 2026-11-27 (issue 31; estimator 2.30 s, labels 0.09 s, writes queued 0.07 s). The only
#: GPU rate measured: other sizes are scaled by their pixel count and a given spp by spp /
#: :data:`AUTO_SPP_COST`, visible (EO) sensors are costed at the same rate (never measured on a GPU)
GPU_SECONDS_PER_IMAGE = 2.59
#: pixels of that image
GPU_RATE_PIXELS = 1024 * 768
#: extra seconds of a GPU render task's first frame (scene build and kernel compilation: 6.2 s
#: against 2.59 s in the same run); a worker's later tasks may reuse compiled kernels (not measured)
GPU_SECONDS_PER_TASK = 3.6
#: ``[render] frames_per_task`` the dry run suggests for GPU workers: the first-frame cost above
#: stays under 10 % of a task (3.6 / (16 x 2.59 + 3.6) = 8 %)
GPU_FRAMES_PER_TASK = 16
#: where each rate of :func:`estimate` comes from (the dry run prints it)
RATE_SOURCES = {
    "cpu": "CPU worker: 0.72 Msamples/s + 1 s per image (humv-usd bench sweep examples/walk.toml "
    "--variants 4 --frames 16 --resolution 1024x768, 2 workers on a 2-core machine, 2026-11-24)",
    "gpu": f"GPU worker: {GPU_SECONDS_PER_IMAGE} s per 1024x768 LWIR image + {GPU_SECONDS_PER_TASK} s per "
    "task (one H100, cuda_ad_mono, walk at automatic quality, render only, tools/gpu_check.py, "
    "2026-11-27; scaled by pixels, EO at the same rate: not measured)",
}
#: bytes written per pixel of an image by the render (EXR with every label channel, zip; the PNG
#: previews, masks and sensor-chain images): walk LWIR 1024x768 9.8 MB per image (the bench's
#: 64 images: 627 MB), an EO camera's 21-channel EXR about 32 bytes per pixel
DISK_BYTES_PER_PIXEL = {"ir": 12.5, "eo": 32.0}
#: bytes of a variant's composed layers per frame (walk: 37 MB for 4 variants of 16 frames)
DISK_BYTES_PER_VARIANT_FRAME = 0.6e6


def layer_keys(scenario: Scenario) -> dict[str, str]:
    """Cache key of each layer compose would build for ``scenario`` (as compose computes it for
    a fresh folder: no hand edits, no user layers), in build order."""
    needed, _ = compose_mod.plan(scenario)
    nodes = layer_graph(scenario, needed)
    keys: dict[str, str] = {}
    passed: dict[str, str] = {}  # the key downstream layers see (without render-only inputs)
    for name in build_order(nodes):
        node = nodes[name]
        upstream = {u: passed[u] for u in node.upstream}
        values = read_values(scenario, node.tool.reads, node.human_id)
        keys[name] = inputs_key(node.tool.version, values, upstream)
        passed[name] = compose_mod.downstream_key(node.tool, values, upstream) or keys[name]
    return keys


@dataclass(frozen=True)
class RenderTask:
    variant: str
    chunk: str  # folder name: f<first>-<last>
    frames: tuple[int, ...]

    @property
    def name(self) -> str:
        return f"{self.variant}/{self.chunk}"


def variant_frames(variant: Variant, frames: list[int] | None) -> list[int]:
    """The frames rendered of a variant: the sweep's list clipped to the variant's range."""
    n = variant.scenario.frame_count
    return list(range(n)) if frames is None else [f for f in frames if f < n]


def render_tasks(sweep: Sweep) -> list[RenderTask]:
    per = sweep.render["frames_per_task"]
    out = []
    for v in sweep.variants:
        frames = variant_frames(v, sweep.render["frames"])
        for i in range(0, len(frames), per):
            chunk = tuple(frames[i : i + per])
            out.append(RenderTask(v.id, f"f{chunk[0]:04d}-{chunk[-1]:04d}", chunk))
    return out


def compose_dependencies(keys: dict[str, dict[str, str]]) -> dict[str, list[str]]:
    """For each variant, the earlier variants whose compose builds a layer it can reuse (the
    first variant with each layer key): composing those first lets it take their layers."""
    first: dict[tuple[str, str], str] = {}
    deps: dict[str, list[str]] = {}
    for vid, layer_key in keys.items():
        deps[vid] = sorted({first[(n, k)] for n, k in layer_key.items() if (n, k) in first})
        for n, k in layer_key.items():
            first.setdefault((n, k), vid)
    return deps


#: samples per pixel to cost a task at when the sweep leaves spp to the render's automatic quality:
#: the LWIR cameras reach NETD/3 at 2 spp (issue 13); an MWIR camera needs about 24
AUTO_SPP_COST = 2


def _selected_sensors(scenario: Scenario, sensors) -> list[dict]:
    """The scenario's sensors the sweep renders (``[render] sensors``; empty: all)."""
    return [s for s in scenario["sensor"] if not sensors or s["id"] in sensors]


def _pixel_bytes(sensor: dict) -> float:
    """Bytes the render writes per pixel of this sensor (:data:`DISK_BYTES_PER_PIXEL`)."""
    return DISK_BYTES_PER_PIXEL["eo" if sensor.get("band") == "EO" else "ir"]


def held_work(sweep: Sweep, loc, limit: int | None = None) -> tuple[set[tuple[str, str]], set[str]]:
    """What :func:`estimate` leaves out for a dataset folder (a :class:`~humv_usd.sweep.where.Location`):
    the (variant, chunk) of the render tasks it already holds, plus those of the variants after
    the first ``limit``, and its composed variants (both empty for a folder not yet there)."""
    done: set[tuple[str, str]] = set()
    if loc.remote or loc.path.is_dir():
        done = store.done_tasks(loc)
    if limit is not None:
        wanted = {v.id for v in sweep.variants[:limit]}
        done |= {(t.variant, t.chunk) for t in render_tasks(sweep) if t.variant not in wanted}
    composed = {v.id for v in sweep.variants if store.compose_done(loc, v.id)}
    return done, composed


def estimate(
    sweep: Sweep,
    keys: dict[str, dict[str, str]],
    workers: int,
    done: set[tuple[str, str]] = frozenset(),
    composed: set[str] = frozenset(),
    gpus: int = 0,
) -> dict:
    """Counts, and an estimated wall time and disk of what is left to do (see the module constants
    for the rates): ``done`` the (variant, chunk) of the render tasks a dataset already holds,
    ``composed`` its composed variants (both empty for a new dataset; their layers are in the
    dataset's layer store).

    ``gpus`` = 0: ``workers`` CPU workers compose and render, wall = (compose + render) / workers.
    ``gpus`` > 0: the renders run on the GPUs (:data:`GPU_SECONDS_PER_IMAGE` scaled by pixels and
    spp, plus :data:`GPU_SECONDS_PER_TASK` per task) while ``workers`` CPU workers compose, and the
    slower side sets the wall time: max(render / gpus, compose / workers)."""
    all_tasks = render_tasks(sweep)
    todo = [t for t in all_tasks if (t.variant, t.chunk) not in done]
    spp, sensors = sweep.render["spp"] or AUTO_SPP_COST, sweep.render["sensors"]
    by_variant = {v.id: v for v in sweep.variants}

    def n_images(t: RenderTask) -> int:
        return len(t.frames) * len(_selected_sensors(by_variant[t.variant].scenario, sensors))

    samples = 0
    disk = 0.0
    gpu_s = GPU_SECONDS_PER_TASK * len(todo)
    for t in todo:
        for s in _selected_sensors(by_variant[t.variant].scenario, sensors):
            pixels = s["resolution"][0] * s["resolution"][1] * len(t.frames)
            samples += pixels * spp
            disk += pixels * _pixel_bytes(s)
            gpu_s += GPU_SECONDS_PER_IMAGE * pixels / GPU_RATE_PIXELS * spp / AUTO_SPP_COST
    images_todo = sum(n_images(t) for t in todo)
    pending = {t.variant for t in todo}
    to_compose = [v for v in sweep.variants if v.id in pending and v.id not in composed]
    disk += sum(v.scenario.frame_count for v in to_compose) * DISK_BYTES_PER_VARIANT_FRAME
    stored = {(n, k) for vid in composed for n, k in keys[vid].items()}
    first_of = {}  # each layer left to build once, with its first variant
    for v in to_compose:
        for n, k in keys[v.id].items():
            if (n, k) not in stored:
                first_of.setdefault((n, k), v)
    compose_s = 0.0
    meshes_of: dict[str, int] = {}  # scene meshes by scene layer key (variants share scenes)
    for (n, _), v in first_of.items():
        tool = n.split("_")[0]
        fixed, per_frame = COMPOSE_SECONDS.get(tool, (0.1, 0.0))
        if tool == "thermal" and (v.scenario["thermal"] or {}).get("model") == "fixed":
            fixed, per_frame = FIXED_SKIN_THERMAL_SECONDS  # no physiology, no garment stacks
        compose_s += fixed + per_frame * v.scenario.frame_count
        if tool == "thermal":
            scene_key = keys[v.id].get("scene", v.id)
            if scene_key not in meshes_of:
                meshes_of[scene_key] = scene_meshes(v.scenario)
            sun = meshes_of[scene_key] > 0 and sun_in_memory(v.scenario)
            compose_s += scene_thermal_seconds(meshes_of[scene_key], sun)
    if gpus > 0:
        render_s = gpu_s
        wall = max(render_s / gpus, compose_s / max(1, workers))
    else:
        render_s = samples / SAMPLES_PER_SECOND_PER_WORKER + images_todo * SECONDS_PER_IMAGE
        wall = (compose_s + render_s) / max(1, workers)
    frames = sum(len(t.frames) for t in all_tasks)
    return {
        "variants": len(sweep.variants),
        "render_tasks": len(all_tasks),
        "frames": frames,
        "images": sum(n_images(t) for t in all_tasks),
        "tasks_done": len(all_tasks) - len(todo),
        "frames_done": frames - sum(len(t.frames) for t in todo),
        "variants_composed": len(composed),
        "variants_to_compose": len(to_compose),
        "images_todo": images_todo,
        "megasamples": round(samples / 1e6, 1),
        "layers": sum(len(lk) for lk in keys.values()),
        "layers_to_build": len(first_of),
        "workers": workers,
        "gpus": gpus,
        "render_on": "gpu" if gpus > 0 else "cpu",
        "frames_per_task": sweep.render["frames_per_task"],
        "rates": RATE_SOURCES["gpu" if gpus > 0 else "cpu"],
        "compose_s": round(compose_s, 1),
        "render_s": round(render_s, 1),
        "wall_s": round(wall, 1),
        "wall_h": round(wall / 3600.0, 2),
        "disk_bytes": disk,
        "disk_gb": round(disk / 1e9, 1),
        "frames_per_hour": round(images_todo / wall * 3600.0) if wall > 0 else math.inf,
    }


def disk_text(est: dict, folder) -> str:
    """ "X GB free at FOLDER" (the free space of its nearest existing parent), with a warning when
    the estimate does not fit."""
    free = free_disk(folder)
    warn = " - WARNING: more than is free; free space or write elsewhere" if est["disk_bytes"] > free else ""
    return f"{size_text(free)} free at {folder}{warn}"


def require_disk(est: dict, folder, yes: bool = False) -> None:
    """Refuse (InputError, one line) a sweep whose estimated writes of what is left do not fit the
    free disk at ``folder``, unless ``yes``: a sweep that fills the disk fails its tasks hours in."""
    free = free_disk(folder)
    if est["disk_bytes"] > free and not yes:
        raise InputError(
            f"sweep: about {size_text(est['disk_bytes'])} left to write ({est['images_todo']} images, "
            f"{est['variants_to_compose']} variants to compose), {size_text(free)} free at "
            f"{folder}: free space or write elsewhere, or pass --yes to go ahead anyway"
        )
