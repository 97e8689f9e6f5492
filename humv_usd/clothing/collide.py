"""Per frame: pose body and garments, remove body-garment intersections, layer, air gap.

The seed's HART checks every frame for garment-body intersections and removes minor ones with
Blender's ShrinkWrap (HumV paper, sec. 2.2.1, challenge 3), because the thermal model needs the
garment outside the skin everywhere. Here, per frame and garment (inner layers first):

1. Pose: linear blend skinning of the body and garment rest points with the frame's skinning
   matrices (what UsdSkel does at render time).
2. Check: signed distance of every garment vertex to the posed body (closest point on the body
   mesh, sign from the interpolated normal; :class:`humv_usd.clothing.geometry.Surface`).
   ``inside``: d < 0; ``close``: 0 <= d < minimum gap; ``layered``: closer than the garment
   under it requires (the inner garment's distance + its fabric thickness + the minimum gap, at
   the inner vertex whose body anchor is nearest, within :data:`LAYER_RADIUS`).
3. Fix: move each offending vertex to its closest body point + required distance along the
   body normal there; re-check the moved ones (a push can land near another body part, e.g.
   in the armpit) up to :data:`PUSH_ITERATIONS` times. In a wedge between two body surfaces
   (crotch, armpit, thighs in contact) the nearest surface alternates; the vertices still
   too close then take the shortest of :data:`ESCAPE_STEPS` that clears them along the sum
   of the body normals they met (which points out of the wedge), the last or the first
   body normal, or else the 26 directions to a cube's faces, edges and corners; where the
   layering cannot be met, for the minimum gap alone. Vertices that none clears
   stay as they are and are counted (``*_after``). Only vertices are checked: a garment
   edge between two outside vertices can still graze a convex body edge by up to ~the sagitta
   of a face (< 1 mm for the helpers' ~2.5 cm faces on limbs).
4. Air gap: distance from each garment vertex to the skin along the inward garment normal
   (Embree ray cast); where the ray misses the body or goes farther than :data:`MAX_AIR_GAP`
   (hems, open ends, a skirt between the legs), the straight distance to the closest skin point
   instead, both capped at :data:`MAX_AIR_GAP`. Never below the closest-point distance, so
   never below the minimum gap after the fix. For an outer garment it spans the layers under
   it (it is the distance to the skin, as the schema defines it).
Props (:class:`humv_usd.clothing.garments.Prop`, the rifle) are rigid: they are posed and
checked (counts, before = after) but never moved, and they take no part in the layering. A
carried rifle is a collider for every garment, though: after the body and shell passes,
garment vertices nearer than the minimum gap to its solid are pushed out along its distance
gradient (:func:`push_off_prop`), then the skin is re-checked (the skin wins where both
cannot hold: ``prop_after`` counts what is left). Garments on higher layers treat the ones under them as
part of the body (e.g. a T-shirt over the ``vest``): they keep the inner garment's distance +
its thickness + the minimum gap where both are. A ``body_like`` inner garment (the ``vest``)
is in addition a surface of its own: after the body pass, outer vertices over its posed mesh
(closest point inside a face or across a gentle edge: the offset within
:data:`SHELL_COS` of the face normal, closer than :data:`LAYER_RADIUS`) that are less than its
thickness + the outer minimum gap outside it are pushed out along its normal
(:func:`push_off_shell`); the rest of the fix (skin re-check) follows. Vertices still inside it
count as ``layered_after``.

Before step 1, :func:`dress` splits the garment faces over the neck and pelvis that lie within
:data:`LAYER_RADIUS` of another garment of the outfit once (:func:`humv_usd.clothing.fit.refine`:
collars, waistbands, crotch); loose parts are draped (:mod:`humv_usd.clothing.drape`) between
steps 1 and 2 when :func:`simulate` gets the frame rate. Props get their clearance from the
body per frame (:func:`humv_usd.avatar.carry.rifle_clearance`: the closed-form distance of the
body's non-holding vertices to the rifle's boxes and cylinders).

5. Rest points for UsdSkel: the fixed posed points mapped back through the vertex's blended
   skinning transform (``rest' = rest + A^-1 (fixed - posed)``, exact for linear blend
   skinning), so UsdSkel skinning of the time-sampled rest points reproduces the fixed shape.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from humv_usd.avatar.carry import (carry_body_of, prop_distance_gradient, prop_signed_distance,
                                   rifle_clearance, rifle_world)
from humv_usd.clothing.drape import Drape
from humv_usd.clothing.fit import BodyRig, FittedGarment, fit_garment, refine
from humv_usd.clothing.garments import garment
from humv_usd.clothing.geometry import RayCaster, Surface, vertex_normals

PUSH_ITERATIONS = 3
#: Distances [m] tried along the summed body normals for vertices still too close after the
#: pushes (wedges such as the crotch and armpits, where the nearest surface alternates).
ESCAPE_STEPS = 0.002 * 2.0 ** np.arange(6)       # 2 mm .. 64 mm
# ... and, if those fail, along the 26 directions to the faces, edges and corners of a cube
_FALLBACK_DIRECTIONS = np.array([[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1)
                                 for z in (-1, 0, 1) if (x, y, z) != (0, 0, 0)], dtype=float)
_FALLBACK_DIRECTIONS /= np.linalg.norm(_FALLBACK_DIRECTIONS, axis=1, keepdims=True)
#: Extra distance a pushed vertex gets beyond the required gap [m] (float32/USD round-off).
PUSH_MARGIN = 2e-5
#: Largest air gap reported [m] (HumvClothingAPI airGap range).
MAX_AIR_GAP = 0.2
#: Inner/outer garment vertices correspond when their body anchors are this close [m].
LAYER_RADIUS = 0.025
#: An outer vertex is "over" a body-like garment when its offset from the closest point makes
#: an angle below acos(SHELL_COS) with that face's normal (not beside the garment's border).
SHELL_COS = 0.9
#: Rounds of (push off the carried prop, push off the skin) per garment and frame, and
#: gradient pushes per round (the rifle's parts overlap).
PROP_ROUNDS = 3
PROP_PUSH_ITERATIONS = 8


@dataclass
class FixCounts:
    """Garment vertices in violation, before and after the fix, for one garment and frame."""
    inside_before: int
    close_before: int
    layered_before: int
    inside_after: int
    close_after: int
    layered_after: int
    min_distance_m: float       # smallest signed vertex-skin distance after the fix
    #: vertices inside a carried prop's solid or closer than the minimum gap to it
    prop_before: int = 0
    prop_after: int = 0

    def as_dict(self) -> dict:
        return dict(vars(self))


@dataclass
class GarmentAnimation:
    """One garment over the frames."""
    fitted: FittedGarment
    posed: np.ndarray           # (F, n, 3) fixed posed points (skeleton space) [m]
    rest: np.ndarray            # (F, n, 3) rest points that UsdSkel skins to ``posed``
    air_gap: np.ndarray         # (F, n) [m]
    counts: list[FixCounts] = field(default_factory=list)
    #: props: per frame, the smallest distance [m] from the body (all but the holding hands
    #: and forearms) to the prop's solid and the body vertices inside it
    #: (:func:`humv_usd.avatar.carry.rifle_clearance`); None for garments
    clearance: np.ndarray | None = None
    body_inside: np.ndarray | None = None
    #: garments with draped (loose) parts: (F, n, 3) the skinned shape before the drape
    skinned: np.ndarray | None = None

    @property
    def name(self) -> str:
        return self.fitted.name


@dataclass
class Outfit:
    """Garments fitted to one body, inner layers first, with their layer correspondences."""
    rig: BodyRig
    garments: list[FittedGarment]
    # per garment: list of (inner garment position, outer vertex ids, inner vertex ids)
    under: list[list[tuple[int, np.ndarray, np.ndarray]]]


@dataclass
class Simulation:
    garments: list[GarmentAnimation]
    frame_seconds: np.ndarray   # (F,) wall time of the per-frame work (pose, check, fix, gap)
    fix_seconds: np.ndarray     # (F,) of which the check + fix (all garments)


def dress(rig: BodyRig, names, refined: bool = True) -> Outfit:
    """Fit ``names`` (catalogue garments, any order; duplicates rejected) to ``rig``
    (``refined``: see :func:`humv_usd.clothing.fit.fit_garment`)."""
    names = [garment(n).name for n in names]          # aliases -> catalogue names
    if len(set(names)) != len(names):
        raise ValueError(f"garment listed twice in {names}")
    fitted = [fit_garment(rig, n, refined=False) for n in names]
    fitted.sort(key=lambda g: (g.garment.layer, g.garment.ease))
    anchors = [rig.surface.closest(g.points).point for g in fitted]
    if refined:                 # finer mesh over the neck/pelvis where another garment is
        joints = len(rig.skeleton.names)
        for k, g in enumerate(fitted):
            others = [anchors[i] for i in range(len(fitted))
                      if i != k and not fitted[i].garment.is_prop]
            if g.garment.is_prop or not others:
                continue
            dist, _ = cKDTree(np.concatenate(others)).query(anchors[k])
            near = dist < LAYER_RADIUS
            quads = np.asarray(g.face_indices).reshape(-1, 4)
            fitted[k] = refine(g, joints, near[quads].any(axis=1))
        anchors = [rig.surface.closest(g.points).point for g in fitted]
    under: list[list] = []
    for o, outer in enumerate(fitted):
        pairs = []
        for i in range(o):
            if outer.garment.is_prop or fitted[i].garment.is_prop:
                continue
            dist, near = cKDTree(anchors[i]).query(anchors[o], distance_upper_bound=LAYER_RADIUS)
            ok = np.isfinite(dist)
            if ok.any():
                pairs.append((i, np.flatnonzero(ok), near[ok]))
        under.append(pairs)
    return Outfit(rig, fitted, under)


def blend_transforms(indices: np.ndarray, weights: np.ndarray, skin: np.ndarray) -> np.ndarray:
    """(n, 4, 4) per-vertex linear-blend transform sum_k w_k skin[idx_k]."""
    return np.einsum("vk,vkij->vij", weights.astype(np.float64), skin[indices])


def apply(blended: np.ndarray, points: np.ndarray) -> np.ndarray:
    return np.einsum("vij,vj->vi", blended[:, :3, :3], points) + blended[:, :3, 3]


def measure(surface: Surface, points: np.ndarray, minimum_gap: float
            ) -> tuple[np.ndarray, FixCounts]:
    """Signed distances and counts of points that are not moved (props): after = before."""
    d = surface.closest(points).signed
    counts = (int(np.sum(d < 0)), int(np.sum((d >= 0) & (d < minimum_gap))), 0)
    return d, FixCounts(*counts, *counts, float(d.min()) if len(d) else 0.0)


def push_off_shell(shell: Surface, flat_normals: np.ndarray, points: np.ndarray,
                   clearance: float) -> tuple[np.ndarray, int, int]:
    """Push ``points`` over ``shell`` (see module doc) to ``clearance`` outside it.
    Returns (points, violations before, violations after)."""
    out = points.copy()

    def violating(p):
        near = shell.closest(p)
        off = p - near.point
        dist = np.linalg.norm(off, axis=1)
        along = np.abs(np.einsum("ij,ij->i", off, flat_normals[near.triangle]))
        over = (dist < LAYER_RADIUS) & ((along >= SHELL_COS * dist) | (dist < 1e-9))
        return np.flatnonzero(over & (near.signed < clearance)), near

    bad, near = violating(out)
    before = len(bad)
    for _ in range(2 * PUSH_ITERATIONS):     # by the deficit: converges in concave spots
        if not len(bad):
            break
        out[bad] += near.normal[bad] * (clearance - near.signed[bad] + PUSH_MARGIN)[:, None]
        bad, near = violating(out)
    return out, before, len(bad)


def push_off_prop(points: np.ndarray, to_world: np.ndarray, prop, clearance: float
                  ) -> tuple[np.ndarray, int, int]:
    """Push ``points`` out of a carried prop's solid (``to_world``: prop frame -> skeleton
    space) to ``clearance`` off it, along the solid's distance gradient
    (:func:`humv_usd.avatar.carry.prop_signed_distance`). Returns (points, violations
    before, after)."""
    inv = np.linalg.inv(to_world)
    local = points @ inv[:3, :3].T + inv[:3, 3]
    d = prop_signed_distance(local, prop)
    bad = np.flatnonzero(d < clearance)
    before = len(bad)
    moved = bad.copy()
    for _ in range(PROP_PUSH_ITERATIONS):   # a push out of one part can land in the next
        if not len(bad):
            break
        local[bad] += (prop_distance_gradient(local[bad], prop)
                       * (clearance - d[bad] + PUSH_MARGIN)[:, None])
        d[bad] = prop_signed_distance(local[bad], prop)
        bad = bad[d[bad] < clearance]
    if len(bad):        # stuck where two parts abut (the gradients alternate): search out
        steps = 0.002 * 2.0 ** (np.arange(14) / 2)                     # 2 mm .. 0.18 m
        cand = (local[bad][:, None, None] + steps[None, :, None, None]
                * _FALLBACK_DIRECTIONS[None, None]).reshape(len(bad), -1, 3)
        ok = prop_signed_distance(cand, prop) >= clearance + PUSH_MARGIN / 2
        first = np.argmax(ok, axis=1)                  # steps ascend: the shortest
        found = ok[np.arange(len(bad)), first]
        local[bad[found]] = cand[np.flatnonzero(found), first[found]]
        bad = bad[~found]
    out = points.copy()
    out[moved] = local[moved] @ to_world[:3, :3].T + to_world[:3, 3]
    return out, before, len(bad)


def _flat_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    n = np.cross(points[triangles[:, 1]] - points[triangles[:, 0]],
                 points[triangles[:, 2]] - points[triangles[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-15)


def push_out(surface: Surface, points: np.ndarray, required: np.ndarray, minimum_gap: float
             ) -> tuple[np.ndarray, np.ndarray, FixCounts]:
    """Move vertices closer to the body than ``required`` out along the body normal.

    Returns (fixed points, signed distance after the fix, counts).
    """
    near = surface.closest(points)
    d = near.signed.copy()

    def count(dist):
        return (int(np.sum(dist < 0)), int(np.sum((dist >= 0) & (dist < minimum_gap))),
                int(np.sum((dist >= minimum_gap) & (dist < required))))

    before = count(d)
    out = points.copy()
    todo = np.flatnonzero(d < required)
    point, normal = near.point[todo], near.normal[todo]
    heading = normal.copy()             # sum of the body normals met: out of a wedge
    for _ in range(PUSH_ITERATIONS):
        if not len(todo):
            break
        out[todo] = point + normal * (required[todo] + PUSH_MARGIN)[:, None]
        again = surface.closest(out[todo])
        d[todo] = again.signed
        still = again.signed < required[todo]
        todo, point, normal = todo[still], again.point[still], again.normal[still]
        heading = heading[still] + normal
    if len(todo):                       # wedge (crotch, armpit): search outward directions
        informed = np.stack([heading, normal, near.normal[todo]], 1)
        informed /= np.maximum(np.linalg.norm(informed, axis=2, keepdims=True), 1e-12)
        left = _escape(surface, out, d, todo, informed, required)
        if len(left):
            left = _escape(surface, out, d, left, _fallback(len(left)), required)
        if len(left):                   # give up the layering there, keep off the skin
            relaxed = np.full_like(required, minimum_gap)
            left = _escape(surface, out, d, left, _fallback(len(left)), relaxed)
    after = count(d)
    return out, d, FixCounts(*before, *after, float(d.min()) if len(d) else 0.0)


def _fallback(m: int) -> np.ndarray:
    return np.broadcast_to(_FALLBACK_DIRECTIONS, (m,) + _FALLBACK_DIRECTIONS.shape)


def _escape(surface: Surface, out: np.ndarray, d: np.ndarray, todo: np.ndarray,
            dirs: np.ndarray, required: np.ndarray) -> np.ndarray:
    """Move ``out[todo]`` by the shortest of :data:`ESCAPE_STEPS` along any of ``dirs``
    ((m, k, 3) unit vectors) that clears the required distance (in place, also ``d``).
    Returns the vertices none cleared."""
    steps = ESCAPE_STEPS
    m, ndir, nstep = len(todo), dirs.shape[1], len(steps)
    cand = (out[todo][:, None, None, :] + steps[None, None, :, None] * dirs[:, :, None, :])
    cand = cand.reshape(m, ndir * nstep, 3)
    check = surface.closest(cand.reshape(-1, 3)).signed.reshape(m, ndir * nstep)
    ok = check >= (required[todo] + PUSH_MARGIN / 2)[:, None]
    cost = np.where(ok, np.tile(steps, ndir)[None, :], np.inf)
    best = np.argmin(cost, axis=1)
    found = np.isfinite(cost[np.arange(m), best])
    rows = np.flatnonzero(found)
    out[todo[rows]] = cand[rows, best[rows]]
    d[todo[rows]] = check[rows, best[rows]]
    return todo[~found]


def air_gap(caster: RayCaster, points: np.ndarray, triangles: np.ndarray,
            distance: np.ndarray) -> np.ndarray:
    """Per-vertex air gap [m] along the inward garment normal; see the module doc."""
    n = vertex_normals(points, triangles)
    t = caster.first_hit(points, -n)
    fallback = np.abs(distance)
    gap = np.where(np.isfinite(t) & (t <= MAX_AIR_GAP), t, fallback)
    return np.clip(np.maximum(gap, fallback), 0.0, MAX_AIR_GAP)


def drapes_of(g: FittedGarment) -> list[Drape]:
    """A :class:`~humv_usd.clothing.drape.Drape` per loose part of ``g``."""
    out = []
    counts = np.asarray(g.face_counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[counts == 4]
    quads = np.asarray(g.face_indices)[starts[:, None] + np.arange(4)]     # loose parts: quads
    for k, part in enumerate(g.garment.parts):
        if part.loose:
            ids = np.flatnonzero(g.part_of == k)
            mine = quads[np.all(np.isin(quads, ids), axis=1)]
            out.append(Drape.for_part(g.points, mine, ids))
    return out


def simulate(outfit: Outfit, skin: np.ndarray, progress=None, fps: float | None = None
             ) -> Simulation:
    """Pose, fix and measure every garment for each frame of ``skin`` ((F, J, 4, 4) skinning
    matrices, :func:`humv_usd.avatar.skeleton.skinning_matrices`). With ``fps`` (and more
    than one frame) loose parts are draped (:mod:`humv_usd.clothing.drape`) before the fix;
    ``GarmentAnimation.skinned`` then keeps the skinned shape they lag."""
    rig = outfit.rig
    skin = np.asarray(skin, dtype=np.float64)
    frames = skin.shape[0]
    anims = [GarmentAnimation(g, np.empty((frames, g.vertex_count, 3)),
                              np.empty((frames, g.vertex_count, 3)),
                              np.empty((frames, g.vertex_count))) for g in outfit.garments]
    frame_s = np.zeros(frames)
    fix_s = np.zeros(frames)
    carried = [g.garment.prop for g in outfit.garments
               if g.garment.is_prop and g.garment.prop.placement == "between_hands"]
    prop_world = rifle_world(rig.skeleton, skin) if carried else None
    dynamic = fps is not None and fps > 0 and frames > 1
    drapes = [drapes_of(g) if dynamic else [] for g in outfit.garments]
    for anim, d in zip(anims, drapes):
        if d:
            anim.skinned = np.empty_like(anim.posed)
    for g, anim in zip(outfit.garments, anims):
        if g.garment.is_prop and g.garment.prop.placement == "between_hands":
            cb = carry_body_of(rig.mesh, rig.joint_indices, rig.joint_weights, rig.face_regions)
            anim.clearance, anim.body_inside, _ = rifle_clearance(cb, rig.skeleton, skin,
                                                                  g.garment.prop)
    for f in range(frames):
        t0 = time.perf_counter()
        body = apply(blend_transforms(rig.joint_indices, rig.joint_weights, skin[f]),
                     rig.mesh.points)
        surface = Surface(body, rig.triangles)
        caster = RayCaster(body, rig.triangles)
        distances: list[np.ndarray] = []
        shells: list[tuple[Surface, np.ndarray, float]] = []     # posed body-like garments
        for k, (g, anim) in enumerate(zip(outfit.garments, anims)):
            gap = g.garment.minimum_gap
            blended = blend_transforms(g.joint_indices, g.joint_weights, skin[f])
            skinned = apply(blended, g.points)
            posed = skinned
            if drapes[k]:
                posed = skinned.copy()
                for drape in drapes[k]:
                    posed[drape.vertices] = drape.step(skinned[drape.vertices], 1.0 / fps,
                                                       surface, gap)
                anim.skinned[f] = skinned
            required = np.full(g.vertex_count, gap)
            for i, outer_ids, inner_ids in outfit.under[k]:
                inner = outfit.garments[i].garment
                need = distances[i][inner_ids] + inner.thickness + gap
                np.maximum.at(required, outer_ids, need)
            t1 = time.perf_counter()
            if g.garment.is_prop:
                dist, counts = measure(surface, posed, gap)
                fixed = posed
            else:
                fixed, dist, counts = push_out(surface, posed, required, gap)
                for shell, flat, thickness in shells:
                    fixed, was, left = push_off_shell(shell, flat, fixed, thickness + gap)
                    counts.layered_before += was
                    counts.layered_after += left
                if shells:                  # the shell pass moved some: skin re-check
                    fixed, dist, again = push_out(surface, fixed, required, gap)
                    counts.inside_after, counts.close_after = again.inside_after, again.close_after
                    counts.min_distance_m = again.min_distance_m
                for prop in carried:        # off the carried rifle, then the skin again
                    for round_ in range(PROP_ROUNDS):
                        fixed, was, left = push_off_prop(fixed, prop_world[f], prop, gap)
                        if round_ == 0:
                            counts.prop_before += was
                        if not was:
                            break
                        fixed, dist, again = push_out(surface, fixed, required, gap)
                        counts.inside_after = again.inside_after
                        counts.close_after = again.close_after
                        counts.min_distance_m = again.min_distance_m
                        _, left, _ = push_off_prop(fixed, prop_world[f], prop, gap)
                        if not left:
                            break
                    counts.prop_after += left   # closer than the gap after the skin pass
                if g.garment.body_like:
                    shells.append((Surface(fixed, g.triangles),
                                   _flat_normals(fixed, g.triangles), g.garment.thickness))
            fix_s[f] += time.perf_counter() - t1
            distances.append(dist)
            anim.posed[f] = fixed
            anim.counts.append(counts)
            anim.air_gap[f] = air_gap(caster, fixed, g.triangles, dist)
            for drape in drapes[k]:
                drape.settle(fixed[drape.vertices])
            rest = g.points.copy()
            moved = np.flatnonzero(np.any(fixed != skinned, axis=1))
            if len(moved):
                delta = np.linalg.solve(blended[moved, :3, :3],
                                        (fixed[moved] - skinned[moved])[:, :, None])[:, :, 0]
                rest[moved] += delta
            anim.rest[f] = rest
        frame_s[f] = time.perf_counter() - t0
        if progress is not None:
            progress(f)
    return Simulation(anims, frame_s, fix_s)
