"""The chair a person sits on (``activity = "sitChair"``): an authored wooden chair at the seat box
the sitting pose reports.

:func:`humv_usd.human.poses` (``sitChair``) computes a seat box under the sitting pose: its top
at the height of the pose's thighs above its soles, its front edge 4 cm behind the backs of the
knees, 0.42 m deep and 0.46 m wide, turned with the person (``Motion.info["chair"]``: centre,
size, yaw, in the avatar's frame). The pose's body rests on that box (the motion's ground
includes it). :func:`chair_parts` builds a chair on it:

* the seat: a slab :data:`SEAT_THICKNESS` thick whose top is the box's top, the box's width and
  depth (extended backwards to the backrest when that has to stand further back);
* four square legs :data:`LEG_WIDTH` wide from the ground to the seat, at the seat's corners;
* a backrest :data:`BACK_HEIGHT` high above the seat, :data:`BACK_THICKNESS` thick, standing
  :data:`BACK_CLEARANCE` behind the rearmost point of the sitting body (last frame) within the
  seat's width and the backrest's height, on two back posts from the ground (the sitting
  body leans on nothing: the pose has the trunk upright).

The chair is closed boxes (outward quads), one mesh, bound to the library's ``wood`` (dry pine,
ECOSTRESS spectra, Incropera's thermal data: :data:`humv_usd.catalog.materials.LIBRARY`), and
labelled class ``prop`` with its own instance id (``prop:<human id>:chair``). It is static in
the avatar's frame (no skinning): it stands where the person sits down.
"""

from __future__ import annotations

import numpy as np

from humv_usd.geometry.mesh import closed_box
from humv_usd.human import usdskel
from humv_usd.human.skeleton import forward_kinematics, skin_weights, skinning_matrices
from humv_usd.usd.mesh import define_mesh, label, write_class
from humv_usd.usd.paths import material_path

#: library material of the chair
CHAIR_MATERIAL = "wood"
#: seat slab, legs, backrest [m]
SEAT_THICKNESS = 0.03
LEG_WIDTH = 0.035
BACK_HEIGHT = 0.42
BACK_THICKNESS = 0.025
#: the backrest's gap behind the sitting body [m]
BACK_CLEARANCE = 0.02
#: catalogue-like name of the chair among a person's props (instance ids ``prop:<id>:chair``)
CHAIR = "chair"


def sits_on_chair(human: dict) -> bool:
    """Whether a ``[[human]]`` entry sits down on a chair (``sitChair``, itself or in a segment)."""
    acts = [human.get("activity")] + [s.get("activity") for s in human.get("segment") or ()]
    return "sitChair" in acts


def _box(base, size):
    """A closed box (outward counter-clockwise quads): centre of its bottom face, size (x, y, z)."""
    return closed_box(base, size)


def chair_frame(chair: dict) -> tuple[np.ndarray, np.ndarray]:
    """(rotation chair-local -> avatar frame (3, 3), origin: the seat box's centre on the ground).
    Chair-local axes: x the person's lateral, y backwards (the person faces -y), z up."""
    c, s = np.cos(chair["yaw_rad"]), np.sin(chair["yaw_rad"])
    to_local = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # as human.poses._chair_box
    cx, cy, cz = chair["center_m"]
    return to_local.T, np.array([cx, cy, cz - chair["size_m"][2] / 2])


