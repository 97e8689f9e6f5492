"""HumV-USD: a USD-native, physics-based simulator of human signatures in EO, MWIR and LWIR.

Importing the package registers the HumV USD schemas (``schemas/``) with USD. That has to happen
before any ``Usd.Stage`` exists, so import ``humv_usd`` before opening or creating stages. The
import stays cheap: only ``pxr`` is loaded here, never mitsuba or bpy.
"""

import logging

from humv_usd.usd.schemas import register_schemas

__version__ = "0.1.0"

register_schemas()
# library code logs; applications (the humv-usd command) decide where it goes
logging.getLogger(__name__).addHandler(logging.NullHandler())
