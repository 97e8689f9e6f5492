"""Per frame: pose body and garments, remove body-garment intersections, layer, air gap.

The seed's HART checks every frame for garment-body intersections and removes minor ones with
Blender's ShrinkWrap (HumV paper, sec. 2.2.1, challenge 3), because the thermal model needs the
garment outside the skin everywhere. Here, per frame and garment (inner layers first):

1. Pose: linear blend skinning of the body and garment rest points with the frame's skinning
   matrices (what UsdSkel does at render time).
2. Check: signed distance of every garment vertex to the posed body (closest point on the body
   mesh, sign from the interpolated normal; :class:`humv_usd.geometry.mesh.Surface`).
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
   stay as they are and are counted (``*_after``).
   Between the vertices (:func:`push_between`): the edge midpoints and triangle centroids
   inside the body or closer than the minimum gap ask their edge's / triangle's vertices to
   move by their deficit along the body normal at their closest point (the least-norm vertex
   move that moves the sample so), a few rounds, then the full vertex fix again. Residual
   (``between_*_after``): samples in wedges (armpit, crotch, a leg through the robe's
   long skirt faces) where the move out of one surface pushes a vertex into the other.
   With ``between_layers`` the samples and vertices over an inner garment's faces are
   pushed off it too (thickness + minimum gap).
4. Air gap: distance from each garment vertex to the skin along the inward garment normal
   (Embree ray cast); where the ray misses the body or goes farther than :data:`MAX_AIR_GAP`
   (hems, open ends, a skirt between the legs), the straight distance to the closest skin point
   instead, both capped at :data:`MAX_AIR_GAP`. Never below the closest-point distance, so
   never below the minimum gap after the fix. For an outer garment it spans the layers under
   it (it is the distance to the skin, as the schema defines it).
Props (:class:`humv_usd.catalog.garments.Prop`, the rifle) are rigid: they are posed and
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
body per frame (:func:`humv_usd.human.carry.rifle_clearance`: the closed-form distance of the
body's non-holding vertices to the rifle's boxes and cylinders).

Per frame the posed body's closest-point structure and ray caster are built once, on first
need; a garment whose box lies near a small part of the body (hair, shoes on their own: at most
:data:`LOCAL_SHARE` of its triangles) queries only that part, with the whole body's answers
(:class:`humv_usd.geometry.mesh.LocalSurface`, :class:`_LocalCaster`).

The fixed posed points are the garment's shape per frame; the clothing layer stores them as a
time-sampled point cache (:mod:`humv_usd.clothing.layer`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from humv_usd.catalog.garments import garment
from humv_usd.clothing.drape import Drape
from humv_usd.clothing.fit import BodyRig, FittedGarment, fit_garment, refine
from humv_usd.geometry.mesh import LocalSurface, Surface, triangles_near_box, vertex_normals
from humv_usd.geometry.raycast import RayCaster
from humv_usd.human.carry import (
    carry_body_of,
    prop_distance_gradient,
    prop_signed_distance,
    rifle_clearance,
    rifle_world,
)

PUSH_ITERATIONS = 3
#: Distances [m] tried along the summed body normals for vertices still too close after the
#: pushes (wedges such as the crotch and armpits, where the nearest surface alternates).
ESCAPE_STEPS = 0.002 * 2.0 ** np.arange(6)  # 2 mm .. 64 mm
# ... and, if those fail, along the 26 directions to the faces, edges and corners of a cube
_FALLBACK_DIRECTIONS = np.array(
    [[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if (x, y, z) != (0, 0, 0)],
    dtype=float,
)
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
#: Rounds of the between-vertex pass (:func:`push_between`): check the samples, push the
#: triangles of those too close, re-fix the moved vertices.
BETWEEN_ROUNDS = 5
#: A garment whose posed points' box lies within these [m] of at most :data:`LOCAL_SHARE`
#: of the body's triangle centroids queries only those (hair: the head and neck): a
#: :class:`humv_usd.geometry.mesh.LocalSurface` (the same answers as the whole body; points
#: it cannot certify go to the whole body) and, for the air gap, ray casters over the
#: triangles near its fixed points (:class:`_LocalCaster`: the same gaps).
LOCAL_REACH = 0.05
LOCAL_SHARE = 0.4
#: Rays of the air gap are first cast over the body triangles within this [m] of the garment
#: (:class:`_LocalCaster`).
LOCAL_RAY = 0.05
#: Samples deeper than this [m] are left (counted): a limb through a garment face (the robe's
#: skirt between striding legs) needs a move around the limb, not a local push.
BETWEEN_DEPTH = 0.02
#: Smallest cosine between a between-vertex push and the body normal at the sample.
WEDGE_COS = 0.5
#: Longest vertex move of the between-vertex pass (all rounds) [m].
BETWEEN_MOVE = 0.03
#: A sample is checked when the Lipschitz bound of its vertices' distances
#: (max_i d_i - |s - v_i|) is below the clearance + this [m]: a sample farther from the
#: body than that cannot be too close to it (the signed distance changes by at most the
#: distance moved); the slack covers sign errors in wedges (thighs in contact).
BETWEEN_SLACK = 0.005


@dataclass
class FixCounts:
    """Garment vertices in violation, before and after the fix, for one garment and frame."""

    inside_before: int
    close_before: int
    layered_before: int
    inside_after: int
    close_after: int
    layered_after: int
    min_distance_m: float  # smallest signed vertex-skin distance after the fix
    #: vertices inside a carried prop's solid or closer than the minimum gap to it
    prop_before: int = 0
    prop_after: int = 0
    #: between the vertices (:func:`push_between`): edge midpoints and triangle centroids
    #: inside the body, closer than the minimum gap to it, inside a garment under it
    between_inside_before: int = 0
    between_close_before: int = 0
    between_layered_before: int = 0
    between_inside_after: int = 0
    between_close_after: int = 0
    between_layered_after: int = 0

    def as_dict(self) -> dict:
        return dict(vars(self))


@dataclass
class GarmentAnimation:
    """One garment over the frames."""

    fitted: FittedGarment
    posed: np.ndarray  # (F, n, 3) fixed posed points (skeleton space) [m]
    air_gap: np.ndarray  # (F, n) [m]
    counts: list[FixCounts] = field(default_factory=list)
    #: props: per frame, the smallest distance [m] from the body (all but the holding hands
    #: and forearms) to the prop's solid and the body vertices inside it
    #: (:func:`humv_usd.human.carry.rifle_clearance`); None for garments
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
    frame_seconds: np.ndarray  # (F,) wall time of the per-frame work (pose, check, fix, gap)
    fix_seconds: np.ndarray  # (F,) of which the check + fix (all garments)
    #: (F,) CPU time (all threads of the process) of the check + fix
    fix_cpu_seconds: np.ndarray | None = None


def dress(rig: BodyRig, names, refined: bool = True) -> Outfit:
    """Fit ``names`` (catalogue garments, any order; duplicates rejected) to ``rig``
    (``refined``: see :func:`humv_usd.clothing.fit.fit_garment`)."""
    names = [garment(n).name for n in names]  # aliases -> catalogue names
    if len(set(names)) != len(names):
        raise ValueError(f"garment listed twice in {names}")
    fitted = [fit_garment(rig, n, refined=False) for n in names]
    fitted.sort(key=lambda g: (g.garment.layer, g.garment.ease))
    anchors = [rig.surface.closest(g.points).point for g in fitted]
    if refined:  # finer mesh over the neck/pelvis where another garment is
        joints = len(rig.skeleton.names)
        for k, g in enumerate(fitted):
            others = [anchors[i] for i in range(len(fitted)) if i != k and not fitted[i].garment.is_prop]
            if g.garment.is_prop or not others:
                continue
            dist, _ = cKDTree(np.concatenate(others)).query(anchors[k])
            near = dist < LAYER_RADIUS
            starts = np.concatenate([[0], np.cumsum(g.face_counts)[:-1]])
            fitted[k] = refine(g, joints, np.logical_or.reduceat(near[g.face_indices], starts))
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


def measure(surface: Surface, points: np.ndarray, minimum_gap: float) -> tuple[np.ndarray, FixCounts]:
    """Signed distances and counts of points that are not moved (props): after = before."""
    d = surface.closest(points).signed
    counts = (int(np.sum(d < 0)), int(np.sum((d >= 0) & (d < minimum_gap))), 0)
    return d, FixCounts(*counts, *counts, float(d.min()) if len(d) else 0.0)


def push_off_shell(
    shell: Surface, flat_normals: np.ndarray, points: np.ndarray, clearance: float
) -> tuple[np.ndarray, int, int]:
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
    for _ in range(2 * PUSH_ITERATIONS):  # by the deficit: converges in concave spots
        if not len(bad):
            break
        out[bad] += near.normal[bad] * (clearance - near.signed[bad] + PUSH_MARGIN)[:, None]
        bad, near = violating(out)
    return out, before, len(bad)


def push_off_prop(
    points: np.ndarray, to_world: np.ndarray, prop, clearance: float
) -> tuple[np.ndarray, int, int]:
    """Push ``points`` out of a carried prop's solid (``to_world``: prop frame -> skeleton
    space) to ``clearance`` off it, along the solid's distance gradient
    (:func:`humv_usd.human.carry.prop_signed_distance`). Returns (points, violations
    before, after)."""
    inv = np.linalg.inv(to_world)
    local = points @ inv[:3, :3].T + inv[:3, 3]
    d = prop_signed_distance(local, prop)
    bad = np.flatnonzero(d < clearance)
    before = len(bad)
    moved = bad.copy()
    for _ in range(PROP_PUSH_ITERATIONS):  # a push out of one part can land in the next
        if not len(bad):
            break
        local[bad] += prop_distance_gradient(local[bad], prop) * (clearance - d[bad] + PUSH_MARGIN)[:, None]
        d[bad] = prop_signed_distance(local[bad], prop)
        bad = bad[d[bad] < clearance]
    if len(bad):  # stuck where two parts abut (the gradients alternate): search out
        steps = 0.002 * 2.0 ** (np.arange(14) / 2)  # 2 mm .. 0.18 m
        cand = (
            local[bad][:, None, None] + steps[None, :, None, None] * _FALLBACK_DIRECTIONS[None, None]
        ).reshape(len(bad), -1, 3)
        ok = prop_signed_distance(cand, prop) >= clearance + PUSH_MARGIN / 2
        first = np.argmax(ok, axis=1)  # steps ascend: the shortest
        found = ok[np.arange(len(bad)), first]
        local[bad[found]] = cand[np.flatnonzero(found), first[found]]
        bad = bad[~found]
    out = points.copy()
    out[moved] = local[moved] @ to_world[:3, :3].T + to_world[:3, 3]
    return out, before, len(bad)


def _flat_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    n = np.cross(
        points[triangles[:, 1]] - points[triangles[:, 0]], points[triangles[:, 2]] - points[triangles[:, 0]]
    )
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-15)


def push_out(
    surface: Surface, points: np.ndarray, required: np.ndarray, minimum_gap: float
) -> tuple[np.ndarray, np.ndarray, FixCounts]:
    """Move vertices closer to the body than ``required`` out along the body normal.

    Returns (fixed points, signed distance after the fix, counts).
    """
    near = surface.closest(points)
    d = near.signed.copy()

    def count(dist):
        return (
            int(np.sum(dist < 0)),
            int(np.sum((dist >= 0) & (dist < minimum_gap))),
            int(np.sum((dist >= minimum_gap) & (dist < required))),
        )

    before = count(d)
    out = points.copy()
    todo = np.flatnonzero(d < required)
    point, normal = near.point[todo], near.normal[todo]
    heading = normal.copy()  # sum of the body normals met: out of a wedge
    for _ in range(PUSH_ITERATIONS):
        if not len(todo):
            break
        out[todo] = point + normal * (required[todo] + PUSH_MARGIN)[:, None]
        again = surface.closest(out[todo])
        d[todo] = again.signed
        still = again.signed < required[todo]
        todo, point, normal = todo[still], again.point[still], again.normal[still]
        heading = heading[still] + normal
    if len(todo):  # wedge (crotch, armpit): search outward directions
        informed = np.stack([heading, normal, near.normal[todo]], 1)
        informed /= np.maximum(np.linalg.norm(informed, axis=2, keepdims=True), 1e-12)
        left = _escape(surface, out, d, todo, informed, required)
        if len(left):
            left = _escape(surface, out, d, left, _fallback(len(left)), required)
        if len(left):  # give up the layering there, keep off the skin
            relaxed = np.full_like(required, minimum_gap)
            left = _escape(surface, out, d, left, _fallback(len(left)), relaxed)
    after = count(d)
    return out, d, FixCounts(*before, *after, float(d.min()) if len(d) else 0.0)


def _fallback(m: int) -> np.ndarray:
    return np.broadcast_to(_FALLBACK_DIRECTIONS, (m,) + _FALLBACK_DIRECTIONS.shape)


def _escape(
    surface: Surface, out: np.ndarray, d: np.ndarray, todo: np.ndarray, dirs: np.ndarray, required: np.ndarray
) -> np.ndarray:
    """Move ``out[todo]`` by the shortest of :data:`ESCAPE_STEPS` along any of ``dirs``
    ((m, k, 3) unit vectors) that clears the required distance (in place, also ``d``).
    Returns the vertices none cleared."""
    steps = ESCAPE_STEPS
    m, ndir, nstep = len(todo), dirs.shape[1], len(steps)
    cand = out[todo][:, None, None, :] + steps[None, None, :, None] * dirs[:, :, None, :]
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


def between_samples(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points checked between the vertices of a triangle mesh: each unique edge's
    midpoint and each triangle's centroid, as (S, 3) vertex ids and (S, 3) barycentric
    weights (an edge's third id repeats its first with weight 0)."""
    t = np.asarray(triangles, dtype=np.int64)
    e = np.unique(np.sort(np.stack([t, np.roll(t, -1, 1)], -1).reshape(-1, 2), axis=1), axis=0)
    ids = np.concatenate([np.column_stack([e, e[:, 0]]), t])
    w = np.concatenate([np.tile([0.5, 0.5, 0.0], (len(e), 1)), np.full((len(t), 3), 1.0 / 3.0)])
    return ids, w


