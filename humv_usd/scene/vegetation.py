"""Procedural plants (issue 30.2): trees, bushes, hedges and crop fields as our own generated
meshes.

A plant is an ``[[scene.object]]`` of kind tree, bush, hedge or crop: an Xform /World/Scene/<id>
(the object's label) with a closed crown mesh ``Crown`` of the object's material (``leaf``: a
big-leaf surface whose faces the thermal tool solves with leaf convection and transpiration,
:mod:`humv_usd.physics.vegetation`) and, for a tree, a closed trunk ``Trunk`` of wood. Shapes:

* crown: an icosphere (subdivided icosahedron) mapped onto an ellipsoid (tree, bush) or a
  superellipsoid of exponent 4 (hedge: a clipped block with rounded edges), its radius
  jittered by smooth random lobes from a seed (the object's id), so no two trees are alike;
* tree: crown radii (size x / 2, size y / 2, 0.35 height) centred 0.35 height below the top;
  trunk an octagonal prism of radius 0.035 height (0.06-0.4 m) from the ground into the crown;
* bush: crown radii (size / 2) centred at half its height, sunk 5 % into the ground;
* hedge: superellipsoid of the object's size (length along the object's x before rotation);
* crop: a field of row crops over the object's size: rows along the object's x, ``row_spacing_m``
  apart across y (:data:`humv_usd.scenario.spec.CROPS`: maize and wheat), each row a closed
  prism of a rounded canopy profile :data:`CROP_ROW_FILL` times the spacing wide and the object's
  height tall (``Crown``: the leaf balance solves every face, as for a hedge).

All faces are triangles, counter-clockwise seen from outside (outward normals); customData
``humv:refine`` = False keeps the thermal tool from re-tessellating them.
"""

from __future__ import annotations

import zlib

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.scenario.spec import CROPS
from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.paths import material_path, object_path

#: material of a tree's trunk (bark as the library's dry wood)
TRUNK_MATERIAL = "wood"
#: the plant kinds of ``[[scene.object]] kind``
PLANT_KINDS = ("tree", "bush", "hedge", "crop")
#: crown subdivisions of the icosahedron (tree, bush: 320 triangles; hedge: 1280)
CROWN_SUBDIVISIONS = {"tree": 2, "bush": 2, "hedge": 3}
#: relative amplitude of the crown's random lobes
CROWN_ROUGHNESS = 0.12
#: row spacing [m] of a crop object without ``row_spacing_m`` (maize)
CROP_ROW_SPACING_M = CROPS["maize"][0]
#: canopy width of a row over the row spacing (gaps between rows stay visible from above)
CROP_ROW_FILL = 0.8
#: canopy profile of a row across y (x width, z height), counter-clockwise from +x: upright
#: sides to 0.6 height, a rounded top half as wide
_ROW_PROFILE = np.array([[-0.5, 0.0], [0.5, 0.0], [0.5, 0.6], [0.25, 1.0], [-0.25, 1.0], [-0.5, 0.6]])
#: at most this many triangles in a crop object: longer row segments beyond it
CROP_MAX_TRIANGLES = 20000
#: length [m] of a row segment (the thermal solve's face length along the row) when within budget
CROP_SEGMENT_M = 2.0


def icosphere(subdivisions: int):
    """(points (P, 3) on the unit sphere, triangles (T, 3)) of a subdivided icosahedron,
    counter-clockwise from outside."""
    t = (1.0 + 5**0.5) / 2.0
    p = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]  # fmt: skip
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
         (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]  # fmt: skip
    points = [np.array(v, dtype=float) / np.linalg.norm(v) for v in p]
    faces = f
    for _ in range(subdivisions):
        cache: dict = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = points[a] + points[b]
                points.append(m / np.linalg.norm(m))
                cache[key] = len(points) - 1
            return cache[key]

        nxt = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            nxt += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = nxt
    return np.array(points), np.array(faces, dtype=np.int64)


