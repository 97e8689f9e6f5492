"""``humv-usd adopt``: a Blender USD export -> OUT/stage.usda + OUT/layers/adopted.usda.

The mapping is :func:`humv_usd.usd.adopt.adopt_blender_export` (Blender's root prim, object/data
pairs, ``_materials``, primvar names, schema attributes restored from the original stage, frame
rate, held temperatures and labels for new meshes). This module does the files: it opens the
export (flattened, so references and sublayers of the export count) and the original stage,
checks the output folder before any work, and writes the two layers atomically, only after
the whole adoption succeeded. The root layer holds only sublayers and stage metadata (the
``humv-usd check`` rule) plus the original root layer's HumV customLayerData (annotators) and
``humv:adoptedFrom``.

Temperatures after an edit (issue 27 deliverable 5): the restored per-face temperatures are the
original scene's, so a person or object moved in Blender would keep its old shadow on the ground
and a new object would cast none. Given the scenario the original was composed from
(``scenario``, checked against the original's ``humv:scenarioDigest``), adopt runs the thermal
tool on the adopted stage and writes ``layers/thermal.usda`` (stronger than ``adopted.usda``):
shadows follow the moved people and objects, new objects cast theirs. A new mesh keeps the held
temperature adopt gave it (its custom property, ``--temperature-k`` or the air). Without a
scenario, a warning names the meshes that moved or are new.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import check_output_dir, commit_files
from humv_usd.pipeline.compose import compose_in_memory
from humv_usd.scenario import Scenario
from humv_usd.thermal import layer as thermal_tool
from humv_usd.usd.adopt import AdoptReport, adopt_blender_export, without_temperatures
from humv_usd.usd.layers import SCOPES, layer_text, open_stage, set_layer_metadata, usd_error_text

log = logging.getLogger(__name__)

ADOPTED_LAYER = "layers/adopted.usda"
THERMAL_LAYER = "layers/thermal.usda"
#: a mesh whose world bounds moved more than this [m] has moved (shadows are stale)
MOVED_M = 1e-3


def _open_export(path: Path) -> Sdf.Layer:
    if not path.is_file():
        raise InputError(bad_value("BLENDER_EXPORT", str(path), "expected an existing USD file"))
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:  # pxr raises Tf.ErrorException on files it cannot read
        raise InputError(f"BLENDER_EXPORT {str(path)!r}: not a USD file ({usd_error_text(exc)})") from None
    if any(str(k).startswith("humv:") for k in dict(stage.GetRootLayer().customLayerData)):
        raise InputError(
            bad_value(
                "BLENDER_EXPORT",
                str(path),
                "a HumV-USD stage (composed or adopted), not a Blender export: render or check it "
                "as it is, or export it from Blender and adopt that",
            )
        )
    return stage.Flatten()


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:  # a symlink loop: the output check reports it
        return False


def _refuse_writing_over_inputs(out: Path, export: Path, original_path) -> None:
    written = (out / "stage.usda", out / ADOPTED_LAYER)
    if original_path is not None:
        original = Path(original_path)
        if _same(out, original.parent) or any(_same(w, original) for w in written):
            raise InputError(
                bad_value(
                    "--out",
                    str(out),
                    f"the folder of --from {original} (adopt writes OUT/stage.usda: choose another folder)",
                )
            )
    if any(_same(w, export) for w in written):
        raise InputError(
            bad_value("--out", str(out), f"would write over BLENDER_EXPORT {export}: choose another folder")
        )


def _bounds(stage: Usd.Stage, time) -> dict[str, np.ndarray]:
    """World-space bounds (min, max) of every mesh outside the people, by path."""
    cache = UsdGeom.BBoxCache(time, [UsdGeom.Tokens.default_], useExtentsHint=False)
    out = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh) and not str(prim.GetPath()).startswith(str(SCOPES["humans"])):
            r = cache.ComputeWorldBound(prim).ComputeAlignedRange()
            out[str(prim.GetPath())] = np.array([r.GetMin(), r.GetMax()], float)
    return out


def moved_meshes(adopted: Usd.Stage, original: Usd.Stage) -> list[str]:
    """Meshes of ``adopted`` that are new or whose world bounds differ from ``original``'s at
    the first frame (people: their SkelRoot's transform), by more than :data:`MOVED_M`."""
    t = Usd.TimeCode(adopted.GetStartTimeCode())
    new, old = _bounds(adopted, t), _bounds(original, t)
    moved = [p for p, b in new.items() if p not in old or np.abs(b - old[p]).max() > MOVED_M]
    humans = adopted.GetPrimAtPath(SCOPES["humans"])
    if humans:
        for person in humans.GetChildren():
            before = original.GetPrimAtPath(person.GetPath())
            a = UsdGeom.Xformable(person).ComputeLocalToWorldTransform(t)
            b = UsdGeom.Xformable(before).ComputeLocalToWorldTransform(t) if before else None
            if b is None or np.abs(np.asarray(a) - np.asarray(b)).max() > MOVED_M:
                moved.append(str(person.GetPath()))
    return moved


def _thermal_layer(scenario: Scenario, adopted: Sdf.Layer, original, report: AdoptReport) -> Sdf.Layer:
    """The thermal tool's layer for the adopted stage (see the module doc)."""
    recorded = dict(original.GetRootLayer().customLayerData).get("humv:scenarioDigest") if original else None
    if recorded is not None and recorded != scenario.digest():
        where = scenario.path or "the scenario"
        raise InputError(
            bad_value(
                "--scenario",
                str(where),
                f"not the scenario --from was composed from (digest {scenario.digest()}, the stage "
                f"records {recorded}): give that scenario file",
            )
        )
    # the tool's input is the geometry, not the temperatures of the original scene: without
    # them its rule "no per-face data" lets it re-tessellate the ground at the new shadow edges
    upstream = compose_in_memory([without_temperatures(adopted)], scenario["general"]["fps"])
    try:
        layer = thermal_tool.build(scenario, upstream)
    except Tf.ErrorException as exc:
        raise InputError(
            f"--scenario: the thermal tool cannot read the adopted stage ({usd_error_text(exc)})"
        ) from None
    # new meshes keep the held temperature adopt gave them (the weaker adopted layer's)
    return without_temperatures(layer, report.new_meshes)


def adopt(
    export_path,
    out_dir,
    original_path=None,
    *,
    fps: float | None = None,
    temperature_k: float | None = None,
    label_class: str = "other",
    scenario: Scenario | None = None,
) -> tuple[Path, AdoptReport]:
    """Adopt the Blender export ``export_path`` into ``out_dir``; returns (stage path, report).
    ``scenario``: the scenario the ``original_path`` stage was composed from; the thermal tool
    then recomputes the temperatures of the adopted stage (``layers/thermal.usda``).

    Raises
    ------
    InputError
        Besides bad inputs: when ``out_dir`` is the ``--from`` stage's folder or a file it would
        write is the ``--from`` stage or the export (adopting must never write over its inputs).
    """
    _refuse_writing_over_inputs(Path(out_dir), Path(export_path), original_path)
    out = check_output_dir(out_dir)
    export = _open_export(Path(export_path))
    original = open_stage(original_path) if original_path is not None else None
    try:
        layer, report = adopt_blender_export(
            export, original, fps=fps, temperature_k=temperature_k, label_class=label_class
        )
    except Tf.ErrorException as exc:  # an export USD cannot edit as the mapping needs
        raise InputError(
            f"BLENDER_EXPORT {str(export_path)!r}: cannot adopt ({usd_error_text(exc)})"
        ) from None
    thermal = _thermal_layer(scenario, layer, original, report) if scenario is not None else None
    if scenario is None and original is not None:
        moved = moved_meshes(Usd.Stage.Open(layer), original)
        if moved:
            shown = ", ".join(moved[:4]) + (f" and {len(moved) - 4} more" if len(moved) > 4 else "")
            log.warning(
                "moved or new since --from: %s; their shadows and the temperatures of the surfaces "
                "around them are the original scene's: pass --scenario (the scenario --from was "
                "composed from) to recompute them",
                shown,
            )
    root = Sdf.Layer.CreateAnonymous("stage.usda")
    frames = int(layer.endTimeCode - layer.startTimeCode) + 1
    set_layer_metadata(
        root, report.fps, frames, f"HumV-USD stage adopted from the Blender export {export_path}"
    )
    root.startTimeCode, root.endTimeCode = layer.startTimeCode, layer.endTimeCode
    data = {}
    if original is not None:
        data = {
            k: v for k, v in dict(original.GetRootLayer().customLayerData).items() if k.startswith("humv:")
        }
    data["humv:adoptedFrom"] = str(export_path)
    root.customLayerData = data
    files = {out / ADOPTED_LAYER: layer.ExportToString()}
    if thermal is not None:
        root.subLayerPaths.append("./" + THERMAL_LAYER)
        files[out / THERMAL_LAYER] = layer_text(thermal)
    root.subLayerPaths.append("./" + ADOPTED_LAYER)
    files[out / "stage.usda"] = root.ExportToString()
    (out / "layers").mkdir(parents=True, exist_ok=True)
    commit_files(out, files)
    return out / "stage.usda", report
