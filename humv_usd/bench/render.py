"""``humv-usd bench render``: infrared error against run time, bias against a brute-force reference.

For the first frame of a composed stage and each infrared sensor, the scene is built once and
then rendered

- by the reference: the plain path tracer (:func:`humv_usd.render.ir.render_band`, Mitsuba's
  ``path`` integrator, independent samples) at ``reference_spp`` samples per pixel and
  ``reference_subbands`` sub-bands;
- by the fast estimator (:func:`humv_usd.render.estimator.render_band_fast`) for every (spp,
  sub-bands) pair of the sweep, and by the path tracer at the former default (16 spp over 4
  sub-bands) for comparison;

and reports per setting: wall and CPU seconds of the band render, the ratio of that wall time
to the pixel-centre ray cast of the same frame (the labels' cast: the physical lower bound of a
frame), the per-pixel Monte Carlo standard error in K (mean and 99th percentile away from
geometric edges; edge pixels apart: their spread is the pixel footprint, signal), and the bias
against the reference: the mean brightness-temperature difference over each labelled region
(instance id; 0 = sky) [K] with its 1-sigma uncertainty from both renders' errors. Curves of
error against run time per sensor band go to a PNG (matplotlib), the default setting marked.
"""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np
from pxr import Usd

from humv_usd.physics import planck
from humv_usd.render import estimator as E
from humv_usd.render import radiometry
from humv_usd.render.export import StageExport
from humv_usd.render.frame import path_table, stage_frames
from humv_usd.render.ir import IRScene, SensorSetup, render_band, subband_spp
from humv_usd.usd import environment as usd_environment
from humv_usd.usd.atmosphere import atmosphere_spectra
from humv_usd.usd.layers import open_stage
from humv_usd.usd.materials import subband_emissivity, subband_transmittance

#: The former default of the path tracer (16 spp split over 4 sub-bands), for comparison.
PATH_BASELINE = (16, 4)


def region_bias(radiance, radiance_ref, stderr, stderr_ref, regions, band, response) -> dict:
    """Per region id: the difference of the region's mean radiance from the reference's, in K
    (divided by dL/dT at the reference region mean's brightness temperature, so that pixel noise
    does not bias it through the non-linear brightness temperature), with its 1-sigma
    uncertainty from both renders' per-pixel errors."""
    out = {}
    for r in np.unique(regions):
        m = (regions == r) & np.isfinite(radiance) & np.isfinite(radiance_ref)
        if not m.any():
            continue
        ref_mean = float(np.mean(radiance_ref[m]))
        _, dl = planck.brightness_temperature_sensitivity(np.array([ref_mean]), band, response)
        dl = float(dl[0])
        var = np.nan_to_num(stderr[m]) ** 2 + np.nan_to_num(stderr_ref[m]) ** 2
        out[int(r)] = {
            "pixels": int(m.sum()),
            "bias_k": float((np.mean(radiance[m]) - ref_mean) / dl) if dl > 0 else None,
            "sigma_k": float(np.sqrt(var.sum()) / m.sum() / dl) if dl > 0 else None,
        }
    return out


