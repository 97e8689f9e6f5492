"""``humv-usd avatar``: the avatar tool on its own — one person → one avatar layer file.

Registered on the command group in :mod:`humv_usd.cli.main` (``main.add_command(avatar)``).
The options mirror :func:`humv_usd.avatar.api.author_avatar`; a bad value is reported as one
line naming the option (``--stature = 3.0: allowed range 0.7..2.3``), exit code 2, and nothing
is written.
"""

from __future__ import annotations

import re
from pathlib import Path

import click

from humv_usd.cli.common import reports_errors
from humv_usd.errors import InputError
from humv_usd.scenario.spec import ACTIVITIES, FITNESS, HUMAN

#: Scenario key (as the validator names it) → CLI option.
OPTION_OF_KEY = {
    "human[0].id": "--id",
    "human[0].sex": "--sex",
    "human[0].age_yr": "--age",
    "human[0].stature_m": "--stature",
    "human[0].mass_kg": "--mass",
    "human[0].build": "--build",
    "human[0].fitness": "--fitness",
    "human[0].activity": "--activity",
    "placement[0].position_m": "--position",
    "placement[0].heading_deg": "--heading",
    "general.fps": "--fps",
    "general.duration_s": "--duration",
    "out_path": "-o/--out",
}
_KEY = re.compile(
    r"^(?P<key>[A-Za-z_]+(?:\[0\])?(?:\.[A-Za-z_]+)?)"
    r"(?P<index>\[\d+\])?(?P<rest> .*)$"
)


def option_message(line: str) -> str:
    """Rename the scenario key that starts a problem line to the CLI option that set it."""
    m = _KEY.match(line)
    if m and m["key"] in OPTION_OF_KEY:
        return OPTION_OF_KEY[m["key"]] + (m["index"] or "") + m["rest"]
    return line


def _choices(name: str) -> str:
    return ", ".join(HUMAN.keys[name].choices)


@click.command("avatar", context_settings={"help_option_names": ["-h", "--help"]})
@click.option(
    "-o",
    "--out",
    "out_path",
    required=True,
    type=str,  # checked by check_output_file: one error line, not click's usage block
    help="Avatar layer file to write (.usda).",
)
@click.option(
    "--id", "human_id", default="p1", show_default=True, help="Id of the person: the prim /World/Humans/<id>."
)
@click.option("--sex", default="male", show_default=True, help=f"One of: {_choices('sex')}.")
@click.option("--age", "age_yr", default=30.0, show_default=True, type=float, help="Age [years], 1..100.")
@click.option(
    "--stature",
    "stature_m",
    default=1.75,
    show_default=True,
    type=float,
    help="Standing height [m], 0.7..2.3.",
)
@click.option(
    "--mass", "mass_kg", default=75.0, show_default=True, type=float, help="Body mass [kg], 7..250."
)
@click.option("--build", default="average", show_default=True, help=f"One of: {_choices('build')}.")
@click.option("--fitness", default="average", show_default=True, help=f"One of: {', '.join(FITNESS)}.")
@click.option("--activity", default="stand", show_default=True, help=f"One of: {', '.join(ACTIVITIES)}.")
@click.option(
    "--position",
    "position_m",
    default=(0.0, 0.0, 0.0),
    show_default=True,
    type=(float, float, float),
    metavar="X Y Z",
    help="Position of the feet [m] (x east, y north, z up).",
)
@click.option(
    "--heading",
    "heading_deg",
    default=0.0,
    show_default=True,
    type=float,
    help="Direction faced, compass azimuth [deg] (0 = north, 90 = east).",
)
@click.option(
    "--fps",
    default=30.0,
    show_default=True,
    type=float,
    help="Frame rate [frames/s] (time codes per second of the layer).",
)
@click.option(
    "--duration",
    "duration_s",
    default=0.0,
    show_default=True,
    type=float,
    help="Length [s]; frames = round(duration*fps)+1.",
)
@reports_errors
def avatar(
    out_path: Path,
    human_id: str,
    sex: str,
    age_yr: float,
    stature_m: float,
    mass_kg: float,
    build: str,
    fitness: str,
    activity: str,
    position_m,
    heading_deg,
    fps: float,
    duration_s: float,
):
    """Write the avatar layer of one person to OUT (no scenario file needed).

    The same layer `compose` writes as layers/avatar_<id>.usda; the ranges are those of the
    scenario keys [[human]] and [[placement]].
    """
    import time

    from humv_usd.avatar.api import author_avatar
    from humv_usd.fileio import check_output_file

    out_path = check_output_file(out_path, "-o/--out")  # fail fast, before building anything
    start = time.perf_counter()
    try:
        path = author_avatar(
            out_path,
            id=human_id,
            sex=sex,
            age_yr=age_yr,
            stature_m=stature_m,
            mass_kg=mass_kg,
            build=build,
            fitness=fitness,
            activity=activity,
            position_m=position_m,
            heading_deg=heading_deg,
            fps=fps,
            duration_s=duration_s,
        )
    except InputError as exc:
        raise InputError("", [option_message(line) for line in exc.problems]) from None
    click.echo(f"{path}  ({time.perf_counter() - start:.2f} s)")
