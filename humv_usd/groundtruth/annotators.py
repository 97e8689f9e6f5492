"""Which ground-truth annotators run: names, defaults, and where the choice comes from.

The scenario's ``[annotations] annotators = [...]`` list is written by ``humv-usd compose`` into
the root layer's ``customLayerData`` under :data:`STAGE_KEY` (the render reads only the stage);
``render_stage(annotators=...)`` / ``humv-usd render --annotators`` override it. Only the
requested annotators are computed. ``depth`` and ``instance_id`` are always written (they come
with the ray cast the render already makes).
"""

from __future__ import annotations

from humv_usd.errors import InputError, bad_value

#: Annotator name -> what it produces.
ANNOTATORS: dict[str, str] = {
    "semantic": "EXR channels class_id and material_kind",
    "body_region": "EXR channels body_region (ids of humv_usd.human.labels.BODY_REGIONS) and jos3_segment",
    "normal": "EXR channels normal_x, normal_y, normal_z (world space, unit geometric normal)",
    "surface": "EXR channels surface_temperature [K] and emissivity (band)",
    "masks": "PNG masks: <frame>.instance.png, <frame>.region.png (colour-coded), "
    "<frame>.region_ids.png (8-bit region ids, the regions --masks format)",
    "boxes": "per object: 2D boxes (full, from the projected geometry; visible, from the mask) "
    "and the world-space axis-aligned 3D box",
    "keypoints": "per person: the 17 COCO keypoints projected, with visibility from the depth buffer",
    "occlusion": "per object: occlusion fraction (1 - visible / unoccluded pixels; unoccluded by a "
    "ray cast of the object alone)",
    "coco": "coco.json: one COCO image per sensor and frame, RLE segmentation per object",
    "regions": "regions.json: per body region (seed Table 2) mean and std of counts (or radiance) "
    "and apparent temperature per sensor and frame",
}
#: Default set: everything (each is cheap next to the Monte Carlo render; see the manifest).
DEFAULT_ANNOTATORS: tuple[str, ...] = tuple(ANNOTATORS)
#: What an annotator needs computed too.
REQUIRES = {"regions": ("body_region",), "masks": ("body_region",)}
#: Key of the annotator list in the root layer's customLayerData.
STAGE_KEY = "humv:annotators"


def resolve(names, where: str = "annotators") -> tuple[str, ...]:
    """Validate annotator names; return them with their requirements, in :data:`ANNOTATORS` order."""
    if isinstance(names, str):
        names = [n.strip() for n in names.split(",") if n.strip()]
    chosen = set()
    for i, name in enumerate(names):
        if name not in ANNOTATORS:
            raise InputError(bad_value(f"{where}[{i}]", name, "allowed annotators: " + ", ".join(ANNOTATORS)))
        chosen.add(name)
        chosen.update(REQUIRES.get(name, ()))
    return tuple(n for n in ANNOTATORS if n in chosen)


def from_stage(stage) -> tuple[tuple[str, ...], str]:
    """(annotators, source) for a stage: its root layer's list, or the default."""
    data = stage.GetRootLayer().customLayerData or {}
    if STAGE_KEY in data:
        return resolve(
            list(data[STAGE_KEY]), where=f"{stage.GetRootLayer().identifier} customLayerData {STAGE_KEY}"
        ), "stage"
    return DEFAULT_ANNOTATORS, "default"


def stage_metadata(scenario) -> dict:
    """customLayerData entries for the root layer (called by compose): the scenario's annotators."""
    section = scenario.get("annotations") or {}
    names = section.get("annotators")
    if names is None:
        return {}
    from pxr import Vt

    return {STAGE_KEY: Vt.StringArray(list(resolve(names, where="annotations.annotators")))}
