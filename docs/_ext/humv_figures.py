"""The physics pages' bench figures, drawn at build time from the committed CSVs of
``docs/physics/data/`` (written by ``make docs-data``, i.e. ``docs/_ext/bench_data.py``).

On ``builder-inited`` every figure whose CSV (or this file) is newer than its SVG is drawn again
into ``docs/physics/_figures/`` (git-ignored): a build after a fresh clone draws them once
(about a second with matplotlib's SVG backend), later builds reuse them. The pages include them
with ``.. figure:: _figures/<name>.svg``.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "physics" / "data"
FIGURES = HERE.parent / "physics" / "_figures"


def read_csv(path: Path) -> tuple[list[str], list[dict]]:
    """(the ``#`` header lines, the rows as dicts of str) of a bench CSV."""
    lines = path.read_text().splitlines()
    header = [ln[1:].strip() for ln in lines if ln.startswith("#")]
    rows = list(csv.DictReader(ln for ln in lines if not ln.startswith("#")))
    return header, rows


def _f(row: dict, key: str) -> float:
    v = row.get(key, "")
    return float(v) if v not in ("", None) else float("nan")


def _footer(fig, header: list[str]) -> None:
    import textwrap

    text = "\n".join(textwrap.fill(h, 150) for h in header)
    fig.text(0.01, 0.005, text, fontsize=6, color="0.4", va="bottom")


def _log_axes(ax, xlabel: str, ylabel: str, *, xbase: int = 10, legend_right: bool = False) -> None:
    """Log-log axes with their labels, a small legend (right of the plot with ``legend_right``)
    and a light grid: the look of every bench figure."""
    ax.set_xscale("log", base=xbase)
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7, **({"loc": "center left", "bbox_to_anchor": (1.02, 0.5)} if legend_right else {}))
    ax.grid(True, which="both", lw=0.3)


