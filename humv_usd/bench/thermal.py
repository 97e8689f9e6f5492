"""Bench cases for ``humv-usd bench thermal``: the clothed avatar of a composed scenario.

:func:`avatar_case` rebuilds, for the first person of a composed stage at frame 0, exactly the
q_rad problem the thermal layer solves for the garments (body + garments as one facet mesh, the
scene surfaces at their temperatures, the sky with the sun, the person's own leaving radiance
for self-occluded rays), so that the fast methods can be timed against the brute reference on a
real ~30k-facet clothed avatar instead of the capsule stand-in.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np
import trimesh
from pxr import Usd

from humv_usd.fileio import atomic_path
from humv_usd.human.usdskel import skinned_points
from humv_usd.scenario.times import spin_up_times
from humv_usd.thermal import human as H
from humv_usd.thermal import layer as TL
from humv_usd.thermal.physiology import simulate_physiology
from humv_usd.thermal.qrad import absorbed_radiation
from humv_usd.thermal.scene_radiance import SceneSurfaces, radiance_map, scene_surface_radiance
from humv_usd.thermal.sky import ClearSky
from humv_usd.thermal.surfaces import (
    forcing_at,
    ground_albedo,
    scene_meshes,
    surface_temperatures,
    with_sky_table,
)
from humv_usd.usd.avatar import read_garment
from humv_usd.usd.paths import human_path


def avatar_case(scenario, stage_path: str | Path) -> dict:
    """The garment q_rad problem of the scenario's first person at frame 0.

    Parameters
    ----------
    scenario : Scenario
        The scenario the stage was composed from.
    stage_path : path
        Its composed ``stage.usda``.

    Returns
    -------
    dict
        ``mesh`` (trimesh, body + garments), ``scene`` (SceneSurfaces or None), ``sky``
        (ClearSky with the sun), ``absorptivity`` (2, faces), ``mesh_radiance`` (2, faces),
        ``center`` (3,), as :func:`bench_qrad` takes them.
    """
    stage = Usd.Stage.Open(str(stage_path))
    th = scenario["thermal"]
    meshes = scene_meshes(stage, scenario)
    slabs = any(m.held_k is None for m in meshes)
    spin = th["surface_spin_up_s"] if slabs else 0.0
    spin_t = spin_up_times(scenario) if slabs else np.zeros(0)
    tables = TL.sky_tables(stage, [0])
    f = with_sky_table(forcing_at(stage, np.r_[spin_t, 0.0]), tables, len(spin_t))
    surf, diag = surface_temperatures(scenario, meshes, np.array([0.0]), spin, f)
    i = len(spin_t)
    sun = (f.sun_direction[i], f.dni_w_m2[i], f.dhi_w_m2[i]) if f.sun_up[i] else None
    sky = H.scenario_sky(
        scenario,
        {
            "air_temperature_k": f.air_temperature_k[i],
            "relative_humidity": f.relative_humidity[i],
            "cloud_cover": f.cloud_cover[i],
        },
        sun,
        float(diag["groundMeanTemperature_k"][0]) if scenario["scene"] else None,
        longwave=None if tables is None else tables[0],
        ground_albedo=ground_albedo(meshes),
    )
    scene = None
    mesh, eps_tri, _ = TL._scene_trimesh(meshes)
    if mesh is not None:
        t_tri = np.concatenate([surf[m.path][0][m.tri_face] for m in meshes])
        scene = SceneSurfaces(
            mesh,
            scene_surface_radiance(
                mesh, t_tri, eps_tri, sky, solar_reflectance=TL._solar_reflectance(meshes)
            ),
        )
    hp = str(human_path(scenario["human"][0]["id"]))
    parts = [H._part(stage, f"{hp}/Body", None)]
    clothing = stage.GetPrimAtPath(f"{hp}/Clothing")
    if clothing:
        parts += [H._part(stage, str(c.GetPath()), read_garment(c)) for c in clothing.GetChildren()]
    pts = [skinned_points(stage, p.path, Usd.TimeCode(0), space="world") for p in parts]
    absorb = np.concatenate(
        [np.repeat(p.absorptivity()[:, None], len(p.triangles), axis=1) for p in parts], axis=1
    )
    return {
        "mesh": H._trimesh(pts, parts),
        "scene": scene,
        "sky": sky,
        "absorptivity": absorb,
        "mesh_radiance": H._self_radiance(parts, th["skin_temperature_k"], float(f.air_temperature_k[i])),
        "center": pts[0].mean(axis=0),
    }


# --------------------------------------------------------------------------- error vs run time
def relative_errors(q, q_ref) -> dict:
    """RMS and max relative error of a q_rad estimate against a reference (facet totals).

    Facets whose reference total is below 1e-6 of the largest are left out of the relative
    figures; ``nrmse`` = rms(q - q_ref) / mean(q_ref) uses all facets.
    """
    a = np.asarray(q, dtype=float)
    b = np.asarray(q_ref, dtype=float)
    if a.ndim == 2:
        a, b = a.sum(axis=0), b.sum(axis=0)
    keep = b > 1e-6 * np.max(np.abs(b))
    rel = (a[keep] - b[keep]) / b[keep]
    return {
        "rms_rel_error": float(np.sqrt(np.mean(rel**2))),
        "max_rel_error": float(np.max(np.abs(rel))),
        "nrmse": float(np.sqrt(np.mean((a - b) ** 2)) / np.mean(b)),
    }


def bench_scene(facets=30000):
    """Test setup: a crude capsule 'avatar' (self-occluding), ground slab, a warm wall, a clear sky.

    Returns (mesh, scene, sky, absorptivity, center).
    """
    per = max(8, int(np.sqrt(facets / 4.0 / 2.0)))  # 4 capsules, ~2 per^2 faces each

    def capsule(radius, height, x, y, z):
        c = trimesh.creation.capsule(height=height, radius=radius, count=[per, per])
        c.apply_translation([x, y, z])
        return c

    mesh = trimesh.util.concatenate(
        [
            capsule(0.17, 0.45, 0.0, 0.0, 1.25),
            capsule(0.075, 0.75, 0.0, -0.1, 0.45),
            capsule(0.075, 0.75, 0.0, 0.1, 0.45),
            capsule(0.05, 0.55, 0.12, 0.25, 1.2),
        ]
    )
    ground = trimesh.creation.box(extents=[60.0, 60.0, 0.2])
    ground.apply_translation([0.0, 0.0, -0.1])
    wall = trimesh.creation.box(extents=[0.3, 6.0, 3.0])
    wall.apply_translation([2.0, 0.0, 1.5])
    smesh = trimesh.util.concatenate([ground, wall])
    n_g = len(ground.faces)
    temp = np.r_[np.full(n_g, 318.0), np.full(len(wall.faces), 305.0)]
    eps = np.r_[np.full(n_g, 0.95), np.full(len(wall.faces), 0.9)]
    rho = np.r_[np.full(n_g, 0.2), np.full(len(wall.faces), 0.35)]
    s = np.array([np.sin(np.radians(40.0)), 0.3, np.cos(np.radians(40.0))])
    sky = ClearSky(
        air_temperature_k=303.0,
        relative_humidity=0.4,
        sun_direction=tuple(s / np.linalg.norm(s)),
        direct_normal_irradiance=800.0,
        diffuse_horizontal_irradiance=100.0,
        ground_temperature_k=318.0,
    )
    scene = SceneSurfaces(smesh, scene_surface_radiance(smesh, temp, eps, sky, rho))
    return mesh, scene, sky, np.array([0.7, 0.95]), np.array([0.0, 0.0, 1.0])


def bench_qrad(
    facets=30000,
    resolutions=(90, 180, 360),
    fast_rays=(16, 64, 256),
    reference_resolution=None,
    mesh=None,
    seed=0,
    adaptive_rays=(32, 64, 128),
    case=None,
    reference=None,
) -> list[dict]:
    """Run time and error of q_rad methods against the brute-force reference.

    Parameters
    ----------
    facets : int
        Approximate facet count of the bench mesh (ignored when ``mesh`` or ``case`` is given).
    resolutions : sequence of int
        Map sizes n (n x n) to try.
    fast_rays, adaptive_rays : sequence of int
        Rays per facet of the fast method / mean rays per facet of the adaptive one.
    reference_resolution : int, optional
        Map size of the brute reference; default max(resolutions).
    mesh : trimesh.Trimesh, optional
        Facets to evaluate instead of the capsule avatar (e.g. a MakeHuman body).
    case : dict, optional
        A whole case instead of the capsule scene: ``mesh``, ``scene`` (SceneSurfaces or None),
        ``sky``, ``absorptivity`` (bands,) or (bands, faces), ``center``, optional
        ``mesh_radiance`` (e.g. :func:`humv_usd.bench.thermal.avatar_case`).
    reference : array (bands, faces), optional
        A precomputed brute reference at ``reference_resolution`` (its run time is then NaN).

    Returns
    -------
    list of dict
        One row per (method, resolution, rays): facets, seconds (wall), cpu_seconds (process
        time; the embree caster is single-threaded, so this is the run time on an idle
        machine), map_seconds (map build), rms_rel_error, max_rel_error, nrmse against the
        reference (the reference row has zeros) and the method's own rms_rel_error_estimate.
    """
    if case is None:
        bmesh, scene, sky, alpha, center = bench_scene(facets)
        mrad = None
        if mesh is not None:
            bmesh = mesh
            center = np.asarray(mesh.bounds.mean(axis=0))
    else:
        bmesh, scene, sky, alpha = case["mesh"], case["scene"], case["sky"], case["absorptivity"]
        center, mrad = case["center"], case.get("mesh_radiance")
    ref_res = int(max(resolutions) if reference_resolution is None else reference_resolution)
    maps, map_seconds = {}, {}
    for res in sorted(set(resolutions) | {ref_res}):
        t0 = time.perf_counter()
        maps[res] = radiance_map(center, sky, scene, res)
        map_seconds[res] = time.perf_counter() - t0
    kw = dict(scene=scene, mesh_radiance=mrad)

    def timed(env, **extra):
        stats: dict = {}
        w0, c0 = time.perf_counter(), time.process_time()
        q = absorbed_radiation(bmesh, env, alpha, stats=stats, **kw, **extra)
        return q, time.perf_counter() - w0, time.process_time() - c0, stats

    if reference is None:
        q_ref, wall, cpu, _ = timed(maps[ref_res], method="brute")
    else:
        q_ref, wall, cpu = np.asarray(reference, dtype=float), float("nan"), float("nan")
    rows = [
        {
            "method": "brute",
            "resolution": ref_res,
            "rays": None,
            "facets": len(bmesh.faces),
            "seconds": wall,
            "cpu_seconds": cpu,
            "map_seconds": map_seconds[ref_res],
            "rms_rel_error": 0.0,
            "max_rel_error": 0.0,
            "nrmse": 0.0,
            "rms_rel_error_estimate": 0.0,
            "reference": True,
        }
    ]
    for res in resolutions:
        runs = [("fast", k) for k in fast_rays] + [("adaptive", k) for k in adaptive_rays]
        if res != ref_res:
            runs.insert(0, ("brute", None))
        for method, k in runs:
            extra = {} if k is None else {"rays": k, "seed": seed}
            q, wall, cpu, stats = timed(maps[res], method=method, **extra)
            rows.append(
                {
                    "method": method,
                    "resolution": res,
                    "rays": k,
                    "facets": len(bmesh.faces),
                    "seconds": wall,
                    "cpu_seconds": cpu,
                    "map_seconds": map_seconds[res],
                    **relative_errors(q, q_ref),
                    "rms_rel_error_estimate": stats.get("rms_rel_error_estimate", 0.0),
                    "reference": False,
                }
            )
    return rows


def plot_thermal_bench(rows: list[dict], g_rows: list[dict], s_rows: list[dict], what: str, png) -> None:
    """``humv-usd bench thermal``'s PNG: q_rad RMS relative error against CPU time per method and
    map resolution (left), garment and skin temperature error against the time step (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for method, marker in (("brute", "s"), ("fast", "o"), ("adaptive", "^")):
        for res in sorted({r["resolution"] for r in rows}):
            pts = [
                (r["cpu_seconds"], r["rms_rel_error"])
                for r in rows
                if r["method"] == method and r["resolution"] == res and not r["reference"]
            ]
            if pts:
                ax.loglog(*zip(*sorted(pts)), marker + "-", label=f"{method} {res}²")
    ax.axvline(1.0, color="0.6", lw=0.8)
    ax.axhline(0.01, color="0.6", lw=0.8)
    ax.set_xlabel("q_rad run time [cpu s]")
    ax.set_ylabel("RMS relative error vs brute reference")
    ax.set_title(f"absorbed radiation, {rows[0]['facets']} facets ({what})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    for key, group, rws in (("case", "garment", g_rows), ("model", "skin", s_rows)):
        for name in dict.fromkeys(r[key] for r in rws):
            pts = [(r["step_s"], max(r["max_error_k"], 1e-12)) for r in rws if r[key] == name]
            ax2.loglog(*zip(*pts), "o-", label=f"{group}: {name}")
    ax2.set_xlabel("time step [s]")
    ax2.set_ylabel("max temperature error [K]")
    ax2.set_title("temperature error vs time step")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(png) as tmp_png:
        fig.savefig(tmp_png, dpi=120, format="png")
    plt.close(fig)


def physiology_run_times(models=("two_node", "jos3")) -> dict[str, float]:
    """Median wall time [s] of 1 h of physiology at 60 s steps per model (after a warm-up)."""
    times = np.arange(0, 3601, 60.0)
    out = {}
    for model in models:
        simulate_physiology(
            times[:3], 100.0, 293.0, 293.0, 0.5, 0.1, 0.5, model=model, spin_up_s=0.0
        )  # compile / warm up
        runs = []
        for _ in range(3):
            t = time.perf_counter()
            simulate_physiology(times, 100.0, 293.0, 293.0, 0.5, 0.1, 0.5, model=model, spin_up_s=0.0)
            runs.append(time.perf_counter() - t)
        out[model] = statistics.median(runs)
    return out
