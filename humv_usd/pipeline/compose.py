"""``humv-usd compose``: scenario → one USD layer per part + a root stage that sublayers them.

The layers form a graph (:mod:`humv_usd.pipeline.graph`): each tool declares the scenario values
it reads and the layers it reads from the stage; compose builds upstream layers first and gives
each layer a cache key, the hash of its tool's version, the values it reads and the keys of its
upstream layers (``humv:inputsKey`` in the layer's customLayerData). A layer whose key is
unchanged is not rebuilt: the file on disk is used (also as upstream of the layers that read it).

Hand edits are never discarded silently. compose.json records the hash of every layer text
compose wrote; a layer edited since is kept while its key is unchanged (and the layers reading
it are rebuilt on the edited file); if it would be rebuilt, compose stops with one error line
per file before writing anything, unless ``force``. The supported way to edit is a user layer:
any sublayer of OUT/stage.usda that compose did not write is kept on re-runs, stronger than
compose's layers, and is part of the stage every tool with upstream layers reads (its content
enters their keys).

Every layer is built in memory first; only when all of them succeeded is anything written, each
file atomically and only if its text changed (so an unchanged scenario rewrites nothing).
Parts the scenario lacks get no layer; the report says what was skipped and why.

Files a layer points at (a scene asset, a site layer) are written as paths relative to the
layer's folder when they share a folder with it (:func:`humv_usd.usd.layers.relative_asset_paths`),
so an output folder moved or copied together with the scenario's assets (same relative
placement) still composes, checks and renders; in memory (and when compose reopens a written
layer) they are absolute.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import logging
import re
import secrets
import time
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from pathlib import Path

from pxr import Sdf, Tf, Usd

import humv_usd
from humv_usd.errors import InputError
from humv_usd.fileio import (
    StagedText,
    check_output_dir,
    commit_files,
    discard_staged,
    finish_pending,
    folder_lock,
    remove_stale_temps,
    stage_file,
)
from humv_usd.groundtruth import annotators
from humv_usd.pipeline.budget import compose_budget, require_fits
from humv_usd.pipeline.graph import Node, build_order, discover_tools, layer_graph, strength_order
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import file_digest, inputs_key, read_values
from humv_usd.scenario.warnings import suspicious
from humv_usd.usd.layers import (
    LAYER_KEYS,
    layer_text,
    open_anonymous,
    relative_asset_paths,
    set_inputs_key,
    set_layer_metadata,
    usd_error_text,
)
from humv_usd.usd.spill import SampleSpill

log = logging.getLogger(__name__)

LAYER_DIR = "layers"
ROOT_NAME = "stage.usda"
REPORT_NAME = "compose.json"
_KEY_TEXT = re.compile(r'"humv:inputsKey"\s*=\s*"([0-9a-f]+)"')


@dataclass
class LayerState:
    """What compose did with one layer and why."""

    name: str
    key: str
    inputs: dict
    upstream: dict[str, str]  # upstream layer -> the key it passes on
    state: str = "cached"  # "rebuilt", "cached" or "kept hand edit"
    why: str = "cached"
    sha256: str | None = None  # of the text compose wrote (kept across runs while cached)
    edited_sha256: str | None = None  # of the file, when edited by hand
    written: bool = False
    seconds: float = 0.0
    loaded: Sdf.Layer | None = None  # the file on disk, opened when it is used as it is
    ran: dict = field(default_factory=dict)  # the rebuilt layer's "humv:<tool>:ran" entries
    #: the key without the inputs only the render reads (the tool's ``RENDER_ONLY`` read paths)
    downstream_key: str | None = None

    @property
    def rebuild(self) -> bool:
        return self.state == "rebuilt"

    @property
    def passed_key(self) -> str:
        """The key downstream layers see: the layer's key without its render-only inputs (a
        sensor's NETD changes the sensors layer, not the thermal layer built on it); a hand edit
        counts as a change of this layer."""
        key = self.downstream_key or self.key
        return key if self.edited_sha256 is None else _sha(key + self.edited_sha256)


@dataclass
class ComposeReport:
    stage_path: Path
    layers: list[tuple[str, bool, float]] = field(default_factory=list)  # name, written, seconds
    skipped: list[tuple[str, str]] = field(default_factory=list)  # part, reason
    removed: list[str] = field(default_factory=list)
    states: dict[str, LayerState] = field(default_factory=dict)  # in build order
    user_layers: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def written(self) -> list[str]:
        return [name for name, wrote, _ in self.layers if wrote]

    @property
    def rebuilt(self) -> list[str]:
        return [n for n, s in self.states.items() if s.rebuild]

    def summary(self) -> str:
        """One line: how many layers were rebuilt, cached, kept; the time."""
        counts: dict[str, list[str]] = {"rebuilt": [], "kept hand edit": [], "cached": []}
        for st in self.states.values():
            counts[st.state].append(st.name)
        parts = [
            f"{len(v)} {k}" + (f" ({', '.join(v)})" if k != "cached" else "") for k, v in counts.items() if v
        ]
        user = f"; {len(self.user_layers)} user layer(s) kept" if self.user_layers else ""
        return f"{len(self.states)} layers: {', '.join(parts)}{user}; {self.seconds:.2f} s"


#: the tools :func:`plan` decides by its rules; any other tool gets its layer when its upstream
#: layers are needed
PLANNED = frozenset(
    {
        "environment",
        "atmosphere",
        "atmosphere_paths",
        "materials",
        "scene",
        "avatar_{id}",
        "clothing_{id}",
        "sensors",
        "thermal",
    }
)


def plan(scenario: Scenario) -> tuple[list[str], list[tuple[str, str]]]:
    """Which layers this scenario needs and which parts are skipped, and why.

    A tool module that none of the rules below names gets its layer when all its upstream
    layers are needed (per person: for every ``[[human]]``)."""
    needed, skipped = ["environment"], []
    has_ir = bool(scenario.infrared_sensors)
    has_meshes = bool(scenario["human"]) or scenario["scene"] is not None
    # EO sensors need the atmosphere too (sun and skylight spectra, paths); it runs LOWTRAN7
    # only for infrared bands (an EO-only scenario gets the analytic/SPCTRL2 tables)
    if scenario["sensor"] or "atmosphere" in scenario.given:
        needed.append("atmosphere")
    else:
        skipped.append(("atmosphere", "no sensor and no [atmosphere] section"))
    if has_meshes:
        needed.append("materials")
    else:
        skipped.append(("materials", "no humans and no scene"))
    if scenario["scene"] is not None:
        needed.append("scene")
    else:
        skipped.append(("scene", "no [scene] section"))
    if scenario["human"]:
        needed.extend(f"avatar_{h['id']}" for h in scenario["human"])
        dressed = [h["id"] for h in scenario["human"] if h["clothing"]]
        needed.extend(f"clothing_{i}" for i in dressed)
        if not dressed:
            skipped.append(("clothing", "nobody wears garments"))
    else:
        skipped.append(("avatar", "no [[human]]"))
    if scenario["sensor"]:
        needed.extend(["sensors", "atmosphere_paths"])
    else:
        skipped.extend([("sensors", "no [[sensor]]"), ("atmosphere_paths", "no [[sensor]]")])
    if has_meshes and has_ir:
        needed.append("thermal")
    else:
        skipped.append(("thermal", "no infrared sensor" if has_meshes else "no meshes"))
    for tool in discover_tools().values():  # a tool the rules above do not plan
        if tool.name in PLANNED:
            continue
        for human_id in [h["id"] for h in scenario["human"]] if tool.per_human else [None]:
            name = tool.layer_name(human_id)
            wanted = [u.format(id=human_id) for u in tool.upstream]
            if all(any(fnmatchcase(n, u) for n in needed) for u in wanted):
                needed.append(name)
            else:
                skipped.append((name, f"needs {', '.join(wanted)}"))
    return needed, skipped


def compose_in_memory(layers: list[Sdf.Layer], fps: float) -> Usd.Stage:
    """A stage of ``layers`` (weakest first) in memory."""
    root = Sdf.Layer.CreateAnonymous(".usda")
    # same time codes per second as the layers, or USD rescales their time samples
    root.timeCodesPerSecond = fps
    root.framesPerSecond = fps
    root.subLayerPaths = [lyr.identifier for lyr in reversed(layers)]  # strongest first
    return Usd.Stage.Open(root)


def root_layer(
    scenario: Scenario, names: list[str], user: list[str] = (), keys: dict[str, str] | None = None
) -> Sdf.Layer:
    """The root layer: ``user`` sublayers (kept as given), then ``names`` (strongest first).

    ``keys`` (layer name -> the ``humv:inputsKey`` compose gave it) go into the root's
    customLayerData as ``humv:layerKeys`` by file path relative to the root: check and render verify that every
    layer file holds the key of this compose, so a set mixed by an interrupted write or a copy
    is refused instead of rendered."""
    g = scenario["general"]
    root = Sdf.Layer.CreateAnonymous(".usda")
    set_layer_metadata(
        root,
        g["fps"],
        scenario.frame_count,
        f"HumV-USD stage for scenario '{g['name']}' (composed by humv-usd compose)",
    )
    root.subLayerPaths = [*user, *(f"./{LAYER_DIR}/{n}.usda" for n in names)]
    root.customLayerData = {
        "humv:scenario": g["name"],
        "humv:scenarioDigest": scenario.digest(),
        "humv:version": humv_usd.__version__,
        **annotators.stage_metadata(scenario),  # [annotations] -> what the render computes
    }
    if keys:
        data = dict(root.customLayerData)
        data[LAYER_KEYS] = {f"{LAYER_DIR}/{n}.usda": keys[n] for n in names if n in keys}
        root.customLayerData = data
    return root


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def stage_layer(path: Path, layer: Sdf.Layer, spill: SampleSpill | None = None) -> tuple[StagedText, str]:
    """Stage ``layer``'s usda text for ``path`` (:func:`humv_usd.fileio.stage_file`) through
    USD's streaming writer, with the samples of ``spill`` spliced in at their placeholders;
    returns (the staged file, its :func:`_sha`). The same bytes as ``layer_text(layer)``."""
    digest: list[str] = []

    def write(tmp: Path) -> None:
        try:
            if spill is not None:
                digest.append(spill.export(layer, tmp))
                return
            ok = layer.Export(str(tmp))
        except Tf.ErrorException as exc:  # USD's writer failed (a full disk): an OSError, one line
            raise OSError(errno.EIO, usd_error_text(exc), str(path)) from None
        if not ok:
            raise OSError(errno.EIO, "USD could not write the layer", str(path))
        h = hashlib.sha256()
        with open(tmp, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        digest.append(h.hexdigest())

    staged = stage_file(path, write)
    return staged, digest[0][:16]


def hold_layer(layer: Sdf.Layer, folder: Path, name: str) -> tuple[Sdf.Layer, Path]:
    """``layer`` read back from a scratch crate (usdc) file in ``folder``, and that file: the
    same specs and values (crate stores them exactly), but a later build reads the samples it
    asks for from the mapped file (page cache) instead of compose holding every frame of every
    person in its own memory until the last reader is built (a crowd's clothing layers: ~55 kB
    per person-frame, issue 29.5). The file has a temp name that :func:`remove_stale_temps`
    removes after a kill; compose removes it when the layer is dropped."""
    tmp = folder / f".{name}.held.{secrets.token_hex(4)}.tmp.usdc"
    try:
        ok = layer.Export(str(tmp))
        held = Sdf.Layer.OpenAsAnonymous(str(tmp)) if ok else None
    except Tf.ErrorException as exc:  # a full disk: an OSError, one line
        tmp.unlink(missing_ok=True)
        raise OSError(errno.EIO, usd_error_text(exc), str(tmp)) from None
    if held is None:
        tmp.unlink(missing_ok=True)
        raise OSError(errno.EIO, "USD could not write or read back the layer", str(tmp))
    return held, tmp


def _previous(out: Path) -> dict:
    """The previous run's compose.json (empty when there is none or it is unreadable)."""
    try:
        return json.loads((out / REPORT_NAME).read_text())
    except (OSError, ValueError):
        return {}


