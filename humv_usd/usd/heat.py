"""Heat sources of scene objects on the stage (warm clutter, issue 30): the one writer and reader
of their attribute (their lights are UsdLux, :mod:`humv_usd.usd.lights`).

* ``humv:heat:heldTemperature`` (float, K, custom): the part's surface is held at this
  temperature by the thermal layer (a prescribed boundary, as a scenario's ``temperature_k``);
  read from the mesh or its nearest ancestor that authors it.
"""

from __future__ import annotations

from pxr import Sdf, Usd

from humv_usd.constants import TEMPERATURE_RANGE_K
from humv_usd.errors import InputError, bad_value

HELD_TEMPERATURE = "humv:heat:heldTemperature"


def write_held_temperature(prim: Usd.Prim, temperature_k: float) -> None:
    """Author the held surface temperature [K] of ``prim`` (a mesh or an ancestor Xform)."""
    prim.CreateAttribute(HELD_TEMPERATURE, Sdf.ValueTypeNames.Float, custom=True).Set(float(temperature_k))


def read_held_temperature(prim: Usd.Prim) -> float | None:
    """The held temperature [K] of ``prim`` or its nearest ancestor that authors one (None when
    none); InputError when it is outside TEMPERATURE_RANGE_K."""
    p = prim
    while p and p.IsValid() and not p.IsPseudoRoot():
        attr = p.GetAttribute(HELD_TEMPERATURE)
        if attr and attr.HasAuthoredValue():
            value = float(attr.Get())
            lo, hi = TEMPERATURE_RANGE_K
            if not lo <= value <= hi:
                raise InputError(
                    bad_value(f"{p.GetPath()}.{HELD_TEMPERATURE}", value, f"expected {lo:g}-{hi:g} K")
                )
            return value
        p = p.GetParent()
    return None
