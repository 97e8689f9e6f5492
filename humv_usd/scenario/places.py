"""Places from a few keys (``[scene.place]``): a street, a rural road, a parking lot or an open
field, generated from a seed as plain scene entries.

:func:`place_items` expands the place into ``[[scene.object]]``-like boxes and panels (road,
pavements, field, facades, dark window panes) and ``[[scene.clutter]]``-like warm objects
(vehicles, lamps, lit windows, animals, HVAC units, fires), with ids ``place_<what>_<n>``. The
entries are exactly what a hand-written scenario would hold, so the scene tool builds, labels
and the thermal tool solves them as hand-made scenes (generated objects are slabs of their
material; clutter parts are held by their models, :mod:`humv_usd.physics.warm_objects`).
:func:`scene_objects` and :func:`scene_clutter` give the scenario's own entries followed by the
generated ones: the one list every tool (instance ids, scene layer) reads.

Layout: the road runs along x, centred on y = 0, over ``length_m`` centred on x = 0; the
generated place lies on z = 0 (the flat ground; terrain heights come with the terrain tool).
Trees (rural_road, open_field, ``vegetation_density``) are generated ``[[scene.object]]`` entries
of kind tree (:mod:`humv_usd.scene.vegetation` builds, labels and the thermal tool solves them
as hand-made plants); their positions and heights are also in :attr:`PlaceItems.trees`. With
``crop`` (maize, wheat) a rural road grows a crop object (kind crop,
:data:`humv_usd.scenario.spec.CROPS`) over its south field, on soil, and an open field over its
north half; trees and warm clutter keep out of it (same draws, so the rest of the place is the
place without the crop).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

from humv_usd.scenario.spec import CLUTTER, CROPS, OBJECT

#: a car's footprint [m] (length, width) at scale 1 (humv_usd.scene.objects.vehicle_parts)
CAR_LENGTH_M, CAR_WIDTH_M = 4.4, 1.8
PAVEMENT_WIDTH_M = 3.0
KERB_HEIGHT_M = 0.12
ROAD_THICKNESS_M = 0.01
FLOOR_HEIGHT_M = 3.0
WINDOW_SIZE_M = (1.2, 1.4)  # width, height
PARKING_BAY_M = 2.7
#: crown diameter over tree height of the generated trees: open-grown broadleaves reach crown
#: diameters of 0.4-0.8 times their height (Pretzsch et al. 2015, Urban For. Urban Green.
#: 14:466, crown allometry of common European species); the middle of that range
CROWN_WIDTH_PER_HEIGHT = 0.6
#: least distance [m] from a generated tree's trunk to a warm object's position
TREE_CLEARANCE_M = 4.0
#: material of a tree's trunk (humv_usd.scene.vegetation.TRUNK_MATERIAL; tests/test_places.py)
TRUNK_MATERIAL = "wood"


#: library materials of each clutter kind's parts besides its ``material`` key
#: (humv_usd.scene.objects.parts_of; tests/test_places.py checks they agree)
KIND_MATERIALS = {
    "vehicle": ("painted_metal", "glass", "rubber"),
    "dog": ("fur",),
    "cattle": ("fur",),
    "street_lamp": (),
    "window": ("glass",),
    "hvac": ("painted_metal",),
    "barbecue": ("painted_metal",),
    "fire": ("soil", "wood"),
}


@dataclass
class PlaceItems:
    objects: list[dict] = field(default_factory=list)
    clutter: list[dict] = field(default_factory=list)
    #: (x, y, height [m]) of trees for the vegetation tool
    trees: list[tuple[float, float, float]] = field(default_factory=list)


def _object(ident, material, center, size, cls="building", heading=0.0, kind="box") -> dict:
    out = {k: copy.deepcopy(v.default) for k, v in OBJECT.keys.items()}
    out.update(
        id=ident,
        kind=kind,
        material=material,
        center_m=[float(c) for c in center],
        size_m=[float(s) for s in size],
        heading_deg=float(heading),
    )
    out["class"] = cls
    return out


def _clutter(ident, kind, position, heading=0.0, **kw) -> dict:
    out = {k: copy.deepcopy(v.default) for k, v in CLUTTER.keys.items()}
    out.update(id=ident, kind=kind, position_m=[float(c) for c in position], heading_deg=float(heading))
    out.update(kw)
    return out


def _vehicle_use(rng, moving: bool) -> dict:
    """A plausible history: driving (warm, running), idling at the kerb, or parked for a while."""
    if moving:
        return {"run_s": float(rng.uniform(600, 3600)), "off_s": 0.0}
    r = rng.uniform()
    if r < 0.15:  # idling
        return {"run_s": float(rng.uniform(120, 1800)), "off_s": 0.0}
    if r < 0.55:  # arrived recently
        return {"run_s": float(rng.uniform(600, 3600)), "off_s": float(rng.uniform(60, 3600))}
    return {"run_s": float(rng.uniform(600, 3600)), "off_s": float(rng.uniform(3 * 3600, 12 * 3600))}


def _row(rng, start, stop, count, spacing) -> list[float]:
    """Up to ``count`` sorted centres in [start, stop] at least ``spacing`` apart (random gaps)."""
    slots = np.arange(start, stop + 1e-9, spacing)
    if len(slots) == 0 or count <= 0:
        return []
    pick = np.sort(rng.choice(len(slots), size=min(count, len(slots)), replace=False))
    jitter = rng.uniform(0.0, 0.3 * (spacing - CAR_LENGTH_M), size=len(pick))
    return [float(slots[i] + j) for i, j in zip(pick, jitter)]


def _drivers(rng, p, items: PlaceItems, n: int, lanes, length) -> None:
    for k in range(n):
        lane = lanes[k % len(lanes)]
        direction = 1.0 if lane < 0 else -1.0  # right-hand traffic
        x0 = float(rng.uniform(-0.4, 0.2) * length) * direction
        end = direction * (length / 2 - CAR_LENGTH_M)
        items.clutter.append(
            _clutter(
                f"place_car_drive_{k}",
                "vehicle",
                [x0, lane, 0.0],
                0.0 if direction > 0 else 180.0,
                speed_m_s=float(rng.uniform(6.0, 14.0)),
                path_m=[[end, lane]],
                **_vehicle_use(rng, True),
            )
        )


def _lamps(rng, items: PlaceItems, n: int, length: float, ys) -> None:
    if n <= 0:
        return
    xs = np.linspace(-length / 2, length / 2, n + 2)[1:-1]
    for k, x in enumerate(xs):
        y = ys[k % len(ys)]
        items.clutter.append(
            _clutter(f"place_lamp_{k}", "street_lamp", [float(x), y, 0.0], 90.0 if y < 0 else -90.0)
        )


def _trees(rng, items: PlaceItems, density: float, xr, yr) -> None:
    """Trees 4-12 m high, uniform over the area at ``density`` per 100 m2, each also a
    ``[[scene.object]]`` of kind tree (humv_usd.scene.vegetation: leaf crown, wood trunk) with
    a crown :data:`CROWN_WIDTH_PER_HEIGHT` times its height across; a tree whose trunk would
    stand within :data:`TREE_CLEARANCE_M` of a warm object (a parked car, an animal, a fire)
    keeps its position in :attr:`PlaceItems.trees` but is not built."""
    area = (xr[1] - xr[0]) * (yr[1] - yr[0])
    n = int(rng.poisson(density * area / 100.0))
    taken = np.array([c["position_m"][:2] for c in items.clutter], dtype=float).reshape(-1, 2)
    for _ in range(min(n, 500)):
        x, y, h = float(rng.uniform(*xr)), float(rng.uniform(*yr)), float(rng.uniform(4.0, 12.0))
        items.trees.append((x, y, h))
        if len(taken) and np.min(np.hypot(taken[:, 0] - x, taken[:, 1] - y)) < TREE_CLEARANCE_M:
            continue
        width = CROWN_WIDTH_PER_HEIGHT * h
        k = sum(o["kind"] == "tree" for o in items.objects)
        items.objects.append(
            _object(f"place_tree_{k}", "leaf", [x, y, 0.0], [width, width, h], "vegetation", kind="tree")
        )


def street(p: dict, rng) -> PlaceItems:
    items = PlaceItems()
    L, W = p["length_m"], p["road_width_m"]
    items.objects.append(
        _object("place_road", p["road_material"], [0, 0, 0], [L, W, ROAD_THICKNESS_M], "ground", kind="panel")
    )
    for s, side in ((-1, "s"), (1, "n")):
        yc = s * (W / 2 + PAVEMENT_WIDTH_M / 2)
        items.objects.append(
            _object(
                f"place_pavement_{side}",
                p["pavement_material"],
                [0, yc, 0],
                [L, PAVEMENT_WIDTH_M, KERB_HEIGHT_M],
                "ground",
            )
        )
    # facades: boxes behind the pavements, their windows on the street side
    n_lit = n_dark = 0
    for s, side in ((-1, "s"), (1, "n")):
        face_y = s * (W / 2 + PAVEMENT_WIDTH_M)
        x = -L / 2
        for b in range(p["buildings"]):
            width = float(rng.uniform(8.0, 14.0))
            if x + width > L / 2:
                break
            floors = int(rng.integers(2, 5))
            depth = 8.0
            height = floors * FLOOR_HEIGHT_M + 0.5
            cx = x + width / 2
            items.objects.append(
                _object(
                    f"place_building_{side}{b}",
                    p["facade_material"],
                    [cx, face_y + s * depth / 2, 0],
                    [width, depth, height],
                )
            )
            cols = max(1, int(width // 3.0))
            for f in range(floors):
                for c in range(cols):
                    wx = x + (c + 0.5) * width / cols
                    wz = f * FLOOR_HEIGHT_M + 1.0
                    heading = -90.0 if s > 0 else 90.0  # outer face towards the street
                    if rng.uniform() < p["window_lit_share"]:
                        items.clutter.append(
                            _clutter(f"place_window_{n_lit}", "window", [wx, face_y, wz], heading)
                        )
                        n_lit += 1
                    else:
                        items.objects.append(
                            _object(
                                f"place_pane_{n_dark}",
                                "glass",
                                [wx, face_y - s * 0.03, wz],
                                [WINDOW_SIZE_M[0], 0.02, WINDOW_SIZE_M[1]],
                                kind="panel",
                            )
                        )
                        n_dark += 1
            x += width + float(rng.uniform(0.0, 2.0))
    n_drive = int(round(p["vehicles"] * p["driving"]))
    n_park = p["vehicles"] - n_drive
    kerb = W / 2 - CAR_WIDTH_M / 2 - 0.3
    half = (L - CAR_LENGTH_M) / 2
    parked = [(x, -kerb, 0.0) for x in _row(rng, -half, half, (n_park + 1) // 2, p["vehicle_spacing_m"])]
    parked += [(x, kerb, 180.0) for x in _row(rng, -half, half, n_park // 2, p["vehicle_spacing_m"])]
    for k, (x, y, h) in enumerate(parked):
        items.clutter.append(
            _clutter(f"place_car_{k}", "vehicle", [x, y, 0.0], h, **_vehicle_use(rng, False))
        )
    _drivers(rng, p, items, n_drive, [-W / 4, W / 4], L)
    _lamps(rng, items, p["lamps"], L, [-(W / 2 + 0.5), W / 2 + 0.5])
    for k in range(p["animals"]):
        y = float(rng.choice([-1, 1])) * (W / 2 + PAVEMENT_WIDTH_M * rng.uniform(0.3, 0.8))
        items.clutter.append(
            _clutter(
                f"place_dog_{k}",
                "dog",
                [float(rng.uniform(-L / 2, L / 2)), y, KERB_HEIGHT_M],
                float(rng.uniform(0, 360)),
            )
        )
    for k in range(p["warm_objects"]):
        s = float(rng.choice([-1, 1]))
        y = s * (W / 2 + PAVEMENT_WIDTH_M - 0.6)
        items.clutter.append(
            _clutter(
                f"place_hvac_{k}", "hvac", [float(rng.uniform(-L / 2, L / 2)), y, KERB_HEIGHT_M], 90.0 * -s
            )
        )
    return items


def rural_road(p: dict, rng) -> PlaceItems:
    items = PlaceItems()
    L, W = p["length_m"], p["road_width_m"]
    items.objects.append(
        _object("place_road", p["road_material"], [0, 0, 0], [L, W, ROAD_THICKNESS_M], "ground", kind="panel")
    )
    field_depth = 30.0
    for s, side in ((-1, "s"), (1, "n")):
        items.objects.append(
            _object(
                f"place_verge_{side}",
                "soil",
                [0, s * (W / 2 + 1.0), 0],
                [L, 2.0, ROAD_THICKNESS_M],
                "ground",
                kind="panel",
            )
        )
        items.objects.append(
            _object(
                f"place_field_{side}",
                p["field_material"],
                [0, s * (W / 2 + 2.0 + field_depth / 2), 0],
                [L, field_depth, ROAD_THICKNESS_M],
                "ground",
                kind="panel",
            )
        )
    n_drive = int(round(p["vehicles"] * p["driving"]))
    _drivers(rng, p, items, n_drive, [-W / 4, W / 4], L)
    half = (L - CAR_LENGTH_M) / 2
    for k, x in enumerate(_row(rng, -half, half, p["vehicles"] - n_drive, p["vehicle_spacing_m"])):
        items.clutter.append(
            _clutter(f"place_car_{k}", "vehicle", [x, -(W / 2 + 1.0), 0.0], 0.0, **_vehicle_use(rng, False))
        )
    _lamps(rng, items, p["lamps"], L, [W / 2 + 1.5])
    for k in range(p["animals"]):
        s = float(rng.choice([-1, 1]))
        items.clutter.append(
            _clutter(
                f"place_cattle_{k}",
                "cattle",
                [
                    float(rng.uniform(-L / 2 + 3, L / 2 - 3)),
                    s * float(rng.uniform(W / 2 + 6, W / 2 + field_depth - 2)),
                    0.0,
                ],
                float(rng.uniform(0, 360)),
            )
        )
    for k in range(p["warm_objects"]):
        items.clutter.append(
            _clutter(
                f"place_fire_{k}",
                "fire",
                [float(rng.uniform(-L / 3, L / 3)), W / 2 + float(rng.uniform(8, 20)), 0.0],
            )
        )
    for s in (-1, 1):
        lo, hi = sorted((s * (W / 2 + 2.5), s * (W / 2 + 2.0 + field_depth)))
        _trees(rng, items, p["vegetation_density"], (-L / 2, L / 2), (lo, hi))
    if p.get("crop", "none") != "none":  # the south field
        _crop_field(
            items, p["crop"], L, -(W / 2 + 2.0 + field_depth), -(W / 2 + 2.0), "place_crop_s", "place_field_s"
        )
    return items


#: margin [m] between a crop field's rows and its field's edges
CROP_MARGIN_M = 0.5


def _crop_field(
    items: PlaceItems,
    crop: str,
    length: float,
    y0: float,
    y1: float,
    ident: str,
    soil_panel: str | None = None,
    clear_m: float = 1.0,
) -> None:
    """A crop field of ``crop`` over x in +-``length`` / 2 and y in [``y0``, ``y1``] (less
    :data:`CROP_MARGIN_M`), added after every random draw so the rest of the place is the place
    without it: ``soil_panel`` (a field panel's id) becomes soil, the trees standing in it are not
    built (they stay in :attr:`PlaceItems.trees`) and warm clutter in it (cattle, cars, fires)
    moves across y = 0 (mirrored); "in it" is within ``clear_m`` of its rows (the field must lie
    farther than that from y = 0)."""
    spacing, height = CROPS[crop]
    y0, y1 = y0 + CROP_MARGIN_M, y1 - CROP_MARGIN_M
    for o in items.objects:
        if o["id"] == soil_panel:
            o["material"] = "soil"
    items.objects[:] = [
        o
        for o in items.objects
        if not (o["kind"] == "tree" and y0 - clear_m <= o["center_m"][1] <= y1 + clear_m)
    ]
    for c in items.clutter:
        if y0 - clear_m <= c["position_m"][1] <= y1 + clear_m:
            c["position_m"][1] = -c["position_m"][1]
    crop_obj = _object(
        ident, "leaf", [0.0, (y0 + y1) / 2, 0.0], [length - 2 * CROP_MARGIN_M, y1 - y0, height], "vegetation",
        kind="crop",
    )  # fmt: skip
    crop_obj["row_spacing_m"] = spacing
    items.objects.append(crop_obj)


def parking_lot(p: dict, rng) -> PlaceItems:
    items = PlaceItems()
    L = p["length_m"]
    rows = (-7.5, -2.5, 2.5, 7.5)  # two double rows of bays, nose to nose, an aisle between
    depth = 25.0
    items.objects.append(
        _object(
            "place_lot", p["road_material"], [0, 0, 0], [L, depth, ROAD_THICKNESS_M], "ground", kind="panel"
        )
    )
    bays = [
        (x, y)
        for y in rows
        for x in np.arange(-L / 2 + PARKING_BAY_M, L / 2 - PARKING_BAY_M + 1e-9, PARKING_BAY_M)
    ]
    pick = rng.choice(len(bays), size=min(p["vehicles"], len(bays)), replace=False) if bays else []
    for k, i in enumerate(sorted(pick)):
        x, y = bays[i]
        heading = 90.0 if y in (-7.5, 2.5) else -90.0
        items.clutter.append(
            _clutter(f"place_car_{k}", "vehicle", [float(x), y, 0.0], heading, **_vehicle_use(rng, False))
        )
    _lamps(rng, items, p["lamps"], L, [0.0, -depth / 2 + 0.5, depth / 2 - 0.5])
    for k in range(p["warm_objects"]):
        items.clutter.append(
            _clutter(
                f"place_hvac_{k}", "hvac", [float(rng.uniform(-L / 2, L / 2)), depth / 2 + 1.0, 0.0], -90.0
            )
        )
    for k in range(p["animals"]):
        items.clutter.append(
            _clutter(
                f"place_dog_{k}",
                "dog",
                [float(rng.uniform(-L / 2, L / 2)), 0.0, 0.0],
                float(rng.uniform(0, 360)),
            )
        )
    return items


def open_field(p: dict, rng) -> PlaceItems:
    items = PlaceItems()
    L = p["length_m"]
    items.objects.append(
        _object(
            "place_field", p["field_material"], [0, 0, 0], [L, L, ROAD_THICKNESS_M], "ground", kind="panel"
        )
    )

    def spot():
        return [float(rng.uniform(-L / 2 + 3, L / 2 - 3)), float(rng.uniform(-L / 2 + 3, L / 2 - 3)), 0.0]

    for k in range(p["vehicles"]):
        items.clutter.append(
            _clutter(
                f"place_car_{k}", "vehicle", spot(), float(rng.uniform(0, 360)), **_vehicle_use(rng, False)
            )
        )
    for k in range(p["animals"]):
        items.clutter.append(_clutter(f"place_cattle_{k}", "cattle", spot(), float(rng.uniform(0, 360))))
    for k in range(p["warm_objects"]):
        kind = ("fire", "barbecue")[k % 2]
        items.clutter.append(_clutter(f"place_{kind}_{k}", kind, spot()))
    _trees(rng, items, p["vegetation_density"], (-L / 2, L / 2), (-L / 2, L / 2))
    if p.get("crop", "none") != "none":  # the north half, 3 m off the middle
        _crop_field(items, p["crop"], L, 3.0, L / 2, "place_crop_n", clear_m=3.0)
    return items


GENERATORS = {
    "street": street,
    "rural_road": rural_road,
    "parking_lot": parking_lot,
    "open_field": open_field,
}


def place_items(place: dict | None) -> PlaceItems:
    """The generated entries of ``[scene.place]`` (empty for kind "none" or no place)."""
    if not place or place.get("kind", "none") == "none":
        return PlaceItems()
    rng = np.random.default_rng(int(place["seed"]))
    return GENERATORS[place["kind"]](place, rng)


def _cached(scene: dict) -> PlaceItems:
    place = scene.get("place")
    key = repr(sorted((place or {}).items()))
    hit = _CACHE.get(key)
    if hit is None:
        hit = _CACHE[key] = place_items(place)
        if len(_CACHE) > 64:
            _CACHE.pop(next(iter(_CACHE)))
    return hit


_CACHE: dict[str, PlaceItems] = {}


def scene_objects(scene: dict | None) -> list[dict]:
    """The scenario's ``[[scene.object]]`` followed by the place's generated boxes and panels."""
    if not scene:
        return []
    return list(scene.get("object") or ()) + _cached(scene).objects


def generated_objects(scene: dict | None) -> list[dict]:
    """The place's generated boxes and panels alone."""
    return _cached(scene).objects if scene else []


def scene_clutter(scene: dict | None) -> list[dict]:
    """The scenario's ``[[scene.clutter]]`` followed by the place's generated warm objects."""
    if not scene:
        return []
    return list(scene.get("clutter") or ()) + _cached(scene).clutter


def scene_trees(scene: dict | None) -> list[tuple[float, float, float]]:
    """Tree positions and heights of the place, for the vegetation tool."""
    return _cached(scene).trees if scene else []


def scene_materials(scene: dict | None) -> set[str]:
    """Library materials the generated objects and every clutter entry's parts use."""
    names = {o["material"] for o in generated_objects(scene)}
    if any(o["kind"] == "tree" for o in generated_objects(scene)):
        names.add(TRUNK_MATERIAL)
    for c in scene_clutter(scene):
        names.update(KIND_MATERIALS[c["kind"]])
        if c["kind"] in ("vehicle", "street_lamp", "hvac"):
            names.add(c["material"])
    return names