def _open_layer(path: Path) -> tuple[Sdf.Layer | None, str | None]:
    """The layer file at ``path`` opened as an anonymous layer, or None and why it does not load."""
    try:
        layer = open_anonymous(path)
    except Exception as exc:  # noqa: BLE001 (USD raises Tf.ErrorException)
        return None, f"does not load as USD ({usd_error_text(exc)})"
    return (layer, None) if layer is not None else (None, "does not load as USD")


def _owned(sub: str) -> bool:
    """Whether a sublayer path of the root is one of compose's layers."""
    prefix = f"./{LAYER_DIR}/"
    return sub.startswith(prefix) and any(
        fnmatchcase(sub.removeprefix(prefix), t.pattern) for t in discover_tools().values()
    )


def _why(state: LayerState, prev: dict | None, version: str, current_key: str | None) -> str:
    if current_key is None:
        return "no inputs key in the file (not written by this compose)"
    if prev is None:
        return "key changed (no record of the previous inputs in compose.json)"
    reasons = []
    if prev.get("version") != version:
        reasons.append(f"version changed: {prev.get('version')} -> {version}")
    old = prev.get("inputs", {})
    changed = sorted(k for k in old.keys() | state.inputs.keys() if old.get(k) != state.inputs.get(k))
    if changed:
        more = f" and {len(changed) - 5} more" if len(changed) > 5 else ""
        reasons.append("inputs changed: " + ", ".join(changed[:5]) + more)
    old_up = prev.get("upstream", {})
    ups = [u for u in state.upstream if old_up.get(u) != state.upstream[u]]
    if ups:
        reasons.append("upstream changed: " + ", ".join(ups))
    return "; ".join(reasons) or "key changed"


