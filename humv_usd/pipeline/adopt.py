"""``humv-usd adopt``: a Blender USD export -> OUT/stage.usda + OUT/layers/adopted.usda.

The mapping is :func:`humv_usd.usd.adopt.adopt_blender_export` (Blender's root prim, object/data
pairs, ``_materials``, primvar names, schema attributes restored from the original stage, frame
rate, held temperatures and labels for new meshes). This module does the files: it opens the
export (flattened, so references and sublayers of the export count) and the original stage,
checks the output folder before any work, and writes the two layers atomically, only after
the whole adoption succeeded. The root layer holds only sublayers and stage metadata (the
``humv-usd check`` rule) plus the original root layer's HumV customLayerData (annotators) and
``humv:adoptedFrom``.
"""

from __future__ import annotations

from pathlib import Path

from pxr import Sdf, Tf, Usd

from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import check_output_dir, write_text_atomic
from humv_usd.usd.adopt import AdoptReport, adopt_blender_export
from humv_usd.usd.layers import open_stage, set_layer_metadata, usd_error_text

ADOPTED_LAYER = "layers/adopted.usda"


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


def adopt(
    export_path,
    out_dir,
    original_path=None,
    *,
    fps: float | None = None,
    temperature_k: float | None = None,
    label_class: str = "other",
) -> tuple[Path, AdoptReport]:
    """Adopt the Blender export ``export_path`` into ``out_dir``; returns (stage path, report).

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
    root.subLayerPaths.append("./" + ADOPTED_LAYER)
    (out / "layers").mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / ADOPTED_LAYER, layer.ExportToString())
    write_text_atomic(out / "stage.usda", root.ExportToString())
    return out / "stage.usda", report
