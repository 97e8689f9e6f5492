"""``humv-usd bench compose``: compose cost against people count and frame count (issue 31.2;
the bench itself is :mod:`humv_usd.bench.compose_cost`)."""

from __future__ import annotations

import json

import click

from humv_usd.cli.common import reports_errors


def _counts(text: str, option: str, top: int) -> list[int]:
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise click.BadParameter(
            f"{text!r}: expected integers separated by commas", param_hint=option
        ) from None
    if not values or min(values) < 1 or max(values) > top:
        raise click.BadParameter(f"{text!r}: each in 1..{top}", param_hint=option)
    return values


@click.command("compose")
@click.option("--people", default="1,2", show_default=True, help="People counts, comma-separated (1-50).")
@click.option("--frames", default="1,4", show_default=True, help="Frame counts, comma-separated (1-600).")
@click.option(
    "--thermal",
    default="jos3",
    show_default=True,
    type=click.Choice(("fixed", "twoNode", "jos3")),
    help="[thermal] model of the bench scenarios.",
)
@click.option("--keep", default=None, type=str, help="Keep the composed stages in this folder.")
@click.option(
    "--scenario",
    default=None,
    type=click.Path(exists=True, dir_okay=False),
    help="Instead of the crowd grid: compose this scenario (or a sweep file's --variant) once "
    "and print its CPU seconds.",
)
@click.option(
    "--variant", default=None, type=click.IntRange(0), help="With a sweep file: the variant's index."
)
@click.option(
    "--stages",
    is_flag=True,
    help="With --scenario: profile the compose (cProfile, CPU clock) and add CPU seconds by stage.",
)
@reports_errors
def bench_compose(people: str, frames: str, thermal: str, keep, scenario, variant, stages):
    """Compose the crowd scenario (walk.toml's site, N people walking, a 64x48 camera) for every
    people x frames point from scratch, print one JSON row per point (seconds per layer, CPU
    seconds) and then how each layer's cost grows: base + per person + per frame [s].
    With --scenario: one compose of that scenario, its CPU seconds (by stage with --stages)."""
    from humv_usd.bench.compose_cost import bench_compose as run
    from humv_usd.bench.compose_cost import scenario_point

    if scenario is not None:
        click.echo(json.dumps(scenario_point(scenario, variant, keep, stages)))
        return
    if variant is not None or stages:
        raise click.BadParameter("only with --scenario", param_hint="--variant/--stages")
    result = run(
        _counts(people, "--people", 50),
        _counts(frames, "--frames", 600),
        thermal,
        keep,
        echo=lambda row: click.echo(json.dumps(row)),
    )
    for layer, fit in result["growth"].items():
        click.echo(json.dumps({"layer": layer, **fit}))
