"""Helpers shared by the layer tools: new layers with our stage conventions, atomic writes."""

from __future__ import annotations

import os
import re
from pathlib import Path

from pxr import Gf, Sdf, Usd, UsdGeom, UsdUtils

import humv_usd  # noqa: F401  (registers the schemas before any stage exists)
from humv_usd.errors import InputError
from humv_usd.fileio import PENDING_NAME, write_text_atomic

WORLD = Sdf.Path("/World")
SCOPES = {
    "environment": WORLD.AppendChild("Environment"),
    "atmosphere": WORLD.AppendChild("Atmosphere"),
    "materials": WORLD.AppendChild("Materials"),
    "scene": WORLD.AppendChild("Scene"),
    "humans": WORLD.AppendChild("Humans"),
    "sensors": WORLD.AppendChild("Sensors"),
}


def attribute_value(attr, time):
    """``attr`` at ``time``, or None when the attribute is missing or invalid."""
    if not attr or not attr.IsValid():
        return None
    return attr.Get(time)


def new_layer_stage(fps: float, frame_count: int, doc: str) -> Usd.Stage:
    """An in-memory stage whose root layer becomes one of our layers.

    Sets our conventions on the layer (Z-up, metres, defaultPrim /World, frame range) so the
    layer is a complete USD file on its own, and defines /World.
    """
    stage = Usd.Stage.CreateInMemory()
    set_layer_metadata(stage.GetRootLayer(), fps, frame_count, doc)
    set_kind(UsdGeom.Xform.Define(stage, WORLD).GetPrim(), "assembly")
    return stage


def set_kind(prim: Usd.Prim, kind: str) -> None:
    """The prim's model kind (assembly, group, component): the model hierarchy that USD tools
    (usdview's pick modes, Omniverse, Blender's importer) use to find the assets in a scene. Ours:
    /World an assembly, /World/Scene and /World/Humans groups, each scene object and person a
    component."""
    Usd.ModelAPI(prim).SetKind(kind)


def set_layer_metadata(layer: Sdf.Layer, fps: float, frame_count: int, doc: str) -> None:
    layer.documentation = doc
    layer.defaultPrim = WORLD.name
    layer.timeCodesPerSecond = fps
    layer.framesPerSecond = fps
    layer.startTimeCode = 0
    layer.endTimeCode = max(frame_count - 1, 0)
    pseudo = layer.pseudoRoot
    pseudo.SetInfo(UsdGeom.Tokens.upAxis, UsdGeom.Tokens.z)
    pseudo.SetInfo(UsdGeom.Tokens.metersPerUnit, 1.0)


#: a layer's cache key (customLayerData): hash of its tool's version, the scenario values it reads
#: and the keys of the layers it reads (humv_usd.scenario.inputs.inputs_key)
INPUTS_KEY = "humv:inputsKey"


#: the root layer's record of its compose-written sublayers' keys (customLayerData):
#: {layer file path relative to the root: humv:inputsKey}
LAYER_KEYS = "humv:layerKeys"


def set_inputs_key(layer: Sdf.Layer, key: str) -> None:
    layer.customLayerData = {**dict(layer.customLayerData), INPUTS_KEY: key}


def layer_text(layer: Sdf.Layer) -> str:
    """The usda text of a layer, as it will be written."""
    return layer.ExportToString()


def relative_asset_paths(layer: Sdf.Layer, folder: str | Path) -> Sdf.Layer:
    """A copy of ``layer`` whose absolute file paths (sublayers, references, payloads, asset
    values) are relative to ``folder``, the folder the layer will be written to, so that an
    output folder can be moved or copied together with the files it points at.

    USD resolves a relative path (``./`` or ``../``) against the layer that holds it. A path is
    made relative only when it shares a folder other than the filesystem root with ``folder``
    (a scenario's assets beside its output); one that does not (e.g. a library under /opt for
    an output under /home) stays absolute. Package-internal paths (``a.usdz[b.usda]``) and
    non-file paths are left as they are. The in-memory ``layer`` is not changed (compose builds
    downstream layers on it, where relative paths would have no anchor); where no path changes,
    ``layer`` itself is returned.
    """
    base = os.path.abspath(folder)

    def relative(path: str) -> str:
        if not path or not os.path.isabs(path) or "[" in path:
            return path
        path = os.path.normpath(path)
        try:
            common = os.path.commonpath([path, base])
        except ValueError:  # another drive
            return path
        if os.path.dirname(common) == common:  # only the filesystem root in common
            return path
        rel = os.path.relpath(path, base)
        return rel if rel.startswith("..") else "./" + rel

    changed: list[str] = []

    def probe(path: str) -> str:  # leaves every path as it is; notes those that would change
        if relative(path) != path:
            changed.append(path)
        return path

    UsdUtils.ModifyAssetPaths(layer, probe)
    if not changed:  # nothing to change: no copy (a crowd's clothing layer is 100s of MB)
        return layer
    copy = Sdf.Layer.CreateAnonymous(".usda")
    copy.TransferContent(layer)
    UsdUtils.ModifyAssetPaths(copy, relative)
    return copy


