"""The thermal layer's per-mesh result on the stage (HumvThermalAPI): the one writer of the
per-face temperature primvar and the model token, and the reader the render uses.

The render and ground truth read the temperatures back (``primvars:humv:thermal:temperature``,
uniform, one value per authored face [K]; :func:`read_face_temperatures`); the model token says
what produced them: "fixed" (held or air temperature), "slab" (the 1-D conduction slab),
"balance" (a garment's energy balance), "jos3" / "twoNode" (the body's physiology model).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from humv_usd.constants import TEMPERATURE_RANGE_K
from humv_usd.errors import InputError, bad_value
from humv_usd.usd import schemas as S
from humv_usd.usd.spill import CHUNK_FRAMES, SampleSpill, Spilled


def write_surface_temperature(
    prim: Usd.Prim, model: str, temperature_k, spill: SampleSpill | None = None
) -> None:
    """Apply HumvThermalAPI to ``prim`` (a mesh or an over of one) and author its per-face
    temperature [K] and ``model`` token.

    ``temperature_k``: (faces,) one value for every frame (the primvar's default), or (frames,
    faces), written as the default when every frame is the same, else a time sample per frame
    (time code = frame), or a series already on disk (:func:`spill_temperatures`). Stored as
    float32. With ``spill`` a time-sampled array goes to it (:mod:`humv_usd.usd.spill`): the
    layer gets a placeholder that the spill's export replaces by the samples.
    """
    prim.ApplyAPI(S.THERMAL_API)
    primvar = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
        S.TEMPERATURE_PRIMVAR.removeprefix("primvars:"),
        Sdf.ValueTypeNames.FloatArray,
        UsdGeom.Tokens.uniform,
    )
    prim.GetAttribute(S.THERMAL_MODEL).Set(model)
    if isinstance(temperature_k, Spilled):
        SampleSpill.bind(primvar.GetAttr(), temperature_k)
        return
    series = np.asarray(temperature_k)
    if spill is not None and series.ndim == 2:
        temperature_k = spill_temperatures(spill, series)
        if isinstance(temperature_k, Spilled):
            SampleSpill.bind(primvar.GetAttr(), temperature_k)
            return
        series = temperature_k
    if series.ndim == 1:
        primvar.Set(Vt.FloatArray.FromNumpy(series.astype(np.float32)))
    elif len(series) == 1 or np.all(series == series[:1]):
        primvar.Set(Vt.FloatArray.FromNumpy(series[0].astype(np.float32)))
    else:
        for frame, values in enumerate(series):
            primvar.Set(Vt.FloatArray.FromNumpy(values.astype(np.float32)), frame)


def spill_temperatures(spill: SampleSpill, series, nearest=None):
    """A (frames, faces) temperature series as :func:`write_surface_temperature` writes it,
    with the frames on disk: (1, faces) when every frame is the same (written as the default),
    else the :class:`~humv_usd.usd.spill.Spilled` handle of its float32 samples.

    ``nearest``: frame i holds row ``nearest[i]`` of ``series`` (samples held between radiation
    steps), expanded a chunk at a time, never whole.
    """
    series = np.asarray(series)
    rows = series if nearest is None else series[np.unique(nearest)]
    if len(rows) == 1 or np.all(rows == rows[:1]):
        return rows[:1]
    if nearest is None:
        return spill.add_array(series)
    nearest = np.asarray(nearest)
    step = CHUNK_FRAMES
    return spill.add((a, series[nearest[a : a + step]]) for a in range(0, len(nearest), step))


def check_temperatures(values, where: str, expected: int | None = None) -> np.ndarray:
    """Validate an array of temperatures [K] (finite, in TEMPERATURE_RANGE_K, right length)."""
    lo, hi = TEMPERATURE_RANGE_K
    a = np.asarray(values, dtype=float).ravel()
    allowed = f"expected {'' if expected is None else f'{expected} '}finite temperatures in {lo:g}-{hi:g} K"
    if expected is not None and a.size != expected:
        raise InputError(bad_value(where, f"<{a.size} values>", allowed + " (one per authored face)"))
    bad = ~np.isfinite(a) | (a < lo) | (a > hi)
    if np.any(bad):
        idx = np.flatnonzero(bad)
        raise InputError(
            bad_value(where, f"{a[idx[0]]!r} at index {idx[0]} ({idx.size} bad of {a.size})", allowed)
        )
    return a


def has_face_temperatures(prim: Usd.Prim) -> bool:
    """Whether the mesh has per-face temperatures (HumvThermalAPI) authored."""
    attr = prim.GetAttribute(S.TEMPERATURE_PRIMVAR)
    return bool(attr and attr.HasValue())


def read_face_temperatures(prim: Usd.Prim, face_count: int, time) -> np.ndarray:
    """One temperature [K] per authored face of a mesh at ``time`` (a constant primvar is
    spread over the ``face_count`` faces); InputError when missing, of another interpolation
    or out of range (:func:`check_temperatures`)."""
    where = f"{prim.GetPath()}.{S.TEMPERATURE_PRIMVAR}"
    attr = prim.GetAttribute(S.TEMPERATURE_PRIMVAR)
    if not attr or not attr.HasValue():
        raise InputError(
            bad_value(
                where,
                None,
                f"a rendered mesh needs one temperature per authored face "
                f"({face_count} faces, uniform primvar, K, HumvThermalAPI)",
            )
        )
    problem = temperature_type_problem(attr)
    if problem:  # e.g. string[] from a hand edit (issue 26)
        raise InputError(f"{where}: {problem}")
    primvar = UsdGeom.Primvar(attr)
    interpolation = primvar.GetInterpolation() if primvar else UsdGeom.Tokens.uniform
    if interpolation not in (UsdGeom.Tokens.uniform, UsdGeom.Tokens.constant):
        raise InputError(
            bad_value(
                f"{where} interpolation",
                str(interpolation),
                "expected uniform (one value per authored face) or constant",
            )
        )
    values = primvar.ComputeFlattened(time) if primvar else attr.Get(time)
    if values is None:
        raise InputError(bad_value(where, None, f"no value at frame {time.GetValue():g}"))
    values = np.asarray(values, dtype=float).ravel()
    if primvar and primvar.GetInterpolation() == UsdGeom.Tokens.constant and values.size == 1:
        values = np.full(face_count, values[0])
    return check_temperatures(values, where, expected=face_count)


#: value types a temperature primvar may have (float[] as the thermal tool writes it)
NUMBER_TYPES = (Sdf.ValueTypeNames.Float, Sdf.ValueTypeNames.Double, Sdf.ValueTypeNames.Half)


def temperature_type_problem(attr: Usd.Attribute) -> str | None:
    """Why a temperature attribute's values are not numbers, or None: a layer that declares it
    with another type (``string[]``). USD takes an attribute's type from its weakest
    declaration but its value from the strongest opinion, so the composed type name can say
    float[] while the value is a string array."""
    for spec in attr.GetPropertyStack(Usd.TimeCode.Default()):
        type_name = getattr(spec, "typeName", None)
        if type_name is not None and type_name.scalarType not in NUMBER_TYPES:
            return f"declared {type_name} in {spec.layer.identifier}; expected float[] (kelvin per face)"
    return None


#: Key of a person's face-temperature noise [K] (RMS over faces, from the q_rad method's ray
#: noise) in the thermal layer's ``humv:thermal`` report (customLayerData, one dict per person).
FACE_NOISE_KEY = "faceTemperatureNoiseRms_K"


#: Key of the same noise per mesh ({mesh path: RMS over its visible faces [K]}), per person.
FACE_NOISE_BY_MESH_KEY = "faceTemperatureNoiseRmsByMesh_K"


def face_temperature_noise_by_mesh(stage: Usd.Stage) -> dict[str, float]:
    """{mesh path: RMS face-temperature noise [K] over its visible faces} (the body's bare
    skin, each garment's outermost faces) from the thermal layer's report; empty when none says
    it (a layer written before the per-mesh estimate: use :func:`face_temperature_noise`)."""
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        report = (layer.customLayerData or {}).get("humv:thermal")
        if not isinstance(report, dict):
            continue
        out = {}
        for value in report.values():
            if isinstance(value, dict) and isinstance(value.get(FACE_NOISE_BY_MESH_KEY), dict):
                out.update({str(k): float(v) for k, v in value[FACE_NOISE_BY_MESH_KEY].items()})
        return out
    return {}


def face_temperature_noise(stage: Usd.Stage) -> dict[str, float]:
    """{person id: RMS face-temperature noise [K]} from the thermal layer's report (the
    ``humv:thermal`` customLayerData of the layer that has one); empty when none says it."""
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        report = (layer.customLayerData or {}).get("humv:thermal")
        if not isinstance(report, dict):
            continue
        out = {}
        for key, value in report.items():
            if isinstance(value, dict) and value.get(FACE_NOISE_KEY) is not None:
                out[str(key)] = float(value[FACE_NOISE_KEY])
        return out
    return {}


#: Per-face noise [K] of a person's face temperatures from the thermal layer's q_rad rays (the
#: first radiation sample's, one value per authored face; uniform float[], custom: not in the
#: HumvThermalAPI schema, like the avatar's label primvars): the render propagates it to each
#: pixel through its smooth shading (:func:`humv_usd.pipeline.ir_pass.thermal_noise`).
FACE_NOISE_PRIMVAR = "primvars:humv:thermal:temperatureNoise"


def write_face_temperature_noise(prim: Usd.Prim, sigma_k) -> None:
    """Author :data:`FACE_NOISE_PRIMVAR` (faces,) [K] on ``prim`` (a mesh or an over of one)."""
    primvar = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
        FACE_NOISE_PRIMVAR.removeprefix("primvars:"), Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.uniform
    )
    primvar.Set(Vt.FloatArray.FromNumpy(np.asarray(sigma_k, dtype=np.float32)))


def read_face_temperature_noise(prim: Usd.Prim) -> np.ndarray | None:
    """:data:`FACE_NOISE_PRIMVAR` of a mesh (faces,) [K], or None when absent, not one value
    per authored face, or not finite and >= 0 (a layer without it: the mesh's RMS stands in)."""
    attr = prim.GetAttribute(FACE_NOISE_PRIMVAR) if prim else None
    if not attr or not attr.HasValue() or not prim.IsA(UsdGeom.Mesh):
        return None
    face_count = len(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get() or [])
    values = attr.Get()
    try:
        values = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        return None
    if values.size != face_count or not np.all(np.isfinite(values) & (values >= 0.0)):
        return None
    return values
