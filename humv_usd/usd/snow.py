"""Snow cover on a ground mesh (issue 30.4): what the scene tool records and the thermal tool
reads.

The scene tool binds a snow-covered ground mesh to the library material ``snow`` (a box
object's roof faces: its GeomSubset :data:`ROOF_SUBSET`) and records on the mesh (customData ``humv:snowCover``) the snow's depth and density and the material of
the bare ground under it; the thermal tool solves the snow layer on that ground
(:func:`humv_usd.physics.snow.simulate_cover`) and binds the faces melted bare by frame 0 to
the bare material.
"""

from __future__ import annotations

from dataclasses import dataclass

from pxr import Usd

#: customData key on a ground mesh under snow
SNOW_COVER_KEY = "humv:snowCover"
#: GeomSubset (family materialBind) of a box object's roof faces under snow; a ground under
#: snow is bound to snow whole
ROOF_SUBSET = "Snow"


@dataclass(frozen=True)
class SnowCover:
    depth_m: float  # snow depth when the surface history starts [m]
    density_kg_m3: float  # [kg m^-3]
    bare_material: str  # path of the bare ground's material


def snow_depths(scene: dict) -> tuple[float, list[float]]:
    """Snow depth [m] on the ground (``[scene.ground] snow_depth_m``, also the flat roofs') and
    on each terrain zone (its own ``snow_depth_m``, else the ground's; 0: a plowed road)."""
    ground = float(scene["ground"].get("snow_depth_m") or 0.0)
    zones = (scene.get("terrain") or {}).get("zone") or ()
    return ground, [ground if z.get("snow_depth_m") is None else float(z["snow_depth_m"]) for z in zones]


def write_snow_cover(prim: Usd.Prim, cover: SnowCover) -> None:
    """Record ``cover`` on a ground mesh prim (the scene tool)."""
    prim.SetCustomDataByKey(
        SNOW_COVER_KEY,
        {
            "depth_m": float(cover.depth_m),
            "density_kg_m3": float(cover.density_kg_m3),
            "bareMaterial": str(cover.bare_material),
        },
    )


def read_snow_cover(prim: Usd.Prim) -> SnowCover | None:
    """The :class:`SnowCover` recorded on a mesh prim; None without snow (or a depth of 0)."""
    data = prim.GetCustomDataByKey(SNOW_COVER_KEY)
    if not data or float(data.get("depth_m", 0.0)) <= 0.0:
        return None
    return SnowCover(float(data["depth_m"]), float(data["density_kg_m3"]), str(data["bareMaterial"]))
