"""What a layer tool reads from the scenario, as flat ``{dotted key: value}`` tables: the inputs of
a layer's cache key (``humv_usd.pipeline.graph``) and what compose.json compares between runs.

A tool declares ``READS``, a tuple of read paths:

* ``"thermal"`` -- a whole section; ``"general.start"`` -- one key;
* ``"sensor.*.position_m"`` -- one key of every entry of an array section;
* ``"human[{id}]"``, ``"placement[{id}]"`` -- the entry of the person a per-person layer is
  built for (``{id}`` is that person's id; an entry matches on its ``id`` or, for placements,
  its ``human`` key);
* ``"@ids"`` -- the instance ids (:func:`humv_usd.scenario.ids.instance_ids`), derived from the
  order of people, objects and props;
* ``"@clutterAir"`` -- the clock and the air that warm clutter's held temperatures follow
  (:data:`CLUTTER_AIR`), or None when the scene has no clutter: the scene layer reads them only
  then, so a scene without clutter is not rebuilt for a new start time or weather;
* ``"@puddles"`` -- the seed and whether it rained, when the ground has puddles (else None);
* ``"@wood"`` -- whether a person sits on a chair or carries a box (the props' wood): the
  materials layer reads it instead of every person's activity, so it is shared across motions;
* ``"@instanceId[{id}]"`` -- that person's instance id alone; ``"@carriesRifle[{id}]"`` -- whether
  that person's clothing holds the rifle (the avatar's arms take the carry pose);
  ``"@holds[{id}]"`` -- the prop held in the right hand (phone, phone_call, handbag) or None;
  ``"@chairId[{id}]"``, ``"@boxId[{id}]"`` -- the instance id of the chair the person sits on,
  of the box it carries, or None: a per-person
  layer that reads these instead of the whole entry is shared between scenarios that differ only
  in what it does not read (e.g. avatars across outfits).

Values are JSON values (date-times as ISO text). A file the scenario names (``weather_csv``,
``bvh``, ``scene.asset.*.file``, ``scene.layers``) is read by content: its value is ``"<path> sha256:<hash of the bytes>"``, so editing the
file changes the key of every layer that reads it.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pxr import Sdf, UsdUtils

from humv_usd.catalog.garments import HELD_PROPS, LONG_GUNS
from humv_usd.scenario.ids import carries_box, instance_ids, sits_on_chair
from humv_usd.scenario.places import scene_clutter
from humv_usd.scenario.spec import SECTIONS

if TYPE_CHECKING:
    from humv_usd.scenario.load import Scenario

#: the frame range: frame count and time codes (``general.fps``, ``general.duration_s``)
FRAMES = ("general.fps", "general.duration_s")
#: when and where: frame times, the sun, the weather series (everything of [general] but the
#: scenario's name and description)
CLOCK = (
    *FRAMES,
    "general.start",
    "general.utc_offset_h",
    "general.time_zone",
    "general.latitude_deg",
    "general.longitude_deg",
    "general.elevation_m",
    "general.seed",
)
#: what warm clutter's held temperatures follow (humv_usd.scene.objects.author_clutter): the
#: clock (the sun's elevation at frame 0, the frames) and the held air
CLUTTER_AIR = (
    *CLOCK,
    "atmosphere.air_temperature_k",
    "atmosphere.wind_speed_m_s",
    "atmosphere.cloud_cover",
)


def _clutter_air(scenario: Scenario) -> dict[str, Any] | None:
    """The values of :data:`CLUTTER_AIR` when the scene has warm clutter (its own or a place's),
    else None."""
    if not scene_clutter(scenario["scene"]):
        return None
    return read_values(scenario, CLUTTER_AIR)


def _puddles(scenario: Scenario) -> dict[str, Any] | None:
    """What the scene layer's puddles follow (:mod:`humv_usd.scene.puddles`): the seed and
    whether it rained, only when ``[scene.ground] puddles`` > 0 (else None: a scene without
    puddles keeps its layer across weather)."""
    scene = scenario["scene"] or {}
    if not float((scene.get("ground") or {}).get("puddles") or 0.0) > 0.0:
        return None
    rain = float((scenario["atmosphere"] or {}).get("rain_mm_h") or 0.0)
    return {"seed": scenario["general"].get("seed"), "rained": rain > 0.0}


def _netd_origin(scenario: Scenario) -> list[str]:
    """Where each sensor's NETD came from (:attr:`Scenario.netd_origin`): the sensors layer
    authors it, so equal values of another origin (given vs the preset's) are another layer."""
    return list(scenario.netd_origin)


def _wood(scenario: Scenario) -> bool:
    """Whether a person sits on a chair or carries a box (the wood the materials tool writes for
    the props the avatar tool authors)."""
    return any(sits_on_chair(h) or carries_box(h) for h in scenario["human"])


DERIVED = {
    "@ids": instance_ids,
    "@clutterAir": _clutter_air,
    "@netdOrigin": _netd_origin,
    "@puddles": _puddles,
    "@wood": _wood,
}
#: the garment that changes the avatar's pose (humv_usd.catalog.garments: carried in both hands)
RIFLE = "rifle"


def _instance_id(scenario: Scenario, human_id: str) -> int:
    return instance_ids(scenario)[f"human:{human_id}"]


def _carries_rifle(scenario: Scenario, human_id: str) -> bool:
    """Whether the person carries a long gun (the rifle or the shotgun: the arms' carry pose)."""
    human = next((h for h in scenario["human"] if h["id"] == human_id), None)
    return human is not None and any(g in LONG_GUNS for g in human.get("clothing") or ())


def _holds(scenario: Scenario, human_id: str) -> str | None:
    """The prop the person holds in the right hand (the arm's hold pose), or None: the first of
    :data:`humv_usd.catalog.garments.HELD_PROPS` in the clothing."""
    human = next((h for h in scenario["human"] if h["id"] == human_id), None)
    return next((g for g in (human or {}).get("clothing") or () if g in HELD_PROPS), None)


def _chair_id(scenario: Scenario, human_id: str) -> int | None:
    """The instance id of the chair the person sits on (``prop:<id>:chair``), or None."""
    return instance_ids(scenario).get(f"prop:{human_id}:chair")


def _box_id(scenario: Scenario, human_id: str) -> int | None:
    """The instance id of the box the person carries (``prop:<id>:box``), or None."""
    return instance_ids(scenario).get(f"prop:{human_id}:box")


def _crowd(scenario: Scenario, human_id: str) -> list | None:
    """Where everybody starts and goes, for a person who avoids the others (placement
    ``avoidance``; None when they do not): their avoided path depends on all of these."""
    place = next((p for p in scenario["placement"] if p["human"] == human_id), None)
    if place is None or place.get("avoidance", "none") == "none":
        return None
    moves = {h["id"]: (h["activity"], h.get("speed_m_s")) for h in scenario["human"]}
    return [
        {
            "human": p["human"],
            "position_m": list(p["position_m"][:2]),
            "heading_deg": p["heading_deg"],
            "waypoints_m": [list(w) for w in p["waypoints_m"]],
            "activity": moves.get(p["human"], ("stand", None))[0],
            "speed_m_s": moves.get(p["human"], ("stand", None))[1],
        }
        for p in scenario["placement"]
    ]


#: values derived for one person: ``"@name[{id}]"``
DERIVED_PER_PERSON = {
    "@instanceId": _instance_id,
    "@carriesRifle": _carries_rifle,
    "@holds": _holds,
    "@chairId": _chair_id,
    "@boxId": _box_id,
    "@crowd": _crowd,
}


def _file_keys(sections) -> frozenset[str]:
    """Names of the keys whose values name files (``path``, ``pathlist``), subsections included."""
    names: set[str] = set()
    for s in sections:
        names |= {name for name, key in s.keys.items() if key.kind in ("path", "pathlist")}
        names |= _file_keys(s.subsections.values())
    return frozenset(names)


#: keys whose values name files (read by content)
FILE_KEYS = _file_keys(SECTIONS.values())


def read_values(scenario: Scenario, reads, human_id: str | None = None) -> dict[str, Any]:
    """The values a tool reads, flattened to ``{dotted key: JSON value}`` (sorted keys)."""
    out: dict[str, Any] = {}
    for read in reads:
        path = read.format(id=human_id) if human_id is not None else read
        if path in DERIVED:
            out[path] = _plain(DERIVED[path](scenario))
            continue
        name, _, ident = path.partition("[")
        if name in DERIVED_PER_PERSON:
            out[path] = _plain(DERIVED_PER_PERSON[name](scenario, ident.rstrip("]")))
            continue
        head, *rest = path.split(".")
        _flatten(head, _select(scenario, head), rest, out)
    return dict(sorted(out.items()))


def _select(scenario: Scenario, head: str):
    """A section, or the entry ``section[ident]`` of an array section."""
    if "[" not in head:
        return scenario[head]
    section, ident = head.rstrip("]").split("[")
    return next((e for e in scenario[section] if ident in (e.get("id"), e.get("human"))), None)


def _flatten(where: str, value, rest: list[str], out: dict) -> None:
    if rest:
        step, *more = rest
        if step == "*":
            for i, item in enumerate(value or []):
                _flatten(f"{where}.{i}", item, more, out)
        else:
            _flatten(f"{where}.{step}", None if value is None else value.get(step), more, out)
        return
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{where}.{k}", v, [], out)
        if not value:
            out[where] = {}
    elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        for i, v in enumerate(value):
            _flatten(f"{where}.{i}", v, [], out)
    else:
        leaf = where.rsplit(".", 1)[-1]
        if leaf in FILE_KEYS and isinstance(value, list):  # a pathlist
            out[where] = [_file_value(v) for v in value]
        else:
            out[where] = _file_value(value) if leaf in FILE_KEYS and value else _plain(value)


def _plain(value):
    """A JSON value: date-times as ISO text, tuples as lists."""
    return json.loads(
        json.dumps(value, default=lambda v: v.isoformat() if isinstance(v, dt.datetime) else str(v))
    )


def _file_value(path: str) -> str:
    return f"{path} sha256:{file_digest(path)}"


def file_digest(path) -> str:
    """Content hash of a file; of a USD file together with every file it pulls in (sublayers,
    references, payloads, asset paths: :func:`_with_usd_dependencies`). Compose keys the user
    layers of a stage by it, so an edit of a file a user layer references rebuilds the layers
    that read the composed stage (the thermal layer's shadows follow a moved or new object)."""
    p = Path(path)
    stat = p.stat()
    digest = _file_hash(str(p), stat.st_size, stat.st_mtime_ns)
    if p.suffix.lower() in USD_SUFFIXES:
        digest = _with_usd_dependencies(str(p), digest)
    return digest


#: file suffixes of USD files, whose layers, references, payloads and assets count too
USD_SUFFIXES = (".usd", ".usda", ".usdc")


def _with_usd_dependencies(path: str, digest: str) -> str:
    """``digest`` combined with the content hashes of every file a USD file pulls in (its
    sublayers, references, payloads and asset paths, recursively; UsdUtils.ComputeAllDependencies),
    so that editing a file an asset references changes the keys too. Unresolved ones are left to
    ``humv-usd check``; a file without dependencies keeps its own digest."""
    try:
        layers, assets, _ = UsdUtils.ComputeAllDependencies(Sdf.AssetPath(path))
    except Exception:  # noqa: BLE001 (pxr raises Tf.ErrorException; the scene tool names the file)
        return digest
    own = str(Path(path).resolve())
    files = {lyr.realPath for lyr in layers if lyr.realPath} | {str(a) for a in assets}
    files = sorted(f for f in files if f and "[" not in f and str(Path(f).resolve()) != own)
    if not files:
        return digest
    parts = [digest]
    for f in files:
        try:
            stat = Path(f).stat()
        except OSError:
            continue
        parts.append(f"{f}:{_file_hash(f, stat.st_size, stat.st_mtime_ns)}")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


@functools.lru_cache(maxsize=64)
def _file_hash(path: str, size: int, mtime_ns: int) -> str:  # size and mtime: the cache key
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def inputs_key(version: str, values: dict, upstream_keys: dict[str, str]) -> str:
    """A layer's cache key: hash of its tool's version, the values it reads and the keys of the
    layers it reads from the stage."""
    text = json.dumps({"version": version, "reads": values, "upstream": upstream_keys}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
