"""Artificial lights on the stage: UsdLux prims with a HumV lamp spectrum and photometry.

A lamp is a ``UsdLux.SphereLight`` (street lamp head, headlight; with ``UsdLux.ShapingAPI``'s
cone angle it is a spot aimed along the light's -Z axis, as UsdLux lights emit), a lit surface a
``UsdLux.RectLight`` (a window: ``width`` x ``height`` in its xy plane, emitting along -Z). The
render reads only lights that carry the HumV attributes:

- ``humv:light:spectrum`` (token): a lamp type of :data:`humv_usd.catalog.lights.LAMPS`;
- ``humv:light:luminousFlux`` [lm] (sphere lights): the lamp's luminous flux into its cone
  (the whole sphere without a cone);
- ``humv:light:luminance`` [cd m-2] (rect lights): the luminance of the lit surface.

UsdLux's own ``inputs:intensity`` is also written so that other USD tools show the lamp
(a sphere of radius r with luminous intensity I has luminance I / (pi r^2); UsdLux's intensity
is that luminance in nits with ``normalize`` off); the render uses the HumV attributes only.

To light an object (e.g. a street-lamp pole of the scene tool) call :func:`write_lamp` with a
path under the object's prim: the lamp then follows the object's transform.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from humv_usd.catalog.lights import LAMPS
from humv_usd.errors import InputError, bad_value

SPECTRUM = "humv:light:spectrum"
LUMINOUS_FLUX = "humv:light:luminousFlux"
LUMINANCE = "humv:light:luminance"
#: Largest accepted luminous flux [lm] (a stadium floodlight ~200 klm) and luminance [cd m-2].
MAX_FLUX_LM = 1.0e6
MAX_LUMINANCE = 1.0e6


@dataclass(frozen=True)
class Lamp:
    """One HumV light at one time: ``kind`` "sphere" or "rect", lamp ``spectrum`` name, the
    light's local-to-world matrix (4x4, row vectors as USD), ``luminous_flux_lm`` (sphere) or
    ``luminance`` (rect) [cd m-2], the cone half-angle [deg] (sphere; 180 = no cone), its
    softness [0-1], the rect's ``width_m`` / ``height_m`` and the sphere's ``radius_m``."""

    path: str
    kind: str
    spectrum: str
    to_world: np.ndarray
    luminous_flux_lm: float = 0.0
    luminance: float = 0.0
    cone_angle_deg: float = 180.0
    cone_softness: float = 0.0
    width_m: float = 1.0
    height_m: float = 1.0
    radius_m: float = 0.05

    @property
    def position(self) -> np.ndarray:
        return np.asarray(self.to_world[3, :3], float)

    @property
    def direction(self) -> np.ndarray:
        """Unit axis the light points along (its local -Z in world space)."""
        d = -np.asarray(self.to_world[2, :3], float)
        return d / np.linalg.norm(d)


def write_lamp(
    stage: Usd.Stage,
    path: str,
    spectrum: str,
    luminous_flux_lm: float,
    position_m=(0.0, 0.0, 0.0),
    aim_m=None,
    cone_angle_deg: float | None = None,
    radius_m: float = 0.05,
) -> Usd.Prim:
    """Define a lamp (UsdLux.SphereLight) at ``path``: ``position_m`` in its parent's space,
    aimed at ``aim_m`` (parent space; None: straight down) with a cone half-angle
    ``cone_angle_deg`` (None: no cone, light in all directions)."""
    light = UsdLux.SphereLight.Define(stage, path)
    light.CreateRadiusAttr(float(radius_m))
    light.CreateTreatAsPointAttr(True)
    p = np.asarray(position_m, float)
    aim = p - np.array([0.0, 0.0, 1.0]) if aim_m is None else np.asarray(aim_m, float)
    fwd = aim - p
    fwd /= np.linalg.norm(fwd)
    helper = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    z = -fwd  # UsdLux lights emit along -Z
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = Gf.Matrix4d(*x, 0.0, *y, 0.0, *z, 0.0, *p, 1.0)
    UsdGeom.Xformable(light).AddTransformOp().Set(m)
    prim = light.GetPrim()
    prim.CreateAttribute(SPECTRUM, Sdf.ValueTypeNames.Token, custom=True).Set(spectrum)
    prim.CreateAttribute(LUMINOUS_FLUX, Sdf.ValueTypeNames.Float, custom=True).Set(float(luminous_flux_lm))
    solid = 4.0 * math.pi
    if cone_angle_deg is not None:
        shaping = UsdLux.ShapingAPI.Apply(prim)
        shaping.CreateShapingConeAngleAttr(float(cone_angle_deg))
        solid = 2.0 * math.pi * (1.0 - math.cos(math.radians(cone_angle_deg)))
    light.CreateIntensityAttr(float(luminous_flux_lm) / solid / (math.pi * radius_m**2))
    return prim


def write_window(
    stage: Usd.Stage, path: str, spectrum: str, luminance: float, width_m: float, height_m: float
):
    """Define a lit window (UsdLux.RectLight, emitting along its -Z) at ``path``; place it with a
    transform op on the returned prim or under a parent."""
    light = UsdLux.RectLight.Define(stage, path)
    light.CreateWidthAttr(float(width_m))
    light.CreateHeightAttr(float(height_m))
    light.CreateIntensityAttr(float(luminance))
    prim = light.GetPrim()
    prim.CreateAttribute(SPECTRUM, Sdf.ValueTypeNames.Token, custom=True).Set(spectrum)
    prim.CreateAttribute(LUMINANCE, Sdf.ValueTypeNames.Float, custom=True).Set(float(luminance))
    return prim


def _checked(prim, name, value, hi):
    if value is None or not (math.isfinite(float(value)) and 0.0 <= float(value) <= hi):
        raise InputError(bad_value(f"{prim.GetPath()}.{name}", value, f"expected 0..{hi:g}"))
    return float(value)


def read_lamps(stage: Usd.Stage, time) -> list[Lamp]:
    """Every HumV light of the stage at time code ``time`` (instance proxies included), in stage
    order. InputError (one line) for an unknown spectrum or a photometry out of range."""
    cache = UsdGeom.XformCache(time)
    out = []
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        attr = prim.GetAttribute(SPECTRUM)
        if not (attr and attr.HasAuthoredValue()):
            continue
        spectrum = str(attr.Get(time))
        if spectrum not in LAMPS:
            raise InputError(
                bad_value(f"{prim.GetPath()}.{SPECTRUM}", spectrum, f"allowed: {', '.join(LAMPS)}")
            )
        if UsdGeom.Imageable(prim).ComputeVisibility(time) == UsdGeom.Tokens.invisible:
            continue
        m = np.array(cache.GetLocalToWorldTransform(prim), dtype=float)
        if prim.IsA(UsdLux.RectLight):
            rect = UsdLux.RectLight(prim)
            out.append(
                Lamp(
                    path=str(prim.GetPath()),
                    kind="rect",
                    spectrum=spectrum,
                    to_world=m,
                    luminance=_checked(
                        prim, LUMINANCE, prim.GetAttribute(LUMINANCE).Get(time), MAX_LUMINANCE
                    ),
                    width_m=float(rect.GetWidthAttr().Get(time)),
                    height_m=float(rect.GetHeightAttr().Get(time)),
                )
            )
        elif prim.IsA(UsdLux.SphereLight):
            flux = _checked(prim, LUMINOUS_FLUX, prim.GetAttribute(LUMINOUS_FLUX).Get(time), MAX_FLUX_LM)
            cone, soft = 180.0, 0.0
            if prim.HasAPI(UsdLux.ShapingAPI):
                shaping = UsdLux.ShapingAPI(prim)
                cone = float(shaping.GetShapingConeAngleAttr().Get(time) or 180.0)
                soft = float(shaping.GetShapingConeSoftnessAttr().Get(time) or 0.0)
            out.append(
                Lamp(
                    path=str(prim.GetPath()),
                    kind="sphere",
                    spectrum=spectrum,
                    to_world=m,
                    luminous_flux_lm=flux,
                    cone_angle_deg=min(max(cone, 0.1), 180.0),
                    cone_softness=min(max(soft, 0.0), 1.0),
                    radius_m=float(UsdLux.SphereLight(prim).GetRadiusAttr().Get(time) or 0.0),
                )
            )
    return out
