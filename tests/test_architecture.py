"""The package graph (docs/architecture.md "Package graph"): packages form layers, an import only
points down, the layer tools do not import each other, and no module hides a ``humv_usd`` import
inside a function (the usual way to dodge a cycle). Checked on the source with ``ast``, so a new
cycle or a tool importing another tool fails here, in ``make test-fast``."""

from __future__ import annotations

import ast
import functools
import re
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "humv_usd"

#: bottom to top; a package may import its own modules and packages of lower levels only
LEVELS = [
    {"core"},  # the modules directly in humv_usd/: constants, errors, fileio, images, mode, assets
    {"physics", "geometry"},  # pure functions
    {"catalog"},  # data tables
    {"scenario"},  # spec, ids, frame times
    {"usd"},  # schemas, paths, readers
    {"human"},  # body model, rig, motion
    {
        "environment",
        "atmosphere",
        "materials",
        "scene",
        "avatar",
        "clothing",
        "sensors",
        "thermal",
    },  # layer tools
    {"render", "groundtruth"},  # consumers of the stage
    {"pipeline"},  # graph, caching, the render's orchestration
    {"sweep"},  # datasets: drives pipeline.compose/render per variant on Dask, merges ground truth
    {"editor"},  # the web editor: forms from the spec, checks sweep files, runs humv-usd as processes
    {"bench"},  # benches: time and error of any of the above, the editor preview too (issue 24)
    {"cli"},
]
LEVEL = {pkg: i for i, level in enumerate(LEVELS) for pkg in level}
TOOLS = LEVELS[6]

#: edges being removed (issue 11: weather, sun and cameras read from the stage); must shrink to empty
PENDING: set[tuple[str, str]] = set()


def _package(module: str) -> str:
    parts = module.split(".")
    if len(parts) < 2:
        return ""
    return parts[1] if (ROOT / parts[1]).is_dir() else "core"


def _modules():
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT.parent).with_suffix("")
        name = ".".join(rel.parts).removesuffix(".__init__")
        yield name, path, ast.parse(path.read_text(), str(path))


