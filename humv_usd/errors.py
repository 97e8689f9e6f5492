"""Errors that the command line reports as one line and exit code 2 (bad input)."""

from __future__ import annotations

import numpy as np


class InputError(ValueError):
    """Bad user input: a scenario value, a file, a USD stage or a BVH.

    The message is one line that names the key (or prim/attribute), the value and what is
    allowed, e.g. ``sensor[0].resolution = [0, 768]: expected two integers in 1..16384``.
    Several problems found at once are joined with newlines (one line each).
    """

    def __init__(self, message: str, problems: list[str] | None = None):
        self.problems = problems if problems else [message]
        super().__init__("\n".join(self.problems) if problems else message)


#: longest value or name shown in an error line; longer ones are cut and their length given
SHOWN_MAX = 120


def shown(text, limit: int = SHOWN_MAX) -> str:
    """A value or name as an error line shows it: printable (``repr`` when it holds control
    characters such as a newline, so the error stays one line) and at most ``limit``
    characters plus its length (a 100,000-character key is not echoed)."""
    text = text if isinstance(text, str) and text.isprintable() else repr(text)
    return text if len(text) <= limit else f"{text[: limit - 40]}... ({len(text)} characters)"


def bad_value(key: str, value, allowed: str) -> str:
    """Format one problem line: ``key = value: allowed`` (long keys and values shortened)."""
    return f"{shown(key)} = {shown(repr(value))}: {allowed}"


def summary(values, limit: int = 6) -> str:
    """A short text of a numeric array for an error line: all values up to ``limit``, else the
    first ``limit`` and the count."""
    a = np.asarray(values).ravel()
    if a.size <= limit:
        return "[" + ", ".join(f"{v:g}" for v in a.tolist()) + "]"
    head = ", ".join(f"{v:g}" for v in a[:limit].tolist())
    return f"[{head}, ...] ({a.size} values)"


class WriteError(OSError):
    """An output file could not be written (disk full, permissions, an encoder error). The
    command line reports it as one line and exit code 1 (not bad input: the same command may
    succeed once the cause is fixed)."""