def _lobes(directions, seed: int, roughness: float):
    """Smooth random radius factors 1 + roughness x (sum of 6 random low-order lobes) per unit
    direction."""
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(6, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    weights = rng.uniform(-1.0, 1.0, 6)
    bumps = (np.maximum(directions @ axes.T, 0.0) ** 3) @ weights
    return 1.0 + roughness * bumps / max(np.abs(weights).sum() / 3.0, 1e-9)


def crown(
    radii, subdivisions: int = 2, seed: int = 0, roughness: float = CROWN_ROUGHNESS, exponent: float = 2.0
):
    """(points (P, 3), triangles (T, 3)) of a crown centred at the origin: unit directions d of
    an icosphere mapped onto the superellipsoid |x/a|^p + |y/b|^p + |z/c|^p = 1 (p = exponent;
    2: an ellipsoid) and scaled by smooth random lobes."""
    d, tris = icosphere(subdivisions)
    a = np.asarray(radii, dtype=float)
    r = np.sum(np.abs(d / a) ** exponent, axis=1) ** (-1.0 / exponent)
    return d * (r * _lobes(d, seed, roughness))[:, None], tris


def prism(radius: float, z0: float, z1: float, sides: int = 8):
    """(points, triangles) of a closed upright prism (a trunk) about the z axis."""
    ang = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([radius * np.cos(ang), radius * np.sin(ang)], axis=1)
    bottom = np.column_stack([ring, np.full(sides, z0)])
    top = np.column_stack([ring, np.full(sides, z1)])
    pts = np.vstack([bottom, top, [[0, 0, z0], [0, 0, z1]]])
    tris = []
    for k in range(sides):
        k1 = (k + 1) % sides
        tris += [(k, k1, sides + k1), (k, sides + k1, sides + k)]  # side, outward
        tris += [(2 * sides, k1, k), (2 * sides + 1, sides + k, sides + k1)]  # bottom down, top up
    return pts, np.array(tris, dtype=np.int64)


def crop_rows(size_m, row_spacing_m: float = CROP_ROW_SPACING_M):
    """(points, triangles) of a crop field centred on the origin (base at z = 0): rows along x
    over the size's x, ``row_spacing_m`` apart across its y (as many as fit, centred), each a
    closed prism of :data:`_ROW_PROFILE` (:data:`CROP_ROW_FILL` x spacing wide, the size's z
    tall) in segments of :data:`CROP_SEGMENT_M` (longer when :data:`CROP_MAX_TRIANGLES` would be
    exceeded)."""
    sx, sy, h = (float(v) for v in size_m)
    s = float(row_spacing_m)
    n_rows = max(1, int(np.floor(sy / s + 1e-9)))
    ys = (np.arange(n_rows) - (n_rows - 1) / 2.0) * s
    m = len(_ROW_PROFILE)
    per_seg = 2 * m
    segs = int(np.ceil(sx / CROP_SEGMENT_M))
    segs = max(1, min(segs, (CROP_MAX_TRIANGLES // n_rows - 2 * (m - 2)) // per_seg))
    xs = np.linspace(-sx / 2, sx / 2, segs + 1)
    prof = _ROW_PROFILE * [CROP_ROW_FILL * min(s, sy), h]
    pts, tris = [], []
    for yc in ys:
        o = sum(len(p) for p in pts)
        ring = np.column_stack([np.zeros(m), prof[:, 0] + yc, prof[:, 1]])
        row = np.concatenate([ring + [x, 0.0, 0.0] for x in xs])
        t = []
        for j in range(segs):
            a, b = j * m, (j + 1) * m
            for k in range(m):
                k1 = (k + 1) % m
                t += [(a + k, a + k1, b + k1), (a + k, b + k1, b + k)]
        last = segs * m
        for k in range(1, m - 1):  # convex end caps: fans, facing -x and +x
            t += [(0, k + 1, k), (last, last + k, last + k + 1)]
        pts.append(row)
        tris.append(np.array(t, dtype=np.int64) + o)
    return np.vstack(pts), np.vstack(tris)


def plant_seed(object_id: str) -> int:
    """A stable seed from an object's id (the same id, the same plant)."""
    return zlib.crc32(object_id.encode())


def plant_parts(kind: str, size_m, seed: int = 0, row_spacing_m: float | None = None):
    """{part name: (points (P, 3), triangles (T, 3))} of a plant in its own frame (base centre
    at the origin, before the object's heading): ``Crown`` and, for a tree, ``Trunk``; a crop's
    rows are ``row_spacing_m`` apart (default :data:`CROP_ROW_SPACING_M`)."""
    sx, sy, h = (float(v) for v in size_m)
    if kind not in PLANT_KINDS:
        raise ValueError(f"invalid model selection {kind}")
    if kind == "crop":
        return {"Crown": crop_rows(size_m, row_spacing_m or CROP_ROW_SPACING_M)}
    if kind == "tree":
        rz = 0.35 * h
        p, t = crown((sx / 2, sy / 2, rz), CROWN_SUBDIVISIONS[kind], seed)
        trunk_r = float(np.clip(0.035 * h, 0.06, 0.4))
        return {
            "Crown": (p + [0.0, 0.0, h - rz], t),
            "Trunk": prism(trunk_r, -0.1, h - rz, 8),
        }
    if kind == "bush":
        p, t = crown((sx / 2, sy / 2, h / 2), CROWN_SUBDIVISIONS[kind], seed)
        return {"Crown": (p + [0.0, 0.0, 0.45 * h], t)}
    p, t = crown((sx / 2, sy / 2, h / 2), CROWN_SUBDIVISIONS[kind], seed, roughness=0.05, exponent=4.0)
    return {"Crown": (p + [0.0, 0.0, 0.48 * h], t)}


def placed(points, center_base, heading_deg: float):
    """Points of a plant turned by ``heading_deg`` about z and moved to ``center_base``."""
    h = np.radians(heading_deg)
    rot = np.array([[np.cos(h), -np.sin(h), 0.0], [np.sin(h), np.cos(h), 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(points, dtype=float) @ rot.T + np.asarray(center_base, dtype=float)


def author_plant(stage: Usd.Stage, o: dict, base_z: float, instance_id: int) -> Usd.Prim:
    """/World/Scene/<id>: an Xform labelled as the object, with its Crown (the object's
    material) and, for a tree, its Trunk (wood) standing at ``base_z`` [m]."""
    root = UsdGeom.Xform.Define(stage, object_path(o["id"]))
    label(root.GetPrim(), instance_id, o["class"])
    x, y, z = o["center_m"]
    parts = plant_parts(o["kind"], o["size_m"], plant_seed(o["id"]), o.get("row_spacing_m"))
    for name, (points, tris) in parts.items():
        material = TRUNK_MATERIAL if name == "Trunk" else o["material"]
        mesh = define_mesh(
            stage,
            root.GetPath().AppendChild(name),
            placed(points, (x, y, z + base_z), o["heading_deg"]),
            np.full(len(tris), 3),
            tris.ravel(),
            material=material_path(material),
        )
        # the thermal tool keeps a plant's faces as they are: a trunk in the moving shade of its
        # crown would otherwise split into 10^4 faces (a crown's faces are leaves, not a slab)
        mesh.GetPrim().SetCustomDataByKey("humv:refine", False)
    return root.GetPrim()
