"""Instance ids every tool and the render agree on, derived from the scenario alone."""

from __future__ import annotations

from typing import TYPE_CHECKING

from humv_usd.catalog.garments import garment

if TYPE_CHECKING:
    from humv_usd.scenario.load import Scenario


def instance_ids(scenario: Scenario) -> dict[str, int]:
    """Stable instance ids: humans 1..N in file order, then the ground, then scene objects,
    then the props people carry (``prop:<human id>:<catalogue name>``, people in file order,
    each one's props in the order of its ``clothing`` list). Props come last so that adding
    or dropping one never renumbers a person or a scene object."""
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