class _Frame:
    """One frame of a stage with its IR scene built once (as ``pipeline.render`` does), ready to
    render any IR sensor repeatedly."""

    def __init__(self, stage_path, frame=None):
        stage = open_stage(stage_path)
        self.stage = stage
        self.exporter = StageExport(stage)
        self.rendered = [s for s in self.exporter.sensors if s.rendered and s.kind != "EO"]
        self.frame = stage_frames(stage)[0] if frame is None else int(frame)
        self.state = self.exporter.frame_state(self.frame, self.rendered)
        self.time = Usd.TimeCode(self.frame)
        self.spectra = atmosphere_spectra(stage, self.time)
        self.sensor_ids = {s.name: f"sensor_{i}" for i, s in enumerate(self.rendered)}
        parts = [
            (part, self.state.points[m.path][part.vertex_ids], self.state.flip[m.path])
            for m in self.state.meshes
            for part in m.parts
        ]
        setups = [
            SensorSetup(self.sensor_ids[s.name], s.resolution[0], s.resolution[1], self.state.cameras[s.name])
            for s in self.rendered
        ]
        use_sky_map = self.spectra.sky_radiance is not None
        use_sun = usd_environment.sun_direction(stage, self.time) is not None
        with tempfile.TemporaryDirectory(prefix="humv_bench_render_") as tmp:
            self.scene = IRScene(
                parts, setups, spp=4, max_depth=-1, workdir=tmp, sky_map=use_sky_map, sun=use_sun
            )
        self.scene.update()

    def setup(self, sensor, n: int):
        sub = radiometry.SubBands(sensor.wavelength_range_um, sensor.band_response, n)
        rad = radiometry.frame_radiometry(
            sub,
            self.state.sky_temperature_k,
            self.spectra,
            usd_environment.sun_direction(self.stage, self.time),
            path_table(self.stage, sensor, self.time),
            dni_w_m2=usd_environment.direct_normal_irradiance(self.stage, self.time),
        )
        band = sensor.wavelength_range_um
        cache: dict = {}

        def eps(material):
            if material.path not in cache:
                cache[material.path] = subband_emissivity(material, band, sub.bands, sub.response)
            return cache[material.path]

        def trans(material):
            return subband_transmittance(material, sub.bands, sub.response)

        return sub, rad, eps, trans

    def ray_cast_seconds(self, sensor_id: str, repeat: int = 3) -> tuple[float, float]:
        """Median (wall, CPU) seconds of the pixel-centre ray cast (depth, ids, normals)."""
        walls, cpus = [], []
        for _ in range(repeat):
            self.scene._hits = {}
            t, c = time.perf_counter(), time.process_time()
            self.scene.hits(sensor_id)
            walls.append(time.perf_counter() - t)
            cpus.append(time.process_time() - c)
        return float(np.median(walls)), float(np.median(cpus))


def _timed(fn, *args, **kwargs):
    t, c = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t, time.process_time() - c


def bench_render(
    stage_path,
    spp_list=(1, 2, 4, 8),
    subband_list=(4, 8, 16),
    reference_spp=256,
    reference_subbands=16,
    default=(E.DEFAULT_SPP, radiometry.DEFAULT_SUBBANDS),
    frame=None,
    sensors=None,
    progress=None,
) -> dict:
    """Error against run time of the IR estimators on one frame of a composed stage (see the
    module docstring). ``progress(text)`` is called before each render."""
    fr = _Frame(stage_path, frame)
    note = progress or (lambda text: None)
    out: dict = {"stage": os.fspath(stage_path), "frame": fr.frame, "default": list(default), "sensors": {}}
    for s in fr.rendered:
        if sensors and s.name not in sensors:
            continue
        sid = fr.sensor_ids[s.name]
        band, response = s.wavelength_range_um, s.band_response
        fr.scene._hits = {}
        cast_s, cast_cpu = fr.ray_cast_seconds(sid)
        hits = fr.scene.hits(sid)
        edge = E.geometric_edges(hits)

        def to_k(radiance, stderr, band=band, response=response):
            bt, dl = planck.brightness_temperature_sensitivity(radiance, band, response)
            with np.errstate(invalid="ignore", divide="ignore"):
                return bt, np.where(dl > 0, stderr / dl, np.nan)

        def path_tracer(spp, n, seed):
            """Mitsuba's path tracer over ``n`` sub-bands: (radiance, stderr), wall, cpu."""
            sub, rad, eps, tr = fr.setup(s, n)
            return _timed(
                render_band, fr.scene, sid, fr.state, sub, eps, rad, subband_spp(spp, len(sub)), seed, tr
            )

        note(f"{s.name}: reference (path tracer, {reference_spp} spp, {reference_subbands} sub-bands)")
        (ref_l, ref_se), ref_wall, ref_cpu = path_tracer(reference_spp, reference_subbands, 991)
        ref_bt, ref_k = to_k(ref_l, ref_se)
        rows = []

        def record(estimator, spp, n, radiance, stderr, wall, cpu):
            bt, se_k = to_k(radiance, stderr)
            rows.append(
                {
                    "estimator": estimator,
                    "spp": int(spp),
                    "subbands": int(n),
                    "wall_s": wall,
                    "cpu_s": cpu,
                    "ratio_to_ray_cast": wall / cast_s if cast_s > 0 else None,
                    "cpu_ratio_to_ray_cast": cpu / cast_cpu if cast_cpu > 0 else None,
                    "noise": E.noise_stats(se_k, edge),
                    "bias_by_region": region_bias(
                        radiance, ref_l, stderr, ref_se, hits.instance, band, response
                    ),
                    "default": estimator == "fast" and (spp, n) == tuple(default),
                }
            )

        for n in subband_list:
            sub, rad, eps, tr = fr.setup(s, n)
            for spp in spp_list:
                note(f"{s.name}: fast, {spp} spp, {n} sub-bands")
                (radiance, stderr), wall, cpu = _timed(
                    E.render_band_fast, fr.scene, sid, fr.state, sub, eps, rad, spp, 7 + spp, tr
                )
                record("fast", spp, n, radiance, stderr, wall, cpu)
        spp, n = PATH_BASELINE
        note(f"{s.name}: path tracer, {spp} spp over {n} sub-bands (the former default)")
        (radiance, stderr), wall, cpu = path_tracer(spp, n, 5)
        record("path", spp, n, radiance, stderr, wall, cpu)
        out["sensors"][s.name] = {
            "band": s.band,
            "band_um": list(band),
            "netd_k": s.netd_k if hasattr(s, "netd_k") else None,
            "resolution": list(s.resolution),
            "ray_cast_s": cast_s,
            "ray_cast_cpu_s": cast_cpu,
            "reference": {
                "estimator": "path",
                "spp": reference_spp,
                "subbands": reference_subbands,
                "wall_s": ref_wall,
                "noise": E.noise_stats(ref_k, edge),
            },
            "rows": rows,
        }
    return out


