"""Ground-truth commands: ``humv-usd regions``, ``humv-usd coco-merge``, ``humv-usd bench labels``
(registered on the ``humv-usd`` group by :func:`register`)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from humv_usd.cli.common import reports_errors
from humv_usd.errors import InputError


@click.command()
@click.argument("render_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--real",
    "real",
    default=None,
    type=click.Path(dir_okay=False, path_type=Path),
    help="A real image (single channel; any format OpenImageIO reads) to compare with.",
)
@click.option(
    "--masks",
    default=None,
    type=click.Path(dir_okay=False, path_type=Path),
    help="PNG of body region ids for --real (0 = not the person; ids of "
    "humv_usd.human.labels.BODY_REGIONS; the render writes <frame>.region_ids.png).",
)
@click.option(
    "--quantity",
    default=None,
    type=click.Choice(["counts", "radiance", "Y", "temperature"]),
    help="Image quantity (default: counts if the EXR has them, else radiance; EO: luminance Y).",
)
@click.option("--sensor", default=None, help="Sensor compared with --real (default: the first).")
@click.option("--frame", default=None, type=int, help="Frame compared with --real (default: the first).")
@reports_errors
def regions(render_dir: Path, real, masks, quantity, sensor, frame):
    """Per-body-region statistics (the seed's Table 2) of a render: writes RENDER_DIR/regions.json."""
    from humv_usd.fileio import check_output_dir
    from humv_usd.groundtruth import regions as R

    if render_dir.is_dir():  # regions.json goes into it: fail fast when it is read-only
        check_output_dir(render_dir, "render folder")
    if (real is None) != (masks is None):
        raise InputError("--real and --masks go together (a real image and its region-id mask PNG)")
    records = R.render_regions(render_dir, quantity)
    path = R.write_regions(render_dir, records)
    chosen = real_stats = None
    if real is not None:
        candidates = [
            r
            for r in records
            if (sensor is None or r["sensor"] == sensor) and (frame is None or r["frame"] == frame)
        ]
        if not candidates:
            raise InputError(
                f"--sensor/--frame = {sensor}/{frame}: no rendered person image with body regions matches"
            )
        chosen = candidates[0]
        real_stats = R.real_regions(real, masks)
    for r in records:
        click.echo(R.format_table(r, real_stats if r is chosen else None))
        click.echo("")
    click.echo(path)


@click.command("coco-merge")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "-o",
    "--out",
    "out",
    required=True,
    type=str,  # checked by check_output_file: one error line, not click's usage block
    help="The merged dataset JSON.",
)
@reports_errors
def coco_merge(inputs, out: Path):
    """Merge per-render COCO files (coco.json, or render folders holding one) into one dataset."""
    from humv_usd.fileio import check_output_file
    from humv_usd.groundtruth.coco import merge

    out = check_output_file(out, "-o/--out")  # fail fast, before reading the inputs
    files = [p / "coco.json" if p.is_dir() else p for p in inputs]
    doc = merge(files, out)
    click.echo(f"{out}  {len(doc['images'])} image(s), {len(doc['annotations'])} annotation(s)")


@click.command("labels")
@click.argument("render_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option("--sensor", default=None, help="Sensor (default: every rendered one).")
@click.option("--frame", default=None, type=int, help="Frame (default: the first rendered).")
@reports_errors
def bench_labels(render_dir: Path, sensor, frame):
    """Label agreement of a render with an independent embree ray cast, and the ground truth's
    cost relative to the Monte Carlo render (from the manifest)."""
    from humv_usd.bench.labels import label_agreement

    try:
        manifest = json.loads((render_dir / "manifest.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"{render_dir}: not a render folder ({exc})") from None
    names = [sensor] if sensor else [s["name"] for s in manifest["sensors"]]
    for name in names:
        click.echo(json.dumps(label_agreement(render_dir, name, frame)))
    gt = manifest.get("ground_truth") or {}
    if gt.get("cost_relative_to_render") is not None:
        click.echo(
            f"ground truth {gt['timings_s']['total']:.2f} s = {gt['cost_relative_to_render']:.3f} x "
            f"the Monte Carlo render ({manifest['settings']['spp']} spp); per annotator: "
            + ", ".join(f"{k} {v:.2f}" for k, v in gt["timings_s"].items() if k != "total" and v)
        )


def register(main, bench) -> None:
    """Add the commands to the ``humv-usd`` group and its ``bench`` group."""
    main.add_command(regions)
    main.add_command(coco_merge)
    bench.add_command(bench_labels)
