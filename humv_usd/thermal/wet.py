"""Wet surfaces in the render (issue 30.4): the thermal tool binds the faces its slabs keep wet
after rain to a wet variant of their material.

The slab's interception reservoir (:func:`humv_usd.physics.slab.simulate_many`) gives each face
a wet share at frame 0; rounded to :data:`humv_usd.catalog.wet.WET_LEVELS`, the faces of a
level are bound (in the thermal layer) to ``<material>__wet<level>``, a material the thermal
layer defines next to the dry one with the spectra of :func:`humv_usd.catalog.wet.wet_spectrum`
(water film over the dry material, Lekner & Dorf 1988; the film as thick as the material's
water capacity and the wet share imply). A mesh whose faces share one level is bound whole;
otherwise one GeomSubset per level (family ``materialBind``) carries the faces. Meshes that
already have per-face materials (GeomSubsets) stay dry in the render (their solve is wet).
The wet share is frame 0's for the whole clip (a surface dries over tens of minutes).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade

from humv_usd.catalog.materials import surface_water
from humv_usd.catalog.wet import wet_level, wet_name, wet_spectrum
from humv_usd.usd.materials import StageMaterial, write_stage_material

#: materials that are water already (puddles, humv_usd.scene.puddles): no film over them
FREE_WATER = ("water",)


def wet_variant(dry: StageMaterial, level: int) -> StageMaterial:
    """``dry`` with ``level`` percent of its surface under water, at ``<dry path>__wet<level>``."""
    tau = dry.transmittance
    rho = dry.reflectance
    if rho is None:  # an emissivity-only (render) material: opaque part 1 - eps - T
        rho = 1.0 - dry.emissivity - (0.0 if tau is None else tau)
    capacity = surface_water(dry.name).water_capacity_kg_m2
    wet_rho, wet_tau = wet_spectrum(dry.wavelengths_um, rho, tau, level / 100.0, capacity)
    eps = 1.0 - wet_rho - (0.0 if wet_tau is None else wet_tau)
    return dataclasses.replace(
        dry,
        path=wet_name(dry.path, level),
        reflectance=wet_rho,
        emissivity=np.clip(eps, 0.0, 1.0),
        transmittance=wet_tau,
        solar_absorptivity=None,
        source=f"{dry.name} with {level} % of its surface wet after rain (humv_usd.catalog.wet: water "
        f"film of {capacity * (level / 100.0) ** 0.5:.3g} mm over it, Lekner & Dorf 1988; water after "
        f"Hale & Querry 1973). {dry.source or ''}".strip(),
    )


def author_wet_surfaces(layer: Usd.Stage, upstream: Usd.Stage, meshes, wet_share: dict) -> dict:
    """Bind the wet faces of ``meshes`` (:class:`humv_usd.thermal.surfaces.SceneMesh`) to wet
    variants of their materials in the thermal ``layer`` stage.

    Parameters
    ----------
    layer : Usd.Stage
        The thermal layer being written (overs).
    upstream : Usd.Stage
        The composed stage the meshes come from.
    meshes : list of SceneMesh
    wet_share : dict
        {mesh path: (F,) wet share [0-1] at frame 0}.

    Returns
    -------
    dict
        {mesh path: {level percent: faces}} of what was bound wet, and the meshes left dry
        under ``"perFaceMaterials"``.
    """
    report: dict = {}
    kept: list[str] = []
    written: set[str] = set()
    for m in meshes:
        share = wet_share.get(m.path)
        if share is None or m.held_k is not None or m.material.name in FREE_WATER:
            continue
        levels = wet_level(share)
        if not np.any(levels > 0):
            continue
        if m.material_of_face is not None:
            kept.append(m.path)
            continue
        found = {int(v): int(np.sum(levels == v)) for v in np.unique(levels) if v > 0}
        for level in found:
            path = wet_name(m.material.path, level)
            if path not in written:
                layer.OverridePrim(Sdf.Path(path).GetParentPath())
                write_stage_material(layer, wet_variant(m.material, level))
                written.add(path)
        over = layer.OverridePrim(m.path)
        if len(found) == 1 and found.get(int(levels[0])) == m.n_faces:
            _bind(over, layer, wet_name(m.material.path, int(levels[0])))
        else:
            UsdShade.MaterialBindingAPI.Apply(over).SetMaterialBindSubsetsFamilyType(
                UsdGeom.Tokens.nonOverlapping
            )
            for level in found:
                subset = UsdGeom.Subset.Define(layer, f"{m.path}/Wet{level}")
                subset.CreateElementTypeAttr(UsdGeom.Tokens.face)
                subset.CreateFamilyNameAttr(UsdShade.Tokens.materialBind)
                subset.CreateIndicesAttr([int(i) for i in np.flatnonzero(levels == level)])
                _bind(subset.GetPrim(), layer, wet_name(m.material.path, level))
        report[m.path] = {str(k): v for k, v in found.items()}
    if kept:
        report["perFaceMaterials"] = kept
    return report


def _bind(prim: Usd.Prim, layer: Usd.Stage, material_path: str) -> None:
    api = UsdShade.MaterialBindingAPI.Apply(prim)
    api.Bind(UsdShade.Material(layer.GetPrimAtPath(material_path)))