def anchored_asset_paths(layer: Sdf.Layer, folder: str | Path) -> Sdf.Layer:
    """Resolve, in place, the file-relative paths (``./``, ``../``) of a layer opened as an
    anonymous layer from a file in ``folder`` (such a layer has no anchor of its own): the
    inverse of :func:`relative_asset_paths`. Returns ``layer``."""
    base = os.path.abspath(folder)

    def anchored(path: str) -> str:
        if path.startswith(("./", "../")) and "[" not in path:
            return os.path.normpath(os.path.join(base, path))
        return path

    UsdUtils.ModifyAssetPaths(layer, anchored)
    return layer


def open_anonymous(path: str | Path) -> Sdf.Layer | None:
    """The layer file at ``path`` as an anonymous layer (edits stay in memory) with its
    file-relative paths anchored at the file's folder (:func:`anchored_asset_paths`); None when
    it does not load. USD errors propagate (Tf.ErrorException)."""
    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    return anchored_asset_paths(layer, Path(path).resolve().parent) if layer is not None else None


def look_at_matrix(position, target, up=(0.0, 0.0, 1.0)) -> Gf.Matrix4d:
    """Local-to-world matrix of a USD camera at ``position`` looking at ``target``.

    USD cameras look down their local -Z with +Y up; world up is +Z. Looking straight up or
    down falls back to +Y as the up hint.
    """
    eye = Gf.Vec3d(*position)
    forward = (Gf.Vec3d(*target) - eye).GetNormalized()
    up_hint = Gf.Vec3d(*up)
    if abs(Gf.Dot(forward, up_hint)) > 0.999:
        up_hint = Gf.Vec3d(0.0, 1.0, 0.0)
    right = Gf.Cross(forward, up_hint).GetNormalized()
    cam_up = Gf.Cross(right, forward)
    back = -forward
    return Gf.Matrix4d(
        right[0],
        right[1],
        right[2],
        0.0,
        cam_up[0],
        cam_up[1],
        cam_up[2],
        0.0,
        back[0],
        back[1],
        back[2],
        0.0,
        eye[0],
        eye[1],
        eye[2],
        1.0,
    )


def finish(stage: Usd.Stage) -> Sdf.Layer:
    """The stage's root layer as a layer that outlives the stage (GetRootLayer is a weak handle)."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(stage.GetRootLayer())
    return layer


def usd_error_text(exc: Exception) -> str:
    """The first message of a Tf.ErrorException ("Error in 'f' at line n in file x : 'msg'").
    A message that quotes bytes which are not UTF-8 (a corrupt file) cannot even be turned into
    text by pxr: then the reason says so."""
    try:
        text = " ".join(str(exc).split())
    except UnicodeDecodeError:
        return "it holds bytes that are not UTF-8 text where USD expects text"
    found = re.findall(r" : '(.*?)'(?: Error in|\)?$)", text)
    first = found[0] if found else (text or type(exc).__name__)
    first = re.sub(r"pxrInternal_\w+?__pxrReserved__::", "", first).strip()
    # USD quotes the text it failed on: a whole long string value would make a page-long line
    return first if len(first) <= 300 else f"{first[:260]}... ({len(first)} characters)"


def broken_sublayers(root: Sdf.Layer, keep: list | None = None) -> list[str]:
    """One line per sublayer, at any depth below ``root``, that is missing or does not load
    (a truncated or corrupt file): ``<file>: sublayer of <layer> not found`` or ``... does not
    load (<USD's reason>)``. USD itself only warns and composes the stage without such a layer,
    which would render a scene with, e.g., the person missing."""
    problems: list[str] = []
    seen: set[str] = set()

    def walk(layer: Sdf.Layer) -> None:
        for sub in layer.subLayerPaths:
            file = layer.ComputeAbsolutePath(sub)
            if file in seen:
                continue
            seen.add(file)
            where = f"{file}: sublayer of {layer.realPath or layer.identifier}"
            if not Path(file).is_file():
                problems.append(f"{where} not found")
                continue
            try:
                child = find_or_open_current(file)
            except Exception as exc:  # pxr raises Tf.ErrorException
                problems.append(f"{where} does not load ({usd_error_text(exc)})")
                continue
            if child is None:
                problems.append(f"{where} does not load")
                continue
            if keep is not None:  # held, so that opening the stage does not parse it again
                keep.append(child)
            walk(child)

    walk(root)
    return problems


_KEY_TEXT = re.compile(r'"humv:inputsKey"\s*=\s*"([0-9a-fA-F]+)"')


def _inputs_key_of(path: Path) -> str | None:
    """A layer file's ``humv:inputsKey``, read from the head of its text (compose writes the
    customLayerData first) rather than by parsing the whole layer again."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16).decode("utf-8", errors="replace")
    except OSError:
        return None
    found = _KEY_TEXT.search(head)
    return found.group(1) if found else None


