"""Instance ids every tool and the render agree on, derived from the scenario alone."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pxr import Sdf

from humv_usd.catalog.garments import garment
from humv_usd.scenario.places import generated_objects, scene_clutter

if TYPE_CHECKING:
    from humv_usd.scenario.load import Scenario


def instance_ids(scenario: Scenario) -> dict[str, int]:
    """Stable instance ids: humans 1..N in file order, then the ground, then scene objects,
    then scene assets (``asset:<id>``), then the top prims under /World/Scene of each
    ``[scene] layers`` file (``layer:<index>:<prim name>``, in the file's order), then the boxes
    of a generated place (``object:place_*``) and the warm clutter (``clutter:<id>``, the
    scenario's then the place's, :mod:`humv_usd.scenario.places`), then the ground's terrain
    zones (``ground_zone:<index>``, :mod:`humv_usd.scene.ground`) and the puddles
    (``ground_puddles``, :mod:`humv_usd.scene.puddles`), then the props people carry (``prop:<human id>:<catalogue name>``, people in file order,
    each one's props in the order of its ``clothing`` list, then ``prop:<human id>:chair`` when it
    sits on a chair, ``prop:<human id>:box`` when it carries the box). Props come last so that adding
    or dropping one never renumbers a person or a scene object."""
    ids: dict[str, int] = {}
    for h in scenario["human"]:
        ids[f"human:{h['id']}"] = len(ids) + 1
    if scenario["scene"]:
        ids["ground"] = len(ids) + 1
        for o in scenario["scene"]["object"]:
            ids[f"object:{o['id']}"] = len(ids) + 1
        for a in scenario["scene"].get("asset") or ():
            ids[f"asset:{a['id']}"] = len(ids) + 1
        for i, file in enumerate(scenario["scene"].get("layers") or ()):
            for name in site_layer_prims(file):
                ids[f"layer:{i}:{name}"] = len(ids) + 1
        for o in generated_objects(scenario["scene"]):  # generated boxes and panels
            ids[f"object:{o['id']}"] = len(ids) + 1
        for c in scene_clutter(scenario["scene"]):  # warm clutter, own then generated
            ids[f"clutter:{c['id']}"] = len(ids) + 1
        for i, _ in enumerate((scenario["scene"].get("terrain") or {}).get("zone") or ()):
            ids[f"ground_zone:{i}"] = len(ids) + 1  # the ground's material zones (their own meshes)
        if float(scenario["scene"]["ground"].get("puddles") or 0.0) > 0.0:
            ids["ground_puddles"] = len(ids) + 1  # the puddles' mesh (humv_usd.scene.puddles)
    for h in scenario["human"]:
        for name in h.get("clothing") or ():
            g = garment(name)
            if g.is_prop:
                ids[f"prop:{h['id']}:{g.name}"] = len(ids) + 1
        if sits_on_chair(h):  # the chair the person sits on (humv_usd.human.chair)
            ids[f"prop:{h['id']}:chair"] = len(ids) + 1
        if carries_box(h):  # the box carried in both hands (humv_usd.human.carry.carried_box)
            ids[f"prop:{h['id']}:box"] = len(ids) + 1
    return ids


def sits_on_chair(human: dict) -> bool:
    """Whether a ``[[human]]`` entry sits down on a chair (``sitChair``, itself or in a segment):
    the avatar tool then authors the chair (:mod:`humv_usd.human.chair`)."""
    acts = [human.get("activity")] + [s.get("activity") for s in human.get("segment") or ()]
    return "sitChair" in acts


#: where the prims of a ``[scene] layers`` file live
SITE_SCOPE = Sdf.Path("/World/Scene")


def site_layer_prims(file: str) -> list[str]:
    """Names of the prims directly under /World/Scene in a site layer file (its own specs, in
    order); empty when the file does not open (the scene tool reports why)."""
    try:
        layer = Sdf.Layer.FindOrOpen(file)
    except Exception:  # noqa: BLE001 (pxr raises Tf.ErrorException; the scene tool names the file)
        return []
    spec = layer.GetPrimAtPath(SITE_SCOPE) if layer is not None else None
    return [child.name for child in spec.nameChildren] if spec else []


def carries_box(human: dict) -> bool:
    """Whether a ``[[human]]`` entry carries the box in both hands (``activity = "carry"``, not a
    BVH clip, or a ``carry`` segment): the avatar tool then authors the box
    (:func:`humv_usd.human.carry.carried_box`)."""
    if human.get("segment"):
        return any(s.get("activity") == "carry" for s in human["segment"])
    return human.get("activity") == "carry" and not human.get("bvh")
