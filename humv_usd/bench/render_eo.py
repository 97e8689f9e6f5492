"""The EO part of ``humv-usd bench render``: error against run time, bias against the spectral
path tracer.

For the first frame of a composed stage and each EO sensor, the parts are loaded once into the
spectral scene of the reference (:class:`humv_usd.render.eo.EOScene`: Mitsuba's spectral path
tracer on the 5-nm grid, ``reference_spp`` samples per pixel) and once into the mono scene of
the fast estimator (:func:`humv_usd.render.eo_fast.render_xyz_fast`), which renders every
(spp, bins) pair of the sweep; the path tracer at its former default (16 spp) is timed too. Per
setting: wall and CPU seconds of the render (before the atmospheric path, the same for both), the
ratio to the pixel-centre ray cast, the mean / p99 per-pixel standard error of Y relative to the
mean Y away from edges (:func:`humv_usd.render.quality.relative_noise`), and the bias per labelled
region (instance id; 0 = sky): the relative difference of the region's mean X, Y, Z from the
reference's, with the 1-sigma uncertainty of Y's from both renders' errors.
"""

from __future__ import annotations

import tempfile

import numpy as np
from pxr import Usd

from humv_usd import mode
from humv_usd.bench.render import _timed, error_panels, finish_error_axes, save_figure
from humv_usd.render import eo, eo_fast
from humv_usd.render import estimator as E
from humv_usd.render import quality as Q
from humv_usd.render.export import StageExport
from humv_usd.render.frame import stage_frames
from humv_usd.render.ir import IRScene, SensorSetup
from humv_usd.usd import environment as usd_environment
from humv_usd.usd.atmosphere import atmosphere_spectra
from humv_usd.usd.layers import open_stage

#: The former EO default: the spectral path tracer at 16 spp.
EO_PATH_BASELINE = 16


def region_bias_xyz(xyz, xyz_ref, y_err, y_err_ref, regions) -> dict:
    """Per region id: relative bias of mean X, Y, Z against the reference and sigma of Y's."""
    out = {}
    for r in np.unique(regions):
        m = regions == r
        ref = [float(np.mean(xyz_ref[..., c][m])) for c in range(3)]
        mine = [float(np.mean(xyz[..., c][m])) for c in range(3)]
        var = np.nan_to_num(y_err[m]) ** 2 + np.nan_to_num(y_err_ref[m]) ** 2
        out[int(r)] = {
            "pixels": int(m.sum()),
            "bias_rel_xyz": [(a / b - 1.0) if b > 0 else None for a, b in zip(mine, ref)],
            "sigma_rel_y": float(np.sqrt(var.sum()) / m.sum() / ref[1]) if ref[1] > 0 else None,
        }
    return out


