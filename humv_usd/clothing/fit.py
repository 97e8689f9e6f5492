"""Fit catalogue garments to a fitted MakeHuman body and skin them to its skeleton.

Rest shape. The garment keeps the faces of its source mesh that its :class:`Cover` rules
select (see :mod:`humv_usd.catalog.garments`) and moves every vertex by the part's ease along
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
Worn props (issue 29: backpack ``on_back`` on Spine1, bag ``at_left_hip`` on the Hips, phone
``in_right_hand``, glasses ``on_face`` on the Head, their temples fitted to the head's width)
are placed from the body's own rest geometry (:func:`_rest_transform`).
Every vertex is bound 100 % to the prop's joint, so it moves rigidly with that joint.

Labels. Every garment face gets the body region (``primvars:humv:label:bodyRegion`` ids) of
the body face nearest to it, so per-region statistics and JOS-3 segments work on garments too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.catalog.garments import SIDED_BONES, SIDED_REGIONS, Cover, Garment, Part, Prop, Shape, garment
from humv_usd.geometry.mesh import Surface, fan_triangulate, vertex_normals
from humv_usd.human import labels as L
from humv_usd.human.body import Body, MeshPart
from humv_usd.human.carry import carry_rest_transform
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


def _bone_position(skeleton: Skeleton, joint: str, p: np.ndarray, tilt: float) -> np.ndarray:
    """Position of points along a bone (0 head, 1 tail) plus ``tilt`` x depth behind the head
    in bone lengths."""
    j = skeleton.index(joint)
    head, tail = skeleton.rest_positions[j], skeleton.tail_positions[j]
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
                t = _bone_position(rig.skeleton, joint, centres, cover.tilt)
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


# ---------------------------------------------------------------------------- fitting
def _fit_part(rig: BodyRig, part: Part):
    source, normals = _source(rig, part.source)
    quads = np.asarray(source.face_indices).reshape(-1, 4)  # all sources are quads
    keep, region = select_faces(rig, source, part.cover)
    faces = quads[keep]
    used, remap = np.unique(faces.ravel(), return_inverse=True)
    faces = remap.reshape(-1, 4)
    p = source.points[used]
    n = normals[used]
    body_n = rig.surface.closest(p).normal
    n = np.where(np.einsum("ij,ij->i", n, body_n)[:, None] < 0, -n, n)
    rest = p + part.ease * n
    if part.loose:
        dense = _loose_weights(rig, rest, faces)
        idx, w = _top_k(dense, INFLUENCES)
    else:
        idx, w = transfer_weights(rig, rest)
    return rest, faces, idx, w, region[keep]


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
        if not len(f):
            raise ValueError(f"garment {g.name!r}: part {k} ({part.source}) selects no faces")
        pts.append(rest)
        faces.append(f + offset)
        idx.append(i)
        wts.append(w)
        regions.append(r)
        part_of.append(np.full(len(rest), k))
        offset += len(rest)
    faces = np.concatenate(faces)
    counts = np.full(len(faces), 4)
    flat = faces.ravel()
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
    parts, which stay quads for the drape): each such quad becomes four (edge midpoints and
    the face centre are new vertices); a neighbouring face that shares a split edge gets the
    midpoint inserted into its boundary (a 5..8-gon, no T-junction crack; its fan
    triangulation starts at an inserted midpoint, so no triangle is degenerate). New
    vertices take the mean of their parents' rest points and skin weights (the 4 largest
    kept, renormalized), the part of their first parent; child faces keep their parent's
    region. ``faces``: a bool mask restricting the split further (e.g. to where another
    garment overlaps, :func:`humv_usd.clothing.collide.dress`)."""
    quads = np.asarray(fitted.face_indices).reshape(-1, 4)
    ids = [L.REGION_ID[r] for r in REFINE_REGIONS]
    loose = [k for k, part in enumerate(fitted.garment.parts) if part.loose]
    split = np.isin(fitted.face_regions, ids) & ~np.isin(fitted.part_of[quads[:, 0]], loose)
    if faces is not None:
        split &= faces
    if not split.any():
        return fitted
    n = len(fitted.points)
    sq = quads[split]
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
        for k in range(4):
            u, v = int(quads[f, k]), int(quads[f, (k + 1) % 4])
            ring.append(u)
            m = lookup.get((min(u, v), max(u, v)))
            if m is not None:
                ring.append(m)
        if len(ring) > 4:  # start the fan at an inserted midpoint
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
    * ``in_right_hand``: its centre 2 cm in front of the right hand's grasp point (the hand
      bone's tail);
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
    if prop.placement == "in_right_hand":
        grasp = sk.tail_positions[sk.index("RightHand")]
        m[:3, 3] = grasp + (0.0, -0.02, 0.0)
        return m
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
