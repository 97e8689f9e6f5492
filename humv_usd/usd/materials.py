"""Materials on the stage: the one reader and writer of ``HumvMaterialAPI`` (spectra and
thermal data).

Every tool that needs a material property (the thermal solve, the render, the labels) reads it
here from the material bound to a mesh on the composed stage: the materials layer, or a
stronger layer a user wrote. The Python catalogue (:mod:`humv_usd.catalog.materials`) is what
the materials tool authors from; nothing downstream reads it.

:class:`StageMaterial` mirrors the catalogue's :class:`~humv_usd.catalog.materials.Material`
(same property names, SI units) with the spectra on the material's own wavelength grid; the
thermal properties are None when the prim does not author them (a render-only material).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from pxr import Gf, Sdf, Usd, UsdShade, Vt

from humv_usd.catalog.materials import Material
from humv_usd.errors import InputError, bad_value, summary
from humv_usd.physics import planck
from humv_usd.physics.sun import solar_absorptivity
from humv_usd.usd import schemas as S

log = logging.getLogger(__name__)

#: Relationship of a ground material to the material under it (the ground slab's substrate,
#: authored by the materials tool for a slab ground). A custom property, not part of
#: HumvMaterialAPI: only a ground's material carries it.
SUBSTRATE_RELATIONSHIP = "humv:material:substrate"

#: Thermal properties (attribute, field) a slab or a fabric needs.
THERMAL_ATTRIBUTES = {
    "conductivity": S.MATERIAL_CONDUCTIVITY,
    "density": S.MATERIAL_DENSITY,
    "specific_heat": S.MATERIAL_SPECIFIC_HEAT,
    "thickness": S.MATERIAL_THICKNESS,
    "solar_absorptivity": S.MATERIAL_SOLAR_ABSORPTIVITY,
}


@dataclass(frozen=True, eq=False)
class StageMaterial:
    """A ``HumvMaterialAPI`` material as the stage composes it.

    Spectra on ``wavelengths_um`` [um] (ascending); ``transmittance`` None: opaque. Thermal
    data (None when not authored): conductivity [W m-1 K-1], density [kg m-3], specific_heat
    [J kg-1 K-1], thickness [m] of the slab or fabric layer, solar_absorptivity [0-1].
    """

    path: str
    wavelengths_um: np.ndarray
    emissivity: np.ndarray
    reflectance: np.ndarray | None = None
    transmittance: np.ndarray | None = None
    conductivity: float | None = None
    density: float | None = None
    specific_heat: float | None = None
    thickness: float | None = None
    solar_absorptivity: float | None = None
    source: str | None = None

    @property
    def name(self) -> str:
        return self.path.rsplit("/", 1)[-1]

    @property
    def opaque(self) -> bool:
        return self.transmittance is None

    def require(self, field: str, mesh_path: str) -> float:
        """The thermal property ``field``, else InputError naming the mesh and the attribute."""
        value = getattr(self, field)
        if value is None:
            raise InputError(
                bad_value(
                    f"{self.path}.{THERMAL_ATTRIBUTES[field]}",
                    None,
                    f"the material bound to {mesh_path} needs it for the thermal solve (HumvMaterialAPI)",
                )
            )
        return value


def write_material(stage: Usd.Stage, path, material: Material) -> UsdShade.Material:
    """Define the material prim ``path`` from a catalogue :class:`Material`: HumvMaterialAPI
    spectra on the material's own wavelength grid [um] (transmittance only for materials one
    can see through), thermal data (conductivity [W m-1 K-1], density [kg m-3], specific heat
    [J kg-1 K-1], thickness [m], solar absorptivity [0-1] of its own spectrum under the reference
    sun) and its source, plus a
    UsdPreviewSurface for DCC viewports (display colour; opacity for glass)."""
    m = material
    mat = UsdShade.Material.Define(stage, path)
    write_material_properties(mat.GetPrim(), m)
    # A UsdPreviewSurface so DCC tools (Blender, usdview) show a sensible colour.
    shader = UsdShade.Shader.Define(stage, mat.GetPath().AppendChild("PreviewSurface"))
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*m.display_color))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.9)
    if not m.opaque:  # glass: see-through in viewports
        visible = float(m.at([0.45, 0.55, 0.65], "transmittance").mean())
        shader.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(round(1.0 - visible, 6))
        shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.05)
    mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return mat


def write_material_properties(prim: Usd.Prim, material: Material) -> None:
    """HumvMaterialAPI on an existing material prim (e.g. one a DCC wrote): the catalogue
    :class:`Material`'s spectra and thermal data, as :func:`write_material` writes them."""
    m = material
    prim.ApplyAPI(S.MATERIAL_API)
    prim.GetAttribute(S.MATERIAL_WAVELENGTHS).Set(Vt.FloatArray(m.spectrum_wavelengths))
    prim.GetAttribute(S.MATERIAL_EMISSIVITY).Set(Vt.FloatArray(m.spectrum_emissivity))
    prim.GetAttribute(S.MATERIAL_REFLECTANCE).Set(Vt.FloatArray(m.spectrum_reflectance))
    if not m.opaque:
        prim.GetAttribute(S.MATERIAL_TRANSMITTANCE).Set(Vt.FloatArray(m.spectrum_transmittance))
    for attr, value in (
        (S.MATERIAL_CONDUCTIVITY, m.conductivity),
        (S.MATERIAL_DENSITY, m.density),
        (S.MATERIAL_SPECIFIC_HEAT, m.specific_heat),
        (S.MATERIAL_THICKNESS, m.thickness),
        (S.MATERIAL_SOLAR_ABSORPTIVITY, m.spectral_solar_absorptivity),
        (S.MATERIAL_SOURCE, m.source),
    ):
        prim.GetAttribute(attr).Set(value)


