"""Per-face label tables read from USD, and per-pixel label images from the render's ray cast.

Per mesh (read once through the readers of :mod:`humv_usd.usd.labels` and :mod:`humv_usd.usd.avatar`,
instance proxies included):

- ``class``: ``humv:label:class`` of the mesh or its nearest ancestor that has one (authored,
  or the HumvLabelAPI fallback "other" where the API is applied); ids :data:`CLASSES`.
- material kind (:data:`KINDS`): ``garment`` for a mesh with HumvClothingAPI or
  ``humv:clothing:garment``; ``skin`` for a mesh with a ``primvars:humv:label:bodyRegion`` that is
  not a garment (a person's body); ``prop`` for class ``prop`` (carried or in the scene);
  ``scene`` otherwise; ``background`` (0) where no surface is hit.
- body region per authored face: ``primvars:humv:label:bodyRegion`` (ids of
  :data:`humv_usd.human.labels.BODY_REGIONS`, 0 = not the body); 0 where absent.
- JOS-3 segment per face: ``primvars:humv:label:jos3Segment`` (0-based, JOS-3 order) or, where
  absent, derived from the region (:data:`humv_usd.human.labels.REGION_TO_JOS3`); -1 = none.

An object is an instance id. Its class is the one at the prim that carries the id (the
"id prim", e.g. the person's SkelRoot), so a garment with its own ``class`` does not change
the person's class, and a prop with its own id is its own object.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd

from humv_usd.errors import InputError, bad_value
from humv_usd.geometry import shading
from humv_usd.human import labels as AL
from humv_usd.usd.avatar import is_garment
from humv_usd.usd.labels import class_attribute, nearest_class, nearest_instance_id, read_face_label

#: Class ids (index = id): 0 background, then the HumvLabelAPI tokens in the schema's order.
CLASSES: tuple[str, ...] = (
    "background",
    "person",
    "ground",
    "building",
    "prop",
    "panel",
    "vegetation",
    "vehicle",
    "other",
    "animal",
    "lamp",
    "hvac",
    "fire",
)
CLASS_ID = {name: i for i, name in enumerate(CLASSES)}
#: Material kinds (index = id).
KINDS: tuple[str, ...] = ("background", "skin", "garment", "prop", "scene")
KIND_ID = {name: i for i, name in enumerate(KINDS)}
#: JOS-3 segment value of pixels that are not on a body region.
NO_SEGMENT = -1

_REGION_TO_SEGMENT = np.full(len(AL.BODY_REGION_NAMES), NO_SEGMENT, dtype=np.int32)
for _rid, _name in AL.BODY_REGIONS:
    _REGION_TO_SEGMENT[_rid] = AL.JOS3_SEGMENTS.index(AL.REGION_TO_JOS3[_name])


@dataclass
class MeshLabels:
    path: str
    class_id: int
    kind: int
    region: np.ndarray  # (F,) int32 per authored face
    segment: np.ndarray  # (F,) int32 per authored face


@dataclass
class ObjectInfo:
    instance_id: int
    prim: str  # the prim that carries the instance id
    class_name: str


def class_of(prim: Usd.Prim) -> str:
    """The class token of ``prim`` or its nearest ancestor with one ("other" when none)."""
    where, value = nearest_class(prim)
    if where is None:
        return "other"
    if value not in CLASS_ID:
        raise InputError(
            bad_value(class_attribute(where), value, "expected one of " + ", ".join(CLASSES[1:]))
        )
    return value


def object_info(prim: Usd.Prim) -> ObjectInfo:
    """The object (instance) a mesh belongs to: id, the prim carrying it, and its class."""
    where, value = nearest_instance_id(prim)
    if where is None:
        return ObjectInfo(0, "", "background")
    return ObjectInfo(value, str(where.GetPath()), class_of(where))


def mesh_labels(prim: Usd.Prim, face_count: int) -> MeshLabels:
    """Class, material kind, and per-face region and JOS-3 segment of one mesh (see module doc)."""
    cls = class_of(prim)
    region = read_face_label(prim, "body_region", face_count, 0, len(AL.BODY_REGIONS))
    segment = read_face_label(prim, "jos3_segment", face_count, 0, len(AL.JOS3_SEGMENTS) - 1)
    if is_garment(prim):
        kind = "garment"
    elif region is not None:
        kind = "skin"
    elif cls == "prop":
        kind = "prop"
    else:
        kind = "scene"
    if region is None:
        region = np.zeros(face_count, dtype=np.int32)
    if segment is None:
        segment = _REGION_TO_SEGMENT[region]
    return MeshLabels(str(prim.GetPath()), CLASS_ID[cls], KIND_ID[kind], region, segment)


class PartTables:
    """Concatenated per-triangle label arrays of the render's parts, indexed by (part, triangle).

    Built per frame and sensor from the meshes' :class:`MeshLabels`, the frame's face
    temperatures and the parts' band emissivities.
    """

    def __init__(
        self,
        parts,
        labels: dict[str, MeshLabels],
        temperatures: dict[str, np.ndarray],
        emissivity: list[float],
    ):
        sizes = np.array([len(p.triangle_face) for p in parts], dtype=np.int64)
        self.offset = np.concatenate([[0], np.cumsum(sizes)[:-1]]) if len(parts) else np.zeros(0, np.int64)
        self.class_id = np.array([labels[p.mesh_path].class_id for p in parts], dtype=np.int32)
        self.kind = np.array([labels[p.mesh_path].kind for p in parts], dtype=np.int32)
        self.emissivity = np.asarray(emissivity, dtype=float)

        def cat(xs, dt):
            return np.concatenate(xs).astype(dt) if xs else np.zeros(0, dt)

        self.region = cat([labels[p.mesh_path].region[p.triangle_face] for p in parts], np.int32)
        self.segment = cat([labels[p.mesh_path].segment[p.triangle_face] for p in parts], np.int32)
        self.temperature = cat([temperatures[p.mesh_path][p.triangle_face] for p in parts], float)

    def region_at(self, part: np.ndarray, triangle: np.ndarray) -> np.ndarray:
        """Body region id of hits given as (part, triangle) indices (-1 = miss -> 0)."""
        part, triangle = np.asarray(part), np.asarray(triangle)
        hit = part >= 0
        if not self.region.size:
            return np.zeros(part.shape, dtype=np.int32)
        g = self.offset[np.where(hit, part, 0)] + np.where(hit, triangle, 0)
        return np.where(hit, self.region[g], 0)

    def smooth_temperature(self, scene, part: np.ndarray, triangle: np.ndarray, position) -> np.ndarray:
        """Surface temperature [K] at the hits (NaN for sky) on the field the render shades:
        the faces' temperatures blended to the corners (:meth:`humv_usd.render.ir.IRScene.corner_blend`,
        Gouraud) with the render's one-ring gain steps of the shadowed term
        (:func:`humv_usd.geometry.shading.ring_gains`, :data:`~humv_usd.geometry.shading.FIELD_GAIN_STEPS`)
        and interpolated at the hit point, not one value per flat face. ``scene`` gives
        ``corner_blend()``, ``vertices(part)``, ``face_corners(part)``."""
        part, triangle = np.asarray(part), np.asarray(triangle)
        out = np.full(part.shape, np.nan)
        hit = part >= 0
        if not self.temperature.size or not hit.any():
            return out
        blend = scene.corner_blend()
        corners = shading.ring_gains(
            blend, self.temperature, np.asarray(blend @ self.temperature).reshape(-1, 3)
        )
        p, t = part[hit], triangle[hit]
        seen = np.flatnonzero(np.bincount(p))  # the hit parts (O(N), not a sort): their triangles' corners
        first = np.zeros(len(scene.parts) + 1, dtype=np.int64)
        tri = []
        for i in seen:
            prt = scene.parts[i]
            tri.append(np.asarray(scene.vertices(prt), float)[scene.face_corners(prt)])
            first[i + 1] = len(tri[-1])
        first = np.cumsum(first)[:-1]
        b = shading.barycentric(np.concatenate(tri), np.asarray(position)[hit], index=first[p] + t)
        out[hit] = np.einsum("ij,ij->i", np.clip(b, 0.0, 1.0), corners[self.offset[p] + t])
        return out

    def images(self, part: np.ndarray, triangle: np.ndarray) -> dict[str, np.ndarray]:
        """Per-pixel label images from the ray cast's part and triangle indices (-1 = sky)."""
        hit = part >= 0
        p = np.where(hit, part, 0)
        g = np.where(hit, self.offset[p] + np.where(hit, triangle, 0), 0) if len(self.offset) else p
        out = {
            "class_id": np.where(hit, self.class_id[p] if len(self.class_id) else 0, 0),
            "material_kind": np.where(hit, self.kind[p] if len(self.kind) else 0, 0),
            "body_region": np.where(hit, self.region[g] if self.region.size else 0, 0),
            "jos3_segment": np.where(hit, self.segment[g] if self.segment.size else 0, NO_SEGMENT),
            "surface_temperature": np.where(hit, self.temperature[g] if self.temperature.size else 0, np.nan),
            "emissivity": np.where(hit, self.emissivity[p] if self.emissivity.size else 0, np.nan),
        }
        return out


