"""Avatar tool → layers/avatar_<id>.usda.

Foundation placeholder: the static MakeHuman base mesh (body group only), scaled uniformly to the
requested stature, standing at its placement. The avatar issue replaces it with fitted macro
targets, a UsdSkel rig, motion and body-region labels.
"""
from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, UsdGeom

from humv_usd.avatar.basemesh import DEFAULT_FACING_DEG, load_groups
from humv_usd.materials.layer import material_path
from humv_usd.scenario import Scenario
from humv_usd.scene.layer import instance_ids
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage
from humv_usd.usd.mesh import define_mesh, label, triangle_areas

NAME = "avatar"
READS = ("general", "human", "placement", "scene")


def human_path(human_id: str) -> Sdf.Path:
    return SCOPES["humans"].AppendChild(human_id)


def body_path(human_id: str) -> Sdf.Path:
    return human_path(human_id).AppendChild("Body")


def body_mesh(stature_m: float):
    """Base-mesh body scaled to ``stature_m``: feet at z = 0, centred on the z axis."""
    points, counts, indices = load_groups(("body",))
    lo, hi = points.min(axis=0), points.max(axis=0)
    scale = stature_m / (hi[2] - lo[2])
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return (points - centre) * scale, counts, indices


def build_one(scenario: Scenario, human: dict) -> Sdf.Layer:
    g = scenario["general"]
    place = next(p for p in scenario["placement"] if p["human"] == human["id"])
    stage = new_layer_stage(g["fps"], scenario.frame_count,
                            f"HumV-USD avatar layer for {human['id']} (static base-mesh placeholder)")
    UsdGeom.Scope.Define(stage, SCOPES["humans"])
    root = UsdGeom.Xform.Define(stage, human_path(human["id"]))
    root.AddTranslateOp().Set(Gf.Vec3d(*place["position_m"]))
    # compass azimuth (clockwise from +y) -> counter-clockwise rotation about +z
    root.AddRotateZOp().Set(float((DEFAULT_FACING_DEG - place["heading_deg"]) % 360.0))
    prim = root.GetPrim()
    prim.ApplyAPI(S.AVATAR_API)
    points, counts, indices = body_mesh(human["stature_m"])
    for attr, value in ((S.AVATAR_SEX, human["sex"]), (S.AVATAR_AGE, human["age_yr"]),
                        (S.AVATAR_STATURE, human["stature_m"]), (S.AVATAR_MASS, human["mass_kg"]),
                        (S.AVATAR_FITNESS, human["fitness"]),
                        (S.AVATAR_ACTIVITY, human["activity"]),
                        (S.AVATAR_BODY_SURFACE_AREA,
                         round(float(triangle_areas(points, counts, indices).sum()), 4))):
        prim.GetAttribute(attr).Set(value)
    label(prim, instance_ids(scenario)[f"human:{human['id']}"], "person")
    define_mesh(stage, body_path(human["id"]), points, counts, indices,
                material=material_path("skin"))
    return finish(stage)