def write_stage_material(stage: Usd.Stage, material: StageMaterial) -> UsdShade.Material:
    """Define the material prim ``material.path`` from a :class:`StageMaterial` (a material
    derived on the stage, e.g. a wet variant of a bound one): HumvMaterialAPI spectra, the
    thermal data it has, its source, and a UsdPreviewSurface of its visible reflectance."""
    m = material
    mat = UsdShade.Material.Define(stage, m.path)
    prim = mat.GetPrim()
    prim.ApplyAPI(S.MATERIAL_API)
    prim.GetAttribute(S.MATERIAL_WAVELENGTHS).Set(Vt.FloatArray([float(v) for v in m.wavelengths_um]))
    prim.GetAttribute(S.MATERIAL_EMISSIVITY).Set(Vt.FloatArray([float(v) for v in m.emissivity]))
    if m.reflectance is not None:
        prim.GetAttribute(S.MATERIAL_REFLECTANCE).Set(Vt.FloatArray([float(v) for v in m.reflectance]))
    if m.transmittance is not None:
        prim.GetAttribute(S.MATERIAL_TRANSMITTANCE).Set(Vt.FloatArray([float(v) for v in m.transmittance]))
    for attr, field in THERMAL_ATTRIBUTES.items():
        value = getattr(m, attr)
        if value is not None:
            prim.GetAttribute(field).Set(float(value))
    if m.source:
        prim.GetAttribute(S.MATERIAL_SOURCE).Set(m.source)
    shader = UsdShade.Shader.Define(stage, mat.GetPath().AppendChild("PreviewSurface"))
    shader.CreateIdAttr("UsdPreviewSurface")
    if m.reflectance is not None:
        rgb = np.interp([0.65, 0.55, 0.45], m.wavelengths_um, m.reflectance)
        shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*(float(v) for v in rgb)))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.9)
    mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return mat


def write_substrate(material_prim: Usd.Prim, substrate_path) -> None:
    """Point a ground material at the material under it (:data:`SUBSTRATE_RELATIONSHIP`: the
    slab ground's substrate, read back by :func:`substrate`)."""
    material_prim.CreateRelationship(SUBSTRATE_RELATIONSHIP, custom=True).SetTargets([substrate_path])