def _spp_curve(ax, pts, label: str) -> None:
    """A cost-error curve of (CPU s, error, spp) points, each point marked with its spp."""
    ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=label)
    for x, y, spp in pts:
        ax.annotate(f"{spp} spp", (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")


def render_error_time(ax_pair, rows, spectral):
    """Left: Monte Carlo error away from edges against CPU time; right: the sub-band model's
    spectral error against the sub-band count."""
    ax, ax2 = ax_pair
    fast = [r for r in rows if r["estimator"] == "fast"]
    for n in sorted({int(r["subbands"]) for r in fast}):
        pts = sorted(
            (_f(r, "cpu_s"), _f(r, "mc_error_mean_k"), int(r["spp"])) for r in fast if int(r["subbands"]) == n
        )
        pts = [p for p in pts if p[1] == p[1]]  # 1 spp states no error of its own
        _spp_curve(ax, pts, f"fast estimator, {n} sub-bands")
    for r in rows:
        if r["estimator"] == "path":
            ax.plot(
                _f(r, "cpu_s"), _f(r, "mc_error_mean_k"), "s", color="C3", label=f"path tracer {r['spp']} spp"
            )
        if r["estimator"] == "reference":
            netd = _f(r, "netd_k")
            ax.axhline(netd / 3, color="0.5", ls="--", lw=0.8, label=f"NETD/3 = {1000 * netd / 3:.1f} mK")
    _log_axes(ax, "CPU time of the band render [s]", "MC error, mean away from edges [K]")
    for sensor in sorted({r["sensor"] for r in spectral}):
        pts = sorted(
            (int(r["subbands"]), _f(r, "max_k"), _f(r, "rms_k")) for r in spectral if r["sensor"] == sensor
        )
        ax2.plot([p[0] for p in pts], [max(p[1], 1e-5) for p in pts], "o-", label=f"{sensor} max")
        ax2.plot([p[0] for p in pts], [max(p[2], 1e-5) for p in pts], "o--", label=f"{sensor} rms")
    _log_axes(ax2, "sub-bands", "spectral error of the sub-band model [K]", xbase=2)


def eo_error_time(ax, rows):
    """The EO render's error of Y relative to the mean Y (away from edges) against CPU time."""
    fast = [r for r in rows if r["estimator"] == "fast"]
    for n in sorted({int(r["bins"]) for r in fast}):
        pts = sorted(
            (_f(r, "cpu_s"), _f(r, "rel_error_mean"), int(r["spp"])) for r in fast if int(r["bins"]) == n
        )
        _spp_curve(ax, pts, f"fast EO estimator, {n} bins")
    for r in rows:
        if r["estimator"] in ("path", "reference"):
            what = "spectral path tracer" if r["estimator"] == "path" else "reference, spectral path tracer"
            ax.plot(
                _f(r, "cpu_s"),
                _f(r, "rel_error_mean"),
                "s" if r["estimator"] == "path" else "D",
                label=f"{what} {r['spp']} spp",
            )
    _log_axes(ax, "CPU time of the render [s]", "error of Y / mean Y, away from edges", legend_right=True)


def qrad_error_time(ax, rows):
    """The absorbed radiation's rms relative error against CPU time by method and map size."""
    groups: dict[tuple[str, str], list] = {}
    for r in rows:
        if r["method"] == "brute" and _f(r, "rms_rel_error") == 0.0:
            ax.axvline(
                _f(r, "cpu_seconds"), color="0.5", ls=":", lw=0.8, label=f"brute reference {r['resolution']}²"
            )
            continue
        groups.setdefault((r["method"], r["resolution"]), []).append(r)
    for (method, res), rs in sorted(groups.items()):
        pts = sorted((_f(r, "cpu_seconds"), max(_f(r, "rms_rel_error"), 1e-6)) for r in rs)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=f"{method}, map {res}²")
    ax.axhline(0.01, color="0.5", ls="--", lw=0.8, label="1 % rms")
    _log_axes(ax, "CPU time [s]", "rms relative error of q_rad", legend_right=True)


def time_steps(ax_pair, garment, skin):
    """Garment and two-node skin temperature error against the time step."""
    ax, ax2 = ax_pair
    for i, case in enumerate(sorted({r["case"] for r in garment})):
        pts = sorted(
            (_f(r, "step_s"), _f(r, "max_error_k"), _f(r, "common_error_k"))
            for r in garment
            if r["case"] == case
        )
        for k, style, when in ((1, "o-", "over the step ends"), (2, "s--", "every 1800 s")):
            steps, errors = [p[0] for p in pts], [max(p[k], 1e-9) for p in pts]
            ax.plot(steps, errors, style, color=f"C{i}", label=f"{case}, {when}")
    ax.set_title("garment (implicit step vs Radau)", fontsize=8)
    for model in sorted({r["model"] for r in skin}):
        pts = sorted((_f(r, "step_s"), _f(r, "max_error_k")) for r in skin if r["model"] == model)
        ax2.plot([p[0] for p in pts], [max(p[1], 1e-9) for p in pts], "o-", label=model)
    ax2.set_title("mean skin (vs the finest step)", fontsize=8)
    for a in (ax, ax2):
        _log_axes(a, "time step [s]", "largest temperature error [K]")


def _draw(name: str, csvs: list[str], plot, panels: int, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = [read_csv(DATA / c) for c in csvs]
    fig, axes = plt.subplots(1, panels, figsize=(4.4 * panels if panels > 1 else 7.5, 3.8))
    plot(axes, *[rows for _, rows in data])
    _footer(fig, data[0][0])
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    tmp = out.with_suffix(".tmp.svg")
    plt.rcParams["svg.hashsalt"] = name  # stable ids: the same CSV gives the same file
    fig.savefig(tmp, format="svg", metadata={"Date": None})
    plt.close(fig)
    os.replace(tmp, out)


#: figure name -> (its CSVs, the plot function, panels)
FIGURE_SPECS = {
    "render_error_time": (["render_error_time.csv", "subband_error.csv"], render_error_time, 2),
    "eo_error_time": (["eo_error_time.csv"], eo_error_time, 1),
    "qrad_error_time": (["qrad_error_time.csv"], qrad_error_time, 1),
    "thermal_time_steps": (["garment_time_steps.csv", "skin_time_steps.csv"], time_steps, 2),
}


def draw_figures(force: bool = False) -> list[Path]:
    """Draw every figure whose inputs are newer than its SVG; the SVGs drawn."""
    FIGURES.mkdir(exist_ok=True)
    drawn = []
    code = Path(__file__).stat().st_mtime
    for name, (csvs, plot, panels) in FIGURE_SPECS.items():
        out = FIGURES / f"{name}.svg"
        newest = max([code] + [(DATA / c).stat().st_mtime for c in csvs])
        if force or not out.is_file() or out.stat().st_mtime < newest:
            _draw(name, csvs, plot, panels, out)
            drawn.append(out)
    return drawn


def setup(app):
    app.connect("builder-inited", lambda app: draw_figures())
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
