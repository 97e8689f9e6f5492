"""Thermal tool → layers/thermal.usda: per-face temperature [K] on every mesh of the stage.

Models (``[thermal] model``):

* ``fixed``: skin at the scenario's uniform skin temperature, garments and any other mesh (e.g.
  from a hand-made layer) at the air temperature;
* ``jos3`` / ``twoNode``: per person, radiation environment → segment MRT → physiology → skin
  facets, and the garment energy balance for garment facets, per frame
  (:mod:`humv_usd.thermal.human`).

Ground and scene objects keep their fixed scenario temperatures in every model (the slab model,
:mod:`humv_usd.physics.slab`, needs the sun of the environment issue).
"""
from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade, Vt

from humv_usd.avatar.layer import body_path, human_path
from humv_usd.materials.library import LIBRARY
from humv_usd.thermal.human import human_temperatures, scenario_sky
from humv_usd.scenario import Scenario
from humv_usd.scene.layer import GROUND, object_path
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage

NAME = "thermal"
READS = ("general", "human", "scene", "thermal", "atmosphere")


def fixed_temperatures(scenario: Scenario) -> dict[Sdf.Path, float]:
    th = scenario["thermal"]
    temps = {body_path(h["id"]): th["skin_temperature_k"] for h in scenario["human"]}
    if scenario["scene"]:
        temps[GROUND] = scenario["scene"]["ground"]["temperature_k"]
        for o in scenario["scene"]["object"]:
            temps[object_path(o["id"])] = o["temperature_k"]
    return temps


def build(scenario: Scenario, upstream: Usd.Stage) -> Sdf.Layer:
    """Read the meshes of the composed ``upstream`` stage; write one temperature per face."""
    g = scenario["general"]
    air = (scenario["atmosphere"] or {}).get("air_temperature_k", 293.15)
    temps = fixed_temperatures(scenario)
    model = scenario["thermal"]["model"]
    stage = new_layer_stage(g["fps"], scenario.frame_count,
                            f"HumV-USD thermal layer: per-face temperatures ({model} model)")
    stage.RemovePrim("/World")  # this layer only adds opinions: overs, no defs
    solved: dict[str, np.ndarray] = {}
    if model != "fixed" and scenario["human"]:
        sky = scenario_sky(scenario)
        scene = _scene_surfaces(upstream, temps, air, sky)
        th = scenario["thermal"]
        report = {"model": model, "qradMethod": "fast", "qradRays": th["radiation_rays"],
                  "mapResolution": th["radiation_resolution"]}
        for h in scenario["human"]:
            temps_h, diag = human_temperatures(upstream, h, str(human_path(h["id"])), scenario,
                                               scene, sky, model, th)
            solved.update(temps_h)
            report[h["id"]] = {k: round(v, 9) for k, v in diag.items()}
        # error estimates (deterministic for fixed seeds) travel with the layer; run times go
        # to compose's report, so an unchanged scenario still rewrites nothing
        stage.GetRootLayer().customLayerData = {"humv:thermal": report}
    for prim in upstream.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        path = prim.GetPath()
        faces = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [])
        over = stage.OverridePrim(path)
        over.ApplyAPI(S.THERMAL_API)
        primvar = UsdGeom.PrimvarsAPI(over).CreatePrimvar(
            S.TEMPERATURE_PRIMVAR.removeprefix("primvars:"), Sdf.ValueTypeNames.FloatArray,
            UsdGeom.Tokens.uniform)
        series = solved.get(str(path))
        if series is None:
            over.GetAttribute(S.THERMAL_MODEL).Set("fixed")
            primvar.Set(Vt.FloatArray.FromNumpy(np.full(faces, temps.get(path, air),
                                                        dtype=np.float32)))
            continue
        over.GetAttribute(S.THERMAL_MODEL).Set(model if str(path).endswith("/Body")
                                               else "balance")
        if len(series) == 1:
            primvar.Set(Vt.FloatArray.FromNumpy(series[0].astype(np.float32)))
        else:
            for frame, values in enumerate(series):
                primvar.Set(Vt.FloatArray.FromNumpy(values.astype(np.float32)), frame)
    return finish(stage)


def _scene_surfaces(upstream: Usd.Stage, temps: dict, air: float, sky):
    """Scene meshes (not people) as ray-cast occluders with their leaving radiance."""
    import trimesh

    from humv_usd.thermal import radiation as R
    from humv_usd.thermal.human import longwave_emissivity
    from humv_usd.usd.mesh import fan_triangulate
    points, faces, t_face, eps_face, offset = [], [], [], [], 0
    for prim in upstream.Traverse():
        if not prim.IsA(UsdGeom.Mesh) or str(prim.GetPath()).startswith(str(SCOPES["humans"])):
            continue
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
        xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(
            Usd.TimeCode.Default()))
        pts = pts @ xf[:3, :3] + xf[3, :3]
        tris, _ = fan_triangulate(np.asarray(mesh.GetFaceVertexCountsAttr().Get()),
                       np.asarray(mesh.GetFaceVertexIndicesAttr().Get()))
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        name = material.GetPrim().GetName() if material else ""
        eps = longwave_emissivity(name) if name in LIBRARY else 0.9
        points.append(pts)
        faces.append(tris + offset)
        offset += len(pts)
        t_face.append(np.full(len(tris), temps.get(prim.GetPath(), air)))
        eps_face.append(np.full(len(tris), eps))
    if not points:
        return None
    mesh = trimesh.Trimesh(np.concatenate(points), np.concatenate(faces), process=False)
    radiance = R.scene_surface_radiance(mesh, np.concatenate(t_face), np.concatenate(eps_face),
                                        sky)
    return R.SceneSurfaces(mesh, radiance)
