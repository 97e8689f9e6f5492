"""``humv-usd bench skinning``: body and garment intersections with the body per activity, for
linear blend skinning, dual quaternion skinning and the avatar tool's arm clearance
(:mod:`humv_usd.bench.skinning`)."""

from __future__ import annotations

from pathlib import Path

import click

from humv_usd.cli.common import reports_errors
from humv_usd.errors import InputError
from humv_usd.fileio import write_json


@click.command("skinning")
@click.option(
    "--activities",
    default=None,
    help="Comma-separated activities (built-in names, <name>+rifle, or bvh:<clip>); default: all of "
    "humv_usd.bench.skinning.ACTIVITIES.",
)
@click.option(
    "--samples", default=6, show_default=True, type=click.IntRange(1, 100), help="Frames measured per clip."
)
@click.option(
    "--seconds", default=3.0, show_default=True, type=click.FloatRange(0.1, 60.0), help="Clip length."
)
@click.option(
    "--garments/--no-garments", default=True, show_default=True, help="Dress and measure the outfit."
)
@click.option(
    "--json",
    "json_out",
    default=None,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Also write the dict here.",
)
@reports_errors
def bench_skinning(
    activities: str | None, samples: int, seconds: float, garments: bool, json_out: Path | None
):
    """Body vertices inside the body and garment triangle centres inside it, per activity, for
    LBS, DQS and the cleared arms (the demo's male 1.78 m / 80 kg in a T-shirt, shorts, shoes)."""
    from humv_usd.bench.skinning import ACTIVITIES, bench_skinning, table
    from humv_usd.human.motion import ACTIVITIES as BUILT_IN

    names = ACTIVITIES if activities is None else tuple(a.strip() for a in activities.split(",") if a.strip())
    bad = [a for a in names if not (a.startswith("bvh:") or a.removesuffix("+rifle") in BUILT_IN)]
    if bad:
        raise InputError(
            f"--activities = {bad[0]!r}: allowed: {', '.join(BUILT_IN)} (+rifle: with the rifle carry) "
            "or bvh:<clip>"
        )
    result = bench_skinning(names, seconds=seconds, samples=samples, garments=garments)
    click.echo("\n".join(table(result)))
    if json_out is not None:
        write_json(json_out, result)
