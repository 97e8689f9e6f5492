"""Compose memory and time of a crowd (issue 29.5): N people walking, each steering round the
others (placement ``avoidance = "socialForce"``), composed (:func:`humv_usd.pipeline.compose.compose`,
what ``humv-usd compose`` runs) in a child process whose peak resident set it reads from /proc.

    python -m humv_usd.bench.crowd --people 10 --duration 1.5 --fps 30 --thermal fixed OUT
    python -m humv_usd.bench.crowd OUT --people 2 --fps 10 --durations 3 6 12 24

The scenario is examples/walk.toml's site and weather with its camera cut to 64x48 pixels; the
people start on a 3 m x 9 m block west of the origin and walk east, every second one on a
diagonal, so their paths cross; outfits: T-shirt, leggings, shoes. The result (JSON on stdout
and in OUT/bench_crowd.json): frames, people, peak RSS [MB], wall time [s], the layer texts
written [MB], compose.json's seconds per layer and each layer build's own peak RSS [MB].

The child composes with a progress hook that, before each layer build, reads the process's
peak resident set (``VmHWM`` of /proc/self/status) and resets it (``5`` to
/proc/self/clear_refs, Linux >= 4.0): the peak of each build on its own. Where the reset is not
allowed the per-layer peaks are left out.

Memory against clip length (issue 29.5): ``--durations 2 4 8`` composes the same crowd at each
duration and adds the peak's growth per frame (a least-squares line through the runs).

Foot slip and closest approach of a composed stage (:func:`motion_figures`, measured on the
stage's posed meshes)::

    python -m humv_usd.bench.crowd --figures OUT/stage/stage.usda [--stride 2]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel
from scipy.spatial import cKDTree

from humv_usd.human.labels import BODY_REGION_NAMES
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import load_scenario
from humv_usd.usd.avatar import read_body_regions
from humv_usd.usd.layers import SCOPES
from humv_usd.usd.paths import body_path

WALK_TOML = Path(__file__).resolve().parents[2] / "examples" / "walk.toml"


#: the outfit every walker wears unless told otherwise
OUTFIT = ("tshirt_black", "leggings", "shoes")


def crowd_scenario(
    people: int, duration_s: float, fps: float, thermal: str = "fixed", clothing=OUTFIT
) -> str:
    """The scenario text (see the module doc); ``clothing``: every walker's garments (None:
    no ``clothing`` key, the scenario's default)."""
    src = WALK_TOML.read_text(encoding="utf-8")
    head = src[: src.index("[[human]]")]
    tail = src[src.index("[scene]") :]
    head = head.replace("fps = 15.0", f"fps = {fps}").replace(
        "duration_s = 2.0", f"duration_s = {duration_s}"
    )
    tail = tail.replace("resolution = [1024, 768]", "resolution = [64, 48]")
    tail = tail.replace('model = "jos3"', f'model = "{thermal}"', 1)
    out = []
    for i in range(people):
        x0, y0 = -6.0 + 1.5 * (i % 3), -4.5 + 1.0 * i
        waypoints = f"[[{x0 + 12.0:.1f}, {-y0 if i % 2 else y0:.1f}]]"
        out.append(
            f"""
[[human]]
id = "p{i}"
sex = "{"male" if i % 2 == 0 else "female"}"
age_yr = {25 + 3 * i}
stature_m = {1.60 + 0.025 * (i % 9):.3f}
mass_kg = {58 + 3 * i}.0
activity = "walk"
speed_m_s = {1.1 + 0.05 * (i % 5):.2f}
{"" if clothing is None else "clothing = " + json.dumps(list(clothing))}

[[placement]]
human = "p{i}"
position_m = [{x0:.1f}, {y0:.1f}, 0.0]
heading_deg = 90.0
waypoints_m = {waypoints}
avoidance = "socialForce"
"""
        )
    return head + "".join(out) + "\n" + tail


