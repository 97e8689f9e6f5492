"""The thermal layer's per-mesh result on the stage (HumvThermalAPI): the one writer of the
per-face temperature primvar and the model token.

The render and ground truth read the temperatures back (``primvars:humv:thermal:temperature``,
uniform, one value per authored face [K]); the model token says what produced them: "fixed"
(held or air temperature), "slab" (the 1-D conduction slab), "balance" (a garment's energy
balance), "jos3" / "twoNode" (the body's physiology model).
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from humv_usd.usd import schemas as S


def write_surface_temperature(prim: Usd.Prim, model: str, temperature_k) -> None:
    """Apply HumvThermalAPI to ``prim`` (a mesh or an over of one) and author its per-face
    temperature [K] and ``model`` token.

    ``temperature_k``: (faces,) one value for every frame (the primvar's default), or (frames,
    faces), written as the default when every frame is the same, else a time sample per frame
    (time code = frame). Stored as float32.
    """
    prim.ApplyAPI(S.THERMAL_API)
    primvar = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
        S.TEMPERATURE_PRIMVAR.removeprefix("primvars:"),
        Sdf.ValueTypeNames.FloatArray,
        UsdGeom.Tokens.uniform,
    )
    prim.GetAttribute(S.THERMAL_MODEL).Set(model)
    series = np.asarray(temperature_k)
    if series.ndim == 1:
        primvar.Set(Vt.FloatArray.FromNumpy(series.astype(np.float32)))
    elif len(series) == 1 or np.all(series == series[:1]):
        primvar.Set(Vt.FloatArray.FromNumpy(series[0].astype(np.float32)))
    else:
        for frame, values in enumerate(series):
            primvar.Set(Vt.FloatArray.FromNumpy(values.astype(np.float32)), frame)
