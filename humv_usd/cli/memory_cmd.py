"""``humv-usd bench memory``: RSS of a long render at frames 30 and 300 (issue 15)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from humv_usd.cli.common import reports_errors

WALK = Path(__file__).resolve().parents[2] / "examples" / "walk.toml"


@click.command("memory")
@click.option(
    "--scenario",
    default=None,
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Scenario (default: examples/walk.toml); its duration is set to give --frames frames.",
)
@click.option("--frames", default=301, show_default=True, type=click.IntRange(32, 100000))
@click.option("--width", default=64, show_default=True, type=click.IntRange(8, 4096))
@click.option("--height", default=48, show_default=True, type=click.IntRange(8, 4096))
@click.option("--spp", default=1, show_default=True, type=click.IntRange(1, 1024))
@click.option("--keep", default=None, type=str, help="Keep the composed stage and render in this folder.")
@reports_errors
def bench_memory(scenario, frames: int, width: int, height: int, spp: int, keep):
    """Render FRAMES frames of a scenario at a small resolution with every annotator and print
    the resident memory after frame 30 and after the last frame (target: within 5 %)."""
    import shutil
    import tempfile
    import tomllib

    from humv_usd.bench.memory import FrameRSS, small_sensors, timed
    from humv_usd.groundtruth import ANNOTATORS
    from humv_usd.pipeline.compose import compose
    from humv_usd.pipeline.render import render_stage
    from humv_usd.scenario import validate

    path = scenario or WALK
    raw = small_sensors(tomllib.loads(path.read_text(encoding="utf-8")), width, height)
    raw["general"] = {**raw["general"], "duration_s": (frames - 1) / float(raw["general"]["fps"])}
    work = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="humv-bench-memory-"))
    try:
        _, t_compose = timed(compose, validate(raw, path), work / "stage")
        sensor = raw["sensor"][0]["id"]
        last = frames - 1
        with FrameRSS(work / "render" / sensor, checkpoints=(30, last)) as rss:
            manifest, t_render = timed(
                render_stage,
                work / "stage" / "stage.usda",
                work / "render",
                spp=spp,
                sensors=[sensor],
                annotators=list(ANNOTATORS),
            )
        growth = rss.growth()
        result = {
            "scenario": str(path),
            "frames": frames,
            "resolution": [width, height],
            "spp": spp,
            "annotators": list(ANNOTATORS),
            "compose_s": round(t_compose, 2),
            "render_s": round(t_render, 2),
            "rss_mb": {str(k): round(v, 1) for k, v in sorted(rss.at.items())},
            "rss_peak_mb": round(rss.peak, 1),
            "growth_30_to_last": None if growth is None else round(growth, 4),
            "rendered": len(manifest["rendered_this_call"]),
        }
        click.echo(json.dumps(result))
        if growth is not None:
            click.echo(
                f"RSS after frame 30: {rss.at[30]:.1f} MB, after frame {last}: {rss.at[last]:.1f} MB "
                f"({growth * 100:+.1f} %; target within 5 %)"
            )
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