def _array(prim: Usd.Prim, name: str, time):
    attr = prim.GetAttribute(name)
    value = attr.Get(time) if attr else None
    if value is None or len(value) == 0:
        return None
    return np.asarray(value, dtype=float)


def _scalar(prim: Usd.Prim, name: str, where: str, lo: float, hi: float, time):
    attr = prim.GetAttribute(name)
    if not attr or not attr.HasAuthoredValue():
        return None
    value = float(attr.Get(time))
    if not (np.isfinite(value) and lo <= value <= hi):
        raise InputError(bad_value(f"{where}.{name}", value, f"expected {lo:g}-{hi:g}"))
    return value


def _spectrum(prim, name, wl, mpath, lo_hi_text, time):
    v = _array(prim, name, time)
    if v is None:
        return None
    if v.size != wl.size or not np.all(np.isfinite(v)) or np.any(v < 0) or np.any(v > 1):
        raise InputError(
            bad_value(
                f"{mpath}.{name}",
                summary(v),
                f"expected {wl.size} {lo_hi_text} in 0-1 (one per wavelength in {S.MATERIAL_WAVELENGTHS})",
            )
        )
    return v


def read_material(material, mesh_path: str | None = None, time=None) -> StageMaterial:
    """The :class:`StageMaterial` of a material prim (or ``UsdShade.Material``).

    ``mesh_path`` (the mesh the material is bound to) only words the errors. Raises InputError
    naming the attribute when the spectra are missing or out of range (wavelengths positive and
    ascending; emissivity, reflectance, transmittance in 0-1 with emissivity + transmittance
    <= 1) or a thermal property is out of range.
    """
    prim = material.GetPrim() if isinstance(material, UsdShade.Material) else material
    time = Usd.TimeCode.Default() if time is None else time
    mpath = str(prim.GetPath())
    bound = f"material bound to {mesh_path}" if mesh_path else "material"
    wl = _array(prim, S.MATERIAL_WAVELENGTHS, time)
    if wl is None:
        raise InputError(
            bad_value(
                f"{mpath}.{S.MATERIAL_WAVELENGTHS}", None, f"{bound} needs wavelengths [um] (HumvMaterialAPI)"
            )
        )
    eps = _array(prim, S.MATERIAL_EMISSIVITY, time)
    if eps is None:
        raise InputError(
            bad_value(
                f"{mpath}.{S.MATERIAL_EMISSIVITY}",
                None,
                f"{bound} needs emissivity values 0-1 (HumvMaterialAPI)",
            )
        )
    if not np.all(np.isfinite(wl)) or np.any(wl <= 0) or np.any(np.diff(wl) <= 0):
        raise InputError(
            bad_value(
                f"{mpath}.{S.MATERIAL_WAVELENGTHS}",
                summary(wl),
                "expected positive, strictly ascending wavelengths [um]",
            )
        )
    if eps.size != wl.size:
        raise InputError(
            bad_value(
                f"{mpath}.{S.MATERIAL_EMISSIVITY}",
                f"<{eps.size} values>",
                f"expected {wl.size} values (one per wavelength in {S.MATERIAL_WAVELENGTHS})",
            )
        )
    if not np.all(np.isfinite(eps)) or np.any(eps < 0) or np.any(eps > 1):
        raise InputError(
            bad_value(f"{mpath}.{S.MATERIAL_EMISSIVITY}", summary(eps), "expected emissivities in 0-1")
        )
    rho = _spectrum(prim, S.MATERIAL_REFLECTANCE, wl, mpath, "reflectances", time)
    tau = _spectrum(prim, S.MATERIAL_TRANSMITTANCE, wl, mpath, "transmittances", time)
    if tau is not None and np.any(tau + eps > 1.0 + 1e-6):
        raise InputError(
            bad_value(
                f"{mpath}.{S.MATERIAL_TRANSMITTANCE}",
                summary(tau),
                f"expected {wl.size} transmittances in 0-1 with emissivity + transmittance <= 1 (one per wavelength)",
            )
        )
    source = prim.GetAttribute(S.MATERIAL_SOURCE)
    alpha = _scalar(prim, S.MATERIAL_SOLAR_ABSORPTIVITY, mpath, 0.0, 1.0, time)
    if rho is not None and wl[0] <= 0.5 and wl[-1] >= 2.5:
        # one set of properties: the thermal solve absorbs the sun the render's spectrum
        # reflects (the attribute is kept for DCCs; a hand edit of it alone is overruled)
        spectral = solar_absorptivity(wl, rho, tau)
        if alpha is not None and abs(alpha - spectral) > 0.01:
            log.warning(
                "%s.%s = %.3f disagrees with its reflectance spectrum (%.3f); the thermal solve uses "
                "the spectrum",
                mpath,
                S.MATERIAL_SOLAR_ABSORPTIVITY,
                alpha,
                spectral,
            )
        alpha = spectral
    return StageMaterial(
        mpath,
        wl,
        eps,
        rho,
        tau,
        conductivity=_scalar(prim, S.MATERIAL_CONDUCTIVITY, mpath, 1e-6, 1e4, time),
        density=_scalar(prim, S.MATERIAL_DENSITY, mpath, 1e-3, 1e5, time),
        specific_heat=_scalar(prim, S.MATERIAL_SPECIFIC_HEAT, mpath, 1.0, 1e5, time),
        thickness=_scalar(prim, S.MATERIAL_THICKNESS, mpath, 1e-6, 100.0, time),
        solar_absorptivity=alpha,
        source=source.Get() if source and source.HasAuthoredValue() else None,
    )


