"""``humv-usd bench frame``: median wall time per frame of a multi-frame render of one sensor,
with its breakdown (:mod:`humv_usd.bench.frame`)."""

from __future__ import annotations

from pathlib import Path

import click

from humv_usd.cli.common import reports_errors


def _s(value) -> str:
    return "   n/a" if value is None else f"{value:6.3f}"


@click.command("frame")
@click.argument("scenario", type=click.Path(exists=True, path_type=Path))
@click.option("--sensor", default=None, help="The IR sensor to time (default: the first).")
@click.option(
    "--frames",
    default=8,
    show_default=True,
    type=click.IntRange(1, 1000),
    help="Frames timed (after frame 0).",
)
@click.option(
    "--spp", default=None, type=click.IntRange(1, 1 << 16), help="Samples per pixel (default: automatic)."
)
@click.option(
    "--json",
    "json_out",
    default=None,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the numbers here.",
)
@reports_errors
def bench_frame(scenario: Path, sensor: str | None, frames: int, spp: int | None, json_out: Path | None):
    """Per-frame cost of rendering SCENARIO (.toml, or a composed stage.usda / its folder).

    Renders frames 0..N of one sensor with labels (frame 0 is the warm-up: scene build, kernels)
    and prints the median over frames 1..N of the wall time per frame (between the ends of
    consecutive frames: writes overlap the next frame) and its parts: estimator, conversions
    (brightness temperature, error in K, edges, statistics), labels, foreground writes, the
    background writer's time; labels as a fraction of the render; CPU per frame; load average.
    """
    from humv_usd.bench.frame import bench_frames
    from humv_usd.fileio import write_json

    out = bench_frames(scenario, sensor=sensor, frames=frames, spp=spp)
    m = out["median"]
    w, h = out["resolution"]
    click.echo(
        f"{scenario}: {out['sensor']} {w}x{h}, median of {out['frames_timed']} frames (after frame 0), "
        f"spp used {out['spp_used']}, load average {' '.join(f'{v:.2f}' for v in out['load_average'])}"
    )
    click.echo(f"  wall per frame          {_s(m.get('wall'))} s   (CPU {_s(m.get('cpu'))} s)")
    click.echo(f"    estimator             {_s(m.get('estimator'))} s   (CPU {_s(m.get('estimator_cpu'))} s)")
    click.echo(f"    conversions           {_s(m.get('conversions'))} s   (BT, error in K, edges, stats)")
    click.echo(
        f"    labels                {_s(m.get('labels'))} s   (CPU {_s(m.get('labels_cpu'))} s; "
        f"{out['labels_fraction']:.3f} x the render)"
    )
    click.echo(f"    writes (foreground)   {_s(m.get('write'))} s")
    click.echo(f"    scene update, export  {_s(m.get('load_export'))} s")
    click.echo(f"  outside the estimator   {_s(out['outside_estimator_s'])} s")
    click.echo(
        f"  writer thread           {_s(out['writer_s_per_frame'])} s per frame, "
        f"CPU {_s(out['writer_cpu_s_per_frame'])} s (overlapped with the next frame)"
    )
    click.echo("  frame   wall    cpu  estim  conv  labels  write")
    for r in out["per_frame"]:
        click.echo(
            f"  {r['frame']:5d} {_s(r['wall'])} {_s(r['cpu'])} {_s(r['estimator'])} {_s(r['conversions'])}"
            f" {_s(r['labels'])} {_s(r['write'])}"
        )
    if json_out is not None:
        write_json(json_out, out)