def _imports(tree: ast.AST):
    """(imported humv_usd module, line, inside a function) for every import of the module."""
    nested = {
        id(n)
        for f in ast.walk(tree)
        if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
        for n in ast.walk(f)
        if isinstance(n, (ast.Import, ast.ImportFrom))
    }
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] if node.module != "humv_usd" else [f"humv_usd.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            if name == "humv_usd" or name.startswith("humv_usd."):
                yield name, node.lineno, id(node) in nested


@functools.cache
def _edge_list():
    return list(_edges_uncached())


def _edges():
    return iter(_edge_list())


def _edges_uncached():
    for module, path, tree in _modules():
        src = _package(module)
        for target, line, hidden in _imports(tree):
            yield module, src, target, _package(target), f"{path.relative_to(ROOT.parent)}:{line}", hidden


def test_every_package_has_a_level():
    packages = {_package(m) for m, _, _ in _modules()} - {""}
    assert packages <= set(LEVEL), f"packages without a level: {sorted(packages - set(LEVEL))}"


def test_imports_point_down_and_tools_are_independent():
    bad, pending = [], set()
    for module, src, target, dst, where, _ in _edges():
        if not src or not dst or src == dst:
            continue
        if (module, target) in PENDING:
            pending.add((module, target))
            continue
        if LEVEL[dst] >= LEVEL[src]:
            what = "tool imports another tool" if src in TOOLS and dst in TOOLS else "import points up"
            bad.append(f"{where}: {module} -> {target} ({what})")
    assert not bad, "\n".join(bad)
    assert pending == PENDING, f"fixed, remove from PENDING: {sorted(PENDING - pending)}"


def test_compose_discovers_the_tool_packages_of_this_graph():
    """pipeline.graph looks for layer tools in the packages this graph calls tools."""
    from humv_usd.pipeline.graph import TOOL_PACKAGES

    assert set(TOOL_PACKAGES) == TOOLS


def test_no_package_cycles():
    graph: dict[str, set[str]] = {}
    for _, src, _, dst, _, _ in _edges():
        if src and dst and src != dst:
            graph.setdefault(src, set()).add(dst)
    seen, stack, cycles = set(), [], []

    def visit(node):
        if node in stack:
            cycles.append(stack[stack.index(node) :] + [node])
            return
        if node in seen:
            return
        seen.add(node)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            visit(nxt)
        stack.pop()

    for node in sorted(graph):
        visit(node)
    assert not cycles, cycles


def test_no_humv_usd_import_hidden_in_a_function():
    """Only the command line imports lazily (``humv-usd --help`` must not load Mitsuba)."""
    hidden = [
        f"{where}: {target}" for _, src, target, _, where, nested in _edges() if nested and src != "cli"
    ]
    assert not hidden, "\n".join(hidden)


@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_tool_reads_upstream_only_through_usd(tool):
    """A tool package imports no other tool, render or ground truth (its inputs are the
    scenario section and the upstream stage, read through humv_usd.usd)."""
    found = {
        dst
        for module, src, target, dst, _, _ in _edges()
        if src == tool and dst != tool and (module, target) not in PENDING
    }
    assert not found & (TOOLS | set().union(*LEVELS[7:]))


#: import name -> distribution name where they differ
DISTRIBUTIONS = {
    "pxr": "usd-core",
    "colour": "colour-science",
    "bpy": "bpy",
    "PIL": "pillow",
    "yaml": "pyyaml",
    "sklearn": "scikit-learn",
    "skimage": "scikit-image",
}


def test_pyproject_declares_every_imported_package():
    """Every third-party package the library imports (at the top or lazily) is a declared
    dependency (bpy as the ``blender`` extra, scikit-learn and scikit-image as the ``detector``
    extra, PyAV as the ``video`` extra), and every declared dependency is imported."""
    project = tomllib.loads((ROOT.parent / "pyproject.toml").read_text())["project"]
    declared = {
        re.split(r"[<>=!~ \[]", d, maxsplit=1)[0].lower()
        for d in project["dependencies"]
        + project["optional-dependencies"]["blender"]
        + project["optional-dependencies"]["detector"]
        + project["optional-dependencies"]["video"]
    }
    imported = set()
    for _, _, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                imported |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                imported.add(node.module.split(".")[0])
    third_party = {m for m in imported if m not in sys.stdlib_module_names and m != "humv_usd"}
    needed = {DISTRIBUTIONS.get(m, m).lower() for m in third_party}
    assert needed <= declared, f"imported but not declared in pyproject.toml: {sorted(needed - declared)}"
    # bpy: the Blender add-on and the interop tests use it, the library does not
    unused = declared - needed - {"bpy"}
    assert not unused, f"declared but never imported: {sorted(unused)}"


def test_every_module_imports():
    """A moved or renamed name breaks an import the linter cannot see (e.g. a lazy caller)."""
    import importlib

    for module, _, _ in _modules():
        importlib.import_module(module)


# ---------------------------------------------------------------------------- attribute names
#: methods that take a property or schema name (the first argument)
NAMED_ACCESS = {
    "GetAttribute",
    "CreateAttribute",
    "HasAttribute",
    "ApplyAPI",
    "RemoveAPI",
    "HasAPI",
    "GetPrimvar",
    "CreatePrimvar",
    "HasPrimvar",
    "GetRelationship",
    "CreateRelationship",
}
#: a HumV property name (``humv:<namespace>:<name>``, a primvar ``primvars:humv:...``, not a
#: two-part custom-data key such as ``humv:annotators``) or API schema name
HUMV_NAME = re.compile(r"^(primvars:)?humv:\w+:|^Humv\w*API$")

#: modules outside humv_usd/usd/ that still read or write HumV attributes by name (issue 11:
#: must shrink to empty); module -> why it is left
NAME_ACCESS_PENDING: dict[str, str] = {}


@functools.cache
def _humv_name_constants() -> frozenset[str]:
    """Module-level constants in humv_usd/usd/ whose value is a HumV property or schema name."""
    names = set()
    for path in (ROOT / "usd").glob("*.py"):
        for node in ast.parse(path.read_text()).body:
            if (
                isinstance(node, ast.Assign)
                and isinstance(node.value, ast.Constant)
                and isinstance(node.value.value, str)
                and HUMV_NAME.match(node.value.value)
            ):
                names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return frozenset(names)


def _names_a_humv_property(arg: ast.AST) -> bool:
    """The argument is (or is built from) a HumV name: a constant of humv_usd/usd/ (``S.X``,
    ``L.X``, ``X``), or a string literal starting with ``humv:`` / ``primvars:humv:`` / ``Humv``."""
    constants = _humv_name_constants()
    for node in ast.walk(arg):
        if isinstance(node, ast.Attribute) and node.attr in constants:
            return True
        if isinstance(node, ast.Name) and node.id in constants:
            return True
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and HUMV_NAME.match(node.value):
            return True
    return False


def _in_fstrings(tree: ast.AST) -> set[int]:
    """ids of the nodes inside f-strings (messages may name an attribute)."""
    return {id(n) for f in ast.walk(tree) if isinstance(f, ast.JoinedStr) for n in ast.walk(f)}


def _named_accesses():
    """module -> lines where a module outside humv_usd/usd/ and cli/ knows a HumV property (or
    API schema) name: a named access (``prim.GetAttribute(S.X)``, ``ApplyAPI("Humv...")``), any
    use of a name constant of humv_usd/usd/ outside an f-string (a helper that takes the name,
    ``S.X in prim.GetAppliedSchemas()``, a table of names), or a module-level constant of its own
    built from a HumV name literal."""
    constants = _humv_name_constants()
    found: dict[str, set[int]] = {}
    for module, _, tree in _modules():
        if _package(module) in {"usd", "cli"}:
            continue
        messages = _in_fstrings(tree)
        for node in ast.walk(tree):
            access = (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Attribute)
                and node.func.attr in NAMED_ACCESS
                and node.args
                and _names_a_humv_property(node.args[0])
            )
            constant = id(node) not in messages and (
                (isinstance(node, ast.Attribute) and node.attr in constants)
                or (isinstance(node, ast.Name) and node.id in constants and isinstance(node.ctx, ast.Load))
            )
            if access or constant:
                found.setdefault(module, set()).add(node.lineno)
        for node in tree.body:
            if isinstance(node, ast.Assign) and any(
                isinstance(n, ast.Constant) and isinstance(n.value, str) and HUMV_NAME.match(n.value)
                for n in ast.walk(node.value)
            ):
                found.setdefault(module, set()).add(node.lineno)
    return {m: sorted(lines) for m, lines in found.items()}


def test_only_usd_knows_attribute_names():
    """Typed readers and writers in humv_usd/usd/ are the only code that reads or writes a HumV
    attribute (or applies a HumV API schema) by name; the command line may name them in messages.
    NAME_ACCESS_PENDING lists what is left, and an entry that no longer applies must go."""
    found = _named_accesses()
    new = {m: lines for m, lines in found.items() if m not in NAME_ACCESS_PENDING}
    assert not new, f"HumV attributes accessed by name outside humv_usd/usd/ (use a reader/writer): {new}"
    stale = sorted(set(NAME_ACCESS_PENDING) - set(found))
    assert not stale, f"remove from NAME_ACCESS_PENDING (no named access left): {stale}"