def _decide(node: Node, state: LayerState, path: Path, prev: dict | None, force: bool) -> str | None:
    """Set ``state`` (rebuild or use the file); return an error line for a hand edit in the way."""
    if not path.is_file():
        state.state, state.why = "rebuilt", "new"
        return None
    text = path.read_bytes().decode("utf-8", errors="replace")  # not UTF-8: an edit, never a crash
    found = _KEY_TEXT.search(text)
    on_disk = found.group(1) if found else None
    file_sha = _sha(text)
    recorded = prev.get("sha256") if prev else None
    edited = recorded is not None and recorded != file_sha
    state.sha256 = recorded or file_sha
    if on_disk == state.key:
        # compose would use this file (kept, and read by downstream tools): it must load
        state.loaded, problem = _open_layer(path)
        if problem:
            state.state, state.why = "rebuilt", f"the file {problem}"
            if not force:
                return (
                    f"{path}: {problem}, so compose cannot use it; re-run with --force to rebuild it "
                    "(an unfinished hand edit in it is then lost), or fix it"
                )
            state.why += "; rebuilt (--force)"
            return None
        if edited:
            state.state, state.why, state.edited_sha256 = "kept hand edit", "kept hand edit", file_sha
        return None
    state.state, state.why = "rebuilt", _why(state, prev, node.tool.version, on_disk)
    if edited:
        if not force:
            return (
                f"{path}: edited by hand since compose wrote it, and compose would rebuild it "
                f"({state.why}); re-run with --force to overwrite the edit, or put the edit in a user "
                f"layer (a sublayer you add to {path.parent.parent / ROOT_NAME}: compose keeps it, "
                "stronger than its own layers)"
            )
        state.why += "; hand edit overwritten (--force)"
    return None