# --------------------------------------------------------------------------- colour masks
def _hsv_to_rgb(h, s, v):
    i = np.floor(h * 6.0).astype(int) % 6
    f = h * 6.0 - np.floor(h * 6.0)
    p, q, t = v * (1 - s), v * (1 - f * s), v * (1 - (1 - f) * s)
    table = np.stack(
        [np.stack(c, -1) for c in ((v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q))]
    )
    return table[i, np.arange(len(h))]


def instance_colours(ids) -> np.ndarray:
    """RGB uint8 colour of each instance id: hue steps by the golden ratio (neighbours differ);
    id 0 (background) is black."""
    ids = np.asarray(ids, dtype=np.int64).ravel()
    h = (ids * 0.6180339887498949) % 1.0
    s = np.where(ids % 2 == 0, 0.65, 0.9)
    v = np.where(ids % 3 == 0, 0.75, 0.95)
    rgb = np.rint(_hsv_to_rgb(h, s, v) * 255).astype(np.uint8)
    rgb[ids == 0] = 0
    return rgb


#: RGB colour per body region id (index = id; 0 = black): matplotlib's tab20, which has 20.
REGION_COLOURS = np.array(
    [
        (0, 0, 0),
        (31, 119, 180),
        (174, 199, 232),
        (255, 127, 14),
        (255, 187, 120),
        (44, 160, 44),
        (152, 223, 138),
        (214, 39, 40),
        (255, 152, 150),
        (148, 103, 189),
        (197, 176, 213),
        (140, 86, 75),
        (196, 156, 148),
        (227, 119, 194),
        (247, 182, 210),
        (127, 127, 127),
        (199, 199, 199),
        (188, 189, 34),
        (219, 219, 141),
        (23, 190, 207),
    ],
    dtype=np.uint8,
)
assert len(REGION_COLOURS) == len(AL.BODY_REGION_NAMES)


def colour_instances(instance: np.ndarray) -> np.ndarray:
    """(H, W) instance ids -> (H, W, 3) uint8 colour-coded mask."""
    inst = np.asarray(instance, dtype=np.int64)
    if inst.size and 0 <= inst.min() and inst.max() < 1 << 24:  # ids: a colour table indexed by id
        ids = np.flatnonzero(np.bincount(inst.ravel()))
        table = np.zeros((int(inst.max()) + 1, 3), dtype=np.uint8)
        table[ids] = instance_colours(ids)
        return table[inst]
    ids, inverse = np.unique(inst, return_inverse=True)
    return instance_colours(ids)[inverse].reshape(np.shape(instance) + (3,))


def colour_regions(region: np.ndarray) -> np.ndarray:
    """(H, W) body region ids -> (H, W, 3) uint8 colour-coded mask (:data:`REGION_COLOURS`)."""
    return REGION_COLOURS[np.clip(np.asarray(region, dtype=np.int64), 0, len(REGION_COLOURS) - 1)]
