"""Scene tool: ground and objects (buildings, props, panels) → layers/scene.usda."""

from __future__ import annotations

from pxr import Sdf, UsdGeom

from humv_usd.scenario import Scenario
from humv_usd.scenario.ids import instance_ids
from humv_usd.scenario.inputs import FRAMES
from humv_usd.scene.geometry import box, ground_grid
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage
from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.paths import GROUND, material_path, object_path

NAME = "scene"
READS = (*FRAMES, "scene", "@ids")
UPSTREAM = ()
VERSION = "1"


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g, scene = scenario["general"], scenario["scene"]
    ids = instance_ids(scenario)
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, "HumV-USD scene layer: " + (scene["site"] or "ground and objects")
    )
    UsdGeom.Xform.Define(stage, SCOPES["scene"])
    ground = scene["ground"]
    mesh = define_mesh(
        stage, GROUND, *ground_grid(ground["size_m"]), material=material_path(ground["material"])
    )
    label(mesh.GetPrim(), ids["ground"], "ground")
    for o in scene["object"]:
        mesh = define_mesh(
            stage,
            object_path(o["id"]),
            *box(o["center_m"], o["size_m"], o["heading_deg"]),
            material=material_path(o["material"]),
        )
        label(mesh.GetPrim(), ids[f"object:{o['id']}"], o["class"])
    return finish(stage)