def chair_parts(chair: dict, body_points: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """The chair's boxes as (centre of the bottom face, size) in chair-local coordinates (see
    :func:`chair_frame`); ``body_points``: the sitting body (avatar frame, last frame) that the
    backrest stands behind (None: at the seat's back edge)."""
    w, d, h = chair["size_m"]
    rot, origin = chair_frame(chair)
    back_y = d / 2 - BACK_THICKNESS / 2
    if body_points is not None:
        local = (np.asarray(body_points, float) - origin) @ rot
        near = (np.abs(local[:, 0]) < w / 2) & (local[:, 2] > h) & (local[:, 2] < h + BACK_HEIGHT)
        if near.any():
            back_y = max(back_y, float(local[near, 1].max()) + BACK_CLEARANCE + BACK_THICKNESS / 2)
    front = -d / 2
    rear = back_y + BACK_THICKNESS / 2
    seat_d = rear - front
    leg = LEG_WIDTH
    parts = [((0.0, (front + rear) / 2, h - SEAT_THICKNESS), (w, seat_d, SEAT_THICKNESS))]
    for x in (-w / 2 + leg / 2, w / 2 - leg / 2):
        parts.append(((x, front + leg / 2, 0.0), (leg, leg, h - SEAT_THICKNESS)))  # front legs
        parts.append(((x, back_y, 0.0), (leg, BACK_THICKNESS, h + BACK_HEIGHT)))  # back posts
    parts.append(((0.0, back_y, h + BACK_HEIGHT / 3), (w - 2 * leg, BACK_THICKNESS, 2 * BACK_HEIGHT / 3)))
    return parts


def chair_mesh(chair: dict, body_points: np.ndarray | None = None):
    """(points (avatar frame), face counts, face indices) of the chair: its boxes' closed quads."""
    rot, origin = chair_frame(chair)
    pts, counts, idx, offset = [], [], [], 0
    for base, size in chair_parts(chair, body_points):
        p, c, i = _box(base, size)
        pts.append(p @ rot.T + origin)
        counts.append(c)
        idx.append(i + offset)
        offset += len(p)
    return np.concatenate(pts), np.concatenate(counts), np.concatenate(idx)


def inside_chair(chair: dict, points: np.ndarray, body_points: np.ndarray | None = None) -> np.ndarray:
    """(n,) signed distance [m] of ``points`` (avatar frame) to the chair's solid (the union of
    its boxes; < 0 inside; exact per box, the union's minimum)."""
    rot, origin = chair_frame(chair)
    local = (np.asarray(points, float) - origin) @ rot
    out = np.full(len(local), np.inf)
    for base, size in chair_parts(chair, body_points):
        half = np.asarray(size) / 2
        centre = np.asarray(base) + (0.0, 0.0, half[2])
        q = np.abs(local - centre) - half
        d = np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
        out = np.minimum(out, d)
    return out


def posed_body_points(body, skeleton, motion, frame: int = -1) -> np.ndarray:
    """The body mesh's points at one frame of ``motion`` (avatar frame; linear blend skinning
    with the rig's weights, as the avatar binds them)."""
    mesh = body.body_mesh()
    idx, w = skin_weights(skeleton, mesh.vertex_ids, 4)
    world = forward_kinematics(skeleton, motion.local_rotations[[frame]], motion.root_translation[[frame]])
    skin = skinning_matrices(skeleton, world)[0]  # (J, 4, 4)
    blend = np.einsum("vk,vkab->vab", w.astype(float), skin[idx])
    pts = np.asarray(mesh.points, dtype=float)
    return np.einsum("vab,vb->va", blend[:, :3, :3], pts) + blend[:, :3, 3]


def author_chair(stage, path, chair: dict, body_points: np.ndarray | None, instance_id: int | None) -> None:
    """Define the chair mesh at ``path`` (avatar frame: a child of the person's SkelRoot),
    bound to :data:`CHAIR_MATERIAL`, labelled class ``prop`` (its own instance id when given),
    with customData ``humv:chair``: the seat's height, the box and the body's closest distance
    to the chair at ``body_points`` (the last frame)."""
    pts, counts, idx = chair_mesh(chair, body_points)
    mesh = define_mesh(stage, path, pts, counts, idx, material=material_path(CHAIR_MATERIAL))
    prim = mesh.GetPrim()
    if instance_id is None:
        write_class(prim, "prop")
    else:
        label(prim, int(instance_id), "prop")
    info = {
        "seatHeight_m": round(float(chair["size_m"][2]), 5),
        "seatSize_m": [round(float(v), 5) for v in chair["size_m"][:2]],
        "yaw_rad": round(float(chair["yaw_rad"]), 6),
    }
    if body_points is not None:
        info["bodyMinDistance_m"] = round(float(inside_chair(chair, body_points, body_points).min()), 6)
    prim.SetCustomDataByKey("humv:chair", info)


#: catalogue-like name of the carried box among a person's props (instance ids ``prop:<id>:box``)
BOX = "box"


def author_box(stage, path, centre, size, skeleton_path, joint_index: int, instance_id: int | None) -> None:
    """Define the box carried in both hands at ``path`` (a child of the person's SkelRoot): a
    closed wooden box (:data:`CHAIR_MATERIAL`) at ``centre``/``size`` in rest coordinates,
    bound 100 % to the joint ``joint_index`` (the Hips: the carry's grasp points are fixed in
    its frame), labelled class ``prop`` (its own instance id when given)."""
    centre, size = np.asarray(centre, float), np.asarray(size, float)
    pts, counts, idx = _box(centre - (0.0, 0.0, size[2] / 2), size)
    mesh = define_mesh(stage, path, pts, counts, idx, material=material_path(CHAIR_MATERIAL))
    prim = mesh.GetPrim()
    joints = np.zeros((len(pts), 4), dtype=np.int32)
    joints[:, 0] = joint_index
    weights = np.zeros((len(pts), 4), dtype=np.float32)
    weights[:, 0] = 1.0
    usdskel.bind_mesh(prim, skeleton_path, joints, weights)
    if instance_id is None:
        write_class(prim, "prop")
    else:
        label(prim, int(instance_id), "prop")
    prim.SetCustomDataByKey("humv:box", {"size_m": [round(float(v), 5) for v in size]})
