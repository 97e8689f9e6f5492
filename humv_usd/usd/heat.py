"""Heat sources and lights of scene objects on the stage (warm clutter, issue 30): the one
writer and reader of their attributes.

* ``humv:heat:heldTemperature`` (float, K, custom): the part's surface is held at this
  temperature by the thermal layer (a prescribed boundary, as a scenario's ``temperature_k``);
  read from the mesh or its nearest ancestor that authors it.
* ``humv:light:kind`` (token: street_lamp, window), ``humv:light:power_W`` (float, electrical
  power [W]): a lit lamp head or window pane; the render's light elements (issue 24) may
  read these to make it shine at night (:func:`read_lights`).
"""

from __future__ import annotations

from pxr import Sdf, Usd

from humv_usd.constants import TEMPERATURE_RANGE_K
from humv_usd.errors import InputError, bad_value

HELD_TEMPERATURE = "humv:heat:heldTemperature"
LIGHT_KIND = "humv:light:kind"
LIGHT_POWER = "humv:light:power_W"


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


def write_light(prim: Usd.Prim, kind: str, power_w: float) -> None:
    """Mark ``prim`` (a lamp head, a window pane) as a lit light of ``kind``."""
    prim.CreateAttribute(LIGHT_KIND, Sdf.ValueTypeNames.Token, custom=True).Set(kind)
    prim.CreateAttribute(LIGHT_POWER, Sdf.ValueTypeNames.Float, custom=True).Set(float(power_w))


def read_lights(stage: Usd.Stage) -> list[tuple[str, str, float]]:
    """(prim path, kind, electrical power [W]) of every lit light on the stage."""
    out = []
    for prim in stage.Traverse():
        attr = prim.GetAttribute(LIGHT_KIND)
        if attr and attr.HasAuthoredValue():
            out.append(
                (str(prim.GetPath()), str(attr.Get()), float(prim.GetAttribute(LIGHT_POWER).Get() or 0.0))
            )
    return out