def plot_error_vs_time(result: dict, path) -> None:
    """Error (mean per-pixel standard error away from edges, K) against CPU time per sensor:
    one curve per sub-band count of the fast estimator, the path tracer's former default as a
    cross, the default setting circled; the top axis is the ratio to the pixel-centre ray cast."""
    fig, panels = error_panels(
        result,
        error=lambda r: r["noise"]["mean_k"],
        group="subbands",
        group_label="sub-bands",
        path_label=lambda r: f"path, {r['spp']} spp/{r['subbands']} sb",
    )
    for ax, name, rec in panels:
        netd = rec.get("netd_k")
        if netd:
            ax.axhline(netd / 3, color="grey", ls="--", lw=1, label="NETD / 3")
        ax.set_xlabel("band render CPU time per frame [s] (all threads; load-independent)")
        ax.set_ylabel("mean per-pixel MC error away from edges [K]")
        finish_error_axes(ax, rec["ray_cast_cpu_s"], f"{name} ({rec['band']})")
    save_figure(fig, path)


def plot_error_curves(ax, rows, error, group: str, group_label: str, path_label) -> None:
    """Error against CPU time on ``ax``: one curve per value of ``group`` for the fast estimator
    (points labelled with their spp), the path tracer as crosses, the default circled. ``error(row)``
    is the plotted error (None: not estimable, left out)."""
    rows = [r for r in rows if error(r) is not None]  # spp 1: not estimable
    fast = [r for r in rows if r["estimator"] == "fast"]
    for n in sorted({r[group] for r in fast}):
        pts = sorted((r["cpu_s"], error(r), r["spp"]) for r in fast if r[group] == n)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=f"fast, {n} {group_label}")
        for x, y, spp in pts:
            ax.annotate(f"{spp}", (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7)
    for r in rows:
        if r["estimator"] == "path":
            ax.plot(r["cpu_s"], error(r), "kx", ms=9, label=path_label(r))
        if r["default"]:
            ax.plot(r["cpu_s"], error(r), "o", ms=14, mfc="none", mec="red", label="default")


def finish_error_axes(ax, ray_cast_cpu_s: float, title: str) -> None:
    """Top axis: the ratio of the render's CPU time to the pixel-centre ray cast's (the physical
    lower bound); title, grid and legend of an error-against-run-time panel."""
    if ray_cast_cpu_s > 0:
        c = ray_cast_cpu_s
        top = ax.secondary_xaxis("top", functions=(lambda x: x / c, lambda r: r * c))
        top.set_xlabel("ratio to the pixel-centre ray cast (CPU)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)


def error_panels(result: dict, error, group: str, group_label: str, path_label):
    """A figure with one panel per sensor of ``result`` (log-log), each with its error curves
    (:func:`plot_error_curves`); returns (figure or None without sensors, [(axes, name,
    record)])."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(result["sensors"])
    if not names:
        return None, []
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.2), squeeze=False)
    panels = []
    for ax, name in zip(axes[0], names):
        rec = result["sensors"][name]
        plot_error_curves(
            ax, rec["rows"], error=error, group=group, group_label=group_label, path_label=path_label
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        panels.append((ax, name, rec))
    return fig, panels


def save_figure(fig, path) -> None:
    """Write a matplotlib figure to ``path`` atomically (a temporary file renamed) and close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    tmp = os.fspath(path) + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)
