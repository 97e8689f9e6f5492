"""What every command shares: bad input as one line per problem and exit code 2."""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import time

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


#: plain progress lines (stderr not a terminal: a log file, nohup, a batch job) start after this
#: many seconds, so that quick runs and their one-line errors stay as they are, and come at
#: most every PLAIN_EVERY_S
PLAIN_AFTER_S = 5.0
PLAIN_EVERY_S = 2.0


def _plain_lines(stage: str):
    """``callback(done, total, text)`` printing ``humv-usd compose: [3/7] layer thermal, 12.4 s``
    lines on stderr (issue 26: compose printed nothing for 97 s into a log)."""
    t0 = time.monotonic()
    last = [-float("inf")]

    def callback(done: int, total: int, text: str) -> None:
        now = time.monotonic()
        if now - t0 < PLAIN_AFTER_S or now - last[0] < PLAIN_EVERY_S:
            return
        last[0] = now
        sys.stderr.write(f"{PROG} {stage}: [{done}/{total}] {text}, {now - t0:.1f} s\n")
        sys.stderr.flush()

    return callback


@contextlib.contextmanager
def progress_display(stage: str, quiet: bool = False):
    """Yield ``callback(done, total, text)`` drawing a rich progress bar (stage, what, ETA) on
    stderr when :func:`wants_progress` says so; plain lines (:func:`_plain_lines`) when stderr
    is the process's own and not a terminal (a log; not --quiet); else None."""
    if not wants_progress(quiet):
        own = sys.stderr is sys.__stderr__  # not a test runner's capture
        yield _plain_lines(stage) if not quiet and own and not sys.stderr.isatty() else None
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
