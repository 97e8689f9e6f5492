"""The ground of the scene layer: the rectangle ``[scene.ground] size_m`` on the terrain
(:mod:`humv_usd.geometry.terrain`), its material zones, and the ground beyond it out to
``horizon_m`` (issue 30.1).

Meshes:

* /World/Scene/Ground: the ground material: the rectangle's faces outside every zone
  (triangles where there is relief or a zone, :func:`humv_usd.scene.geometry.terrain_grid`), then the
  rings beyond it (:func:`humv_usd.scene.geometry.horizon_rings`, on the terrain's plane);
  a flat ground without zones keeps the 16 x 16 quads it always had;
* /World/Scene/GroundZone<i>: the faces of zone i (their centre inside the strip or mask), bound
  to the zone's material, with customData ``humv:groundZone`` = True (the thermal tool solves
  them as ground: material over soil, bottom held).

Under snow (``[scene.ground] snow_depth_m`` > 0) every piece is bound to snow over its material
(:func:`humv_usd.catalog.snow.cover_name`: ``<material>__snow<mm>``, deep snow ``snow``) and
records the snow and its own material (:mod:`humv_usd.usd.snow`); the thermal tool
melts the snow and binds the faces bare by frame 0 to that material. The flat roofs of box
objects carry the same snow (:func:`cover_roof`).

Every piece is a plain triangle/quad mesh (refinable by the thermal tool at shadow edges), labelled with
class ``ground`` (the zones with their own instance ids).
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from humv_usd.catalog.snow import cover_name
from humv_usd.geometry.terrain import Terrain, polyline_distance, terrain_from_section
from humv_usd.scene.geometry import drop_degenerate, ground_grid, horizon_rings, snap_to_edges, terrain_grid
from humv_usd.usd.mesh import bind_material, define_mesh, label
from humv_usd.usd.paths import GROUND, material_path
from humv_usd.usd.snow import ROOF_SUBSET, SnowCover, snow_depths, write_snow_cover

#: customData key that marks a ground zone mesh
GROUND_ZONE_KEY = "humv:groundZone"
#: cells per axis of a flat ground without zones (the mesh before issue 30)
FLAT_CELLS = 16


def zone_path(i: int):
    """Prim path of ground zone ``i``."""
    return GROUND.GetParentPath().AppendChild(f"GroundZone{i}")


def scene_terrain(scene: dict) -> Terrain:
    """The :class:`~humv_usd.geometry.terrain.Terrain` of a ``[scene]`` section."""
    return terrain_from_section(scene.get("terrain"), scene["ground"]["size_m"])


def _compact(points, faces):
    """(points, counts, indices) of the vertices that ``faces`` (F, 3 or 4) use."""
    used, inverse = np.unique(faces.ravel(), return_inverse=True)
    return points[used], np.full(len(faces), faces.shape[1]), np.asarray(inverse).ravel()


def _snapped(t: Terrain, points, tris):
    """The terrain grid with its vertices snapped onto the edges of the strip zones
    (:func:`humv_usd.scene.geometry.snap_to_edges`: a road's edge runs along triangle edges
    instead of zigzagging across them), heights taken again at the moved vertices."""
    locked = None
    for z in t.zones:
        if z.path_m is None:  # a mask image: its pixels' staircase stays
            continue

        def signed(x, y, z=z):
            return polyline_distance(x, y, z.path_m) - z.width_m / 2

        points, locked = snap_to_edges(points, tris, signed, locked)
    if locked is None:
        return points, tris
    points[:, 2] = t.height(points[:, 0], points[:, 1])
    return points, drop_degenerate(points, tris)


def ground_pieces(scene: dict, terrain: Terrain | None = None):
    """[(path, material name, points, counts, indices)] of the ground meshes (module doc)."""
    ground = scene["ground"]
    size = ground["size_m"]
    t = terrain or scene_terrain(scene)
    section = scene.get("terrain") or {}
    if t.has_relief or t.zones:
        points, counts, idx, _ = terrain_grid(t, size, float(section.get("cell_m") or 2.0))
        points, tris = _snapped(t, points, idx.reshape(-1, 3))
        counts, idx = np.full(len(tris), 3), tris.ravel()
        centroids = points[tris][:, :, :2].mean(axis=1)
        zone = t.zone_at(centroids[:, 0], centroids[:, 1])
    else:
        points, counts, idx = ground_grid(size, FLAT_CELLS)
        points[:, 2] = t.plane(points[:, 0], points[:, 1])
        zone = np.full(len(counts), -1)
    quads = idx.reshape(len(counts), -1)
    pts, counts, indices = _compact(points, quads[zone < 0])
    far_p, far_c, far_i = horizon_rings(t, size, float(ground.get("horizon_m") or 0.0))
    pieces = [
        (
            GROUND,
            ground["material"],
            np.concatenate([pts, far_p]),
            np.concatenate([counts, far_c]),
            np.concatenate([indices, far_i + len(pts)]),
        )
    ]
    for i, z in enumerate(t.zones):
        sel = zone == i
        if sel.any():
            pieces.append((zone_path(i), z.material, *_compact(points, quads[sel])))
    return pieces


def author_ground(stage: Usd.Stage, scene: dict, ids: dict[str, int]) -> None:
    """Define the ground meshes of :func:`ground_pieces` on ``stage``, labelled ``ground``
    with the ground's instance id, zone i with ``ground_zone:<i>``'s
    (:func:`humv_usd.scenario.ids.instance_ids`)."""
    zones = {zone_path(i): i for i in range(len((scene.get("terrain") or {}).get("zone") or ()))}
    ground = scene["ground"]
    on_ground, on_zone = snow_depths(scene)
    for path, material, points, counts, indices in ground_pieces(scene):
        snow = on_ground if path == GROUND else on_zone[zones[path]]
        shown = cover_name(material, snow) if snow > 0.0 else material
        mesh = define_mesh(stage, path, points, counts, indices, material=material_path(shown))
        if snow > 0.0:  # the thermal tool melts it and binds the faces bare by frame 0 to material
            cover = SnowCover(
                snow, float(ground.get("snow_density_kg_m3") or 250.0), str(material_path(material))
            )
            write_snow_cover(mesh.GetPrim(), cover)
        iid = ids["ground"] if path == GROUND else ids.get(f"ground_zone:{zones[path]}", ids["ground"])
        label(mesh.GetPrim(), iid, "ground")
        if path != GROUND:
            mesh.GetPrim().SetCustomDataByKey(GROUND_ZONE_KEY, True)


def cover_roof(stage: Usd.Stage, mesh: UsdGeom.Mesh, scene: dict, material: str) -> None:
    """Snow on the flat roof of a box object (``[scene.ground] snow_depth_m`` > 0): its upward
    faces (normal z > 0.9) in a GeomSubset ``Snow`` bound to snow over ``material``
    (:func:`humv_usd.catalog.snow.cover_name`), the rest keeping ``material``; the mesh records the cover like the ground
    (:mod:`humv_usd.usd.snow`), so the thermal tool melts it (from below too, on a heated
    building) and drops the faces melted bare by frame 0 from the subset."""
    ground = scene["ground"]
    depth = float(ground.get("snow_depth_m") or 0.0)
    if depth <= 0.0:
        return
    pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=float)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
    idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get())
    first = np.r_[0, np.cumsum(counts)[:-1]]
    up = []
    for f, (s, c) in enumerate(zip(first, counts)):
        v = pts[idx[s : s + c]]
        n = np.cross(v[1] - v[0], v[2] - v[0])
        if n[2] > 0.9 * np.linalg.norm(n):
            up.append(f)
    if not up:
        return
    prim = mesh.GetPrim()
    UsdShade.MaterialBindingAPI.Apply(prim).SetMaterialBindSubsetsFamilyType(UsdGeom.Tokens.nonOverlapping)
    subset = UsdGeom.Subset.Define(stage, prim.GetPath().AppendChild(ROOF_SUBSET))
    subset.CreateElementTypeAttr(UsdGeom.Tokens.face)
    subset.CreateFamilyNameAttr(UsdShade.Tokens.materialBind)
    subset.CreateIndicesAttr(up)
    bind_material(subset.GetPrim(), material_path(cover_name(material, depth)))
    density = float(ground.get("snow_density_kg_m3") or 250.0)
    write_snow_cover(prim, SnowCover(depth, density, str(material_path(material))))


def footprint_base(terrain: Terrain, center_xy, size_xy, heading_deg: float = 0.0) -> float:
    """Lowest ground height [m] under a rectangular footprint (corners, edge midpoints and
    centre of ``size_xy`` at ``center_xy`` turned by ``heading_deg``): the z an object's base
    sits at so that it stands on the terrain without floating (it sinks into a slope's upper
    side instead, as a building's foundation does). 0 on flat ground."""
    if not terrain.has_relief and not any(terrain.slope_deg):
        return 0.0
    u = np.array([-0.5, 0.0, 0.5])
    gx, gy = np.meshgrid(u * size_xy[0], u * size_xy[1])
    h = np.radians(heading_deg)
    x = center_xy[0] + np.cos(h) * gx - np.sin(h) * gy
    y = center_xy[1] + np.sin(h) * gx + np.cos(h) * gy
    return float(np.min(terrain.height(x, y)))
