"""A warm ``humv-usd``: one long-lived process that runs commands one after the other.

The editor's preview runs ``compose`` and ``render`` after every edit. As new processes each
call pays Python's imports (USD, numpy, scipy, Mitsuba), pythermalcomfort's import and numba's
compile of its JOS-3 functions, about 4-5 CPU-s of a fast preview's 11 (``humv-usd bench
preview``). This process imports once and keeps numba's compiled functions: the editor
(:class:`humv_usd.editor.jobs.JobManager`) writes one JSON list of ``humv-usd`` arguments per
line to its stdin; it runs the command in-process, exactly as the command line would (the same
``main``, the same exit codes), with stderr joined to stdout, and ends the command's output
with one line ``SENTINEL + exit code``. Cancel kills the whole process (its own process group);
the editor starts a new one for the next command.

Run as ``python -m humv_usd.cli.warm`` (the editor does; not a user command).
"""

from __future__ import annotations

import gc
import json
import sys
import traceback

from pxr import Sdf

from humv_usd.editor.jobs import WARM_SENTINEL as SENTINEL


def fresh_layers() -> int:
    """Make the next command read every layer file as it is on disk now; returns how many
    loaded layers had to be reloaded.

    ``Usd.Stage.Open`` reuses a layer that is still in memory (USD's layer registry) instead of
    reading its file again. A stage of the previous command that only a reference cycle keeps
    alive is such a case: the render after a NETD edit read the sensors layer of the compose
    before it (found with ``humv-usd bench preview``: heading edit, then NETD edit). Collecting
    the garbage frees those; a layer something still holds is reloaded from its file."""
    gc.collect()
    held = [layer for layer in Sdf.Layer.GetLoadedLayers() if not layer.anonymous]
    for layer in held:
        try:
            layer.Reload(force=True)
        except Exception:  # noqa: BLE001 (Tf.ErrorException: its file is gone; the command says so)
            pass
    return len(held)


def run(args: list[str]) -> int:
    """Run ``humv-usd ARGS`` in this process (every layer read from its file: :func:`fresh_layers`);
    its exit code."""
    from humv_usd.cli.main import main

    fresh_layers()
    try:
        main.main(args=args, prog_name="humv-usd", standalone_mode=True)
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except BaseException:  # noqa: BLE001 (as the command line would: a traceback, exit 1)
        traceback.print_exc()
        return 1
    return 0


def preload() -> None:
    """Import what compose and render need before the first command comes (the editor starts
    this process when the page opens a preview, so the imports overlap the user's reading)."""
    import humv_usd.cli.main  # noqa: F401
    import humv_usd.pipeline.compose  # noqa: F401
    import humv_usd.pipeline.render  # noqa: F401
    import humv_usd.thermal.layer  # noqa: F401

    try:
        import pythermalcomfort.models  # noqa: F401  (JOS-3: about 1 CPU-s)
    except ImportError:  # the physiology says so when a command needs it
        pass


def serve() -> None:
    """Read commands (JSON argument lists, one a line) from stdin until it closes."""
    sys.stderr = sys.stdout  # one stream, in order, as the editor's jobs read them
    preload()
    for line in sys.stdin:
        try:
            args = json.loads(line)
        except ValueError:
            args = None
        if not isinstance(args, list) or not all(isinstance(a, str) for a in args):
            print(f"humv-usd: error: warm worker: not a JSON list of strings: {line[:80]!r}")
            code = 2
        else:
            code = run(args)
        sys.stdout.write(f"{SENTINEL}{code}\n")
        sys.stdout.flush()


if __name__ == "__main__":
    serve()
