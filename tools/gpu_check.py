"""Check the render on a GPU: time per frame and agreement with the CPU render.

Run on a machine with an NVIDIA GPU and humv-usd installed (the CPU backend needs Debian's
libllvm19, as everywhere)::

    python tools/gpu_check.py STAGE --out DIR [--sensor NAME] [--frames 0:7] [--backends cuda,llvm] [--resolution WxH]

It renders STAGE's frames once per backend, each in a fresh process (Mitsuba has one variant per
process), with the same seed and the default automatic quality, into ``DIR/<backend>/`` with
``humv_usd.pipeline.render.render_stage`` (the code ``humv-usd render --backend`` runs), then
prints per backend the time per frame (median over the frames after the first, which also
compiles the kernels; the first separately) split into the render's stages from the manifest,
and per pair of backends the agreement of each frame:

- **radiance**: the image's (and the people's) mean difference in units of its standard error,
  mean z = mean(L_a - L_b) / (sqrt(sum(s_a^2 + s_b^2)) / n): two unbiased renders give |mean z|
  < 3 but for 1 in 370; and per pixel z = (L_a - L_b) / sqrt(s_a^2 + s_b^2) from each render's
  own Monte Carlo standard error, whose mean is ~0 and standard deviation ~1 when the stated
  errors are good (a bit less where the render filters, more at geometric edges and where a
  frame stopped after few batches: the error of a pixel from one or two batches has heavy
  tails); the fraction of |z| > 4 is printed with what a normal distribution gives (6e-5), and
  the share of pixels that differ where neither render stated an error;
- **labels**: the share of pixels whose instance id differs (the label ray cast runs on the same
  backend as the render: edge pixels may flip at float rounding) and the largest depth
  difference.

A GPU machine without the full set-up can split the work: ``render`` on the GPU machine with
``--export DIR`` (compact ``.npz`` per frame: radiance, its error, instance id, depth), then
``compare`` on any machine against a CPU render of the same stage and frames.

Visible (EO) cameras are compared on their luminance Y with its error ``Y_stderr``; infrared,
NIR and SWIR cameras on their band radiance.

Before rendering it checks that this Python can import what the render needs
(:data:`RENDER_PACKAGES`; a GPU machine without network gets them carried as wheels, see
docs/user/gpu.md) and names the missing ones in one line (exit 2) instead of a traceback.

Subcommands: ``check`` (default: render every backend, compare; exit 1 when a backend failed),
``render`` (one backend), ``compare A B`` (two render folders or exports), ``needs`` (the
packages the render imports and whether this Python has them). Writes ``DIR/gpu_check.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: Stages of a frame in the manifest's per-frame ``timings_s`` (render includes the estimator).
STAGES = ("load_export", "render", "estimator", "labels", "write", "cpu")
#: label class of people (its class_id: the index in humv_usd.groundtruth.labels.CLASSES, read
#: where the labels are compared, so that this tool imports the package only when it needs it)
PERSON_LABEL = "person"
#: The fraction of |z| > 4 for a standard normal variable (two-sided).
NORMAL_TAIL_4 = 6.33e-5
#: What a render needs beyond the standard library, as import name -> distribution. Measured
#: (``python -X importtime -m humv_usd.cli.main render ...`` of stages with LWIR, EO, NIR and SWIR
#: cameras, 2026-11-27): numpy, scipy, usd-core, OpenEXR, OpenImageIO and ephem on import,
#: mitsuba and drjit when the variant is chosen, pycocotools for the COCO labels; pvlib only for
#: its ASTM G173 table (``data/ASTMG173.csv``, read with numpy by
#: :func:`humv_usd.physics.sun.reference_solar_spectrum`: a material's solar absorptivity).
#: Optional: embreex (the labels' CPU ray caster; without it, and always on CUDA, Mitsuba casts
#: them). ``tests/test_gpu_check.py`` checks that the render's modules import nothing else.
RENDER_PACKAGES = {
    "numpy": "numpy",
    "scipy": "scipy",
    "pxr": "usd-core",
    "OpenEXR": "OpenEXR",
    "OpenImageIO": "OpenImageIO",
    "ephem": "ephem",
    "mitsuba": "mitsuba",
    "drjit": "drjit",
    "pycocotools": "pycocotools",
    "pvlib": "pvlib",
}


def missing_packages(packages: dict | None = None) -> list[str]:
    """Distributions of :data:`RENDER_PACKAGES` this Python cannot import (found without
    importing them)."""
    import importlib.util

    out = []
    for module, dist in (RENDER_PACKAGES if packages is None else packages).items():
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            out.append(dist)
    return out


def _needs_line(missing: list[str]) -> str:
    """One line naming what this Python lacks for the render."""
    return (
        f"gpu_check: this Python ({sys.version.split()[0]} at {sys.executable}) cannot import "
        f"{', '.join(missing)}, which the render needs: install them, or on a machine without network "
        "carry them as wheels for this Python (docs/user/gpu.md, 'Carrying the set-up')"
    )


def _parse_frames(text: str | None) -> list[int] | None:
    """``A:B`` (inclusive), ``a,b,c`` or one number."""
    if not text:
        return None
    if ":" in text:
        lo, hi = (int(v) for v in text.split(":"))
        return list(range(lo, hi + 1))
    return [int(v) for v in text.split(",")]


def _render(
    stage: str, out: str, backend: str, frames: str | None, sensor: str | None, seed: int, resolution=None
) -> dict:
    """Render in this process with ``backend`` forced (``resolution``: "WxH", every sensor at
    that pixel count, as ``render --resolution``); returns the timing summary."""
    sys.path.insert(0, str(ROOT))
    from humv_usd import mode
    from humv_usd.pipeline.render import render_stage

    mode.set_backend(backend)
    t0 = time.perf_counter()
    mi = mode.mitsuba()
    start_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    manifest = render_stage(
        stage,
        out,
        frames=_parse_frames(frames),
        sensors=[sensor] if sensor else None,
        seed=seed,
        force=True,
        yes=True,
        resolution=tuple(int(v) for v in resolution.lower().split("x")) if resolution else None,
    )
    wall = time.perf_counter() - t0
    summary = {
        "backend": backend,
        "variant": mode.variant(),
        "variant_reason": mode.variant_reason(),
        "mitsuba": mi.__version__,
        "mitsuba_start_s": start_s,
        "wall_s": wall,
        "sensors": {},
    }
    for s in manifest["sensors"] + manifest.get("eo_sensors", []):
        frames_ = s.get("frames", [])
        per = {k: [f["timings_s"].get(k, 0.0) for f in frames_] for k in STAGES}
        rest = {k: v[1:] for k, v in per.items()} if len(frames_) > 1 else per
        summary["sensors"][s.get("name", s.get("id", "?"))] = {
            "frames": [f["frame"] for f in frames_],
            "first_frame_s": {k: v[0] for k, v in per.items() if v},
            "median_frame_s": {k: statistics.median(v) for k, v in rest.items() if v},
            # infrared/NIR/SWIR: the automatic quality's batches; EO: the samples per pixel used
            "batches": [
                f.get("quality", {}).get("batches", f.get("monte_carlo_error_relative", {}).get("spp_used"))
                for f in frames_
            ],
            "quality_met": [f.get("quality", {}).get("met") for f in frames_],
            "exr": [f["exr"] for f in frames_],
        }
    return summary


def _export(render_dir: str, summary: dict, export_dir: str, frames=None) -> list[str]:
    """Compact per-frame arrays of a render for :func:`compare` elsewhere (``frames``: only
    these)."""
    sys.path.insert(0, str(ROOT))
    from humv_usd.images import read_exr

    os.makedirs(export_dir, exist_ok=True)
    written = []
    for name, s in summary["sensors"].items():
        for frame, rel in zip(s["frames"], s["exr"]):
            if frames is not None and frame not in frames:
                continue
            ch = read_exr(os.path.join(render_dir, rel))
            value, stderr = _measured(ch)
            path = os.path.join(export_dir, f"{summary['backend']}_{name}_{frame:04d}.npz")
            np.savez_compressed(
                path,
                radiance=value.astype(np.float32),
                radiance_stderr=stderr.astype(np.float32),
                instance_id=ch["instance_id"].astype(
                    np.int16 if ch["instance_id"].max() < 2**15 else np.int32
                ),
                depth=ch["depth"].astype(np.float32),
                # the people's statistics need each pixel's class
                **({"class_id": ch["class_id"].astype(np.int16)} if "class_id" in ch else {}),
            )
            written.append(path)
    with open(os.path.join(export_dir, f"{summary['backend']}_summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    return written


def _measured(ch: dict) -> tuple[np.ndarray, np.ndarray]:
    """(value, its Monte Carlo standard error) an image is compared on: the band radiance of an
    infrared, NIR or SWIR image, the luminance Y of a visible (EO) one."""
    if "radiance" in ch:
        return ch["radiance"], ch["radiance_stderr"]
    return ch["Y"], ch["Y_stderr"]


def _frames_of(where: str) -> dict[tuple[str, int], dict]:
    """(sensor, frame) -> arrays, from a render folder (manifest.json) or an export folder."""
    out = {}
    manifest = os.path.join(where, "manifest.json")
    if os.path.exists(manifest):
        sys.path.insert(0, str(ROOT))
        from humv_usd.images import read_exr

        with open(manifest) as f:
            m = json.load(f)
        for s in m["sensors"] + m.get("eo_sensors", []):
            for fr in s["frames"]:
                ch = read_exr(os.path.join(where, fr["exr"]))
                value, stderr = _measured(ch)
                out[(s.get("name", s.get("id")), fr["frame"])] = {
                    "radiance": value,
                    "radiance_stderr": stderr,
                    **{k: ch[k] for k in ("instance_id", "class_id", "depth") if k in ch},
                }
        return out
    for p in sorted(Path(where).glob("*_*_[0-9][0-9][0-9][0-9].npz")):
        _, rest = p.stem.split("_", 1)
        name, frame = rest.rsplit("_", 1)
        with np.load(p) as z:
            out[(name, int(frame))] = {k: z[k] for k in z.files}
    return out


def _z_stats(d: np.ndarray, s2: np.ndarray) -> dict:
    """Per-pixel z = d / sqrt(s2) (pixels with an error) and the region's mean difference in
    units of its own standard error, ``mean_z`` = mean(d) / (sqrt(sum s2) / n) over every pixel
    (pixels' errors independent). A per-pixel error estimated from few batches has heavy tails
    (an EO frame that stopped at one batch: |z| > 4 in 2 % of the pixels between two CPU seeds),
    while ``mean_z`` pools them: a bias between two backends shows there first. ``silent``:
    the share of pixels that differ where both stated no error at all."""
    n = int(d.size)
    if n == 0:
        return {"pixels": 0}
    has = s2 > 0
    z = d[has] / np.sqrt(s2[has])
    total = float(s2.sum())
    out = {
        "pixels": n,
        "mean_z": float(d.mean() / (np.sqrt(total) / n))
        if total > 0
        else (0.0 if not d.any() else float("inf")),
        "silent": float(np.mean(~has & (d != 0.0))),
    }
    if z.size:
        out.update(mean=float(z.mean()), std=float(z.std()), beyond_4=float(np.mean(np.abs(z) > 4.0)))
    return out


def compare(a: str, b: str) -> dict:
    """Agreement of two renders of the same stage, frames and sensors (see the module text)."""
    fa, fb = _frames_of(a), _frames_of(b)
    common = sorted(set(fa) & set(fb))
    if not common:
        raise SystemExit(
            f"compare: no (sensor, frame) in both {a} ({sorted(fa)[:3]}) and {b} ({sorted(fb)[:3]})"
        )
    sys.path.insert(0, str(ROOT))
    from humv_usd.groundtruth.labels import CLASSES

    person_class = CLASSES.index(PERSON_LABEL)
    result = {"frames": []}
    for key in common:
        x, y = fa[key], fb[key]
        s2 = x["radiance_stderr"].astype(float) ** 2 + y["radiance_stderr"].astype(float) ** 2
        d = x["radiance"].astype(float) - y["radiance"].astype(float)
        ok = np.isfinite(d) & np.isfinite(s2)
        cls = x["class_id"] if "class_id" in x else y.get("class_id")
        people = np.zeros(d.shape, bool) if cls is None else np.asarray(cls) == person_class
        same_id = x["instance_id"].astype(np.int64) == y["instance_id"].astype(np.int64)
        finite = np.isfinite(x["depth"]) & np.isfinite(y["depth"])
        depth = float(np.max(np.abs(x["depth"][finite] - y["depth"][finite]))) if finite.any() else 0.0
        result["frames"].append(
            {
                "sensor": key[0],
                "frame": key[1],
                "all": _z_stats(d[ok], s2[ok]),
                "people": _z_stats(d[ok & people], s2[ok & people]),
                "relative_mean_difference": float(
                    (x["radiance"].mean() - y["radiance"].mean()) / max(abs(y["radiance"].mean()), 1e-30)
                ),
                "label_pixels_differing": float(1.0 - same_id.mean()),
                "depth_max_difference_m": depth,
            }
        )
    return result


def _print_compare(name: str, res: dict) -> None:
    print(
        f"agreement {name} (z = difference / combined Monte Carlo error; normal: std 1, |z|>4 {NORMAL_TAIL_4:.0e})"
    )
    for f in res["frames"]:
        al, pe = f["all"], f["people"]
        nan = float("nan")
        print(
            f"  {f['sensor']} frame {f['frame']:>3}: image mean z {al.get('mean_z', nan):+.2f}, people "
            f"({pe.get('pixels', 0)} px) {pe.get('mean_z', nan):+.2f} (|mean z| < 3 agrees); per pixel z mean "
            f"{al.get('mean', nan):+.3f} std {al.get('std', nan):.3f} |z|>4 {al.get('beyond_4', nan):.1e}, "
            f"people std {pe.get('std', nan):.3f} |z|>4 {pe.get('beyond_4', nan):.1e}; differing without an "
            f"error {al.get('silent', nan):.1e}; mean {f['relative_mean_difference']:+.1e} relative; "
            f"labels differ {f['label_pixels_differing']:.1e}, depth {f['depth_max_difference_m']:.1e} m"
        )


def _print_summary(s: dict) -> None:
    print(
        f"{s['backend']}: {s['variant']} ({s['variant_reason']}); Mitsuba start {s['mitsuba_start_s']:.2f} s, render {s['wall_s']:.1f} s"
    )
    for name, v in s["sensors"].items():
        n = len(v["frames"])
        med = v["median_frame_s"]
        first = v["first_frame_s"]
        parts = ", ".join(f"{k} {med[k]:.3f}" for k in STAGES if k in med)
        fps = 1.0 / med["render"] if med.get("render") else float("nan")
        print(
            f"  {name}: {n} frames, sample batches {v['batches']}, quality met {v['quality_met']}; median s/frame: {parts} (render only: {fps:.2f} frames/s)"
        )
        print(
            f"  {name}: first frame (compiles kernels): "
            + ", ".join(f"{k} {first[k]:.3f}" for k in STAGES if k in first)
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd")
    for name in ("check", "render"):
        p = sub.add_parser(name)
        p.add_argument("stage")
        p.add_argument("--out", required=True)
        p.add_argument("--frames", default="0:7")
        p.add_argument("--sensor", default=None)
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--resolution", default=None, help="WxH: every sensor at this pixel count")
        if name == "check":
            p.add_argument("--backends", default="cuda,llvm")
        else:
            p.add_argument("--backend", default="cuda")
            p.add_argument("--export", default=None, help="write compact per-frame .npz here")
            p.add_argument("--export-frames", default=None, help="only these frames (default: all)")
            p.add_argument(
                "--log", default=None, help="debug log of the render (estimator timings) to this file"
            )
    p = sub.add_parser("compare")
    p.add_argument("a")
    p.add_argument("b")
    sub.add_parser("needs")
    args = ap.parse_args(argv)

    if args.cmd == "needs":
        missing = missing_packages()
        for module, dist in RENDER_PACKAGES.items():
            print(f"  {dist:14s} (import {module}): {'MISSING' if dist in missing else 'ok'}")
        if missing:
            print(_needs_line(missing))
        return 2 if missing else 0
    if args.cmd in ("render", "check") and (missing := missing_packages()):
        print(_needs_line(missing), file=sys.stderr)
        return 2

    if args.cmd == "render":
        if args.log:
            import logging

            logging.basicConfig(
                filename=args.log, level=logging.INFO, format="%(relativeCreated)9.0f %(name)s %(message)s"
            )
            logging.getLogger("humv_usd.render").setLevel(logging.DEBUG)
        out = os.path.join(args.out, args.backend)
        summary = _render(args.stage, out, args.backend, args.frames, args.sensor, args.seed, args.resolution)
        with open(os.path.join(args.out, f"{args.backend}_summary.json"), "w") as f:
            json.dump(summary, f, indent=1)
        _print_summary(summary)
        if args.export:
            for path in _export(out, summary, args.export, _parse_frames(args.export_frames)):
                print(f"  exported {path}")
        return 0
    if args.cmd == "compare":
        res = compare(args.a, args.b)
        _print_compare(f"{args.a} vs {args.b}", res)
        return 0
    if args.cmd != "check":
        ap.print_help()
        return 2
    backends = [b for b in args.backends.split(",") if b]
    report = {"backends": {}, "agreement": {}, "failed": {}}
    for backend in backends:
        cmd = [sys.executable, __file__, "render", args.stage, "--out", args.out, "--backend", backend]
        cmd += ["--frames", args.frames, "--seed", str(args.seed)] + (
            ["--sensor", args.sensor] if args.sensor else []
        )
        cmd += ["--resolution", args.resolution] if args.resolution else []
        run = subprocess.run(cmd, text=True, capture_output=True)
        sys.stdout.write(run.stdout)
        if run.returncode != 0:
            why = run.stderr.strip().splitlines()[-1] if run.stderr.strip() else f"exit {run.returncode}"
            report["failed"][backend] = why
            print(f"{backend}: failed ({why})")
            continue
        with open(os.path.join(args.out, f"{backend}_summary.json")) as f:
            report["backends"][backend] = json.load(f)
    done = list(report["backends"])
    for i, a in enumerate(done):
        for b in done[i + 1 :]:
            res = compare(os.path.join(args.out, a), os.path.join(args.out, b))
            report["agreement"][f"{a}-{b}"] = res
            _print_compare(f"{a} vs {b}", res)
    with open(os.path.join(args.out, "gpu_check.json"), "w") as f:
        json.dump(report, f, indent=1)
    return 1 if report["failed"] or not done else 0


if __name__ == "__main__":
    sys.exit(main())
