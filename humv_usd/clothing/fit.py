"""Fit catalogue garments to a fitted MakeHuman body and skin them to its skeleton.

Rest shape. The garment keeps the part of its source mesh that its :class:`Cover` rules
select (see :mod:`humv_usd.catalog.garments`), cut along smooth curves rather than along the
source's quads (:func:`cut_fields`, :func:`clip_faces`: two per-vertex fields, the smoothed
indicator of the covered regions and the signed distance inside the covers' bone intervals; the
quads crossing their zero levels are clipped there, so hems are planes and necklines smooth
curves, not 2 cm staircases; a cover only a face or two wide keeps its faces whole), and moves
every vertex by the part's ease along
the source surface's outward vertex normal: ``rest = helper + ease * n``. The helpers already
follow the body (MakeHuman's targets deform them with it), so this fits any body from
:func:`humv_usd.human.body.build_body`. The helper's own normal is used rather than the body's
at the nearest point because it stays smooth where the tights bridge body concavities (crotch,
armpits, between the buttocks), where the nearest body normal flips between two surfaces; it is
flipped where it disagrees with the body normal there.

Skinning by weight transfer. Each garment vertex takes the body's skin weights (the 4 CMU-rig
influences the Body mesh is bound with) at the closest body surface point: barycentric
interpolation of the closest triangle's three vertices, the 4 largest kept and renormalized.
The garment then moves with the skin under it through the same Skeleton (UsdSkel), for any
motion. Loose parts (the robe's skirt) instead: lower-leg and foot influences are moved to
their thigh, other non-pelvic ones to the pelvis; the weights are smoothed over the part's mesh
(Laplacian, :data:`LOOSE_SMOOTHING` steps) so front and back blend both legs, and blended
towards the ``Hips`` joint with height (all pelvis at the waistband, all thighs at the hem).
That skinned shape swings with the mean of the thighs; :mod:`humv_usd.clothing.drape` adds
inertia (lag) and stretch constraints on top of it per frame, and the per-frame collision fix
(:mod:`humv_usd.clothing.collide`) pushes out whatever a leg would pierce.

Props (the rifle). A :class:`~humv_usd.catalog.garments.Prop` is built from its boxes and
8-sided cylinders (closed, outward quads and octagon caps) and placed in the rest pose:
``between_hands``: held in the rifle carry of :mod:`humv_usd.human.carry` (which the avatar
layer applies to the motion of whoever wears the rifle): its grip at the right hand's grasp
point and its handguard through the left one in the carry pose (standing, frame 0), that
placement expressed in the RightHand joint's rest frame (so in the rest pose the rifle hangs
off the right hand wherever the carry's hand rotation puts it).
Worn props (issue 29: backpack ``on_back`` on Spine1, bag ``at_left_hip`` on the Hips, phone,
phone_call and handbag held in the right hand, glasses ``on_face`` on the Head, their temples
fitted to the head's width)
are placed from the body's own rest geometry (:func:`_rest_transform`).
Every vertex is bound 100 % to the prop's joint, so it moves rigidly with that joint.

Labels. Every garment face gets the body region (``primvars:humv:label:bodyRegion`` ids) of
the body face nearest to it, so per-region statistics and JOS-3 segments work on garments too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from humv_usd.catalog.garments import (
    HAIR_GARMENTS,
    SIDED_BONES,
    SIDED_REGIONS,
    Cover,
    Garment,
    Part,
    Prop,
    Shape,
    garment,
)
from humv_usd.geometry.mesh import Surface, fan_triangulate, vertex_normals
from humv_usd.human import labels as L
from humv_usd.human.body import Body, MeshPart
from humv_usd.human.carry import HELD_PLACEMENTS, carry_rest_transform, hand_points, held_rest_transform
from humv_usd.human.skeleton import Skeleton, skeleton_for, skin_weights

INFLUENCES = 4
CYLINDER_SIDES = 8
#: Laplacian smoothing steps of a loose part's skin weights.
LOOSE_SMOOTHING = 40
_PELVIC = ("Hips", "LowerBack", "LHipJoint", "RHipJoint", "LeftUpLeg", "RightUpLeg")
_TO_THIGH = {
    "LeftLeg": "LeftUpLeg",
    "LeftFoot": "LeftUpLeg",
    "LeftToeBase": "LeftUpLeg",
    "RightLeg": "RightUpLeg",
    "RightFoot": "RightUpLeg",
    "RightToeBase": "RightUpLeg",
}


@dataclass(frozen=True)
class BodyRig:
    """A fitted body with what fitting and collisions need (rest pose, skeleton space)."""

    body: Body
    skeleton: Skeleton
    mesh: MeshPart  # the Body mesh (render mesh, compact indices)
    triangles: np.ndarray  # (T, 3) fan triangles of ``mesh``
    triangle_face: np.ndarray  # (T,) polygon of each triangle
    joint_indices: np.ndarray  # (V, 4) the Body mesh's skinning
    joint_weights: np.ndarray  # (V, 4)
    face_regions: np.ndarray  # (F,) body region id per Body face
    surface: Surface  # rest-pose closest-point queries


def prepare(
    body: Body,
    skeleton: Skeleton | None = None,
    skinning: tuple[np.ndarray, np.ndarray] | None = None,
    face_regions: np.ndarray | None = None,
) -> BodyRig:
    """Skeleton, skinning and region labels of ``body`` exactly as the avatar layer has them.

    ``skinning``: the Body mesh's (joint indices, weights), (V, 4) each, as bound on the stage
    (:func:`humv_usd.usd.avatar.read_body_mesh`); None: the rig's weights (what the avatar
    tool binds). ``face_regions``: the body region id per Body face as labelled on the stage
    (None: labelled here as the avatar tool labels them).
    """
    skeleton = skeleton_for(body.points, body.groups) if skeleton is None else skeleton
    mesh = body.body_mesh()
    if skinning is None:
        indices, weights = skin_weights(skeleton, mesh.vertex_ids, INFLUENCES)
    else:
        indices, weights = (np.asarray(a) for a in skinning)
    regions = L.body_regions(mesh, skeleton, indices, weights) if face_regions is None else face_regions
    tris, triangle_face = fan_triangulate(mesh.face_counts, mesh.face_indices)
    return BodyRig(
        body,
        skeleton,
        mesh,
        tris,
        triangle_face,
        indices,
        weights,
        regions,
        Surface(mesh.points, tris),
    )


@dataclass(frozen=True)
class FittedGarment:
    """A garment on one body: rest mesh in skeleton space and its skinning."""

    garment: Garment
    points: np.ndarray  # (n, 3) rest points [m]
    face_counts: np.ndarray  # (F,)
    face_indices: np.ndarray  # (sum counts,)
    triangles: np.ndarray  # (T, 3) fan triangles
    joint_indices: np.ndarray  # (n, 4) int32
    joint_weights: np.ndarray  # (n, 4) float32, rows sum to 1
    face_regions: np.ndarray  # (F,) body region id per face
    part_of: np.ndarray  # (n,) index of the Part each vertex comes from

    @property
    def name(self) -> str:
        return self.garment.name

    @property
    def vertex_count(self) -> int:
        return len(self.points)


# ---------------------------------------------------------------------------- selection
def _source(rig: BodyRig, source: str) -> tuple[MeshPart, np.ndarray]:
    """(mesh, outward vertex normals of the whole mesh) of a Part's source."""
    part = rig.mesh if source == "body" else rig.body.helper(source)
    tris, _ = fan_triangulate(part.face_counts, part.face_indices)
    return part, vertex_normals(part.points, tris)


