"""The composed stage as a glTF binary (GLB) for the browser's 3D view, plus its cameras.

Meshes are read as the render reads them (:class:`humv_usd.render.scene_export.SceneMeshes`:
rendered purposes, instance proxies, UsdSkel skinning at the frame), coloured by their bound
material's visible reflectance (R 0.61, G 0.55, B 0.46 µm; grey without one). Coordinates stay in
the stage frame (Z up, metres): the editor's three.js scene is Z up too.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from pxr import Usd, UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.fileio import atomic_path
from humv_usd.render.scene_export import SceneMeshes
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
    for prim in meshes.prims:
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
    return StageView(glb_path, len(meshes.prims), triangles, cameras, (lo, hi))
