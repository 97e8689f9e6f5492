"""Avatar tool → layers/avatar_<id>.usda.

The body is MakeHuman's CC0 mesh with its macro targets fitted to the requested sex, age,
stature, mass and build (:func:`humv_usd.avatar.body.build_body`), standing still at its
placement. Still to come (avatar issue): the UsdSkel rig, motion and body-region labels.
"""
from __future__ import annotations

from pxr import Gf, Sdf, UsdGeom

from humv_usd.avatar.basemesh import DEFAULT_FACING_DEG
from humv_usd.avatar.body import build_body
from humv_usd.materials.layer import material_path
from humv_usd.scenario import Scenario
from humv_usd.scene.layer import instance_ids
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage
from humv_usd.usd.mesh import define_mesh, label

NAME = "avatar"
READS = ("general", "human", "placement", "scene")


def human_path(human_id: str) -> Sdf.Path:
    return SCOPES["humans"].AppendChild(human_id)


def body_path(human_id: str) -> Sdf.Path:
    return human_path(human_id).AppendChild("Body")


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
    body = build_body(human["sex"], human["age_yr"], human["stature_m"], human["mass_kg"],
                      human["build"])
    mesh = body.body_mesh()
    for attr, value in ((S.AVATAR_SEX, human["sex"]), (S.AVATAR_AGE, human["age_yr"]),
                        (S.AVATAR_STATURE, human["stature_m"]), (S.AVATAR_MASS, human["mass_kg"]),
                        (S.AVATAR_FITNESS, human["fitness"]),
                        (S.AVATAR_ACTIVITY, human["activity"]),
                        (S.AVATAR_BODY_SURFACE_AREA, round(body.body_surface_area_m2, 4))):
        prim.GetAttribute(attr).Set(value)
    # how the request was met: measured values and the macro/scale fit (for reports and QA)
    prim.SetCustomDataByKey("humv:fit", {
        "statureMeasured_m": round(body.stature_m, 5), "massFromVolume_kg": round(body.mass_kg, 4),
        "volume_m3": round(body.volume_m3, 6), "density_kg_m3": round(body.density_kg_m3, 2),
        "bodyFat_pct": round(body.body_fat_pct, 2), "uniformScale": round(body.uniform_scale, 6),
        "lateralScale": round(body.lateral_scale, 6),
        "macros": {k: round(float(v), 6) for k, v in vars(body.macros).items()}})
    label(prim, instance_ids(scenario)[f"human:{human['id']}"], "person")
    define_mesh(stage, body_path(human["id"]), mesh.points, mesh.face_counts, mesh.face_indices,
                material=material_path("skin"))
    return finish(stage)