def bench_render_eo(
    stage_path,
    spp_list=(2, 4, 8),
    bins_list=(4, 8, 12, 16),
    reference_spp=64,
    default=(eo_fast.DEFAULT_EO_SPP, eo_fast.DEFAULT_EO_BINS),
    frame=None,
    sensors=None,
    progress=None,
    scale: float = 1.0,
) -> dict:
    """Error against run time of the EO estimators on one frame (see the module docstring);
    ``scale`` shrinks the sensors' resolution (quick looks)."""
    stage = open_stage(stage_path)
    exporter = StageExport(stage)
    eo_sensors = [s for s in exporter.sensors if s.rendered and s.kind == "EO"]
    eo_sensors = [s for s in eo_sensors if not sensors or s.name in sensors]
    note = progress or (lambda text: None)
    frame = stage_frames(stage)[0] if frame is None else int(frame)
    out: dict = {"stage": str(stage_path), "frame": frame, "default": list(default), "sensors": {}}
    if not eo_sensors:
        return out
    state = exporter.frame_state(frame, eo_sensors)
    t = Usd.TimeCode(frame)
    spectra = atmosphere_spectra(stage, t)
    sun_dir = usd_environment.sun_direction(stage, t)
    sun, sky, ran = eo.illumination(spectra, sun_dir, usd_environment.direct_normal_irradiance(stage, t))
    parts = [
        (p, state.points[m.path][p.vertex_ids], state.flip[m.path]) for m in state.meshes for p in m.parts
    ]
    ids = {s.name: f"eo_{i}" for i, s in enumerate(eo_sensors)}
    setups = [
        SensorSetup(
            ids[s.name],
            max(1, round(s.resolution[0] * scale)),
            max(1, round(s.resolution[1] * scale)),
            state.cameras[s.name],
        )
        for s in eo_sensors
    ]
    with tempfile.TemporaryDirectory(prefix="humv_bench_eo_") as tmp:
        spectral = eo.EOScene(parts, setups, 4, -1, tmp, sky=sky is not None, sun=sun is not None)
        spectral.set_illumination(sun_dir, sun, sky)
        spectral.update()
        mode.mitsuba()
        mono = IRScene(parts, setups, 2, -1, tmp)
        mono.update()
    weight = eo_fast.horizontal_irradiance(sun, sky, sun_dir)
    for s in eo_sensors:
        sid = ids[s.name]
        mono._hits = {}
        walls, cpus = [], []
        for _ in range(3):
            mono._hits = {}
            (_, w_s, c_s) = _timed(mono.hits, sid)
            walls.append(w_s)
            cpus.append(c_s)
        cast_s, cast_cpu = float(np.median(walls)), float(np.median(cpus))
        hits = mono.hits(sid)
        edge = E.geometric_edges(hits)
        note(f"{s.name}: reference (spectral path tracer, {reference_spp} spp)")
        (ref_xyz, ref_err), ref_wall, ref_cpu = _timed(spectral.render_xyz, sid, reference_spp, 991)
        rows = []

        def record(estimator, spp, bins, xyz, y_err, wall, cpu, cast_s=cast_s, cast_cpu=cast_cpu, hits=hits):
            rows.append(
                {
                    "estimator": estimator,
                    "spp": int(spp),
                    "bins": bins,
                    "wall_s": wall,
                    "cpu_s": cpu,
                    "ratio_to_ray_cast": wall / cast_s if cast_s > 0 else None,
                    "cpu_ratio_to_ray_cast": cpu / cast_cpu if cast_cpu > 0 else None,
                    "noise": Q.relative_noise(xyz[..., 1], y_err, edge),
                    "bias_by_region": region_bias_xyz(xyz, ref_xyz, y_err, ref_err, hits.instance),
                    "default": estimator == "fast" and (spp, bins) == tuple(default),
                }
            )

        for n in bins_list:
            bins = eo_fast.visible_bins(n)
            light = eo_fast.bin_illumination(bins, sun, sky, sun_dir)
            rho = {}

            def reflectance_of(material, bins=bins, rho=rho):
                if material.path not in rho:
                    rho[material.path] = bins.mean(eo.reflectance_spectrum(material), weight)
                return rho[material.path]

            for spp in spp_list:
                note(f"{s.name}: fast, {spp} spp, {n} bins")
                mode.mitsuba()
                (xyz, err), wall, cpu = _timed(
                    eo_fast.render_xyz_fast, mono, sid, state, bins, reflectance_of, light, spp, 7 + spp
                )
                record("fast", spp, n, xyz, err[..., 1], wall, cpu)
        note(f"{s.name}: spectral path tracer, {EO_PATH_BASELINE} spp (the former default)")
        (xyz, y_err), wall, cpu = _timed(spectral.render_xyz, sid, EO_PATH_BASELINE, 5)
        record("path", EO_PATH_BASELINE, None, xyz, y_err, wall, cpu)
        mode.mitsuba()
        out["sensors"][s.name] = {
            "band": s.band,
            "resolution": [setups[eo_sensors.index(s)].width, setups[eo_sensors.index(s)].height],
            "illumination": ran,
            "ray_cast_s": cast_s,
            "ray_cast_cpu_s": cast_cpu,
            "reference": {
                "estimator": "path (spectral, 5 nm)",
                "spp": reference_spp,
                "wall_s": ref_wall,
                "cpu_s": ref_cpu,
                "noise": Q.relative_noise(ref_xyz[..., 1], ref_err, edge),
            },
            "rows": rows,
        }
    return out


def plot_eo_error_vs_time(result: dict, path) -> None:
    """Relative error of Y (mean away from edges) against CPU time per EO sensor: one curve per
    bin count of the fast estimator, the path tracer's former default as a cross, the default
    circled, the 1 % target dashed; the top axis is the ratio to the pixel-centre ray cast."""

    fig, panels = error_panels(
        result,
        error=lambda r: r["noise"]["mean"],
        group="bins",
        group_label="bins",
        path_label=lambda r: f"path, {r['spp']} spp",
    )
    if fig is None:
        return
    for ax, name, rec in panels:
        ax.axhline(eo_fast.EO_TARGET_RELATIVE, color="grey", ls="--", lw=1, label="target (1 % of mean Y)")
        ax.set_xlabel("render CPU time per frame [s] (all threads; load-independent)")
        ax.set_ylabel("mean per-pixel MC error of Y / mean Y, away from edges")
        finish_error_axes(
            ax, rec["ray_cast_cpu_s"], f"{name} (EO, {rec['resolution'][0]}x{rec['resolution'][1]})"
        )
    save_figure(fig, path)
