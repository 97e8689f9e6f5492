"""What every command shares: bad input as one line per problem and exit code 2."""

from __future__ import annotations

import contextlib
import functools
import os
import sys

import click

from humv_usd.assets import MissingAssetError
from humv_usd.errors import InputError, WriteError

PROG = "humv-usd"


def _fail(lines, code: int):
    for line in lines:
        click.echo(f"{PROG}: error: {line}", err=True)
    sys.exit(code)


def reports_errors(fn):
    """Turn our exceptions into one-line messages and exit codes (no tracebacks)."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except InputError as exc:
            _fail(exc.problems, 2)
        except MissingAssetError as exc:
            _fail([str(exc)], 1)
        except WriteError as exc:  # an output file (e.g. in the background writer) could not be written
            _fail([str(exc)], 1)
        except KeyboardInterrupt:  # Ctrl-C: finished files are kept; compose and render resume
            _fail(
                ["interrupted (Ctrl-C); what was finished is kept: run the same command again to resume"], 130
            )

    return wrapper


def wants_progress(quiet: bool) -> bool:
    """A progress display only for a person: stderr is a terminal, not CI, not --quiet."""
    return not quiet and sys.stderr.isatty() and not os.environ.get("CI")


@contextlib.contextmanager
def progress_display(stage: str, quiet: bool = False):
    """Yield ``callback(done, total, text)`` drawing a rich progress bar (stage, what, ETA) on
    stderr, or None when :func:`wants_progress` says no (pipes, CI, --quiet)."""
    if not wants_progress(quiet):
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(
        TextColumn(f"[bold]{stage}[/bold]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task("", total=None)

        def callback(done: int, total: int, text: str) -> None:
            bar.update(task, completed=done, total=total, description=text)

        yield callback


def set_verbosity(verbose: int) -> None:
    """A command's own -v/-vv: info / debug log lines on stderr (the group's -v does the same)."""
    import logging

    if verbose:
        logging.getLogger().setLevel(logging.INFO if verbose == 1 else logging.DEBUG)
