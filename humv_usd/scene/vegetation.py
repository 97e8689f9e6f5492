"""Procedural plants (issue 30.2): trees, bushes and hedges as our own generated meshes.

A plant is an ``[[scene.object]]`` of kind tree, bush or hedge: an Xform /World/Scene/<id>
(the object's label) with a closed crown mesh ``Crown`` of the object's material (``leaf``: a
big-leaf surface whose faces the thermal tool solves with leaf convection and transpiration,
:mod:`humv_usd.physics.vegetation`) and, for a tree, a closed trunk ``Trunk`` of wood. Shapes:

* crown: an icosphere (subdivided icosahedron) mapped onto an ellipsoid (tree, bush) or a
  superellipsoid of exponent 4 (hedge: a clipped block with rounded edges), its radius
  jittered by smooth random lobes from a seed (the object's id), so no two trees are alike;
* tree: crown radii (size x / 2, size y / 2, 0.35 height) centred 0.35 height below the top;
  trunk an octagonal prism of radius 0.035 height (0.06-0.4 m) from the ground into the crown;
* bush: crown radii (size / 2) centred at half its height, sunk 5 % into the ground;
* hedge: superellipsoid of the object's size (length along the object's x before rotation).

All faces are triangles, counter-clockwise seen from outside (outward normals); customData
``humv:refine`` = False keeps the thermal tool from re-tessellating them.
"""

from __future__ import annotations

import zlib

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.paths import material_path, object_path

#: material of a tree's trunk (bark as the library's dry wood)
TRUNK_MATERIAL = "wood"
#: the plant kinds of ``[[scene.object]] kind``
PLANT_KINDS = ("tree", "bush", "hedge")
#: crown subdivisions of the icosahedron (tree, bush: 320 triangles; hedge: 1280)
CROWN_SUBDIVISIONS = {"tree": 2, "bush": 2, "hedge": 3}
#: relative amplitude of the crown's random lobes
CROWN_ROUGHNESS = 0.12


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


def plant_seed(object_id: str) -> int:
    """A stable seed from an object's id (the same id, the same plant)."""
    return zlib.crc32(object_id.encode())


def plant_parts(kind: str, size_m, seed: int = 0):
    """{part name: (points (P, 3), triangles (T, 3))} of a plant in its own frame (base centre
    at the origin, before the object's heading): ``Crown`` and, for a tree, ``Trunk``."""
    sx, sy, h = (float(v) for v in size_m)
    if kind not in PLANT_KINDS:
        raise ValueError(f"invalid model selection {kind}")
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
    for name, (points, tris) in plant_parts(o["kind"], o["size_m"], plant_seed(o["id"])).items():
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