def bound_material(prim: Usd.Prim) -> UsdShade.Material:
    """The material bound to a mesh (or GeomSubset), an ancestor's binding included
    (``UsdShade.MaterialBindingAPI.ComputeBoundMaterial``); InputError naming the prim when
    there is none."""
    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    if not material or not material.GetPrim().IsValid():
        raise InputError(
            bad_value(
                f"{prim.GetPath()}.material:binding",
                None,
                "a mesh needs a bound material carrying "
                f"{S.MATERIAL_WAVELENGTHS} and {S.MATERIAL_EMISSIVITY} (HumvMaterialAPI)",
            )
        )
    return material


def face_materials(prim: Usd.Prim, nfaces: int, read=None, time=None) -> tuple[list, np.ndarray]:
    """(materials, material index (F,) of each authored face) of a mesh with per-face materials.

    GeomSubsets with their own material binding (``UsdShade.MaterialBindingAPI
    .GetMaterialBindSubsets``, as DCCs export a multi-material mesh) come first, a face in two
    subsets keeping the first; the other faces take the mesh's own binding (an ancestor's
    included). ``read(prim)`` turns a mesh or subset prim into the value listed (default: the
    :class:`StageMaterial` of its bound material, :func:`read_material`); values are listed once
    per material path (``.path``). The render and the thermal tool both read per-face materials
    here. InputError naming the subset when its indices are not faces of the mesh, or naming the
    mesh when a face has no material."""
    mesh_path = str(prim.GetPath())
    time = Usd.TimeCode.Default() if time is None else time
    if read is None:

        def read(p):
            return read_material(bound_material(p), mesh_path, time)

    material_of_face = np.full(nfaces, -1, dtype=np.int64)
    materials: list = []
    order: dict[str, int] = {}

    def index_of(material) -> int:
        if material.path not in order:
            order[material.path] = len(materials)
            materials.append(material)
        return order[material.path]

    for subset in UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets():
        attr = subset.GetIndicesAttr()
        indices = attr.Get(time) if attr else None
        if indices is None or len(indices) == 0:
            continue
        indices = np.asarray(indices, dtype=np.int64)
        if indices.min() < 0 or indices.max() >= nfaces:
            raise InputError(
                bad_value(
                    f"{subset.GetPath()}.indices",
                    summary(indices),
                    f"expected face indices in 0..{nfaces - 1}",
                )
            )
        k = index_of(read(subset.GetPrim()))
        free = indices[material_of_face[indices] < 0]
        material_of_face[free] = k
    if np.any(material_of_face < 0):
        material_of_face[material_of_face < 0] = index_of(read(prim))
    return materials, material_of_face