def _user_layers(out: Path):
    """Sublayers of OUT/stage.usda compose did not write, the hashes of their files, the hash of
    the root without them (None when there is no readable root) and error lines."""
    root_path = out / ROOT_NAME
    if not root_path.is_file():
        return [], {}, None, []
    try:
        root = Sdf.Layer.OpenAsAnonymous(str(root_path))
    except Exception:  # noqa: BLE001 (USD raises Tf.ErrorException; unreadable roots are rewritten)
        root = None
    if root is None:
        return [], {}, None, []
    user = [s for s in root.subLayerPaths if not _owned(s)]
    hashes, errors = {}, []
    for sub in user:
        file = (out / sub).resolve()
        if not file.is_file():
            errors.append(f"{root_path}: user sublayer {sub}: file not found ({file})")
            continue
        _, problem = _open_layer(file)
        if problem:
            errors.append(
                f"{root_path}: user sublayer {sub}: {file} {problem}; fix it or remove it from the root"
            )
            continue
        hashes[sub] = file_digest(file)  # with the files it references: a referenced edit counts
    root.subLayerPaths = [s for s in root.subLayerPaths if _owned(s)]
    return user, hashes, _sha(layer_text(root)), errors


def _root_edit(out: Path, prev: dict, disk_sha: str | None, root_sha: str, force: bool):
    """Whether the root was edited by hand (other than adding sublayers) and an error line if
    compose would rewrite such an edit."""
    recorded = prev.get("stage", {}).get("sha256")
    edited = bool(recorded) and disk_sha is not None and disk_sha != recorded and not force
    if edited and root_sha != recorded:
        return edited, [
            f"{out / ROOT_NAME}: edited by hand (other than adding sublayers) since compose wrote it, "
            "and compose would rewrite it; re-run with --force to overwrite the edit, or put the edit "
            "in a user layer (a sublayer you add to the root)"
        ]
    return edited, []


