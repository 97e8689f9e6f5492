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
#: the framed box's bounding sphere fills this share of the view's smaller field of view
FILL = 0.85
#: the least radius framed [m] (one person alone)
MIN_RADIUS_M = 2.0


def framing(view: StageView, fov_y_deg: float = VIEW_FOV_Y_DEG, aspect: float = VIEW_ASPECT):
    """(eye, target) [m] of the 3D view: looking at the centre of :attr:`StageView.focus` (the
    people and the cameras; the whole bounds only without either) from behind the first camera
    (along its horizontal heading, else from the south) and 30° above, at the distance where the
    box's bounding sphere fills :data:`FILL` of the smaller field of view:
    ``d = r / (FILL sin(min(fov_y, fov_x) / 2))``, ``tan(fov_x / 2) = aspect tan(fov_y / 2)``.
    """
    lo, hi = view.focus if view.focus is not None else view.bounds
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    target = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, MIN_RADIUS_M)
    half_y = math.radians(fov_y_deg) / 2
    half = min(half_y, math.atan(aspect * math.tan(half_y)))
    distance = radius / (FILL * math.sin(half))
    heading = np.array([0.0, 1.0, 0.0])  # looking north
    if view.cameras:
        forward = np.asarray(view.cameras[0].forward, dtype=float)
        if np.hypot(forward[0], forward[1]) > 1e-6:
            heading = np.array([forward[0], forward[1], 0.0]) / np.hypot(forward[0], forward[1])
    elevation = math.radians(30.0)
    back = -heading * math.cos(elevation) + np.array([0.0, 0.0, math.sin(elevation)])
    return target + distance * back, target