def has_stage_material(prim: Usd.Prim) -> bool:
    """Whether the material bound to ``prim`` (an ancestor's binding included) carries
    HumvMaterialAPI (what the render and the thermal tool need)."""
    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    return bool(material) and material.GetPrim().HasAPI(S.MATERIAL_API)


def mesh_material(prim: Usd.Prim, time=None) -> StageMaterial:
    """:func:`read_material` of the material bound to a mesh (errors name the mesh)."""
    return read_material(bound_material(prim), str(prim.GetPath()), time)


def substrate(material: StageMaterial, stage: Usd.Stage, mesh_path: str) -> StageMaterial:
    """The material under a ground material (its relationship ``humv:material:substrate``),
    else InputError naming the ground mesh."""
    rel = stage.GetPrimAtPath(material.path).GetRelationship(SUBSTRATE_RELATIONSHIP)
    targets = rel.GetTargets() if rel else []
    prim = stage.GetPrimAtPath(targets[0]) if targets else None
    if not prim:
        raise InputError(
            bad_value(
                f"{material.path}.{SUBSTRATE_RELATIONSHIP}",
                [str(t) for t in targets] or None,
                f"the slab of {mesh_path} is thinner than its construction and needs the material under "
                "it (the materials tool authors it for a ground without temperature_k)",
            )
        )
    return read_material(prim, mesh_path)


def _check_reach(material: StageMaterial, band_um) -> None:
    wl = material.wavelengths_um
    if wl.size > 1 and (wl[-1] < band_um[0] or wl[0] > band_um[1]):
        raise InputError(
            bad_value(
                f"{material.path}.{S.MATERIAL_WAVELENGTHS}",
                f"{wl[0]:g}-{wl[-1]:g} um",
                f"expected a table that reaches into the band {band_um[0]:g}-{band_um[1]:g} um",
            )
        )


def band_emissivity(material: StageMaterial, band_um, response=None) -> float:
    """Band emissivity [0-1] of a material over ``band_um`` (lower, upper) [um] with an optional
    relative response: :func:`humv_usd.physics.planck.band_emissivity`, the one Planck-weighted
    band mean (weighting blackbody at :data:`humv_usd.constants.EMISSIVITY_WEIGHTING_TEMPERATURE_K`),
    on the material's table. The thermal solve (its long-wave band) and the render
    (each sensor band and sub-band) both call this, so a surface emits in the render what it
    loses in the thermal balance (Kirchhoff). InputError when the material's table does not
    reach into the band."""
    _check_reach(material, band_um)
    return planck.band_emissivity(material.wavelengths_um, material.emissivity, band_um, response)


def subband_emissivity(material: StageMaterial, band_um, subbands, response=None) -> np.ndarray:
    """(n,) :func:`band_emissivity` of each sub-band (lower, upper) [um] of ``band_um``."""
    _check_reach(material, band_um)
    return np.array(
        [planck.band_emissivity(material.wavelengths_um, material.emissivity, b, response) for b in subbands]
    )


def subband_transmittance(material: StageMaterial, subbands, response=None) -> np.ndarray | None:
    """(n,) band transmittance (the Planck-weighted band mean,
    :func:`humv_usd.physics.planck.band_emissivity`) of each sub-band of a see-through material;
    None when it is opaque."""
    if material.transmittance is None:
        return None
    return np.array(
        [
            planck.band_emissivity(material.wavelengths_um, material.transmittance, b, response)
            for b in subbands
        ]
    )
