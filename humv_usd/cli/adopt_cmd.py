"""``humv-usd adopt``: a Blender USD export back into a stage HumV renders.

Registered on the command group in :mod:`humv_usd.cli.main`. The mapping is
:mod:`humv_usd.usd.adopt`; the files :mod:`humv_usd.pipeline.adopt`. Bad input is one line,
exit 2, nothing written.
"""

from __future__ import annotations

from pathlib import Path

import click

from humv_usd.cli.common import reports_errors


@click.command("adopt", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("blender_export", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o", "--out", "out_dir", required=True, help="Output folder (stage.usda + layers/adopted.usda)."
)
@click.option(
    "--from",
    "original",
    default=None,
    help="The composed stage the export came from (OUT/stage.usda): restores what Blender drops "
    "(sensor, avatar, label and thermal attributes, environment, atmosphere, frame rate).",
)
@click.option("--fps", type=float, default=None, help="Frames per second (default: the --from stage's).")
@click.option(
    "--temperature-k",
    type=float,
    default=None,
    help="Held temperature [K] of new meshes without a humv_temperature_k custom property "
    "(default: the air temperature at the first frame).",
)
@click.option(
    "--label-class",
    default="other",
    show_default=True,
    help="Class of new meshes without a humv_class custom property.",
)
@click.option(
    "--scenario",
    "scenario_file",
    default=None,
    type=click.Path(dir_okay=False, path_type=Path),
    help="The scenario the --from stage was composed from: the thermal tool recomputes the "
    "temperatures of the adopted stage (shadows follow moved people and objects, new objects "
    "cast theirs) into OUT/layers/thermal.usda.",
)
@reports_errors
def adopt(blender_export: Path, out_dir: str, original, fps, temperature_k, label_class, scenario_file):
    """Adopt BLENDER_EXPORT (Blender's wm.usd_export) as a HumV stage in OUT.

    Maps Blender's conventions back: /root -> /World, object/data prim pairs -> one prim,
    /root/_materials -> /World/Materials with HumvMaterialAPI (from the --from stage, else the
    library material of the same name), primvars:humv_thermal_temperature ->
    primvars:humv:thermal:temperature; new meshes get a held temperature and a new label.
    """
    from humv_usd.errors import InputError
    from humv_usd.pipeline.adopt import adopt as run
    from humv_usd.scenario import load_scenario

    scenario = None
    if scenario_file is not None:
        if original is None:
            raise InputError("--scenario needs --from (the stage composed from that scenario)")
        scenario = load_scenario(scenario_file)
    stage, report = run(
        blender_export,
        out_dir,
        original,
        fps=fps,
        temperature_k=temperature_k,
        label_class=label_class,
        scenario=scenario,
    )
    library = sorted(k for k, v in report.materials.items() if v == "library")
    click.echo(
        f"{stage}  ({report.prims} prims; {len(report.restored)} restored from the original; "
        f"materials: {len(report.materials) - len(library)} original, {len(library)} library"
        f"{' (' + ', '.join(library) + ')' if library else ''}; fps {report.fps:g} from {report.fps_source})"
    )
    for path, entry in report.new_meshes.items():
        parts = [f"{k} {v}" for k, v in entry.items()]
        click.echo(f"  new mesh {path}: {', '.join(parts)}")
    if report.static_export:
        click.echo("  no animation in the export: people and garments stay at the exported frame")
    if scenario is not None:
        click.echo("  temperatures recomputed for the adopted stage: layers/thermal.usda")
    for path in report.kept_blender_values:
        click.echo(f"  {path}: topology changed, Blender's per-face values kept")