def compose(
    scenario: Scenario,
    out_dir: str | Path,
    force: bool = False,
    wait: bool = False,
    yes: bool = False,
    progress=None,
) -> ComposeReport:
    """Write OUT/layers/*.usda and OUT/stage.usda for ``scenario``; see the module doc.

    ``force``: overwrite layers (and the root) edited by hand instead of stopping. The folder is
    locked while compose runs (:func:`humv_usd.fileio.folder_lock`): another compose into it
    raises InputError naming that process, or with ``wait`` waits for it. All files are written
    as one change (:func:`humv_usd.fileio.commit_files`): a kill leaves the old set or the new
    one; a change a kill interrupted is finished first. A scenario whose estimated memory or
    disk (:mod:`humv_usd.pipeline.budget`) exceeds this machine's is refused unless ``yes``.
    ``progress(done, total, text)``: called before each layer build and after the last."""
    out = check_output_dir(out_dir)
    require_fits(compose_budget(scenario), out, yes)
    for line in suspicious(scenario):  # valid but probably not meant: one line each
        log.warning(line)
    with folder_lock(out, "humv-usd compose", wait=wait):
        finish_pending(out)  # a compose killed after its commit point: complete its write
        for folder in (out, out / LAYER_DIR):  # one killed before it: drop its temp files
            remove_stale_temps(folder)
        return _compose_locked(scenario, out, force, progress)


def downstream_key(tool, values: dict, upstream: dict) -> str | None:
    """The key the layers built on ``tool``'s layer see: its inputs key without the values of
    the tool's ``RENDER_ONLY`` read paths (inputs only the render reads); None when it declares
    none (then they see its key). The sweep's ``layer_keys`` predicts keys with it too."""
    patterns = getattr(tool.module, "RENDER_ONLY", ())
    if not patterns:
        return None
    kept = {k: v for k, v in values.items() if not any(fnmatchcase(k, p) for p in patterns)}
    return inputs_key(tool.version, kept, upstream)


