"""The layer graph compose builds: tools found by their declarations, one node per layer, the
build order from what each layer reads off the stage, and the sublayer strength order.

A layer tool is any module of a tool package that declares, at module level:

* ``NAME`` -- the layer it writes (``"thermal"``); with ``{id}`` (``"avatar_{id}"``) one layer
  per ``[[human]]``, ``{id}`` being the person's id;
* ``READS`` -- the scenario values it reads (:mod:`humv_usd.scenario.inputs` read paths);
* ``UPSTREAM`` -- the layers whose prims it reads from the composed stage: layer names,
  ``"avatar_{id}"`` (the same person's layer) or ``"avatar_*"`` (every person's);
* ``VERSION`` -- bumped whenever the tool's output for the same inputs changes (code, catalogue
  or data the tool ships);

optionally ``upstream_for(scenario)`` -- the subset of ``UPSTREAM`` a given scenario makes it read
(the sensors tool reads a person's avatar layer only for a camera that tracks them), and
``RENDER_ONLY`` -- read paths (``fnmatch`` patterns over the ``READS`` values) that only the
render reads: the key the layers built on this one see leaves them out (compose's
``LayerState.passed_key``; the sensors tool's image chain);

and builds with ``build(scenario, upstream)`` (per person: ``build_one(scenario, human)``, with
``upstream=`` when it declares ``UPSTREAM``), ``upstream`` being the in-memory composition of
exactly its upstream layers.
"""

from __future__ import annotations

import functools
import importlib
import pkgutil
from dataclasses import dataclass
from fnmatch import fnmatchcase
from types import ModuleType

from pxr import Sdf, Usd

from humv_usd.errors import InputError
from humv_usd.scenario import Scenario

#: packages whose modules may declare a layer tool (docs/architecture.md "Package graph")
TOOL_PACKAGES = (
    "environment",
    "atmosphere",
    "materials",
    "scene",
    "avatar",
    "clothing",
    "sensors",
    "thermal",
)
#: sublayer strength, strongest first. A layer matching none of these sits directly above (is
#: stronger than) the strongest of its upstream layers, or weakest when it has none.
STRENGTH = (
    "thermal",
    "sensors",
    "clothing_*",
    "avatar_*",
    "scene",
    "materials",
    "atmosphere_paths",  # over /World/Atmosphere: its Paths only, next to the sky it goes with
    "atmosphere",
    "environment",
)


@dataclass(frozen=True)
class Tool:
    """A layer tool's declarations (see the module doc)."""

    name: str
    reads: tuple[str, ...]
    upstream: tuple[str, ...]
    version: str
    module: ModuleType

    @property
    def per_human(self) -> bool:
        return "{id}" in self.name

    def layer_name(self, human_id: str | None = None) -> str:
        return self.name.format(id=human_id) if self.per_human else self.name

    @property
    def pattern(self) -> str:
        """Glob of the file names of its layers (compose owns these inside OUT/layers)."""
        return self.name.replace("{id}", "*") + ".usda"

    @property
    def spills(self) -> bool:
        """Whether the tool takes a :class:`~humv_usd.usd.spill.SampleSpill` (``SPILLS``): its
        per-frame samples go to disk as they are made (issue 29.5). Compose passes one only when
        no later layer of the build reads this one (the layer in memory holds placeholders)."""
        return bool(getattr(self.module, "SPILLS", False))

    def build(
        self, scenario: Scenario, human: dict | None, upstream: Usd.Stage | None, spill=None
    ) -> Sdf.Layer:
        if spill is not None and not self.per_human:
            return self.module.build(scenario, upstream, spill=spill)
        if not self.per_human:
            return self.module.build(scenario, upstream)
        if self.upstream:
            return self.module.build_one(scenario, human, upstream=upstream)
        return self.module.build_one(scenario, human)


@functools.cache
def discover_tools() -> dict[str, Tool]:
    """Every module of the tool packages that declares NAME, READS, UPSTREAM and VERSION."""
    tools: dict[str, Tool] = {}
    for package in TOOL_PACKAGES:
        pkg = importlib.import_module(f"humv_usd.{package}")
        for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
            module = importlib.import_module(f"{pkg.__name__}.{info.name}")
            if not all(hasattr(module, a) for a in ("NAME", "READS", "UPSTREAM", "VERSION")):
                continue
            tool = Tool(module.NAME, tuple(module.READS), tuple(module.UPSTREAM), str(module.VERSION), module)
            if tool.name in tools:
                raise AssertionError(f"two tools write layer {tool.name}: {module.__name__}")
            tools[tool.name] = tool
    return tools


@dataclass(frozen=True)
class Node:
    """One layer of a compose: the tool that writes it, for whom, and the layers it reads."""

    name: str
    tool: Tool
    human: dict | None
    upstream: tuple[str, ...]

    @property
    def human_id(self) -> str | None:
        return self.human["id"] if self.human else None


def layer_graph(scenario: Scenario, needed: list[str]) -> dict[str, Node]:
    """Nodes of the ``needed`` layers; upstream layers the scenario lacks are left out."""
    tools = discover_tools()
    humans = {h["id"]: h for h in scenario["human"]}
    nodes = {}
    for name in needed:
        tool, human = tool_of(name, tools, humans)
        declared = tool.upstream
        if hasattr(tool.module, "upstream_for"):  # narrowed to what this scenario makes it read
            declared = tuple(tool.module.upstream_for(scenario))
        wanted = [u.format(id=human["id"]) if human else u for u in declared]
        upstream = tuple(n for n in needed if n != name and any(fnmatchcase(n, u) for u in wanted))
        nodes[name] = Node(name, tool, human, upstream)
    return nodes


def tool_of(name: str, tools: dict[str, Tool], humans: dict[str, dict]) -> tuple[Tool, dict | None]:
    """The tool that writes layer ``name`` (and the person, for a per-person layer)."""
    if name in tools:
        return tools[name], None
    for tool in tools.values():
        prefix, _, suffix = tool.name.partition("{id}")
        if tool.per_human and name.startswith(prefix) and name.endswith(suffix):
            ident = name[len(prefix) : len(name) - len(suffix)]
            if ident in humans:
                return tool, humans[ident]
    raise AssertionError(f"no tool writes layer {name}")


def build_order(nodes: dict[str, Node]) -> list[str]:
    """Upstream layers first (Kahn's topological sort); ties in the order of ``nodes``."""
    order: list[str] = []
    done: set[str] = set()
    todo = list(nodes)
    while todo:
        ready = next((n for n in todo if set(nodes[n].upstream) <= done), None)
        if ready is None:
            raise InputError(f"layer graph has a cycle among {', '.join(todo)} (check the tools' UPSTREAM)")
        order.append(ready)
        done.add(ready)
        todo.remove(ready)
    return order


def strength_order(nodes: dict[str, Node]) -> list[str]:
    """Layer names strongest first (see STRENGTH)."""
    ranked = [n for pattern in STRENGTH for n in nodes if fnmatchcase(n, pattern)]
    for name in build_order(nodes):  # unlisted layers above their strongest upstream layer
        if name in ranked:
            continue
        above = [ranked.index(u) for u in nodes[name].upstream if u in ranked]
        ranked.insert(min(above) if above else len(ranked), name)
    return ranked
