"""Person pixel heights of the camera sampler's dataset presets against what the datasets publish
(issue 28): ``python -m humv_usd.bench.viewpoints [N] [SEED]``.

For each viewpoint preset (:mod:`humv_usd.catalog.viewpoints`) the sweep's camera sampler
(:func:`humv_usd.sweep.cameras.sample_view`) draws N poses around one standing adult of
:data:`STATURE_M` with no occluder; the person's box height [px] is the projected cylinder's
(:func:`humv_usd.sweep.cameras.person_box_px`). Where the preset has published bins
(``published_bins_px``: edges and the fraction of the dataset's person boxes in each), the table
gives the sampled fraction per bin, the published one and their total variation distance
(half the sum of absolute differences, 0 = the same histogram, 1 = disjoint); where a dataset
publishes only bin edges (KAIST's near/medium/far), the sampled fractions alone. Where a dataset
publishes box-area bins instead (``published_area_bins_px2``: LTD's small / medium / large), the
same comparison for the area [px^2] of the person's box (height x width of the projected
cylinder, re-projected from each drawn pose).
"""

from __future__ import annotations

import datetime as dt
import sys

import numpy as np

from humv_usd.catalog.viewpoints import VIEWPOINTS
from humv_usd.geometry.camera import Camera, CameraPose
from humv_usd.geometry.rig import camera_axes, direction_angles
from humv_usd.physics.sensor import field_of_view_deg
from humv_usd.scenario import validate
from humv_usd.sweep.cameras import parse_camera, person_box_px, sample_view, with_sensor_keys

#: Stature of the sampled person [m]: the mean adult of ANSUR II's men and women (1.756 m and
#: 1.629 m, equal weights; humv_usd.human.population).
STATURE_M = 1.69


def base_scenario() -> dict:
    """One standing adult at the origin and one sensor (replaced by the preset's), no scene."""
    return {
        "general": {
            "name": "viewpoints",
            "start": dt.datetime(2024, 6, 21, 12, 0),
            "utc_offset_h": 0.0,
            "latitude_deg": 50.0,
            "longitude_deg": 0.0,
            "fps": 1.0,
        },
        "human": [{"id": "p1", "sex": "male", "stature_m": STATURE_M, "activity": "stand"}],
        "placement": [{"human": "p1", "position_m": [0.0, 0.0, 0.0]}],
        "sensor": [
            {"id": "cam", "preset": "tau2_640", "position_m": [0.0, -10.0, 1.5], "look_at_m": [0.0, 0.0, 1.0]}
        ],
    }


def _views(name: str, n: int, seed: int):
    """(validated scenario, sampler, the ``n`` drawn views) of viewpoint preset ``name`` (the
    sweep's per-variant seeding, ``default_rng([seed, k, 28])``)."""
    problems: list[str] = []
    sampler = parse_camera({"preset": name}, problems)
    if problems:
        raise ValueError("; ".join(problems))
    scenario = validate(with_sensor_keys(base_scenario(), sampler))
    views = [sample_view(sampler, scenario, np.random.default_rng([seed, k, 28])) for k in range(n)]
    return scenario, sampler, views


def sample_heights(name: str, n: int, seed: int = 0) -> np.ndarray:
    """Person box heights [px] of ``n`` poses of viewpoint preset ``name``."""
    return np.array([v["person_height_px"] for v in _views(name, n, seed)[2]])


def sample_boxes(name: str, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(heights, widths) [px] of the person's box in ``n`` poses of preset ``name``: each drawn
    pose (position, look-at point, roll) re-projected through the sensor's pinhole camera."""
    scenario, sampler, views = _views(name, n, seed)
    s = scenario["sensor"][sampler.sensor]
    w, h = (int(v) for v in s["resolution"])
    fov_x = field_of_view_deg(w * s["pixel_pitch_um"] * 1e-6, s["focal_length_mm"] * 1e-3)
    out = []
    for v in views:
        eye = np.asarray(v["position_m"], float)
        az, el = direction_angles(np.asarray(v["look_at_m"], float) - eye)
        fwd, up = camera_axes(float(az), float(el), v["roll_deg"])
        camera = Camera.from_pose(CameraPose(eye, fwd, up, fov_x), w, h)
        out.append(person_box_px(camera, np.zeros(3), STATURE_M)[:2])
    heights, widths = np.array(out).T
    return heights, widths


def bin_fractions(heights, edges) -> np.ndarray:
    """Fraction of ``heights`` in each bin [edges[i], edges[i+1])."""
    counts, _ = np.histogram(np.asarray(heights, float), bins=np.asarray(edges, float))
    return counts / max(len(heights), 1)


def compare(name: str, n: int, seed: int = 0) -> dict:
    """Sampled statistics of preset ``name`` and, where published, the bin fractions side by side
    with the total variation distance."""
    vp = VIEWPOINTS[name]
    if vp.published_area_bins_px2:
        h, w = sample_boxes(name, n, seed)
    else:
        h = sample_heights(name, n, seed)
    out = {
        "preset": name,
        "n": n,
        "median": float(np.median(h)),
        "p10": float(np.percentile(h, 10)),
        "p90": float(np.percentile(h, 90)),
    }
    if vp.published_bins_px:
        edges, published = vp.published_bins_px
        sampled = bin_fractions(h, edges)
        out["edges"] = list(edges)
        out["sampled"] = sampled.tolist()
        if published:
            out["published"] = list(published)
            out["tv_distance"] = float(0.5 * np.abs(sampled - np.asarray(published)).sum())
    if vp.published_area_bins_px2:
        edges, published = vp.published_area_bins_px2
        sampled = bin_fractions(h * w, edges)
        out["area_edges"] = list(edges)
        out["area_sampled"] = sampled.tolist()
        out["area_published"] = list(published)
        out["area_tv_distance"] = float(0.5 * np.abs(sampled - np.asarray(published)).sum())
    return out


def table(n: int = 200, seed: int = 0) -> str:
    """The comparison of every preset as text."""
    lines = [f"{'preset':10s} {'median':>7s} {'p10':>6s} {'p90':>6s}  bins [px]: sampled / published"]
    for name in VIEWPOINTS:
        r = compare(name, n, seed)
        row = f"{name:10s} {r['median']:7.1f} {r['p10']:6.1f} {r['p90']:6.1f}"
        if "edges" in r:
            e = r["edges"]
            pub = r.get("published") or [None] * len(r["sampled"])
            cells = [
                f"{e[i]:g}-{e[i + 1]:g}: {s:.2f}" + ("" if p is None else f"/{p:.2f}")
                for i, (s, p) in enumerate(zip(r["sampled"], pub))
            ]
            row += "  " + "; ".join(cells)
            if "tv_distance" in r:
                row += f"  (TV distance {r['tv_distance']:.2f})"
            else:
                row += "  (no published fractions)"
        elif "area_edges" not in r:
            row += "  (no published histogram)"
        if "area_edges" in r:
            e = r["area_edges"]
            cells = [
                f"{e[i]:g}-{e[i + 1]:g}: {s:.3f}/{p:.3f}"
                for i, (s, p) in enumerate(zip(r["area_sampled"], r["area_published"]))
            ]
            row += "  box area [px^2]: " + "; ".join(cells) + f"  (TV distance {r['area_tv_distance']:.2f})"
        lines.append(row)
    return "\n".join(lines)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    n = int(argv[0]) if argv else 200
    seed = int(argv[1]) if len(argv) > 1 else 0
    print(table(n, seed))  # noqa: T201
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
