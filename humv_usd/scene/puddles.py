"""Puddles after rain (issue 30.4): flat water patches on the ground, from a seed.

With ``[scene.ground] puddles`` > 0 and rain (``[atmosphere] rain_mm_h`` > 0) the scene layer
adds one mesh /World/Scene/Puddles: irregular discs (:data:`SIDES`-gons whose radius wobbles by
up to :data:`ROUGHNESS` with smooth random lobes) of radius 0.3-1.5 m (log-uniform), scattered
uniformly over the ground rectangle until they cover the asked share of it, each lifted
:data:`LIFT_M` above the terrain at its vertices, none within reach of an object, a plant, an
asset or warm clutter (ground only). Material ``water`` (a 2 cm puddle over the soil:
:data:`humv_usd.catalog.materials.SURFACE_WATER` lets it evaporate freely), labelled ``ground``
with its own instance id (``ground_puddles``), customData ``humv:groundZone`` (the thermal tool solves it as
ground: water over the substrate) and ``humv:refine`` False. The render's fast estimator draws
them as calm mirrors (Fresnel reflection, emissivity 1 - R: :mod:`humv_usd.render.estimator`).

Puddle sizes: urban puddles after rain are decimetres to a few metres across (a log-uniform
0.3-1.5 m radius is an assumption of this model, not a measured distribution).
"""

from __future__ import annotations

import numpy as np
from pxr import Usd

from humv_usd.geometry.terrain import Terrain
from humv_usd.usd.mesh import define_mesh, label
from humv_usd.usd.paths import GROUND, material_path

#: the puddles' mesh
PUDDLES = GROUND.GetParentPath().AppendChild("Puddles")
#: material of a puddle
MATERIAL = "water"
#: height of a puddle's surface above the terrain [m]
LIFT_M = 0.005
#: polygon sides of a puddle
SIDES = 12
#: radius range of the puddles [m] (log-uniform)
RADIUS_M = (0.3, 1.5)
#: relative amplitude of a puddle's radius lobes
ROUGHNESS = 0.25
#: most puddles in a scene
MAX_PUDDLES = 4000


def puddle_discs(seed: int, share: float, size_xy, keep_out=()) -> list[tuple[float, float, float]]:
    """(x, y, radius) [m] of puddles covering ``share`` of the ground rectangle ``size_xy``
    centred at the origin, none within its radius of a keep-out circle (x, y, r)."""
    if share <= 0.0:
        return []
    rng = np.random.default_rng([int(seed), 30_42])
    w, d = float(size_xy[0]), float(size_xy[1])
    target, area, out = share * w * d, 0.0, []
    blocked = np.asarray(list(keep_out), dtype=float).reshape(-1, 3)
    lo, hi = np.log(RADIUS_M[0]), np.log(RADIUS_M[1])
    for _ in range(50 * MAX_PUDDLES):
        if area >= target or len(out) >= MAX_PUDDLES:
            break
        r = float(np.exp(rng.uniform(lo, hi)))
        x, y = float(rng.uniform(-w / 2 + r, w / 2 - r)), float(rng.uniform(-d / 2 + r, d / 2 - r))
        if len(blocked) and np.any(np.hypot(blocked[:, 0] - x, blocked[:, 1] - y) < blocked[:, 2] + r):
            continue
        out.append((x, y, r))
        area += np.pi * r * r
    return out


def puddle_mesh(discs, terrain: Terrain, seed: int = 0):
    """(points (P, 3), counts (F,), indices) of the puddles: a triangle fan per disc, counter-
    clockwise from above, each vertex :data:`LIFT_M` above the terrain."""
    rng = np.random.default_rng([int(seed), 30_43])
    a = np.linspace(0.0, 2.0 * np.pi, SIDES, endpoint=False)
    points, indices = [], []
    for k, (x, y, r) in enumerate(discs):
        phase = rng.uniform(0.0, 2.0 * np.pi, 3)
        wobble = 1.0 + ROUGHNESS * sum(np.sin((j + 2) * a + phase[j]) / (j + 1) for j in range(3)) / 1.84
        ring = np.stack([x + r * wobble * np.cos(a), y + r * wobble * np.sin(a)], axis=1)
        xy = np.vstack([[x, y], ring])
        base = k * (SIDES + 1)
        points.append(np.column_stack([xy, terrain.height(xy[:, 0], xy[:, 1]) + LIFT_M]))
        for i in range(SIDES):
            indices += [base, base + 1 + i, base + 1 + (i + 1) % SIDES]
    if not points:
        return np.zeros((0, 3)), np.zeros(0, int), np.zeros(0, int)
    return np.vstack(points), np.full(len(indices) // 3, 3), np.asarray(indices)


def author_puddles(
    stage: Usd.Stage, discs, terrain: Terrain, ground_id: int, seed: int = 0
) -> Usd.Prim | None:
    """Define :data:`PUDDLES` (module doc); None when there are no puddles."""
    if not discs:
        return None
    mesh = define_mesh(stage, PUDDLES, *puddle_mesh(discs, terrain, seed), material=material_path(MATERIAL))
    prim = mesh.GetPrim()
    label(prim, ground_id, "ground")
    prim.SetCustomDataByKey("humv:groundZone", True)
    prim.SetCustomDataByKey("humv:refine", False)
    return prim
