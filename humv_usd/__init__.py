"""HumV-USD: a USD-native, physics-based simulator of human signatures in EO, MWIR and LWIR.

Importing the package registers the HumV USD schemas (``schemas/``) with USD. That has to happen
before any ``Usd.Stage`` exists, so import ``humv_usd`` before opening or creating stages. The
import stays cheap: only ``pxr`` is loaded here, never mitsuba or bpy.
"""

import logging
import os
import signal
import sys
import threading


def _starting(signum, frame):  # noqa: ARG001 (the signal handler's signature)
    """Ctrl-C while the humv-usd command starts (imports: nothing written yet): one line, exit
    130, instead of a traceback from inside an import (issue 26). The command line restores
    Python's handler once it is loaded (:mod:`humv_usd.cli.main`)."""
    os.write(2, b"humv-usd: interrupted (Ctrl-C) while starting; nothing was written\n")
    os._exit(130)


def _is_the_command() -> bool:
    argv0 = sys.argv[0] if sys.argv else ""
    return os.path.basename(argv0) == "humv-usd" or argv0.endswith(os.path.join("humv_usd", "cli", "main.py"))


if _is_the_command() and threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, _starting)

from humv_usd.usd.schemas import register_schemas  # noqa: E402 (after the start-up handler)

__version__ = "0.1.0"

register_schemas()
# library code logs; applications (the humv-usd command) decide where it goes
logging.getLogger(__name__).addHandler(logging.NullHandler())
