"""``humv-usd edit``: the HumV editor, a local web app over a scenario file."""

from __future__ import annotations

from pathlib import Path

import click

from humv_usd.cli.common import reports_errors


@click.command()
@click.argument(
    "scenario", required=False, default="scenario.toml", type=click.Path(dir_okay=False, path_type=Path)
)
@click.option(
    "-o",
    "--out",
    "out_dir",
    default=None,
    type=str,
    help="Output folder of compose, render and preview (default: out/<scenario name>).",
)
@click.option("--port", default=8765, show_default=True, type=click.IntRange(1, 65535))
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Interface to listen on; another than 127.0.0.1 needs the token printed at start.",
)
@click.option("--open/--no-open", "show", default=False, help="Open a browser window.")
@click.option(
    "--library",
    "libraries",
    multiple=True,
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    help="A folder of shared assets the scenario's file keys may name besides its own folder "
    "(read-only; repeatable).",
)
@reports_errors
def edit(scenario: Path, out_dir: str | None, port: int, host: str, show: bool, libraries):
    """Edit SCENARIO (TOML; created on the first save) in the browser: tabs from the scenario
    spec with live validation, plan, 3D view, preview, compose/render/sweep jobs."""
    from humv_usd.editor.app import address, new_token, serve
    from humv_usd.fileio import check_output_dir

    out = check_output_dir(out_dir or str(Path("out") / scenario.stem))
    token = new_token(host)
    click.echo(f"humv-usd edit: {scenario.resolve()} -> {address(host, port, token)}")
    if token:
        click.echo(
            "  the token in this address is required on every request (another interface than 127.0.0.1)"
        )
    serve(scenario, out, host=host, port=port, token=token, show=show, libraries=libraries)