def bench_crowd(
    out: Path, people: int, duration_s: float, fps: float, thermal: str = "fixed", clothing=OUTFIT
) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = out / "crowd.toml"
    scenario.write_text(crowd_scenario(people, duration_s, fps, thermal, clothing), encoding="utf-8")
    t = time.perf_counter()
    cmd = [sys.executable, "-m", "humv_usd.bench.crowd", "--child", str(scenario), str(out / "stage")]
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    peaks = json.loads((out / "layer_peaks.json").read_text())
    layers = out / "stage" / "layers"
    report = json.loads((out / "stage" / "compose.json").read_text())
    result = {
        "people": people,
        "frames": int(round(duration_s * fps)) + 1,
        "fps": fps,
        "thermal": thermal,
        "clothing": None if clothing is None else list(clothing),
        "peak_rss_mb": peaks["peak_mb"],
        "wall_s": round(seconds, 1),
        # CPU seconds of the child (user + system): less sensitive than wall time to a shared machine
        "cpu_s": round(cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime, 1),
        "layer_text_mb": round(sum(p.stat().st_size for p in layers.glob("*.usda")) / 1e6, 1),
        "layer_seconds": {e["name"]: e["seconds"] for e in report["layers"] if "seconds" in e},
        "layer_peak_rss_mb": peaks["layers"],
        "cpus": os.cpu_count(),
    }
    (out / "bench_crowd.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return result


def _status_kb(key: str) -> float:
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return float(line.split()[1])
    return float("nan")


def child_compose(scenario: Path, out: Path) -> None:
    """Compose ``scenario`` into ``out`` recording each layer build's peak RSS [MB] to
    ``out/../layer_peaks.json`` (see the module doc)."""
    peaks: dict[str, float] = {}
    current = ["load"]

    def reset() -> bool:
        try:
            with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
                fh.write("5")
            return True
        except OSError:
            return False

    resettable = reset()

    def progress(done: int, total: int, text: str) -> None:
        peaks[current[0]] = round(_status_kb("VmHWM") / 1024.0, 1)
        current[0] = text.removeprefix("layer ")
        reset()

    compose(load_scenario(scenario), out, yes=True, progress=progress)
    peaks[current[0]] = round(_status_kb("VmHWM") / 1024.0, 1)
    # the phases (load, each layer, writing) cover the run: the largest is the run's peak; without
    # resets VmHWM is the run's peak already
    result = {"peak_mb": max(peaks.values()), "layers": peaks if resettable else {}}
    (Path(out).parent / "layer_peaks.json").write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


def bench_durations(
    out: Path, people: int, durations, fps: float, thermal: str = "fixed", clothing=OUTFIT
) -> dict:
    """:func:`bench_crowd` at each duration (one child each) and the line peak RSS = a + b x
    frames through them: ``peak_mb_per_frame`` (b) and ``peak_mb_at_0`` (a)."""
    runs = [bench_crowd(Path(out) / f"{d:g}s", people, d, fps, thermal, clothing) for d in durations]
    frames = np.array([r["frames"] for r in runs], dtype=float)
    peak = np.array([r["peak_rss_mb"] for r in runs])
    slope, at0 = np.polyfit(frames, peak, 1) if len(runs) > 1 else (float("nan"), float(peak[0]))
    result = {"runs": runs, "peak_mb_per_frame": round(float(slope), 3), "peak_mb_at_0": round(float(at0), 1)}
    (Path(out) / "bench_crowd_durations.json").write_text(
        json.dumps(result, indent=2) + "\n", encoding="utf-8"
    )
    return result


#: a foot's vertex touches the ground while within this height [m] of the foot's lowest level
#: over the clip (a swinging foot passed 4 mm above that level at 30 fps, s7, and must not
#: count): a touching vertex should not move
#: (rolling without slipping, :mod:`humv_usd.human.contact`; the motion code's own report counts
#: its sole points within 1 cm, which a rolling heel or toe moves by rotation alone)
CONTACT_TOL_M = 0.002
#: people whose hips are nearer than this [m] get their surfaces' distance measured
NEAR_M = 1.5


def _people(stage: Usd.Stage) -> list[Usd.Prim]:
    """The people: SkelRoots under /World/Humans with a Body mesh."""
    humans = stage.GetPrimAtPath(SCOPES["humans"])
    return [
        p
        for p in (humans.GetChildren() if humans else [])
        if p.IsA(UsdSkel.Root) and p.GetChild(body_path("p").name).IsA(UsdGeom.Mesh)
    ]


def _stance_slip(xy: np.ndarray, h: np.ndarray, tol: float) -> float:
    """Largest horizontal excursion [m] of a point while it stays in contact: for every point
    (column of ``xy`` (F, n, 2) and ``h`` (F, n)) and every run of frames with ``h <= tol``, the
    distance from where the run began."""
    slip = 0.0
    touch = h <= tol
    for j in np.flatnonzero(touch.any(axis=0)):
        t = np.r_[False, touch[:, j], False].astype(np.int8)
        starts, ends = np.flatnonzero(np.diff(t) == 1), np.flatnonzero(np.diff(t) == -1)
        for a, b in zip(starts, ends, strict=True):
            if b - a > 1:
                slip = max(slip, float(np.linalg.norm(xy[a:b, j] - xy[a, j], axis=1).max()))
    return slip


def motion_figures(stage_path: Path, stride: int = 1, near_m: float = NEAR_M) -> dict:
    """Foot slip and closest approach of the people on a composed stage, measured on what the
    stage holds (independent of the motion code's own ``humv:contact`` report): each Body posed
    by UsdSkel (``SkinningQuery.ComputeSkinnedPoints``), garments from their point caches, all
    in world space, every ``stride``-th frame.

    * foot slip: the Body's ``leftFoot``/``rightFoot`` vertices; a vertex touches while it is
      within :data:`CONTACT_TOL_M` of its foot's lowest level over the clip (the feet are in shoes, so that level is the sole's thickness above the ground);
      slip: the largest horizontal excursion of a vertex during one run of touching frames,
      max per person; beside it the motion's own report (the avatar's ``humv:contact``
      customData, its sole points within 1 cm: :func:`humv_usd.human.contact.contact_report`);
    * closest approach: the smallest horizontal distance between two people's root joints
      (hips) at the same frame, and the smallest distance between their surfaces (Body and
      garment vertices, a k-d tree) over the frames at which their hips are nearer than
      ``near_m``;
    * lowest points: the lowest Body vertex and the lowest garment vertex of any person [m], to
      compare with the ground (z = 0 on flat ground).
    """
    stage = Usd.Stage.Open(str(stage_path))
    fps = stage.GetTimeCodesPerSecond()
    t0, t1 = int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode())
    frames = list(range(t0, t1 + 1, stride))
    people = _people(stage)
    cache = UsdSkel.Cache()
    for p in people:
        cache.Populate(UsdSkel.Root(p), Usd.PrimDefaultPredicate)
    info = []
    for p in people:
        body = p.GetChild(body_path("p").name)
        skel = UsdSkel.BindingAPI(body).GetInheritedSkeleton()
        regions = read_body_regions(body)
        names = list(BODY_REGION_NAMES)
        mesh = UsdGeom.Mesh(body)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
        face_of = np.repeat(np.arange(len(counts)), counts)
        feet = {
            side: np.unique(idx[regions[face_of] == names.index(side)]) for side in ("leftFoot", "rightFoot")
        }
        garments = [UsdGeom.Mesh(g) for g in Usd.PrimRange(p) if g.IsA(UsdGeom.Mesh) and g != body]
        info.append(
            {
                "id": p.GetName(),
                "body": body,
                "query": cache.GetSkinningQuery(body),
                "skel": cache.GetSkelQuery(skel),
                "skel_prim": skel.GetPrim(),
                "feet": feet,
                "garments": garments,
                "contact": dict(p.GetCustomDataByKey("humv:contact") or {}),
            }
        )
    n, F = len(info), len(frames)
    hips = np.zeros((n, F, 2))
    feet_xyz = {(i, s): [] for i in range(n) for s in ("leftFoot", "rightFoot")}
    lowest = {"body": np.inf, "garments": np.inf}
    surface = {}  # (a, b) -> (distance, frame)
    xcache = UsdGeom.XformCache()
    for k, f in enumerate(frames):
        t = Usd.TimeCode(f)
        xcache.SetTime(t)
        pts = []
        for i, d in enumerate(info):
            xforms = d["skel"].ComputeSkinningTransforms(t)
            points = UsdGeom.Mesh(d["body"]).GetPointsAttr().Get(t)
            if not d["query"].ComputeSkinnedPoints(xforms, points, t):
                raise RuntimeError(f"UsdSkel could not skin {d['body'].GetPath()} at {f}")
            m = np.asarray(xcache.GetLocalToWorldTransform(d["skel_prim"]))
            body = np.asarray(points, dtype=np.float64) @ m[:3, :3] + m[3, :3]
            root = np.asarray(d["skel"].ComputeJointSkelTransforms(t)[0])[3, :3] @ m[:3, :3] + m[3, :3]
            hips[i, k] = root[:2]
            for s, v in d["feet"].items():
                feet_xyz[(i, s)].append(body[v])
            parts = [body]
            lowest["body"] = min(lowest["body"], float(body[:, 2].min()))
            for g in d["garments"]:
                gm = np.asarray(xcache.GetLocalToWorldTransform(g.GetPrim()))
                gp = np.asarray(g.GetPointsAttr().Get(t), dtype=np.float64).reshape(-1, 3)
                parts.append(gp @ gm[:3, :3] + gm[3, :3])
            pts.append(np.concatenate(parts))
            if len(parts) > 1:
                lowest["garments"] = min(lowest["garments"], min(float(x[:, 2].min()) for x in parts[1:]))
        for a in range(n):
            for b in range(a + 1, n):
                if np.linalg.norm(hips[a, k] - hips[b, k]) < near_m:
                    dist = float(cKDTree(pts[a]).query(pts[b], k=1)[0].min())
                    if dist < surface.get((a, b), (np.inf,))[0]:
                        surface[(a, b)] = (dist, f)
    per = []
    for i, d in enumerate(info):
        slip = 0.0
        for s in ("leftFoot", "rightFoot"):
            xyz = np.asarray(feet_xyz[(i, s)])  # (F, n, 3)
            h = xyz[..., 2] - xyz[..., 2].min()
            slip = max(slip, _stance_slip(xyz[..., :2], h, CONTACT_TOL_M))
        per.append(
            {
                "id": d["id"],
                "foot_slip_m": round(slip, 4),
                "motion_report_slip_m": d["contact"].get("max_slip_m"),
                "motion_report_penetration_m": d["contact"].get("max_penetration_m"),
            }
        )
    pair_hips = [
        (float(np.linalg.norm(hips[a] - hips[b], axis=1).min()), a, b)
        for a in range(n)
        for b in range(a + 1, n)
    ]
    best = min(pair_hips) if pair_hips else (float("nan"), 0, 0)
    near = min(surface.items(), key=lambda kv: kv[1][0]) if surface else None
    return {
        "stage": str(stage_path),
        "fps": fps,
        "frames_measured": F,
        "stride": stride,
        "people": per,
        "max_foot_slip_m": max((p["foot_slip_m"] for p in per), default=float("nan")),
        "closest_hips_m": round(best[0], 4),
        "closest_hips_pair": [info[best[1]]["id"], info[best[2]]["id"]] if pair_hips else [],
        "closest_surfaces_m": None if near is None else round(near[1][0], 4),
        "closest_surfaces_pair": None if near is None else [info[near[0][0]]["id"], info[near[0][1]]["id"]],
        "closest_surfaces_frame": None if near is None else near[1][1],
        "lowest_body_m": round(lowest["body"], 4),
        "lowest_garment_m": round(lowest["garments"], 4),
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--people", type=int, default=10)
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--durations", type=float, nargs="+", help="several durations [s]: memory against frames")
    ap.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    ap.add_argument(
        "--clothing",
        default=",".join(OUTFIT),
        help="comma-separated garments of every walker; 'none': no clothing key (the default outfit)",
    )
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--thermal", default="fixed", choices=("fixed", "twoNode", "jos3"))
    ap.add_argument(
        "--figures",
        action="store_true",
        help="OUT is a composed stage: print its foot slip and closest approach (motion_figures)",
    )
    ap.add_argument("--stride", type=int, default=1, help="with --figures: every n-th frame")
    a = ap.parse_args(argv)
    if a.child is not None:  # the composing child (see the module doc)
        child_compose(a.child, a.out)
        return
    if a.figures:
        sys.stdout.write(json.dumps(motion_figures(a.out, a.stride), indent=2) + "\n")
        return
    clothing = None if a.clothing == "none" else [c for c in a.clothing.split(",") if c]
    if a.durations:
        result = bench_durations(a.out, a.people, a.durations, a.fps, a.thermal, clothing)
    else:
        result = bench_crowd(a.out, a.people, a.duration, a.fps, a.thermal, clothing)
    sys.stdout.write(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
