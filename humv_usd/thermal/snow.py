"""Snow cover in the render (issue 30.4): the thermal tool binds the faces of a snow-covered
ground that its slabs melted bare by frame 0 to the bare ground's material.

The scene tool binds a ground under snow to snow over its material (``<material>__snow<mm>``,
deep: ``snow``; :mod:`humv_usd.catalog.snow`) and records the material under it
(:mod:`humv_usd.usd.snow`); the thermal tool's snow layer
(:func:`humv_usd.physics.snow.simulate_cover`) gives each face its snow water equivalent at
frame 0, so its depth. Faces with none left get a GeomSubset ``SnowFree`` (family
``materialBind``, nonOverlapping) bound to the bare material (the materials layer defines it: it
is a ground material); faces whose depth rounds to a shallower level than the mesh's get a
GeomSubset ``Snow<mm>`` bound to that level, which this layer defines when the stage lacks it;
a mesh whose faces all moved to one material is bound whole. On a box object's roof (the scene's
GeomSubset :data:`humv_usd.usd.snow.ROOF_SUBSET` bound to snow) faces off the scene's level
leave that subset: melted ones take the object's own binding again, shallower ones a
``Snow<mm>`` subset. The cover is frame 0's for the
whole clip (snow melts over hours, a clip lasts seconds).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade

from humv_usd.catalog.dyes import material as library_material
from humv_usd.catalog.snow import cover_name, split_snow_name
from humv_usd.usd.materials import write_material
from humv_usd.usd.mesh import bind_material
from humv_usd.usd.snow import ROOF_SUBSET


def author_snow_cover(layer: Usd.Stage, upstream: Usd.Stage, meshes, snow_water: dict) -> dict:
    """Bind the faces of ``meshes`` (:class:`humv_usd.thermal.surfaces.SceneMesh`) without snow
    at frame 0 to their bare material in the thermal ``layer`` stage.

    Parameters
    ----------
    layer : Usd.Stage
        The thermal layer being written (overs).
    upstream : Usd.Stage
        The composed stage (the bare material is defined there).
    meshes : list of SceneMesh
    snow_water : dict
        {mesh path: (F,) snow water equivalent at frame 0 [kg m^-2]; NaN on faces never under
        snow (a roof's walls)}.

    Returns
    -------
    dict
        {mesh path: {"faces", "snowFree", "meanWater_kg_m2", "meanDepth_m"} and, where faces
        changed material, "levels": {material name: faces}}.
    """
    report: dict = {}
    written: set = set()
    for m in meshes:
        water = snow_water.get(m.path)
        if water is None or m.snow is None:
            continue
        water = np.asarray(water, dtype=float)
        snowy = ~np.isnan(water)
        bare = snowy & (water <= 0.0)
        area = m.face_geometry()[2][snowy] + 1e-300
        mean = float(np.average(water[snowy], weights=area))
        report[m.path] = {
            "faces": int(snowy.sum()),
            "snowFree": int(bare.sum()),
            "meanWater_kg_m2": round(mean, 3),
            "meanDepth_m": round(mean / m.snow.density_kg_m3, 4),
        }
        base = Sdf.Path(m.snow.bare_material)
        depth = np.nan_to_num(water) / m.snow.density_kg_m3
        names = np.array(
            [
                "" if not ok else base.name if w <= 0.0 else cover_name(base.name, d)
                for w, d, ok in zip(np.nan_to_num(water), depth, snowy)
            ]
        )
        moved = snowy & (names != cover_name(base.name, m.snow.depth_m))  # off the scene's level
        if not moved.any():
            continue
        found = sorted(set(names[moved]))
        for name in found:
            _define(layer, upstream, base.GetParentPath().AppendChild(name), written)
        report[m.path]["levels"] = {str(n): int(np.sum(names[moved] == n)) for n in found}
        roof = upstream.GetPrimAtPath(Sdf.Path(m.path).AppendChild(ROOF_SUBSET))
        if roof:  # a roof: its snow subset keeps the faces still at the scene's level
            kept = [int(i) for i in np.flatnonzero(snowy & ~moved)]
            over = layer.OverridePrim(roof.GetPath())
            if kept:
                UsdGeom.Subset(over).CreateIndicesAttr().Set(kept)
            else:  # an empty materialBind subset is invalid: drop it
                over.SetActive(False)
            found = [n for n in found if n != base.name]  # bare: the mesh's own binding again
        else:
            over = layer.OverridePrim(m.path)
            if moved.all() and len(found) == 1:
                bind_material(over, base.GetParentPath().AppendChild(found[0]))
                continue
            UsdShade.MaterialBindingAPI.Apply(over).SetMaterialBindSubsetsFamilyType(
                UsdGeom.Tokens.nonOverlapping
            )
        for name in found:
            level = split_snow_name(name)
            child = "SnowFree" if level is None else f"Snow{level[1]}"
            subset = UsdGeom.Subset.Define(layer, Sdf.Path(m.path).AppendChild(child))
            subset.CreateElementTypeAttr(UsdGeom.Tokens.face)
            subset.CreateFamilyNameAttr(UsdShade.Tokens.materialBind)
            subset.CreateIndicesAttr([int(i) for i in np.flatnonzero(moved & (names == name))])
            bind_material(subset.GetPrim(), base.GetParentPath().AppendChild(name))
    return report


def _define(layer: Usd.Stage, upstream: Usd.Stage, path: Sdf.Path, written: set) -> None:
    """Define the library material at ``path`` in ``layer`` unless the stage has it (a shallower
    snow level than the scene bound)."""
    if upstream.GetPrimAtPath(path) or path in written:
        return
    layer.OverridePrim(path.GetParentPath())
    write_material(layer, path, library_material(path.name))
    written.add(path)