def _face_centres(points, counts, indices) -> np.ndarray:
    counts = np.asarray(counts)
    face_of = np.repeat(np.arange(len(counts)), counts)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, face_of, points[np.asarray(indices)])
    return sums / counts[:, None]


def _expand(cover: Cover) -> list[tuple[set[int], str | None]]:
    """A Cover as (region ids, joint name or None) pairs, one per side for sided bones."""
    if cover.bone in SIDED_BONES:
        out = []
        for side, joint in zip(("left", "right"), SIDED_BONES[cover.bone]):
            names = set()
            for r in cover.regions:
                if r not in SIDED_REGIONS:
                    raise ValueError(f"region {r!r} has no side but bone {cover.bone!r} has")
                names.add(side + r[0].upper() + r[1:])
            out.append(({L.REGION_ID[n] for n in names}, joint))
        return out
    ids = set()
    for r in cover.regions:
        if r in SIDED_REGIONS:
            ids |= {L.REGION_ID["left" + r[0].upper() + r[1:]], L.REGION_ID["right" + r[0].upper() + r[1:]]}
        else:
            ids.add(L.REGION_ID[r])
    return [(ids, cover.bone)]


def _bone_position(
    skeleton: Skeleton, joint: str, p: np.ndarray, tilt: float, level: bool = False
) -> np.ndarray:
    """Position of points along a bone (0 head, 1 tail) plus ``tilt`` x depth behind the head
    in bone lengths; ``level``: by height, (z - z_head) / (z_tail - z_head)."""
    j = skeleton.index(joint)
    head, tail = skeleton.rest_positions[j], skeleton.tail_positions[j]
    if level:
        return (p[:, 2] - head[2]) / (tail[2] - head[2])
    axis = tail - head
    length2 = float(axis @ axis)
    t = (p - head) @ axis / length2
    if tilt:
        t = t + tilt * (p[:, 1] - head[1]) / np.sqrt(length2)
    return t


