"""Scene tool: ground and objects (buildings, props, panels) → layers/scene.usda."""
from __future__ import annotations

from pxr import Sdf, UsdGeom

from humv_usd.materials.layer import material_path
from humv_usd.scenario import Scenario
from humv_usd.scene.geometry import box, ground_grid
from humv_usd.usd.layers import SCOPES, finish, new_layer_stage
from humv_usd.usd.mesh import define_mesh, label

NAME = "scene"
READS = ("general", "human", "scene")
GROUND = SCOPES["scene"].AppendChild("Ground")


def instance_ids(scenario: Scenario) -> dict[str, int]:
    """Stable instance ids: humans 1..N in file order, then the ground, then scene objects,
    then the props people carry (``prop:<human id>:<catalogue name>``, people in file order,
    each one's props in the order of its ``clothing`` list). Props come last so that adding
    or dropping one never renumbers a person or a scene object."""
    from humv_usd.clothing.garments import garment
    ids: dict[str, int] = {}
    for h in scenario["human"]:
        ids[f"human:{h['id']}"] = len(ids) + 1
    if scenario["scene"]:
        ids["ground"] = len(ids) + 1
        for o in scenario["scene"]["object"]:
            ids[f"object:{o['id']}"] = len(ids) + 1
    for h in scenario["human"]:
        for name in h.get("clothing") or ():
            g = garment(name)
            if g.is_prop:
                ids[f"prop:{h['id']}:{g.name}"] = len(ids) + 1
    return ids


def object_path(object_id: str) -> Sdf.Path:
    return SCOPES["scene"].AppendChild(object_id)


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g, scene = scenario["general"], scenario["scene"]
    ids = instance_ids(scenario)
    stage = new_layer_stage(g["fps"], scenario.frame_count, "HumV-USD scene layer: "
                            + (scene["site"] or "ground and objects"))
    UsdGeom.Xform.Define(stage, SCOPES["scene"])
    ground = scene["ground"]
    mesh = define_mesh(stage, GROUND, *ground_grid(ground["size_m"]),
                       material=material_path(ground["material"]))
    label(mesh.GetPrim(), ids["ground"], "ground")
    for o in scene["object"]:
        mesh = define_mesh(stage, object_path(o["id"]),
                           *box(o["center_m"], o["size_m"], o["heading_deg"]),
                           material=material_path(o["material"]))
        label(mesh.GetPrim(), ids[f"object:{o['id']}"], o["class"])
    return finish(stage)
