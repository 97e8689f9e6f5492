"""``humv-usd bench places``: compose and render cost of a generated place against its size
(issue 30.6; the bench itself is :mod:`humv_usd.bench.places`)."""

from __future__ import annotations

import json

import click

from humv_usd.cli.common import reports_errors
from humv_usd.scenario.spec import PLACE_KINDS


@click.command("places")
@click.option(
    "--kind", "kinds", multiple=True, type=click.Choice(PLACE_KINDS[1:]), help="Place kinds (default all)."
)
@click.option(
    "--factors", default="0.5,1,2", show_default=True, help="Size factors of the example's counts and length."
)
@click.option("--width", default=64, show_default=True, type=click.IntRange(8, 4096))
@click.option("--height", default=48, show_default=True, type=click.IntRange(8, 4096))
@click.option("--spp", default=2, show_default=True, type=click.IntRange(1, 1024))
@click.option("--keep", default=None, type=str, help="Keep the composed stages and renders in this folder.")
@reports_errors
def bench_places(kinds, factors: str, width: int, height: int, spp: int, keep):
    """Compose examples/places/<kind>.toml at growing sizes (no people, small sensors), render
    frame 0 of every sensor, and print one JSON row per size: objects, meshes, triangles,
    scene/thermal/compose/render seconds, peak RSS."""
    from humv_usd.bench.places import place_scaling

    try:
        sizes = [float(f) for f in factors.split(",")]
    except ValueError:
        raise click.BadParameter(
            f"{factors!r}: expected numbers separated by commas", param_hint="--factors"
        ) from None
    if not sizes or min(sizes) <= 0 or max(sizes) > 20:
        raise click.BadParameter(f"{factors!r}: factors in (0, 20]", param_hint="--factors")
    for kind in kinds or PLACE_KINDS[1:]:
        for row in place_scaling(kind, sizes, width, height, spp, keep):
            click.echo(json.dumps(row))
