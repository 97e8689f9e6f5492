"""Bench cases for ``humv-usd bench thermal``: the clothed avatar of a composed scenario.

:func:`avatar_case` rebuilds, for the first person of a composed stage at frame 0, exactly the
q_rad problem the thermal layer solves for the garments (body + garments as one facet mesh, the
scene surfaces at their temperatures, the sky with the sun, the person's own leaving radiance
for self-occluded rays), so that the fast methods can be timed against the brute reference on a
real ~30k-facet clothed avatar instead of the capsule stand-in.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Usd

from humv_usd.catalog.garments import GARMENTS
from humv_usd.catalog.materials import LIBRARY
from humv_usd.human.usdskel import skinned_points
from humv_usd.scenario.times import spin_up_times
from humv_usd.thermal import human as H
from humv_usd.thermal import layer as TL
from humv_usd.thermal import radiation as R
from humv_usd.thermal.surfaces import (
    forcing_at,
    scene_meshes,
    surface_temperatures,
    with_sky_table,
)
from humv_usd.usd import schemas as S
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
        ``center`` (3,), as :func:`humv_usd.thermal.radiation.bench_qrad` takes them.
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
    )
    scene = None
    mesh, eps_tri, _ = TL._scene_trimesh(meshes)
    if mesh is not None:
        t_tri = np.concatenate([surf[m.path][0][m.tri_face] for m in meshes])
        scene = R.SceneSurfaces(
            mesh,
            R.scene_surface_radiance(
                mesh, t_tri, eps_tri, sky, solar_reflectance=TL._solar_reflectance(meshes)
            ),
        )
    hp = str(human_path(scenario["human"][0]["id"]))
    parts = [H._part(stage, f"{hp}/Body", None)]
    clothing = stage.GetPrimAtPath(f"{hp}/Clothing")
    if clothing:
        parts += [
            H._part(stage, str(c.GetPath()), c.GetAttribute(S.CLOTHING_GARMENT).Get())
            for c in clothing.GetChildren()
        ]
    pts = [skinned_points(stage, p.path, Usd.TimeCode(0), space="world") for p in parts]

    def alpha(p):
        name = "skin" if p.garment is None else GARMENTS[p.garment].fabric
        return np.array([LIBRARY[name].solar_absorptivity, H.longwave_emissivity(name)])

    absorb = np.concatenate([np.repeat(alpha(p)[:, None], len(p.triangles), axis=1) for p in parts], axis=1)
    return {
        "mesh": H._trimesh(pts, parts),
        "scene": scene,
        "sky": sky,
        "absorptivity": absorb,
        "mesh_radiance": H._self_radiance(parts, th["skin_temperature_k"], float(f.air_temperature_k[i])),
        "center": pts[0].mean(axis=0),
    }
