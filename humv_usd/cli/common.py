"""What every command shares: bad input as one line per problem and exit code 2."""

from __future__ import annotations

import functools
import sys

import click

from humv_usd.assets import MissingAssetError
from humv_usd.errors import InputError

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
        except KeyboardInterrupt:  # Ctrl-C: finished files are kept; compose and render resume
            _fail(
                ["interrupted (Ctrl-C); what was finished is kept: run the same command again to resume"], 130
            )

    return wrapper
