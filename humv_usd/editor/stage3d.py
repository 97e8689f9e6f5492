"""The composed stage as a glTF binary (GLB) for the browser's 3D view, plus its cameras.

Meshes are read as the render reads them (:class:`humv_usd.render.scene_export.SceneMeshes`:
rendered purposes, instance proxies, UsdSkel skinning at the frame), coloured by their bound
material's visible reflectance (R 0.61, G 0.55, B 0.46 µm; grey without one). Coordinates stay in
the stage frame (Z up, metres): the editor's three.js scene is Z up too.

The view starts framed on what matters, the people and the sensors (:func:`framing`), not on
the bounds of everything: the ground reaches the horizon (rings to ``horizon_m``, 20 km by
default), and a view of those bounds showed the people as a dot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from pxr import Usd, UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import atomic_path
from humv_usd.render.scene_export import SceneMeshes
from humv_usd.usd.layers import SCOPES
from humv_usd.usd.sensor import read_camera_pose

#: wavelengths [µm] standing for red, green and blue in the preview colours
RGB_UM = (0.61, 0.55, 0.46)


@dataclass(frozen=True)
class StageCamera:
    name: str
    origin: np.ndarray
    forward: np.ndarray
    up: np.ndarray
    fov_x_deg: float


@dataclass(frozen=True)
class StageView:
    """What the 3D view shows: the GLB file, its mesh and triangle counts, the cameras."""

    glb: Path
    meshes: int
    triangles: int
    cameras: list[StageCamera]
    bounds: tuple[np.ndarray, np.ndarray]
    #: (lo, hi) of the people's meshes and the cameras' origins (the bounds without people or cameras)
    focus: tuple[np.ndarray, np.ndarray] | None = None


def _colour(material) -> list[int]:
    refl = getattr(material, "reflectance", None)
    if refl is None:
        return [150, 150, 150, 255]
    wl = np.asarray(material.wavelengths_um, dtype=float)
    rgb = [float(np.interp(w, wl, np.asarray(refl, dtype=float))) for w in RGB_UM]
    return [int(round(255 * min(max(c, 0.0), 1.0) ** (1 / 2.2))) for c in rgb] + [255]


def stage_view(stage_path: Path, glb_path: Path, frame: int = 0) -> StageView:
    """Write the stage's meshes at ``frame`` to ``glb_path`` (atomically) and read its cameras."""
    stage = Usd.Stage.Open(str(stage_path))
    if stage is None:
        raise InputError(bad_value("stage", str(stage_path), "cannot be opened as a USD stage"))
    meshes = SceneMeshes(stage)
    cache = UsdGeom.XformCache(Usd.TimeCode(frame))
    scene = trimesh.Scene()
    triangles = 0
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    people = [np.full(3, np.inf), np.full(3, -np.inf)]
    for prim in meshes.prims:
        person = prim.GetPath().HasPrefix(SCOPES["humans"])
        info = meshes.mesh_info(prim, Usd.TimeCode(frame))
        world, flip = meshes.world_points(prim, info, frame, cache)
        for part in info.parts:
            tris = part.vertex_ids[part.triangles]
            if flip:
                tris = tris[:, ::-1]
            used, local = np.unique(tris.ravel(), return_inverse=True)
            material = trimesh.visual.material.PBRMaterial(
                baseColorFactor=_colour(part.material),
                metallicFactor=0.0,
                roughnessFactor=1.0,
                doubleSided=True,
            )
            mesh = trimesh.Trimesh(
                world[used],
                local.reshape(-1, 3),
                process=False,
                visual=trimesh.visual.TextureVisuals(material=material),
            )
            scene.add_geometry(mesh, node_name=f"{info.path}:{part.key}")
            triangles += len(tris)
            lo, hi = np.minimum(lo, world[used].min(axis=0)), np.maximum(hi, world[used].max(axis=0))
            if person:
                people = [
                    np.minimum(people[0], world[used].min(axis=0)),
                    np.maximum(people[1], world[used].max(axis=0)),
                ]
    cameras = []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if prim.IsA(UsdGeom.Camera):
            pose = read_camera_pose(prim, Usd.TimeCode(frame))
            cameras.append(StageCamera(prim.GetName(), pose.origin, pose.forward, pose.up, pose.fov_x_deg))
    glb_path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(glb_path) as tmp:
        Path(tmp).write_bytes(scene.export(file_type="glb"))
    if not np.all(np.isfinite(lo)):
        lo, hi = np.zeros(3), np.zeros(3)
    points = [c.origin for c in cameras] + ([people[0], people[1]] if np.all(np.isfinite(people[0])) else [])
    focus = (np.min(points, axis=0), np.max(points, axis=0)) if points else None
    return StageView(glb_path, len(meshes.prims), triangles, cameras, (lo, hi), focus)


#: the editor's 3D view: three.js perspective camera (NiceGUI's default vertical field of view
#: [deg]) and the scene element's width / height [px]
VIEW_FOV_Y_DEG = 75.0
VIEW_ASPECT = 1000 / 620
#: the framed points span at most this share of the view (normalised device coordinates)
FILL = 0.85
#: the least half-size framed [m] (one person alone)
MIN_HALF_SIZE_M = 1.0
#: the view looks down at the layout by this angle [deg]
ELEVATION_DEG = 25.0


def _extent(eye, target, points, fov_y_deg: float, aspect: float) -> float:
    """The largest |normalised device coordinate| of ``points`` seen from ``eye`` looking at
    ``target`` (Z up, perspective, vertical field of view ``fov_y_deg``); inf when a point is
    not in front of the eye."""
    f = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    v = points - eye
    depth = v @ f
    if np.any(depth <= 1e-6):
        return math.inf
    ty = math.tan(math.radians(fov_y_deg) / 2)
    return float(
        max(np.max(np.abs(v @ right) / (depth * aspect * ty)), np.max(np.abs(v @ up) / (depth * ty)))
    )


def framing(view: StageView, fov_y_deg: float = VIEW_FOV_Y_DEG, aspect: float = VIEW_ASPECT):
    """(eye, target) [m] of the 3D view, framed on :attr:`StageView.focus` (the people and the
    cameras; the whole bounds only without either): looking at its centre from the side of the
    first camera's line of sight (so the cameras-to-people line runs across the wider, horizontal
    field of view; from the east without cameras) and :data:`ELEVATION_DEG` above, at the least
    distance (bisection) where every corner of the box lies within :data:`FILL` of the view.
    """
    lo, hi = view.focus if view.focus is not None else view.bounds
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    target = (lo + hi) / 2
    half = np.maximum((hi - lo) / 2, MIN_HALF_SIZE_M)
    corners = np.array(
        [target + half * np.array([sx, sy, sz]) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    )
    heading = np.array([0.0, 1.0, 0.0])  # looking north
    if view.cameras:
        forward = np.asarray(view.cameras[0].forward, dtype=float)
        if np.hypot(forward[0], forward[1]) > 1e-6:
            heading = np.array([forward[0], forward[1], 0.0]) / np.hypot(forward[0], forward[1])
    side = np.array([heading[1], -heading[0], 0.0])  # the line of sight's right-hand side
    elevation = math.radians(ELEVATION_DEG)
    direction = side * math.cos(elevation) + np.array([0.0, 0.0, math.sin(elevation)])
    near, far = 1e-3, 1e3 + 10.0 * float(np.linalg.norm(half))
    for _ in range(60):  # the extent falls as the eye moves back along ``direction``
        mid = (near + far) / 2
        if _extent(target + mid * direction, target, corners, fov_y_deg, aspect) <= FILL:
            far = mid
        else:
            near = mid
    return target + far * direction, target