def select_faces(rig: BodyRig, part: MeshPart, covers: tuple[Cover, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(bool mask of the kept faces, region id of every face of ``part``)."""
    centres = _face_centres(part.points, part.face_counts, part.face_indices)
    nearest = rig.surface.closest(centres)
    region = rig.face_regions[rig.triangle_face[nearest.triangle]]
    if not covers:
        return np.ones(len(centres), dtype=bool), region
    keep = np.zeros(len(centres), dtype=bool)
    for cover in covers:
        for ids, joint in _expand(cover):
            sel = np.isin(region, sorted(ids))
            if joint is not None:
                t = _bone_position(rig.skeleton, joint, centres, cover.tilt, cover.level)
                sel &= (t >= cover.t_min) & (t <= cover.t_max)
            keep |= sel
    return keep, region


# ---------------------------------------------------------------------------- weights
def transfer_weights(rig: BodyRig, points: np.ndarray, k: int = INFLUENCES) -> tuple[np.ndarray, np.ndarray]:
    """Body skin weights at the closest body points of ``points``; see the module doc."""
    dense = _dense_at(rig, points)
    return _top_k(dense, k)


def _dense_at(rig: BodyRig, points: np.ndarray) -> np.ndarray:
    near = rig.surface.closest(points)
    corners = rig.triangles[near.triangle]  # (n, 3) body vertices
    n = len(points)
    joints = len(rig.skeleton.names)
    idx = rig.joint_indices[corners]  # (n, 3, 4)
    w = rig.joint_weights[corners] * near.bary[:, :, None]  # (n, 3, 4)
    dense = np.zeros((n, joints))
    rows = np.repeat(np.arange(n), 3 * rig.joint_indices.shape[1])
    np.add.at(dense, (rows, idx.ravel()), w.ravel())
    return dense


def _top_k(dense: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(-dense, axis=1)[:, :k]
    weights = np.take_along_axis(dense, order, axis=1)
    weights /= weights.sum(axis=1, keepdims=True)
    order = np.where(weights > 0, order, 0)
    return order.astype(np.int32), weights.astype(np.float32)


def _loose_weights(rig: BodyRig, points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Dense weights of a loose part (see the module doc)."""
    names = rig.skeleton.names
    dense = _dense_at(rig, points)
    hips = names.index("Hips")
    moved = np.zeros_like(dense)
    for j, name in enumerate(names):
        target = _TO_THIGH.get(name, name if name in _PELVIC else "Hips")
        moved[:, names.index(target)] += dense[:, j]
    # Laplacian smoothing over the part's edges (uniform weights, lambda 0.5)
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 3]], faces[:, [3, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    degree = np.bincount(e.ravel(), minlength=len(points)).astype(np.float64)[:, None]
    w = moved
    for _ in range(LOOSE_SMOOTHING):
        s = np.zeros_like(w)
        np.add.at(s, e[:, 0], w[e[:, 1]])
        np.add.at(s, e[:, 1], w[e[:, 0]])
        w = 0.5 * w + 0.5 * s / np.maximum(degree, 1.0)
    z = points[:, 2]
    up = (z - z.min()) / max(z.max() - z.min(), 1e-9)  # 0 at the hem, 1 at the waistband
    w = (1.0 - up)[:, None] * w
    w[:, hips] += up
    return w


# ---------------------------------------------------------------------------- cutting
#: Laplacian smoothing steps of a part's covered-region indicator before it is cut at 1/2
#: (the cut then runs as a smooth curve across the quads, not along their staircase).
CUT_SMOOTHING = 8
#: A vertex whose cut value is within this fraction of its largest change along an edge is
#: put on the cut (no sliver faces where the cut passes next to a vertex).
CUT_SNAP = 0.1
#: Smallest |value| of the region field at a vertex whose faces are all (none) covered.
CUT_MARGIN = 0.05
#: Cap [m] of the bone-position term of the cut (regions without a bone limit: +this).
CUT_REACH = 0.1


def _vertex_edges(faces: list[list[int]] | np.ndarray) -> np.ndarray:
    """Unique undirected edges (e, 2) of polygon faces."""
    e = [(f[k], f[(k + 1) % len(f)]) for f in faces for k in range(len(f))]
    return np.unique(np.sort(np.asarray(e, dtype=np.int64), axis=1), axis=0)


def _smooth(values: np.ndarray, edges: np.ndarray, steps: int) -> np.ndarray:
    """``steps`` of uniform Laplacian smoothing (lambda 1/2) of per-vertex ``values``."""
    degree = np.bincount(edges.ravel(), minlength=len(values)).astype(np.float64)
    v = values.astype(np.float64)
    for _ in range(steps):
        s = np.bincount(edges[:, 0], weights=v[edges[:, 1]], minlength=len(v))
        s += np.bincount(edges[:, 1], weights=v[edges[:, 0]], minlength=len(v))
        v = np.where(degree > 0, 0.5 * v + 0.5 * s / np.maximum(degree, 1.0), v)
    return v


def cut_fields(rig: BodyRig, points: np.ndarray, quads: np.ndarray, region: np.ndarray, covers) -> tuple:
    """Per-vertex fields whose common positive set is what ``covers`` keep of a quad mesh.

    ``(regions, bone)``: ``regions`` = the indicator of the covered faces (their region in a
    cover's regions), averaged to the vertices and smoothed (:data:`CUT_SMOOTHING` steps), minus
    1/2 (held at >= :data:`CUT_MARGIN` where all of a vertex's faces are covered, <= -that where
    none is): its zero level runs along the border of the covered regions as a smooth curve. ``bone``
    = the distance [m] inside a cover's bone interval (``min(t - t_min, t_max - t)`` x bone
    length, capped at :data:`CUT_REACH`), per vertex the largest over the covers whose regions
    the vertex touches (a vertex outside all of them: those its neighbours touch; +:data:`CUT_REACH`
    far from them, where the region field cuts): its zero level is the plane t = t_min (t_max) of :func:`_bone_position`, a straight
    hem, cuff or brim.
    """
    n = len(points)
    corners = quads.ravel()
    face_of = np.repeat(np.arange(len(quads)), 4)
    valence = np.bincount(corners, minlength=n).astype(np.float64)
    edges = _vertex_edges(quads)
    covered = np.zeros(len(quads), dtype=bool)
    for cover in covers:
        for ids, _ in _expand(cover):
            covered |= np.isin(region, sorted(ids))
    outside = np.bincount(corners, weights=covered[face_of], minlength=n) == 0
    bone = np.full(n, -np.inf)
    touched = np.zeros(n, dtype=bool)
    for cover in covers:
        for ids, joint in _expand(cover):
            mine = np.isin(region, sorted(ids))
            touch = np.bincount(corners, weights=mine[face_of], minlength=n) > 0
            # vertices outside every cover take the terms of their neighbours' covers: the
            # term is then continuous across the edges the cut crosses
            near = np.zeros(n, dtype=bool)
            near[edges[:, 0]] |= touch[edges[:, 1]]
            near[edges[:, 1]] |= touch[edges[:, 0]]
            touch |= near & outside
            if joint is None:
                inside = np.full(n, CUT_REACH)
            else:
                j = rig.skeleton.index(joint)
                axis = rig.skeleton.tail_positions[j] - rig.skeleton.rest_positions[j]
                length = float(abs(axis[2]) if cover.level else np.linalg.norm(axis))
                t = _bone_position(rig.skeleton, joint, points, cover.tilt, cover.level)
                inside = np.minimum(t - cover.t_min, cover.t_max - t) * length
            bone = np.where(touch, np.maximum(bone, np.minimum(inside, CUT_REACH)), bone)
            touched |= touch
    bone[~touched] = CUT_REACH
    share = np.bincount(corners, weights=covered[face_of], minlength=n) / np.maximum(valence, 1.0)
    regions = _smooth(share, edges, CUT_SMOOTHING) - 0.5
    # the smoothing moves the cut only among the border's vertices (those touching covered and
    # uncovered faces): a vertex with all its faces covered stays in, none covered out (no holes
    # where a covered strip is narrow, no islands)
    regions = np.where(share >= 1.0, np.maximum(regions, CUT_MARGIN), regions)
    regions = np.where(share <= 0.0, np.minimum(regions, -CUT_MARGIN), regions)
    return regions, bone


def _snap(field: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """``field`` with values near zero (see :data:`CUT_SNAP`) set to zero."""
    change = np.zeros(len(field))
    step = np.abs(field[edges[:, 0]] - field[edges[:, 1]])
    np.maximum.at(change, edges[:, 0], step)
    np.maximum.at(change, edges[:, 1], step)
    out = field.copy()
    out[np.abs(field) < CUT_SNAP * change] = 0.0
    return out


def clip_faces(faces: list[list[int]], fields: list[np.ndarray]):
    """Clip polygon ``faces`` to where every per-vertex field in ``fields`` is >= 0.

    Each field is linear along an edge: a polygon crossing its zero level keeps its part on the
    positive side (Sutherland-Hodgman against the level, one field after the other), with a new
    vertex where the level crosses an edge, shared by the two polygons on that edge (no crack).
    Values are first snapped to 0 near a vertex (:func:`_snap`). Returns (faces, parent face of
    each, new vertices as (a, b, s): the point a + s (b - a) of existing vertices a, b; new
    vertices of a later field may lie on edges of earlier new ones).
    """
    parent = list(range(len(faces)))
    n = max((max(f) for f in faces), default=-1) + 1
    new: list[tuple[int, int, float]] = []
    fields = [np.asarray(f, dtype=np.float64) for f in fields]
    for k in range(len(fields)):
        f = _snap(fields[k], _vertex_edges(faces)) if faces else fields[k]
        fields[k] = f
        made: dict[tuple[int, int], int] = {}
        out, out_parent = [], []
        for face, par in zip(faces, parent):
            values = f[face]
            if np.all(values >= 0):
                out.append(face)
                out_parent.append(par)
                continue
            if np.all(values <= 0):
                continue
            ring = []
            for i, a in enumerate(face):
                b = face[(i + 1) % len(face)]
                fa, fb = f[a], f[b]
                if fa >= 0:
                    ring.append(a)
                if (fa > 0 > fb) or (fb > 0 > fa):
                    key = (min(a, b), max(a, b))
                    if key not in made:
                        lo, hi = key
                        made[key] = n + len(new)
                        new.append((lo, hi, f[lo] / (f[lo] - f[hi])))
                    ring.append(made[key])
            if len(ring) >= 3:
                out.append(ring)
                out_parent.append(par)
        # the new vertices' values in the fields still to come (linear along their edge)
        if made:
            ids = np.array(sorted(made.values()))
            a, b, s = (np.array(x) for x in zip(*(new[i - n] for i in ids)))
            for j in range(len(fields)):
                g = fields[j]
                grown = np.concatenate([g, np.zeros(n + len(new) - len(g))])
                grown[ids] = g[a] + s * (g[b] - g[a]) if j > k else 0.0
                fields[j] = grown
        faces, parent = out, out_parent
    return faces, parent, new


def _openings(faces) -> int:
    """Number of connected pieces of the border (edges of one face only) of polygon ``faces``."""
    e = np.array([(f[k], f[(k + 1) % len(f)]) for f in faces for k in range(len(f))], dtype=np.int64)
    if not len(e):
        return 0
    key, count = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    border = key[count == 1]
    if not len(border):
        return 0
    ids, local = np.unique(border, return_inverse=True)
    local = local.reshape(-1, 2)
    graph = coo_matrix((np.ones(len(local)), (local[:, 0], local[:, 1])), shape=(len(ids), len(ids)))
    return int(connected_components(graph, directed=False)[0])


def _cut(points: np.ndarray, normals: np.ndarray, faces, fields):
    """Clip (:func:`clip_faces`), then the kept vertices' (points, normals), the faces renumbered
    over them and each face's parent."""
    faces, parent, new = clip_faces([list(map(int, f)) for f in faces], fields)
    if not faces:
        return points[:0], normals[:0], [], np.zeros(0, dtype=int)
    n = len(points)
    p = np.concatenate([np.asarray(points, dtype=np.float64), np.zeros((len(new), 3))])
    nrm = np.concatenate([np.asarray(normals, dtype=np.float64), np.zeros((len(new), 3))])
    for i, (a, b, s) in enumerate(new):  # in order: a later one may lie on an earlier one's edge
        p[n + i] = p[a] + s * (p[b] - p[a])
        m = nrm[a] + s * (nrm[b] - nrm[a])
        nrm[n + i] = m / max(float(np.linalg.norm(m)), 1e-12)
    used = np.unique(np.concatenate(faces))
    remap = np.full(len(p), -1)
    remap[used] = np.arange(len(used))
    return p[used], nrm[used], [remap[f] for f in faces], np.asarray(parent)


# ---------------------------------------------------------------------------- fitting
def _fit_part(rig: BodyRig, part: Part):
    """(rest points, faces as vertex lists, joint indices, weights, region per face) of one
    Part: the source faces its covers keep, cut along smooth curves (:func:`cut_fields`,
    :func:`clip_faces`), offset by the ease."""
    source, normals = _source(rig, part.source)
    quads = np.asarray(source.face_indices).reshape(-1, 4)  # all sources are quads
    keep, region = select_faces(rig, source, part.cover)
    cut = None
    if part.cover and not part.loose:
        fields = cut_fields(rig, source.points, quads, region, part.cover)
        cut = _cut(source.points, normals, quads, fields)
        if len(cut[2]) < 0.5 * keep.sum():  # a strip a face or two wide (a hair tail): faces
            cut = None
        elif _openings(cut[2]) > _openings(quads[keep]):
            # the cut tore the part (regions interleaved where a hanging hand's tights face is
            # labelled as the hip beside it, e.g. a jacket's cuff on a short woman): the faces
            cut = None
    if cut is not None:
        p, n, faces, parent = cut
        region = region[parent]
    else:
        faces = quads[keep]
        used, remap = np.unique(faces.ravel(), return_inverse=True)
        faces = remap.reshape(-1, 4)
        p, n = source.points[used], normals[used]
        region = region[keep]
    body_n = rig.surface.closest(p).normal
    n = np.where(np.einsum("ij,ij->i", n, body_n)[:, None] < 0, -n, n)
    rest = p + part.ease * n
    if part.loose:
        dense = _loose_weights(rig, rest, faces)
        idx, w = _top_k(dense, INFLUENCES)
    else:
        idx, w = transfer_weights(rig, rest)
    return rest, [list(map(int, f)) for f in faces], idx, w, region


def fit_garment(rig: BodyRig, name: str, refined: bool = False) -> FittedGarment:
    """Fit the catalogue garment ``name`` to the body of ``rig`` (props: :func:`fit_prop`);
    ``refined``: with the finer mesh over all of :data:`REFINE_REGIONS` (:func:`refine`;
    :func:`humv_usd.clothing.collide.dress` refines only where garments overlap)."""
    g = garment(name)
    if g.is_prop:
        return fit_prop(rig, g)
    pts, faces, idx, wts, regions, part_of = [], [], [], [], [], []
    offset = 0
    for k, part in enumerate(g.parts):
        rest, f, i, w, r = _fit_part(rig, part)
        if not len(f) and k > 0 and g.name in HAIR_GARMENTS:
            # a tied tail on a body whose hair proxy reaches no neck face (a small child: the
            # proxy's tail lies on the head and back): the scalp layer alone
            continue
        if not len(f):
            raise ValueError(f"garment {g.name!r}: part {k} ({part.source}) selects no faces")
        pts.append(rest)
        faces += [[v + offset for v in face] for face in f]
        idx.append(i)
        wts.append(w)
        regions.append(r)
        part_of.append(np.full(len(rest), k))
        offset += len(rest)
    counts = np.array([len(f) for f in faces])
    flat = np.array([v for f in faces for v in f])
    fitted = FittedGarment(
        g,
        np.concatenate(pts),
        counts,
        flat,
        fan_triangulate(counts, flat)[0],
        np.concatenate(idx),
        np.concatenate(wts),
        np.concatenate(regions).astype(np.int32),
        np.concatenate(part_of),
    )
    return refine(fitted, len(rig.skeleton.names)) if refined else fitted


# ---------------------------------------------------------------------------- refinement
#: Body regions where garments overlap (collars at the neck; waistbands, hems and the crotch
#: over the pelvis): their garment faces are split once (:func:`refine`) where another
#: garment of the outfit lies within LAYER_RADIUS (:func:`humv_usd.clothing.collide.dress`).
REFINE_REGIONS = ("neck", "pelvis")


def refine(fitted: FittedGarment, joints: int, faces: np.ndarray | None = None) -> FittedGarment:
    """One midpoint subdivision of the quads over :data:`REFINE_REGIONS` (not of loose
    parts, which stay quads for the drape; polygons cut at a hem stay whole): each such quad
    becomes four (edge midpoints and
    the face centre are new vertices); a neighbouring face that shares a split edge gets the
    midpoint inserted into its boundary (a 5..8-gon, no T-junction crack; its fan
    triangulation starts at an inserted midpoint, so no triangle is degenerate). New
    vertices take the mean of their parents' rest points and skin weights (the 4 largest
    kept, renormalized), the part of their first parent; child faces keep their parent's
    region. ``faces``: a bool mask restricting the split further (e.g. to where another
    garment overlaps, :func:`humv_usd.clothing.collide.dress`)."""
    counts = np.asarray(fitted.face_counts)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    flat = np.asarray(fitted.face_indices)
    rings = [flat[s : s + c] for s, c in zip(starts, counts)]
    ids = [L.REGION_ID[r] for r in REFINE_REGIONS]
    loose = [k for k, part in enumerate(fitted.garment.parts) if part.loose]
    split = np.isin(fitted.face_regions, ids) & ~np.isin(fitted.part_of[flat[starts]], loose) & (counts == 4)
    if faces is not None:
        split &= faces
    if not split.any():
        return fitted
    n = len(fitted.points)
    sq = np.stack([rings[f] for f in np.flatnonzero(split)])
    edges = np.stack([sq, np.roll(sq, -1, axis=1)], -1).reshape(-1, 2)  # (4s, 2)
    keys, inverse = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True)
    mid = n + inverse.reshape(-1, 4)  # midpoint id of edge (k, k+1) of each quad
    centre = n + len(keys) + np.arange(len(sq))
    a, b, c, d = sq.T
    mab, mbc, mcd, mda = mid.T
    children = np.stack(
        [
            np.stack([a, mab, centre, mda], 1),
            np.stack([mab, b, mbc, centre], 1),
            np.stack([centre, mbc, c, mcd], 1),
            np.stack([mda, centre, mcd, d], 1),
        ],
        1,
    ).reshape(-1, 4)
    lookup = {(int(u), int(v)): n + k for k, (u, v) in enumerate(keys)}
    polys, regions = [], []
    for f in np.flatnonzero(~split):  # neighbours: insert the split edges' midpoints
        ring = []
        face = rings[f]
        for k in range(len(face)):
            u, v = int(face[k]), int(face[(k + 1) % len(face)])
            ring.append(u)
            m = lookup.get((min(u, v), max(u, v)))
            if m is not None:
                ring.append(m)
        if len(ring) > len(face):  # start the fan at an inserted midpoint
            first = next(i for i, x in enumerate(ring) if x >= n)
            ring = ring[first:] + ring[:first]
        polys.append(ring)
        regions.append(fitted.face_regions[f])
    polys += [list(q) for q in children]
    regions += list(np.repeat(fitted.face_regions[split], 4))
    counts = np.array([len(r) for r in polys])
    flat = np.array([i for r in polys for i in r])
    # new vertices: edge midpoints, then face centres
    parents = [keys[:, 0], keys[:, 1]]
    pts = np.concatenate([fitted.points, fitted.points[keys].mean(axis=1), fitted.points[sq].mean(axis=1)])
    dense = np.zeros((n, joints))
    np.add.at(
        dense,
        (np.repeat(np.arange(n), fitted.joint_indices.shape[1]), fitted.joint_indices.ravel()),
        fitted.joint_weights.astype(float).ravel(),
    )
    new_dense = np.concatenate([dense[keys].mean(axis=1), dense[sq].mean(axis=1)])
    idx, w = _top_k(new_dense, fitted.joint_indices.shape[1])
    part_of = np.concatenate([fitted.part_of, fitted.part_of[parents[0]], fitted.part_of[sq[:, 0]]])
    return FittedGarment(
        fitted.garment,
        pts,
        counts,
        flat,
        fan_triangulate(counts, flat)[0],
        np.concatenate([fitted.joint_indices, idx]),
        np.concatenate([fitted.joint_weights, w]),
        np.asarray(regions, dtype=np.int32),
        part_of,
    )


# ---------------------------------------------------------------------------- props
def _shape_mesh(shape: Shape) -> tuple[np.ndarray, list[list[int]]]:
    """(points, faces as vertex lists, outward CCW) of a box or an x-axis cylinder."""
    c = np.asarray(shape.centre, dtype=float)
    if shape.radius <= 0:
        h = np.asarray(shape.size, dtype=float) / 2
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        pts = c + corners * h  # index = 4 * (x>0) + 2 * (y>0) + (z>0)
        faces = [
            [0, 1, 3, 2],
            [4, 6, 7, 5],  # -x, +x
            [0, 4, 5, 1],
            [2, 3, 7, 6],  # -y, +y
            [0, 2, 6, 4],
            [1, 5, 7, 3],
        ]  # -z, +z
        return pts, faces
    n = CYLINDER_SIDES
    a = 2 * np.pi * (np.arange(n) + 0.5) / n
    half = shape.size[0] / 2
    ring = np.stack([np.zeros(n), shape.radius * np.cos(a), shape.radius * np.sin(a)], 1)
    pts = np.concatenate([c + ring - [half, 0, 0], c + ring + [half, 0, 0]])
    faces = [[k, (k + 1) % n, n + (k + 1) % n, n + k] for k in range(n)]
    faces.append(list(range(n - 1, -1, -1)))  # -x cap
    faces.append(list(range(n, 2 * n)))  # +x cap
    return pts, faces


def prop_mesh(prop: Prop) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points, face counts, face indices) of a prop in its own frame."""
    pts, counts, indices, offset = [], [], [], 0
    for shape in prop.shapes:
        p, faces = _shape_mesh(shape)
        pts.append(p)
        counts.extend(len(f) for f in faces)
        indices.extend(offset + k for f in faces for k in f)
        offset += len(p)
    return np.concatenate(pts), np.array(counts), np.array(indices)


#: Clearance [m] of props worn on the body (backpack, bag) from the skin: clears the thickest
#: outer garment (the down coat stands ~22 mm off the skin) with a few mm to spare.
WORN_PROP_CLEARANCE = 0.035
#: Glasses: the frame's back at least this far [m] in front of the face (nose bridge, brows).
GLASSES_CLEARANCE = 0.004


def _near_band(points: np.ndarray, z: float, half: float, max_abs_x: float = np.inf) -> np.ndarray:
    """``points`` within ``half`` of height ``z`` and ``max_abs_x`` of the mid-plane."""
    sel = (np.abs(points[:, 2] - z) <= half) & (np.abs(points[:, 0]) <= max_abs_x)
    if not sel.any():
        raise ValueError(f"no body points near height {z:.3f} m")
    return points[sel]


#: Body regions a worn prop rests against (the arms, which hang beside the hips in the rest
#: pose and swing past, are left out).
TRUNK_REGIONS = ("chest", "abdomen", "back", "pelvis", "leftUpperLeg", "rightUpperLeg")


def _trunk_points(rig: BodyRig) -> np.ndarray:
    faces = np.isin(rig.face_regions, [L.REGION_ID[r] for r in TRUNK_REGIONS])
    return rig.mesh.points[np.unique(rig.triangles[faces[rig.triangle_face]])]


def _rest_transform(rig: BodyRig, prop: Prop) -> np.ndarray:
    """4x4 transform prop frame -> rest pose (skeleton space) for ``prop.placement``:

    * ``between_hands``: the rifle carry of :mod:`humv_usd.human.carry` (right-hand props);
    * ``on_back``: its origin (the centre of the face towards the back) at the middle of the Spine1 bone less 12 cm, :data:`WORN_PROP_CLEARANCE` behind the
      rearmost body point of the torso within the prop's height;
    * ``at_left_hip``: its origin (inner face) at the left hip joint's height,
      :data:`WORN_PROP_CLEARANCE` outside the outermost trunk point within its height,
      3 cm behind the hip joint;
    * ``held_front``, ``held_ear``, ``by_handle``: held in the right hand, the palm on its grip
      (:func:`humv_usd.human.carry.held_rest_transform`; the arm's pose: ``carry.apply_hold``);
    * ``on_face``: its origin level with the eyes' centres (MakeHuman's eye helpers), midway
      between them, the frame 12 mm in front of the corneas or :data:`GLASSES_CLEARANCE` in
      front of the face behind it (nose bridge, brows), whichever is further forward.
    """
    sk, body_pts = rig.skeleton, rig.mesh.points
    m = np.eye(4)
    if prop.placement == "between_hands":
        if prop.joint != "RightHand":
            raise ValueError(f"the carry holds props in the right hand, not {prop.joint!r}")
        return carry_rest_transform(sk)
    if prop.placement == "on_back":
        j = sk.index("Spine1")
        z = 0.5 * (sk.rest_positions[j, 2] + sk.tail_positions[j, 2]) - 0.12
        height = max(s.centre[2] + s.size[2] / 2 for s in prop.shapes) - min(
            s.centre[2] - s.size[2] / 2 for s in prop.shapes
        )
        torso = _near_band(_trunk_points(rig), z, height / 2 + WORN_PROP_CLEARANCE)
        m[:3, 3] = (0.0, torso[:, 1].max() + WORN_PROP_CLEARANCE, z)
        return m
    if prop.placement == "at_left_hip":
        hip = sk.rest_positions[sk.index("LeftUpLeg")]
        half = max(s.size[2] for s in prop.shapes) / 2
        side = _near_band(_trunk_points(rig), hip[2], half + WORN_PROP_CLEARANCE)
        m[:3, 3] = (side[:, 0].max() + WORN_PROP_CLEARANCE, hip[1] + 0.03, hip[2])
        return m
    if prop.placement in HELD_PLACEMENTS:  # held in the right hand, the palm on it
        mesh = rig.mesh
        return held_rest_transform(
            sk, hand_points(mesh.points, mesh.face_counts, mesh.face_indices, rig.face_regions), prop
        )
    if prop.placement == "on_face":
        eyes = [rig.body.helper(f"{s}-eye").points for s in ("l", "r")]
        centre = 0.5 * (eyes[0].mean(axis=0) + eyes[1].mean(axis=0))
        lenses = [s for s in prop.shapes if s.name.endswith("_lens")]
        half_w = max(abs(s.centre[0]) + s.size[0] / 2 for s in lenses)
        half_h = max(s.size[2] for s in lenses) / 2
        # in front of the corneas and of whatever else of the face is behind the frame (the
        # bridge of the nose, brows, cheeks)
        face = body_pts[
            (np.abs(body_pts[:, 0] - centre[0]) <= half_w + 0.005)
            & (np.abs(body_pts[:, 2] - centre[2]) <= half_h + 0.005)
            & (body_pts[:, 1] < centre[1] + 0.03)
        ]
        front = min(min(e[:, 1].min() for e in eyes) - 0.012, face[:, 1].min() - GLASSES_CLEARANCE)
        depth = max(s.size[1] / 2 - s.centre[1] for s in prop.shapes if not s.name.endswith("_temple"))
        m[:3, 3] = (centre[0], front - depth, centre[2])
        return m
    raise ValueError(f"unknown prop placement {prop.placement!r}")


def fitted_prop(rig: BodyRig, prop: Prop) -> Prop:
    """``prop`` adapted to the body: the glasses' temples run along this head's sides (4 mm off
    the skin at eye height) back to the ears; other props are returned unchanged."""
    if prop.placement != "on_face":
        return prop
    origin = _rest_transform(rig, prop)[:3, 3]
    head = _near_band(rig.mesh.points, origin[2], 0.01, 0.12)
    head = head[(head[:, 1] > origin[1]) & (head[:, 1] < origin[1] + 0.14)]
    half_width = np.abs(head[:, 0] - origin[0]).max() + 0.004
    length = 0.6 * (head[:, 1].max() - origin[1])  # to the ears, ~3/5 of the head's depth
    shapes = []
    for s in prop.shapes:
        if s.name.endswith("_temple"):
            x = np.sign(s.centre[0]) * half_width
            s = Shape(s.name, (float(x), length / 2, s.centre[2]), (s.size[0], float(length), s.size[2]))
        shapes.append(s)
    return Prop(tuple(shapes), prop.joint, prop.placement)


def place_prop(rig: BodyRig, prop: Prop, points: np.ndarray) -> np.ndarray:
    """The prop's points (own frame) placed on the body in the rest pose (see module doc and
    :func:`_rest_transform`)."""
    m = _rest_transform(rig, prop)
    return points @ m[:3, :3].T + m[:3, 3]


def fit_prop(rig: BodyRig, g: Garment) -> FittedGarment:
    """A rigid prop on the body of ``rig``: placed, bound 100 % to its joint."""
    prop = fitted_prop(rig, g.prop)
    local, counts, indices = prop_mesh(prop)
    points = place_prop(rig, prop, local)
    n = len(points)
    idx = np.zeros((n, INFLUENCES), dtype=np.int32)
    idx[:, 0] = rig.skeleton.index(g.prop.joint)
    w = np.zeros((n, INFLUENCES), dtype=np.float32)
    w[:, 0] = 1.0
    centres = _face_centres(points, counts, indices)
    near = rig.surface.closest(centres)
    regions = rig.face_regions[rig.triangle_face[near.triangle]].astype(np.int32)
    return FittedGarment(
        g,
        points,
        counts,
        indices,
        fan_triangulate(counts, indices)[0],
        idx,
        w,
        regions,
        np.zeros(n, dtype=int),
    )
