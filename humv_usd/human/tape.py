"""A tape measure for MakeHuman bodies: girths as ANSUR II measures them, on the mesh.

:func:`girths` slices the closed ``body`` mesh with a plane at a landmark, keeps the section
loop nearest the landmark (the limb or trunk being measured, not a neighbouring arm) and
returns the perimeter of that loop's convex hull: a tape laid round the body bridges
concavities (between the buttocks, under the bust) the same way.

Landmarks follow the ANSUR II definitions (Gordon et al. 2014, NATICK/TR-15/007, appendix of
measurement descriptions) as closely as the joint positions of MakeHuman's skeleton helpers
allow (the ``joint-*`` groups of base.obj; a joint = the mean of its cube's vertices):

=============  =====================================================================
waist          horizontal, at the ``joint-spine-3`` height (about the omphalion)
waist_depth    front-back extent of the waist loop
waist_breadth  side-to-side extent of the waist loop
chest          horizontal, 60 % of the way from ``joint-spine-2`` to ``joint-spine-1``
               (about the nipple level, below the armpits where the arms are separate)
buttock        horizontal, at the hip joints' height (the buttocks' greatest protrusion)
thigh          perpendicular to the femur, 20 % of the way from the hip to the knee
calf           perpendicular to the tibia, 30 % of the way from the knee to the ankle
biceps         perpendicular to the humerus, half-way from the shoulder to the elbow
forearm        perpendicular to the forearm, 25 % of the way from the elbow to the wrist
wrist          perpendicular to the forearm, 95 % of the way from the elbow to the wrist
neck           perpendicular to the neck, half-way from the neck joint to the head joint
=============  =====================================================================

The limbs are measured on the left side. All lengths in metres.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import ConvexHull

GIRTHS = (
    "waist",
    "waist_depth",
    "waist_breadth",
    "chest",
    "buttock",
    "thigh",
    "calf",
    "biceps",
    "forearm",
    "wrist",
    "neck",
)


def _joint(points: np.ndarray, groups, name: str) -> np.ndarray:
    return points[np.unique(groups[name])].mean(axis=0)


def _section(mesh: trimesh.Trimesh, origin: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The section loop whose centroid is nearest ``origin`` (its points, (n, 3))."""
    path = mesh.section(plane_normal=normal, plane_origin=origin)
    if path is None:
        raise ValueError(f"the plane at {origin} misses the body")
    loops = path.discrete
    return min(loops, key=lambda loop: float(np.linalg.norm(loop.mean(axis=0) - origin)))


def _hull_perimeter(loop: np.ndarray, origin: np.ndarray, normal: np.ndarray) -> float:
    n = normal / np.linalg.norm(normal)
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    q = np.c_[(loop - origin) @ u, (loop - origin) @ v]
    return float(ConvexHull(q).area)  # in 2-D, "area" is the perimeter


def girths(points: np.ndarray, groups) -> dict[str, float]:
    """Girths and the waist's depth and breadth [m] of a body in our frame (Z up, facing -Y).

    points: the full base.obj vertex list of a body (e.g. ``Body.points``, metres);
    groups: base.obj's groups (``Body.groups``): the ``body`` quads and the ``joint-*`` cubes.
    """
    faces = np.asarray(groups["body"])
    tris = np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
    mesh = trimesh.Trimesh(points, tris, process=False)
    up = np.array([0.0, 0.0, 1.0])
    j = {n: _joint(points, groups, f"joint-{n}") for n in ("l-upper-leg", "l-knee", "l-ankle")}
    j |= {
        n: _joint(points, groups, f"joint-{n}") for n in ("l-shoulder", "l-elbow", "l-hand", "neck", "head")
    }
    j |= {n: _joint(points, groups, f"joint-{n}") for n in ("spine-1", "spine-2", "spine-3")}

    def mid(p):  # on the body's mid-plane
        return np.array([0.0, p[1], p[2]])

    def limb(a, b, t):
        d = j[b] - j[a]
        o = j[a] + t * d
        return _hull_perimeter(_section(mesh, o, d), o, d)

    out: dict[str, float] = {}
    o = mid(j["spine-3"])
    waist = _section(mesh, o, up)
    out["waist"] = _hull_perimeter(waist, o, up)
    out["waist_depth"] = float(np.ptp(waist[:, 1]))
    out["waist_breadth"] = float(np.ptp(waist[:, 0]))
    o = mid(j["spine-2"] + 0.6 * (j["spine-1"] - j["spine-2"]))
    out["chest"] = _hull_perimeter(_section(mesh, o, up), o, up)
    o = mid(j["l-upper-leg"])
    out["buttock"] = _hull_perimeter(_section(mesh, o, up), o, up)
    out["thigh"] = limb("l-upper-leg", "l-knee", 0.2)
    out["calf"] = limb("l-knee", "l-ankle", 0.3)
    out["biceps"] = limb("l-shoulder", "l-elbow", 0.5)
    out["forearm"] = limb("l-elbow", "l-hand", 0.25)
    out["wrist"] = limb("l-elbow", "l-hand", 0.95)
    out["neck"] = limb("neck", "head", 0.5)
    return out