def _shell_deficit(
    shell: Surface, flat: np.ndarray, clearance: float, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For points ``q`` over ``shell`` (:func:`push_off_shell`'s test): (clearance - signed
    distance, -inf where not over; shell normal; unsigned distance; inside the fabric)."""
    near = shell.closest(q)
    off = q - near.point
    dist = np.linalg.norm(off, axis=1)
    along = np.abs(np.einsum("ij,ij->i", off, flat[near.triangle]))
    over = (dist < LAYER_RADIUS) & ((along >= SHELL_COS * dist) | (dist < 1e-9))
    return np.where(over, clearance - near.signed, -np.inf), near.normal, dist, over


def _between_counts(signed: np.ndarray, layered: np.ndarray, minimum_gap: float) -> tuple:
    return (int(np.sum(signed < 0)), int(np.sum((signed >= 0) & (signed < minimum_gap))), int(layered.sum()))


def push_between(
    surface: Surface,
    points: np.ndarray,
    d: np.ndarray,
    samples,
    minimum_gap: float,
    required: np.ndarray,
    shells=(),
) -> tuple[np.ndarray, np.ndarray, tuple, tuple]:
    """Resolve what a vertex-only fix misses: garment points between the vertices (edge
    midpoints and triangle centroids, :func:`between_samples`) inside the body or closer
    than ``minimum_gap`` to it, or inside a garment under it (``shells``: (posed Surface,
    flat face normals, thickness) of the inner garments; over their faces as
    :func:`push_off_shell` defines it, closer than thickness + ``minimum_gap``; for the
    shells the vertices are checked too).

    ``d``: the vertices' signed body distances (after :func:`push_out`). A sample at
    barycentric weights w moves by the displacement D of its vertices i by sum_i w_i D_i;
    the smallest (least-norm) vertex displacements that move it by the vector t are
    D_i = w_i t / sum_j w_j^2, i.e. t for both vertices of an edge and all three of a
    triangle (the face is translated). So each too-close sample asks its vertices to move
    by t = (deficit + :data:`PUSH_MARGIN`) along h / (h . n), n the body (or shell) normal
    at its closest point and h the normalized sum of n and the body normals at its
    vertices weighted by w (on a smooth part h = n; in a wedge such as the armpit, where
    the vertices sit on opposite surfaces, h points out of the wedge; h . n >=
    :data:`WEDGE_COS`); a vertex shared by several takes the request of the most violated
    sample, and no vertex moves more than :data:`BETWEEN_MOVE` in all. Moved vertices
    closer to the body than ``required`` are put back to it along the body normal; the
    samples that touch a moved vertex are checked again, for :data:`BETWEEN_ROUNDS` rounds;
    then :func:`push_out` (with its wedge escapes) re-fixes every moved vertex, so the
    vertex guarantee holds, and the samples they touch are checked once more (the counts
    after). Samples deeper than :data:`BETWEEN_DEPTH` are left (a limb through a face).
    Only samples whose Lipschitz bound max_i (d_i - |s - v_i|) is below the clearance +
    :data:`BETWEEN_SLACK` are checked (the signed distance is 1-Lipschitz on a closed
    surface; where the body overlaps itself the sign can jump, so a few more can be
    missed: ``humv-usd bench clothing`` counts all samples).

    Returns (points, signed vertex distances, counts before, counts after), counts =
    (inside, close, layered) samples.
    """
    ids, w = samples
    out = points.copy()
    d = d.copy()
    n = len(out)
    reach = np.linalg.norm(out[ids] - np.einsum("sk,ski->si", w, out[ids])[:, None], axis=2)
    bound = np.max(d[ids] - reach, axis=1)
    near_any = bound < minimum_gap + BETWEEN_SLACK
    shell_cand = []
    for shell, flat, thickness in shells:  # vertices' distances to the shell: bound
        _, _, dist_v, _ = _shell_deficit(shell, flat, thickness + minimum_gap, out)
        b = np.max(dist_v[ids] - reach, axis=1)
        shell_cand.append(b < thickness + minimum_gap + BETWEEN_SLACK)
        near_any |= shell_cand[-1]
    cand = np.flatnonzero(near_any)
    vertex_check = np.arange(n)
    is_cand = np.zeros(len(ids), dtype=bool)
    is_cand[cand] = True
    signed = np.full(len(ids), np.inf)  # last checked state of every sample
    layered = np.zeros(len(ids), dtype=bool)
    ever = np.zeros(n, dtype=bool)
    before = None
    last = False  # the recheck after the full vertex fix
    for round_ in range(BETWEEN_ROUNDS + 2):
        q = np.einsum("sk,ski->si", w[cand], out[ids[cand]])
        near = surface.closest(q)
        signed[cand] = near.signed
        layered[cand] = False
        deficit = minimum_gap - near.signed
        normal = near.normal
        v_def = np.full(len(vertex_check), -np.inf)
        v_normal = np.zeros((len(vertex_check), 3))
        for (shell, flat, thickness), sc in zip(shells, shell_cand):
            clearance = thickness + minimum_gap
            use = sc[cand]
            if use.any():
                sd, sn, _, _ = _shell_deficit(shell, flat, clearance, q[use])
                rows = np.flatnonzero(use)
                layered[cand[rows]] |= sd > minimum_gap  # inside the inner fabric
                take = sd > deficit[rows]
                deficit[rows[take]] = sd[take]
                normal[rows[take]] = sn[take]
            if len(vertex_check):
                vd, vn, _, _ = _shell_deficit(shell, flat, clearance, out[vertex_check])
                take = vd > v_def
                v_def[take], v_normal[take] = vd[take], vn[take]
        if before is None:
            before = _between_counts(signed, layered, minimum_gap)
        bad = (deficit > 0) & (deficit < BETWEEN_DEPTH)
        bad_v = v_def > 0
        if last:
            break
        if (not bad.any() and not bad_v.any()) or round_ >= BETWEEN_ROUNDS:
            # the full vertex fix (wedges: escapes) on every vertex moved here, then recheck
            moved = np.flatnonzero(ever)
            if not len(moved):
                break
            fixed, dm, _ = push_out(surface, out[moved], required[moved], minimum_gap)
            changed = moved[np.any(fixed != out[moved], axis=1)]
            out[moved], d[moved] = fixed, dm
            last = True
        else:
            # out of a wedge (armpit, crotch): along the sample's normal + its vertices'
            # normals (opposite sides of the wedge add up to its bisector), by the deficit
            # along the sample's normal
            rows = np.flatnonzero(bad)
            sv = ids[cand[rows]]
            uv, inv = np.unique(sv, return_inverse=True)
            nv = surface.closest(out[uv]).normal[inv.reshape(sv.shape)]
            head = normal[rows] + np.einsum("sk,ski->si", w[cand[rows]], nv)
            head /= np.maximum(np.linalg.norm(head, axis=1, keepdims=True), 1e-12)
            cos = np.maximum(np.einsum("si,si->s", head, normal[rows]), WEDGE_COS)
            normal[rows] = head / cos[:, None]
            # per vertex: the request of its most violated sample (own requests first)
            order = np.flatnonzero(bad)[np.argsort(-deficit[bad])]
            take = w[cand[order]] > 0
            rows = np.repeat(order, take.sum(axis=1))
            verts = np.concatenate([vertex_check[bad_v], ids[cand[order]][take]])
            push = np.concatenate(
                [
                    v_normal[bad_v] * (v_def[bad_v] + PUSH_MARGIN)[:, None],
                    normal[rows] * (deficit[rows] + PUSH_MARGIN)[:, None],
                ]
            )
            changed, first = np.unique(verts, return_index=True)
            total = out[changed] + push[first] - points[changed]  # bounded in all
            length = np.linalg.norm(total, axis=1, keepdims=True)
            out[changed] = points[changed] + total * np.minimum(1.0, BETWEEN_MOVE / np.maximum(length, 1e-12))
            near_v = surface.closest(out[changed])  # keep the moved ones off the body
            low = near_v.signed < required[changed]
            out[changed[low]] = (
                near_v.point[low] + near_v.normal[low] * (required[changed[low]] + PUSH_MARGIN)[:, None]
            )
            ever[changed] = True
        # re-check the candidate samples that touch a moved vertex
        touched = np.zeros(n, dtype=bool)
        touched[changed] = True
        cand = np.flatnonzero(is_cand & np.any(touched[ids] & (w > 0), axis=1))
        vertex_check = changed if shells else changed[:0]
        if not len(cand) and not len(vertex_check):
            break
    after = _between_counts(signed, layered, minimum_gap)
    return out, d, before, after


def air_gap(caster: RayCaster, points: np.ndarray, triangles: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Per-vertex air gap [m] along the inward garment normal; see the module doc."""
    n = vertex_normals(points, triangles)
    t = caster.hit_distance(points, -n)
    fallback = np.abs(distance)
    gap = np.where(np.isfinite(t) & (t <= MAX_AIR_GAP), t, fallback)
    return np.clip(np.maximum(gap, fallback), 0.0, MAX_AIR_GAP)


class _BodyFrame:
    """The posed body of one frame for the garments' queries: the whole body's
    :class:`Surface` and :class:`RayCaster` built on first need, or a garment's local part
    (:data:`LOCAL_REACH`, :data:`LOCAL_SHARE`, :class:`_LocalCaster`)."""

    def __init__(self, points: np.ndarray, triangles: np.ndarray):
        self.points, self.triangles = points, triangles
        self._surface: Surface | None = None
        self._caster: RayCaster | None = None

    def whole(self) -> Surface:
        if self._surface is None:
            self._surface = Surface(self.points, self.triangles)
        return self._surface

    def whole_caster(self) -> RayCaster:
        if self._caster is None:
            self._caster = RayCaster(self.points, self.triangles, normalize=False)
        return self._caster

    def surface_for(self, points: np.ndarray, local: bool = True):
        """A Surface (or, with ``local``, a LocalSurface) answering closest-point queries
        near ``points``."""
        if self._surface is not None or not len(points) or not local:
            return self.whole()
        lo, hi = points.min(axis=0), points.max(axis=0)
        keep = triangles_near_box(self.points, self.triangles, lo, hi, LOCAL_REACH)
        if len(keep) > LOCAL_SHARE * len(self.triangles):
            return self.whole()
        return LocalSurface(self.points, self.triangles, lo, hi, LOCAL_REACH, self.whole, keep)

    def near_triangles(self, lo: np.ndarray, hi: np.ndarray, reach: float) -> np.ndarray:
        """The triangles with a point within ``reach`` of the box [lo, hi] (their bounding
        boxes that near): every triangle a ray from inside the box can hit within ``reach``."""
        return triangles_near_box(self.points, self.triangles, lo, hi, reach, by_bounds=True)

    def small(self, points: np.ndarray) -> bool:
        """Whether the body triangles within :data:`MAX_AIR_GAP` of the box of ``points`` are
        at most :data:`LOCAL_SHARE` of them (a garment that local structures serve)."""
        if not len(points):
            return True
        lo, hi = points.min(axis=0), points.max(axis=0)
        return len(self.near_triangles(lo, hi, MAX_AIR_GAP)) <= LOCAL_SHARE * len(self.triangles)

    def caster_for(self, points: np.ndarray):
        """A ray caster whose hits within :data:`MAX_AIR_GAP` of ``points`` are the whole
        body's (:class:`_LocalCaster`), or the whole body's."""
        if self._caster is not None or not len(points):
            return self.whole_caster()
        lo, hi = points.min(axis=0), points.max(axis=0)
        # the second tier (most garments have rays that miss: hems, open ends) decides
        if len(self.near_triangles(lo, hi, MAX_AIR_GAP)) > LOCAL_SHARE * len(self.triangles):
            return self.whole_caster()
        return _LocalCaster(self, lo, hi, self.near_triangles(lo, hi, LOCAL_RAY))


def _compact_caster(points: np.ndarray, triangles: np.ndarray) -> RayCaster:
    """A :class:`RayCaster` (metres, not normalised) over ``triangles`` and only their vertices."""
    used = np.zeros(len(points), dtype=bool)
    used[triangles.ravel()] = True
    local = np.cumsum(used) - 1
    return RayCaster(points[used], local[triangles], normalize=False)


class _LocalCaster:
    """:meth:`RayCaster.hit_distance` for rays from inside the box [lo, hi], the same as the
    whole body's up to :data:`MAX_AIR_GAP` (the air gap uses no farther hit: beyond it, or on
    a miss, it takes the closest-point distance either way).

    First over the triangles within :data:`LOCAL_RAY` of the box: a hit there at t <=
    LOCAL_RAY is the whole body's first hit (any nearer hit lies on a triangle that near,
    which is kept). The other rays are cast again over the triangles within MAX_AIR_GAP of the
    box (built only if some ray needs it; the whole body's caster if that is built): a hit
    there at t <= MAX_AIR_GAP is the whole body's for the same reason, and a farther hit or
    a miss means the whole body has none within MAX_AIR_GAP either. The casters hold only
    the vertices of their triangles (Embree's build time grows with the vertex buffer), so
    their float32 frames are shifted to their own centres: a distance may differ from the
    whole body caster's in its float32 rounding (measured: 4 of 14,823 hair gaps, by
    <= 7e-10 m)."""

    def __init__(self, frame: _BodyFrame, lo: np.ndarray, hi: np.ndarray, near: np.ndarray):
        self.frame, self.lo, self.hi = frame, lo, hi
        self.near = _compact_caster(frame.points, frame.triangles[near])

    def hit_distance(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        t = self.near.hit_distance(origins, directions)
        again = np.flatnonzero(~(t <= LOCAL_RAY))
        if len(again):
            f = self.frame
            if f._caster is not None:
                wide = f._caster
            else:
                wide_tris = f.near_triangles(self.lo, self.hi, MAX_AIR_GAP)
                wide = _compact_caster(f.points, f.triangles[wide_tris])
            t[again] = wide.hit_distance(origins[again], directions[again])
        return t


def drapes_of(g: FittedGarment) -> list[Drape]:
    """A :class:`~humv_usd.clothing.drape.Drape` per loose part of ``g``."""
    out = []
    counts = np.asarray(g.face_counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[counts == 4]
    quads = np.asarray(g.face_indices)[starts[:, None] + np.arange(4)]  # loose parts: quads
    for k, part in enumerate(g.garment.parts):
        if part.loose:
            ids = np.flatnonzero(g.part_of == k)
            mine = quads[np.all(np.isin(quads, ids), axis=1)]
            out.append(Drape.for_part(g.points, mine, ids))
    return out


def simulate(
    outfit: Outfit,
    skin: np.ndarray,
    progress=None,
    fps: float | None = None,
    between: bool = True,
    between_layers: bool = False,
) -> Simulation:
    """Pose, fix and measure every garment for each frame of ``skin`` ((F, J, 4, 4) skinning
    matrices, :func:`humv_usd.human.skeleton.skinning_matrices`). With ``fps`` (and more
    than one frame) loose parts are draped (:mod:`humv_usd.clothing.drape`) before the fix;
    ``GarmentAnimation.skinned`` then keeps the skinned shape they lag. ``between``: also
    fix the points between the vertices (:func:`push_between`; False: vertices only, for
    benchmarks); ``between_layers``: that pass also pushes them off the garments under them
    (slower: ~2-3x the fix time for a full outfit; off by default)."""
    rig = outfit.rig
    skin = np.asarray(skin, dtype=np.float64)
    frames = skin.shape[0]
    anims = [
        GarmentAnimation(
            g,
            np.empty((frames, g.vertex_count, 3)),
            np.empty((frames, g.vertex_count)),
        )
        for g in outfit.garments
    ]
    frame_s = np.zeros(frames)
    fix_s = np.zeros(frames)
    fix_cpu = np.zeros(frames)
    samples = [
        between_samples(g.triangles) if between and not g.garment.is_prop else None for g in outfit.garments
    ]
    last_cloth = max([k for k, g in enumerate(outfit.garments) if not g.garment.is_prop], default=-1)
    carried = [
        g.garment.prop
        for g in outfit.garments
        if g.garment.is_prop and g.garment.prop.placement == "between_hands"
    ]
    prop_world = rifle_world(rig.skeleton, skin) if carried else None
    dynamic = fps is not None and fps > 0 and frames > 1
    drapes = [drapes_of(g) if dynamic else [] for g in outfit.garments]
    for anim, d in zip(anims, drapes):
        if d:
            anim.skinned = np.empty_like(anim.posed)
    for g, anim in zip(outfit.garments, anims):
        if g.garment.is_prop and g.garment.prop.placement == "between_hands":
            cb = carry_body_of(rig.mesh, rig.joint_indices, rig.joint_weights, rig.face_regions)
            anim.clearance, anim.body_inside, _ = rifle_clearance(cb, rig.skeleton, skin, g.garment.prop)
    local_ok = [True] * len(outfit.garments)
    for f in range(frames):
        t0 = time.perf_counter()
        body = apply(blend_transforms(rig.joint_indices, rig.joint_weights, skin[f]), rig.mesh.points)
        frame_body = _BodyFrame(body, rig.triangles)
        skinned_all = [
            apply(blend_transforms(g.joint_indices, g.joint_weights, skin[f]), g.points)
            for g in outfit.garments
        ]
        # one garment near most of the body: the whole body's structures serve them all
        small = all(frame_body.small(p) for p in skinned_all)
        distances: list[np.ndarray] = []
        shells: list[tuple[Surface, np.ndarray, float]] = []  # posed body-like garments
        worn: list[tuple[Surface, np.ndarray, float]] = []  # all posed garments so far
        for k, (g, anim) in enumerate(zip(outfit.garments, anims)):
            gap = g.garment.minimum_gap
            skinned = skinned_all[k]
            posed = skinned
            surface = frame_body.surface_for(skinned, small and local_ok[k])
            if drapes[k]:
                posed = skinned.copy()
                for drape in drapes[k]:
                    posed[drape.vertices] = drape.step(skinned[drape.vertices], 1.0 / fps, surface, gap)
                anim.skinned[f] = skinned
            required = np.full(g.vertex_count, gap)
            for i, outer_ids, inner_ids in outfit.under[k]:
                inner = outfit.garments[i].garment
                need = distances[i][inner_ids] + inner.thickness + gap
                np.maximum.at(required, outer_ids, need)
            t1, c1 = time.perf_counter(), time.process_time()
            if g.garment.is_prop:
                dist, counts = measure(surface, posed, gap)
                fixed = posed
            else:
                fixed, dist, counts = push_out(surface, posed, required, gap)
                for round_ in range(PROP_ROUNDS if shells else 0):  # off the shells, skin re-check
                    left_all = 0
                    for shell, flat, thickness in shells:
                        fixed, was, left = push_off_shell(shell, flat, fixed, thickness + gap)
                        if round_ == 0:
                            counts.layered_before += was
                        left_all += left
                    fixed, dist, again = push_out(surface, fixed, required, gap)
                    counts.inside_after, counts.close_after = again.inside_after, again.close_after
                    counts.min_distance_m = again.min_distance_m
                    # a skin push can put a vertex back into a shell (beside a vest's armhole)
                    left_all = sum(
                        push_off_shell(shell, flat, fixed, thickness + gap)[1]
                        for shell, flat, thickness in shells
                    )
                    if not left_all:
                        break
                if shells and left_all:  # where the two disagree (beside an armhole) the shell wins
                    for shell, flat, thickness in shells:
                        fixed, _, left = push_off_shell(shell, flat, fixed, thickness + gap)
                    dist, again = measure(surface, fixed, gap)
                    counts.inside_after, counts.close_after = again.inside_after, again.close_after
                    counts.min_distance_m = again.min_distance_m
                    left_all = sum(
                        push_off_shell(shell, flat, fixed, thickness + gap)[1]
                        for shell, flat, thickness in shells
                    )
                counts.layered_after += left_all if shells else 0
                if samples[k] is not None:  # between the vertices (body, inner garments)
                    fixed, dist, was, left = push_between(
                        surface, fixed, dist, samples[k], gap, required, worn
                    )
                    (
                        counts.between_inside_before,
                        counts.between_close_before,
                        counts.between_layered_before,
                    ) = was
                    (
                        counts.between_inside_after,
                        counts.between_close_after,
                        counts.between_layered_after,
                    ) = left
                    counts.inside_after = int(np.sum(dist < 0))
                    counts.close_after = int(np.sum((dist >= 0) & (dist < gap)))
                    counts.min_distance_m = float(dist.min())
                for prop in carried:  # off the carried rifle, then the skin again
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
                    counts.prop_after += left  # closer than the gap after the skin pass
                if g.garment.body_like:
                    shells.append(
                        (Surface(fixed, g.triangles), _flat_normals(fixed, g.triangles), g.garment.thickness)
                    )
                if between and between_layers and k < last_cloth:
                    worn.append(
                        (Surface(fixed, g.triangles), _flat_normals(fixed, g.triangles), g.garment.thickness)
                    )
            if isinstance(surface, LocalSurface) and surface.fallbacks:
                local_ok[k] = False  # its queries reach beyond the local part: the whole body
            fix_s[f] += time.perf_counter() - t1
            fix_cpu[f] += time.process_time() - c1
            distances.append(dist)
            anim.posed[f] = fixed
            anim.counts.append(counts)
            caster = frame_body.caster_for(fixed) if small else frame_body.whole_caster()
            anim.air_gap[f] = air_gap(caster, fixed, g.triangles, dist)
            for drape in drapes[k]:
                drape.settle(fixed[drape.vertices])
        frame_s[f] = time.perf_counter() - t0
        if progress is not None:
            progress(f)
    return Simulation(anims, frame_s, fix_s, fix_cpu)