def unfinished_set(root: Sdf.Layer) -> list[str]:
    """Lines naming why the root and its sublayers are not one consistent set as compose wrote
    it: a write of several files that a kill interrupted (its journal is still beside the root),
    or a sublayer whose ``humv:inputsKey`` is not the one the root recorded for it
    (``humv:layerKeys``: the file comes from another compose, e.g. a new avatar beside the old
    thermal layer; a file without a key was made by hand and is not flagged). Call after
    :func:`broken_sublayers` found every sublayer loadable. A root without a record (older
    stages, hand-made roots) is not checked."""
    folder = Path(root.realPath).parent if root.realPath else None
    if folder is not None and (folder / PENDING_NAME).is_file():
        return [
            f"{folder}: a compose into this folder was interrupted while it moved its new files into "
            f"place ({PENDING_NAME} is there); run humv-usd compose again, which finishes it"
        ]
    keys = dict(root.customLayerData).get(LAYER_KEYS) or {}
    out = []
    for sub, expected in dict(keys).items():
        file = Path(root.ComputeAbsolutePath(sub))
        found = _inputs_key_of(file)
        if found is not None and found != expected:
            out.append(
                f"{file}: {INPUTS_KEY} {found}, but {root.realPath or root.identifier} was "
                f"composed with {expected}: the layer comes from another compose (an interrupted "
                "write or a copied file); run humv-usd compose again"
            )
    return out


def find_or_open_current(file: str) -> Sdf.Layer | None:
    """``Sdf.Layer.FindOrOpen`` that reads the file again when a layer of that path is still
    loaded in this process and the file changed since (``Reload`` re-reads only then; a layer with
    unsaved edits is left as it is): a long-lived process (tests, the editor's worker) that opened
    a composed folder, then recomposed it, otherwise checked and rendered the old layers (a
    thermal layer with the first body's face counts over the second body's garments)."""
    layer = Sdf.Layer.Find(file)
    if layer is None:
        return Sdf.Layer.FindOrOpen(file)
    if not layer.dirty:
        layer.Reload()
    return layer


def open_root_layer(path) -> Sdf.Layer:
    """The root layer of the stage file at ``path``, or InputError naming the file and the reason."""
    path = Path(path)
    if path.is_dir():
        hint = f" (e.g. {path / 'stage.usda'})" if (path / "stage.usda").is_file() else ""
        raise InputError(f"{path}: is a folder, expected a USD stage file{hint}")
    if not path.is_file():
        raise InputError(f"{path}: stage file not found")
    try:
        layer = find_or_open_current(str(path))
    except Exception as exc:  # pxr raises Tf.ErrorException
        raise InputError(f"{path}: cannot open as a USD stage ({usd_error_text(exc)})") from None
    if layer is None:
        raise InputError(f"{path}: cannot open as a USD stage")
    return layer


def open_stage(path) -> Usd.Stage:
    """Open a USD stage, or raise InputError with one line naming the file and the reason.

    A sublayer that is missing or does not load is an error too (one line per such layer,
    naming it): USD would open the stage without it."""
    root = open_root_layer(path)
    opened: list[Sdf.Layer] = []
    broken = broken_sublayers(root, opened) or unfinished_set(root)
    if broken:
        raise InputError(broken[0], broken)
    try:
        stage = Usd.Stage.Open(root)
    except Exception as exc:  # pxr raises Tf.ErrorException
        raise InputError(f"{path}: cannot open as a USD stage ({usd_error_text(exc)})") from None
    if stage is None:
        raise InputError(f"{path}: cannot open as a USD stage")
    return stage


def library_layer_main(path: Path, build, doc: str, argv=None) -> int:
    """Command line of a committed library layer (layers/*.usda): write it, or ``--check`` it.

    ``build()`` returns the Sdf.Layer; ``--check`` prints whether ``path`` holds exactly its text
    and exits 1 when it does not (CI keeps the committed files in step with the code).
    """
    import argparse

    parser = argparse.ArgumentParser(description=doc)
    parser.add_argument("--check", action="store_true", help="exit 1 if the file is out of date")
    args = parser.parse_args(argv)
    text = layer_text(build())
    if args.check:
        ok = path.is_file() and path.read_text(encoding="utf-8") == text
        print(f"{path}: {'up to date' if ok else 'out of date'}")  # noqa: T201 (a `python -m` command)
        return 0 if ok else 1
    write_text_atomic(path, text)
    print(f"wrote {path}")  # noqa: T201 (a `python -m` command)
    return 0