def _compose_locked(scenario: Scenario, out: Path, force: bool, progress=None) -> ComposeReport:
    t0 = time.perf_counter()
    layer_dir = out / LAYER_DIR
    fps = scenario["general"]["fps"]
    needed, skipped = plan(scenario)
    nodes = layer_graph(scenario, needed)
    order = build_order(nodes)
    strength = strength_order(nodes)
    prev_report = _previous(out)
    prev_layers = {e["name"]: e for e in prev_report.get("layers", []) if "key" in e}
    user, user_hashes, disk_root_sha, errors = _user_layers(out)

    # 1. decide what to rebuild, before building (or writing) anything
    states: dict[str, LayerState] = {}
    for name in order:
        node = nodes[name]
        upstream = {u: states[u].passed_key for u in node.upstream}
        if node.upstream:
            upstream.update({f"user:{u}": h for u, h in user_hashes.items()})
        values = read_values(scenario, node.tool.reads, node.human_id)
        key = inputs_key(node.tool.version, values, upstream)
        states[name] = LayerState(name, key, values, upstream)
        states[name].downstream_key = downstream_key(node.tool, values, upstream)
        error = _decide(node, states[name], layer_dir / f"{name}.usda", prev_layers.get(name), force)
        errors += [error] if error else []
    keys = {name: st.key for name, st in states.items()}
    root_sha = _sha(layer_text(root_layer(scenario, strength, keys=keys)))
    root_edited, root_errors = _root_edit(out, prev_report, disk_root_sha, root_sha, force)
    errors += root_errors
    stale = [
        p
        for t in discover_tools().values()
        for p in (sorted(layer_dir.glob(t.pattern)) if layer_dir.is_dir() else [])
        if p.stem not in nodes
    ]
    for p in stale:
        recorded = prev_layers.get(p.stem, {}).get("sha256")
        if recorded and recorded != _sha(p.read_text()) and not force:
            errors.append(
                f"{p}: edited by hand, and the scenario no longer has this layer; re-run with --force "
                "to remove it, or move the edit into a user layer"
            )
    if errors:
        raise InputError("", errors)

    # 2. build in dependency order; unchanged layers come from their files. Streaming: each
    # rebuilt layer's text goes to a temp file beside its target as soon as it is built (the
    # change is committed at the end, as one), and a layer is dropped from memory after the
    # last layer that reads it is built, so compose holds the layers a build needs, not the
    # texts of all of them (a crowd's avatar and clothing layers: issue 29)
    layers: dict[str, Sdf.Layer] = {}
    held: dict[str, Path] = {}  # layers held for later builds: their scratch files (hold_layer)
    had_layer_dir = layer_dir.is_dir()
    staged: dict[str, StagedText] = {}
    side: dict[Path, StagedText] = {}
    user_layers = [open_anonymous((out / u).resolve()) for u in user]
    last_use = {u: i for i, name in enumerate(order) for u in nodes[name].upstream}

    def layer_of(name: str) -> Sdf.Layer:
        if name not in layers:
            layers[name] = states[name].loaded or open_anonymous(layer_dir / f"{name}.usda")
        return layers[name]

    to_build = [name for name in order if states[name].rebuild]
    try:
        for i, name in enumerate(order):
            node, state = nodes[name], states[name]
            if not state.rebuild:
                continue
            if progress is not None:
                progress(to_build.index(name), len(to_build), f"layer {name}")
            t = time.perf_counter()
            upstream = None
            if node.upstream:
                below = [layer_of(u) for u in reversed(strength) if u in node.upstream]
                upstream = compose_in_memory(below + list(reversed(user_layers)), fps)
            # a spilled layer holds placeholders, not samples: only for a layer no later build reads
            spill = SampleSpill(layer_dir, name) if node.tool.spills and last_use.get(name, -1) <= i else None
            try:
                layer = node.tool.build(scenario, node.human, upstream, spill)
                del upstream
                set_inputs_key(layer, state.key)
                # the file holds paths relative to its folder (a movable output), the layer in
                # memory absolute ones (downstream tools compose it, anonymous, without an anchor).
                # Written by USD's streaming writer (with a spill's samples spliced in), never
                # held as one string: a crowd's layer texts are GBs (issue 29.5)
                staged[name], state.sha256 = stage_layer(
                    layer_dir / f"{name}.usda", relative_asset_paths(layer, layer_dir), spill
                )
            finally:
                if spill is not None:
                    spill.close()
            # files a tool writes beside its layer (the sky texture the atmosphere layer's dome
            # points at): staged now, committed with the layers as one change
            for file_name, write in getattr(node.tool.module, "side_files", lambda _: {})(layer).items():
                side[layer_dir / file_name] = stage_file(layer_dir / file_name, write)
            state.ran = {k: dict(v) for k, v in dict(layer.customLayerData).items() if k.endswith(":ran")}
            if last_use.get(name, -1) > i:  # a later build reads it: held on disk
                layers[name], held[name] = hold_layer(layer, layer_dir, name)
            del layer
            for u in node.upstream:  # no later layer reads it: drop it
                if last_use.get(u) == i:
                    layers.pop(u, None)
                    states[u].loaded = None
                    with contextlib.suppress(KeyError, OSError):
                        held.pop(u).unlink()
            state.seconds = time.perf_counter() - t
    except BaseException:
        discard_staged([*staged.values(), *side.values()])
        raise
    finally:
        layers.clear()
        for path in held.values():
            with contextlib.suppress(OSError):
                path.unlink()
        if not had_layer_dir:  # the folder holding them, if this run made it and it is empty
            with contextlib.suppress(OSError):
                layer_dir.rmdir()
    if progress is not None:
        progress(len(to_build), len(to_build), "writing")
    root_text = layer_text(root_layer(scenario, strength, user, keys=keys))

    # 3. write changed layers, the root and the report as one change (a kill leaves old or new)
    report = ComposeReport(stage_path=out / ROOT_NAME, skipped=skipped, states=states, user_layers=user)
    files: dict = {layer_dir / f"{name}.usda": staged[name] for name in order if states[name].rebuild}
    files.update(side)
    # a root edited by hand whose content compose would not change stays as it is
    if not root_edited:
        files[out / ROOT_NAME] = root_text
    unchanged = {
        p: x.same_as(p)
        if isinstance(x, StagedText)
        else p.is_file() and p.read_text(encoding="utf-8", errors="replace") == x
        for p, x in files.items()
    }
    for name in order:
        state = states[name]
        state.written = state.rebuild and not unchanged[layer_dir / f"{name}.usda"]
        report.layers.append((name, state.written, state.seconds))
    report.removed = [p.name for p in stale]
    wrote_root = not root_edited and not unchanged[out / ROOT_NAME]
    report.layers.append(("stage", wrote_root, 0.0))
    report.seconds = time.perf_counter() - t0
    try:
        files[out / REPORT_NAME] = _report_text(
            scenario, report, prev_report, nodes, order, strength, root_sha
        )
    except BaseException:
        discard_staged(files.values())
        raise
    commit_files(out, files, remove=stale)
    return report


