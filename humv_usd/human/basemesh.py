"""MakeHuman's CC0 base mesh (hm08): its frame and how it maps onto ours.

The mesh itself is read (once, cached) by :func:`humv_usd.human.macro.obj_data`.
"""

from __future__ import annotations

import numpy as np

# MakeHuman: decimetres, +Y up, the body faces +Z. Ours: metres, +Z up; (x, y, z) -> (x, -z, y)
# is a proper rotation (det +1), so the faces keep their outward counter-clockwise winding and
# the body faces -Y (compass azimuth 180 deg).
_MH_TO_USD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]) * 0.1
DEFAULT_FACING_DEG = 180.0