def _report_text(scenario, report, prev_report, nodes, order, strength, root_sha) -> str:
    """compose.json: the graph, what was rebuilt and why, run times, the hashes of what compose
    wrote (to recognise hand edits) and what each tool ran."""
    prev_ran = prev_report.get("ran", {})
    ran = {}
    for name in order:  # what each tool ran and skipped (its layer's "humv:<tool>:ran")
        if not report.states[name].rebuild:
            if name in prev_ran:
                ran[name] = prev_ran[name]
            continue
        for v in report.states[name].ran.values():
            ran[name] = v
    entries = []
    for name in order:
        s, node = report.states[name], nodes[name]
        entries.append(
            {
                "name": name,
                "state": s.state,
                "why": s.why,
                "written": s.written,
                "seconds": round(s.seconds, 4),
                "key": s.key,
                "version": node.tool.version,
                "reads": list(node.tool.reads),
                "upstream": s.upstream,
                "inputs": s.inputs,
                "sha256": s.sha256,
            }
        )
    root_written = report.layers[-1][1]
    entries.append({"name": "stage", "written": root_written, "seconds": 0.0})
    doc = {
        "humv_usd": humv_usd.__version__,
        "scenario_digest": scenario.digest(),
        "summary": report.summary(),
        "seconds_total": round(report.seconds, 4),
        "build_order": order,
        "strength": strength,
        "user_layers": report.user_layers,
        "layers": entries,
        "stage": {"sha256": root_sha, "written": root_written},
        "skipped": [{"part": p, "reason": r} for p, r in report.skipped],
        "ran": ran,
        "removed": report.removed,
    }
    return json.dumps(doc, indent=2) + "\n"
