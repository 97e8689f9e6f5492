"""Load and validate a scenario file (TOML).

Every problem is reported as one line naming the key, the value and what is allowed; all
problems of a file are collected before :class:`~humv_usd.errors.InputError` is raised, so a user
fixes them in one go. Unknown keys are errors, with a did-you-mean suggestion.
"""

from __future__ import annotations

import copy
import datetime as dt
import difflib
import hashlib
import json
import math
import re
import stat
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from humv_usd.catalog.garments import ALIASES, GARMENTS, HELD_PROPS, LONG_GUNS
from humv_usd.catalog.sensors import (
    netd_for_f_number,  # another aperture than the preset's
    netd_scaling_origin,
    scenario_values,
)
from humv_usd.errors import InputError, bad_value, shown
from humv_usd.geometry.rig import HANDHELD_SHAKE_RMS_DEG
from humv_usd.scenario.ids import carries_box
from humv_usd.scenario.spec import (
    ASSET_FORMATS,
    BAND_DEFAULT_UM,
    BANDS,
    BANDS_NOT_YET,
    SECTIONS,
    SEGMENT_WITH_BOX,
    SENSOR_FALLBACK,
    SENSOR_PRESET_KEYS,
    SPEED_RANGE_M_S,
    START_RANGE,
    Key,
    Section,
    band_range_problem,
)

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
#: longest identifier (human, sensor, object id). An id becomes a prim name, part of layer file
#: names (``avatar_<id>.usda``, ``clothing_<id>.usda``) and a render output folder; 64 keeps every
#: such name far below the 255-byte file-name limit of common file systems with room for the
#: prefixes and suffixes, and keeps prim paths and error lines readable.
ID_MAX_CHARS = 64


@dataclass(frozen=True)
class Scenario:
    """A validated scenario: ``data`` holds every section with defaults filled in."""

    data: dict[str, Any]
    path: Path | None = None
    given: frozenset[str] = frozenset()  # sections present in the file
    #: keys present in the file, as ``section.key`` / ``section[i].key`` (warnings about keys
    #: that do nothing in their context name only what the user wrote, not defaults)
    given_keys: frozenset[str] = frozenset()
    #: per sensor, where its ``netd_k`` came from, recorded when the table was filled
    #: (``_fill_sensor``): given, the preset's, the preset's scaled to another f-number, or the
    #: fallback; the sensors tool authors it with the NETD, the render reports it (issue 24)
    netd_origin: tuple[str, ...] = ()

    @property
    def infrared_sensors(self) -> list[dict]:
        """Sensors whose band lies beyond 3 µm (rendered from emission, need sky and thermal)."""
        return [s for s in self.data["sensor"] if s["wavelength_um"][0] >= 3.0]

    def __getitem__(self, section: str) -> Any:
        return self.data[section]

    def get(self, section: str, default: Any = None) -> Any:
        return self.data.get(section, default)

    @property
    def frame_count(self) -> int:
        g = self.data["general"]
        return int(round(g["duration_s"] * g["fps"])) + 1

    def digest(self) -> str:
        """Content hash of the whole scenario (the root layer records it; each layer's own key
        hashes only what its tool reads: :mod:`humv_usd.scenario.inputs`)."""
        text = json.dumps(self.data, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _suggest(name: str, known) -> str:
    if len(name) > 100:  # nothing that long is a typo of a key (and difflib would be slow)
        return ""
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


#: an allowed-names list longer than this is cut to the closest matches (one readable line)
_LIST_MAX = 240


def _allowed(name: str, known, what: str = "keys") -> str:
    """The allowed names for an unknown ``name``: all of them while they fit on a readable
    line; otherwise the count, the closest ones (difflib) and where the full list is."""
    known = list(known)
    listing = ", ".join(known)
    if len(listing) <= _LIST_MAX:
        return f"allowed {what}: {listing}"
    close = difflib.get_close_matches(name, known, n=5, cutoff=0.3) if len(name) <= 100 else []
    nearest = f"; the closest: {', '.join(close)}" if close else ""
    return f"{len(known)} allowed {what}{nearest} (all in docs/reference/scenario.rst)"


def _range_text(key: Key) -> str:
    lo = int(key.lo) if key.integer else key.lo
    hi = int(key.hi) if key.integer else key.hi
    return f"{lo}..{hi}"


def _check_number(where: str, value: Any, key: Key, problems: list[str]) -> Any:
    integer = key.integer or key.kind == "int"
    ok_type = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type:
        what = "an integer" if integer else "a number"
        problems.append(bad_value(where, value, f"expected {what} in {_range_text(key)}"))
        return None
    if isinstance(value, float) and not math.isfinite(value):
        problems.append(bad_value(where, value, f"expected a finite number in {_range_text(key)}"))
        return None
    if (key.lo is not None and value < key.lo) or (key.hi is not None and value > key.hi):
        problems.append(bad_value(where, value, f"allowed range {_range_text(key)}"))
        return None
    return int(value) if integer else float(value)


def _check_value(where: str, value: Any, key: Key, problems: list[str]) -> Any:
    if key.kind in ("float", "int"):
        return _check_number(where, value, key, problems)
    if key.kind == "str":
        if not isinstance(value, str):
            problems.append(bad_value(where, value, "expected a string"))
            return None
        if "\x00" in value:  # USD's strings end at a NUL: the name would be cut there
            problems.append(bad_value(where, value, "contains a NUL character (\\u0000)"))
            return None
        return value
    if key.kind == "choice":
        if value not in key.choices:
            allowed = ", ".join(key.choices)
            hint = _suggest(str(value), key.choices) if isinstance(value, str) else ""
            if key.choices is BANDS and isinstance(value, str) and value.upper() in BANDS_NOT_YET:
                hint = f" ({value.upper()}, {BANDS_NOT_YET[value.upper()]}, is not rendered yet)"
            problems.append(bad_value(where, value, f"allowed values: {allowed}") + hint)
            return None
        return value
    if key.kind == "vec":
        what = "integers" if key.integer else "numbers"
        if not isinstance(value, list) or len(value) != key.n:
            problems.append(bad_value(where, value, f"expected {key.n} {what}, each in {_range_text(key)}"))
            return None
        out = [_check_number(f"{where}[{i}]", v, key, problems) for i, v in enumerate(value)]
        return None if any(v is None for v in out) else out
    if key.kind == "datetime":
        if not isinstance(value, dt.datetime) or value.tzinfo is not None:
            problems.append(
                bad_value(
                    where,
                    value if not isinstance(value, dt.datetime) else value.isoformat(),
                    "expected a TOML local date-time such as "
                    "2018-10-24T14:05:00 (no offset; give utc_offset_h)",
                )
            )
            return None
        lo, hi = START_RANGE
        if not lo <= value <= hi:
            problems.append(
                bad_value(where, value.isoformat(), f"allowed range {lo.isoformat()}..{hi.isoformat()}")
            )
            return None
        return value
    if key.kind == "points":
        if not isinstance(value, list):
            problems.append(
                bad_value(where, value, f"expected a list of [{', '.join('x y z'.split()[: key.n])}] points")
            )
            return None
        out = [
            _check_value(f"{where}[{i}]", v, Key("vec", key.doc, n=key.n, lo=key.lo, hi=key.hi), problems)
            for i, v in enumerate(value)
        ]
        return None if any(v is None for v in out) else out
    if key.kind == "path":
        if not isinstance(value, str) or not value:
            problems.append(bad_value(where, value, "expected a file path"))
            return None
        return value
    if key.kind == "pathlist":
        if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
            problems.append(bad_value(where, value, "expected a list of file paths"))
            return None
        return list(value)
    if key.kind == "map":
        if not isinstance(value, dict):
            problems.append(bad_value(where, value, "expected a table {pattern = value, ...}"))
            return None
        out, before = [], len(problems)
        for pattern, v in value.items():
            if v not in key.choices:
                problems.append(
                    bad_value(f"{where}.{pattern}", v, f"allowed: {', '.join(key.choices)}")
                    + (_suggest(v, key.choices) if isinstance(v, str) else "")
                )
            out.append([pattern, v])
        return out if len(problems) == before else None
    if key.kind == "strlist":
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            problems.append(bad_value(where, value, "expected a list of strings"))
            return None
        if key.choices:
            bad = [(i, v) for i, v in enumerate(value) if v not in key.choices]
            for i, v in bad:
                problems.append(
                    bad_value(
                        f"{where}[{i}]", v, f"allowed: {', '.join(key.choices)}{_suggest(v, key.choices)}"
                    )
                )
            if bad:
                return None
        return list(value)
    raise AssertionError(f"unknown key kind {key.kind}")


def _check_table(where: str, table: Any, section: Section, problems: list[str]) -> dict:
    if not isinstance(table, dict):
        problems.append(bad_value(where, table, "expected a table"))
        return {}
    out: dict[str, Any] = {}
    known = list(section.keys) + list(section.subsections)
    for name, value in table.items():
        if name in section.subsections:
            continue
        if name not in section.keys:
            problems.append(
                f"{where}.{shown(name)}: unknown key{_suggest(name, known)}; {_allowed(name, known)}"
            )
            continue
        out[name] = _check_value(f"{where}.{name}", value, section.keys[name], problems)
    for name, key in section.keys.items():
        if name not in table:
            if key.required:
                problems.append(f"{where}.{name}: missing required key ({key.doc})")
            else:
                out[name] = copy.deepcopy(key.default)
    for name, sub in section.subsections.items():
        out[name] = _check_section(f"{where}.{name}", table.get(name), sub, problems)
    return out


def _check_section(where: str, raw: Any, section: Section, problems: list[str]):
    if raw is None:
        if section.required:
            problems.append(f"[{where}]: missing required section")
        if section.array:
            return []
        if section.subsections:  # a part of the scene that is absent ([scene])
            return None
        raw = {}  # settings sections ([thermal], [atmosphere]): defaults
    if section.array:
        if not isinstance(raw, list):
            problems.append(bad_value(where, raw, f"expected an array of tables [[{where}]]"))
            return []
        return [_check_table(f"{where}[{i}]", t, section, problems) for i, t in enumerate(raw)]
    return _check_table(where, raw, section, problems)


def _check_ids(where: str, items: list[dict], problems: list[str]) -> set[str]:
    seen: set[str] = set()
    for i, item in enumerate(items):
        ident = item.get("id")
        if ident is None:
            continue
        if len(ident) > ID_MAX_CHARS:
            shown = f"{ident[:20]}...({len(ident)} characters)"
            problems.append(bad_value(f"{where}[{i}].id", shown, f"at most {ID_MAX_CHARS} characters"))
        elif not _IDENT.match(ident):
            problems.append(
                bad_value(
                    f"{where}[{i}].id", ident, "expected letters, digits and _ (not starting with a digit)"
                )
            )
        elif ident in seen:
            problems.append(bad_value(f"{where}[{i}].id", ident, "must be unique"))
        seen.add(ident)
    return seen


#: the facing direction of a BVH's rest pose by its up axis when bvh_forward_axis is not given
BVH_DEFAULT_FORWARD = {"Y": "Z", "Z": "-Y"}


def _check_garments(data: dict, problems: list[str]) -> None:
    """Garment names, checked with the first pass (an unknown garment was reported only after
    every other problem had been fixed, issue 26)."""
    for i, hum in enumerate(data["human"] or []):
        if not isinstance(hum, dict):
            continue
        seen: set[str] = set()
        for k, name in enumerate(hum.get("clothing") or []):
            if not isinstance(name, str):
                continue
            canonical = ALIASES.get(name, name)
            if canonical not in GARMENTS:
                problems.append(
                    bad_value(f"human[{i}].clothing[{k}]", name, "allowed garments: " + ", ".join(GARMENTS))
                    + _suggest(name, GARMENTS)
                )
            elif canonical in seen:
                problems.append(bad_value(f"human[{i}].clothing[{k}]", name, "listed twice"))
            elif canonical in LONG_GUNS + HELD_PROPS and seen & set(LONG_GUNS + HELD_PROPS):
                held = next(g for g in seen if g in LONG_GUNS + HELD_PROPS)
                problems.append(
                    bad_value(f"human[{i}].clothing[{k}]", name, f"the right hand already holds {held!r}")
                )
            elif canonical in LONG_GUNS + HELD_PROPS and carries_box(hum):
                problems.append(
                    bad_value(f"human[{i}].clothing[{k}]", name, "the hands carry the box (activity carry)")
                )
            seen.add(canonical)


def _cross_checks(data: dict, problems: list[str], netd_origin: list[str] | None = None) -> None:
    humans = _check_ids("human", data["human"], problems)
    _check_ids("sensor", data["sensor"], problems)
    if data["scene"]:
        _check_ids("scene.object", data["scene"]["object"], problems)
        _check_assets(data["scene"], problems)
        _check_clutter(data["scene"], problems)
    placed: set[str] = set()
    for i, p in enumerate(data["placement"]):
        h = p.get("human")
        if h is None:
            continue
        if h not in humans:
            problems.append(
                bad_value(
                    f"placement[{i}].human",
                    h,
                    "expected the id of a [[human]]: " + (shown(", ".join(sorted(humans))) or "none defined"),
                )
                + _suggest(h, humans)
            )
        elif h in placed:
            problems.append(bad_value(f"placement[{i}].human", h, "each human is placed once"))
        placed.add(h)
    for h in sorted(humans - placed):
        problems.append(f"human id {shown(repr(h))}: no [[placement]] places this human")
    for i, hum in enumerate(data["human"]):
        up = hum.get("bvh_up_axis") or "Y"
        if hum.get("bvh_forward_axis") is None:  # bvh_up_axis = "Z" with the Y-up default Z never worked
            hum["bvh_forward_axis"] = BVH_DEFAULT_FORWARD[up]
        elif hum["bvh_forward_axis"].lstrip("-") == up:
            problems.append(
                bad_value(
                    f"human[{i}].bvh_forward_axis",
                    hum["bvh_forward_axis"],
                    f"the same axis as human[{i}].bvh_up_axis = {up!r}"
                    + (f" (BVH {hum['bvh']})" if hum.get("bvh") else "")
                    + "; expected a horizontal axis",
                )
            )
        if hum.get("bvh") and hum.get("speed_m_s") is not None:
            problems.append(
                bad_value(
                    f"human[{i}].speed_m_s", hum["speed_m_s"], "not with bvh (the motion file sets the speed)"
                )
            )
        _check_segments(i, hum, problems)
        speed, activity = hum.get("speed_m_s"), hum.get("activity")
        if hum.get("segment"):
            activity = None  # the segments set the motion (checked above)
        if speed is not None and activity is not None:
            lo, hi = SPEED_RANGE_M_S.get(activity, (None, None))
            if lo is None:
                problems.append(
                    bad_value(
                        f"human[{i}].speed_m_s",
                        speed,
                        f"only for walk, run or carry (activity is {activity!r})",
                    )
                )
            elif not lo <= speed <= hi:
                problems.append(
                    bad_value(f"human[{i}].speed_m_s", speed, f"allowed range for {activity}: {lo}..{hi}")
                )
    for i, s in enumerate(data["sensor"]):
        origin = _fill_sensor(i, s, problems)
        if netd_origin is not None:
            netd_origin.append(origin)
        band = s.get("band")
        if band is None:
            continue
        lo, hi = s["wavelength_um"]
        if lo >= hi:
            problems.append(
                bad_value(f"sensor[{i}].wavelength_um", [lo, hi], "expected [short, long] with short < long")
            )
        elif problem := band_range_problem(f"sensor[{i}].wavelength_um", band, (lo, hi)):
            problems.append(problem)
        p_lo, p_hi = s["agc_percentiles"]
        if p_lo >= p_hi:
            problems.append(
                bad_value(
                    f"sensor[{i}].agc_percentiles", [p_lo, p_hi], "expected [low, high] with low < high"
                )
            )
        _check_rig(i, s, placed, problems)


def _check_segments(i: int, hum: dict, problems: list[str]) -> None:
    """A motion sequence (``[[human.segment]]``, humv_usd.human.sequence): what each segment
    may combine (the transitions' own lengths are checked when the motion is built)."""
    segs = hum.get("segment") or []
    if not segs:
        return
    for key, why in (("bvh", "a BVH file is one motion"), ("speed_m_s", "give speed_m_s per segment")):
        if hum.get(key) is not None:
            problems.append(bad_value(f"human[{i}].{key}", hum[key], f"not with human[{i}].segment ({why})"))
    for j, seg in enumerate(segs):
        where = f"human[{i}].segment[{j}]"
        act = seg.get("activity")
        walking = act in SPEED_RANGE_M_S
        if seg.get("duration_s") is not None and seg.get("distance_m") is not None:
            problems.append(
                bad_value(f"{where}.distance_m", seg["distance_m"], "give duration_s or distance_m, not both")
            )
        for key in ("distance_m", "speed_m_s"):
            if seg.get(key) is not None and act is not None and not walking:
                problems.append(
                    bad_value(
                        f"{where}.{key}", seg[key], f"only for walk, run or carry (activity is {act!r})"
                    )
                )
        if seg.get("turn_deg") is not None and act is not None and act != "turn":
            problems.append(
                bad_value(f"{where}.turn_deg", seg["turn_deg"], f"only for turn (activity is {act!r})")
            )
        if act not in SEGMENT_WITH_BOX and any(s.get("activity") == "carry" for s in segs):
            problems.append(
                bad_value(
                    f"{where}.activity",
                    act,
                    "the hands hold the box of this sequence's carry: only " + ", ".join(SEGMENT_WITH_BOX),
                )
            )
        if act == "sitChair" and any(s.get("activity") == "sitChair" for s in segs[:j]):
            problems.append(
                bad_value(f"{where}.activity", act, "one sitChair per sequence (one chair is authored)")
            )
        speed = seg.get("speed_m_s")
        if speed is not None and walking:
            lo, hi = SPEED_RANGE_M_S[act]
            if not lo <= speed <= hi:
                problems.append(
                    bad_value(f"{where}.speed_m_s", speed, f"allowed range for {act}: {lo}..{hi}")
                )
        if j < len(segs) - 1 and seg.get("duration_s") is None and seg.get("distance_m") is None:
            problems.append(f"{where}.duration_s: missing (only the last segment may leave out its length)")
        prev = segs[j - 1].get("activity") if j else None
        if walking and prev in SPEED_RANGE_M_S:
            problems.append(
                bad_value(
                    f"{where}.activity",
                    act,
                    f"follows {prev!r}: put a stationary segment (e.g. stand) between",
                )
            )


def _check_rig(i: int, s: dict, placed: set[str], problems: list[str]) -> None:
    """A sensor's platform and pointing keys (humv_usd.geometry.rig): where it is (position_m,
    the orbit or path_m), what it looks at (look_at_m, a placed person, target_path_m or the
    direction of travel), gimbal limits in order; a handheld camera shakes by default."""
    platform, target = s["platform"], s.get("target") or "point"
    if s.get("shake_rms_deg") is None:
        s["shake_rms_deg"] = HANDHELD_SHAKE_RMS_DEG if platform == "handheld" else 0.0
    for name in ("gimbal_pitch_range_deg", "gimbal_yaw_range_deg"):
        lo, hi = s[name]
        if lo >= hi:
            problems.append(
                bad_value(f"sensor[{i}].{name}", [lo, hi], "expected [low, high] with low < high")
            )
    if (target == "point" or platform == "aerial") and s.get("look_at_m") is None:
        what = "the orbit centre" if platform == "aerial" else "the point the camera looks at"
        problems.append(f"sensor[{i}].look_at_m: missing required key ({what} [x, y, z] [m])")
    if target == "human" and s.get("target_human") not in placed:
        problems.append(
            bad_value(
                f"sensor[{i}].target_human",
                s.get("target_human"),
                f"expected the id of a placed [[human]] ({', '.join(sorted(placed)) or 'none placed'})",
            )
        )
    if target == "path" and not s.get("target_path_m"):
        problems.append(f"sensor[{i}].target_path_m: missing required key (target = 'path')")
    if platform in ("aerial", "vehicle", "drone"):
        if s.get("position_m") is not None:
            sets = (
                "the orbit sets it: altitude_m, orbit_radius_m, orbit_speed_m_s"
                if platform == "aerial"
                else "path_m sets it"
            )
            problems.append(
                bad_value(
                    f"sensor[{i}].position_m", s["position_m"], f"not with platform = '{platform}' ({sets})"
                )
            )
        if platform != "aerial":
            pts = np.asarray(s.get("path_m") or [], dtype=float).reshape(-1, 3)
            if len(pts) < 2 or not np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9):
                problems.append(
                    bad_value(
                        f"sensor[{i}].path_m",
                        s.get("path_m") or [],
                        f"a {platform} needs at least two distinct points [[x, y, z], ...] [m]",
                    )
                )
        return
    if s.get("position_m") is None:
        problems.append(
            f"sensor[{i}].position_m: missing required key (camera position [x, y, z] [m] of a {platform})"
        )
    elif platform == "mast" and not 2.0 <= s["position_m"][2] <= 100.0:
        problems.append(
            bad_value(
                f"sensor[{i}].position_m[2]",
                s["position_m"][2],
                "a mast camera's height above the ground: 2.0..100.0 m",
            )
        )
    if target == "point" and s.get("position_m") and s.get("look_at_m"):
        d = [a - b for a, b in zip(s["look_at_m"], s["position_m"])]
        if math.sqrt(sum(x * x for x in d)) < 1e-6:
            problems.append(
                bad_value(f"sensor[{i}].look_at_m", s["look_at_m"], "must differ from position_m")
            )


def _check_assets(scene: dict, problems: list[str]) -> None:
    """Asset ids (prim names next to the objects and the ground), placement keys, formats."""
    _check_ids("scene.asset", scene["asset"], problems)
    taken = {o["id"] for o in scene["object"]} | {"Ground"}
    for i, a in enumerate(scene["asset"]):
        where = f"scene.asset[{i}]"
        if a.get("id") in taken:
            problems.append(bad_value(f"{where}.id", a["id"], "already names a scene object or the ground"))
        suffix = Path(a.get("file") or "").suffix.lower()
        if a.get("file") and suffix not in ASSET_FORMATS:
            problems.append(
                bad_value(f"{where}.file", a["file"], "expected a file ending in " + ", ".join(ASSET_FORMATS))
            )
        m = a.get("transform") or []
        if m and len(m) != 4:
            problems.append(bad_value(f"{where}.transform", m, "expected 4 rows of 4 numbers"))
        elif m:
            problems.extend(_placement_problems(f"{where}.transform", m))
        if m and (a.get("position_m") is not None or a.get("heading_deg") is not None):
            problems.append(
                bad_value(f"{where}.transform", "...", "give transform or position_m/heading_deg, not both")
            )


def _check_clutter(scene: dict, problems: list[str]) -> None:
    """Clutter ids: unique, and no object's, asset's or the ground's name; generated place
    prims are named ``place_*`` (reserved)."""
    _check_ids("scene.clutter", scene["clutter"], problems)
    taken = {o["id"] for o in scene["object"]} | {a["id"] for a in scene["asset"]} | {"Ground"}
    for i, c in enumerate(scene["clutter"]):
        ident = c.get("id") or ""
        if ident in taken or ident.startswith("place_"):
            problems.append(
                bad_value(
                    f"scene.clutter[{i}].id",
                    ident,
                    "already names a scene object, asset or the ground (or starts with place_)",
                )
            )


def _placement_problems(where: str, m) -> list[str]:
    """A 4x4 placement matrix (USD row vectors, translation in the last row) must be affine (last
    column 0, 0, 0, 1: a projective matrix divides the points by w) and invertible (a zero
    determinant flattens the asset to a plane, line or point)."""
    a = np.asarray(m, dtype=float)
    if a.shape != (4, 4):
        return [bad_value(where, m, "expected 4 rows of 4 numbers")]
    if not np.allclose(a[:, 3], [0.0, 0.0, 0.0, 1.0]):
        return [
            bad_value(where, a[:, 3].tolist(), "last column: expected [0, 0, 0, 1] (an affine placement)")
        ]
    det = float(np.linalg.det(a[:3, :3]))
    if not abs(det) > 1e-12:
        return [
            bad_value(where, det, "determinant of the 3x3 part: expected non-zero (it flattens the asset)")
        ]
    return []


def _fill_sensor(i: int, s: dict, problems: list[str]) -> str:
    """Sensor keys not given: from the preset, else SENSOR_FALLBACK (band edges by band).
    Returns where the NETD came from (:attr:`Scenario.netd_origin`)."""
    values = scenario_values(s["preset"]) if s.get("preset") else {}
    if s.get("band") is not None and values and s["band"] != values["band"]:
        for name in ("wavelength_um", "gain", "offset"):  # another band than the preset's:
            del values[name]  # edges by band, fallback counts
    gain_given = s.get("gain") is not None
    netd_given = s.get("netd_k") is not None
    for name in SENSOR_PRESET_KEYS:
        if s.get(name) is None:
            s[name] = copy.deepcopy(values.get(name, SENSOR_FALLBACK.get(name)))
    if netd_given:
        netd_origin = f"given: sensor[{i}].netd_k"
    elif "netd_k" in values:
        netd_origin = f"preset {s['preset']}"
    else:
        netd_origin = f"default: {SENSOR_FALLBACK['netd_k']:g} K (no netd_k and no preset)"
    if (
        values
        and not netd_given
        and s.get("band") == values.get("band") != "EO"
        and s.get("f_number") is not None
        and s["f_number"] != values.get("f_number")
    ):
        s["netd_k"] = netd_for_f_number(values["netd_k"], values["f_number"], s["f_number"])
        netd_origin = netd_scaling_origin(s["preset"], s["f_number"])
    if s.get("band") in ("EO", "NIR", "SWIR") and not gain_given and values.get("band") != s["band"]:
        s["gain"] = None  # reflected light without a gain: auto exposure
    if s.get("wavelength_um") is None and s.get("band") is not None:
        s["wavelength_um"] = list(BAND_DEFAULT_UM[s["band"]])
    for name in ("resolution", "focal_length_mm"):
        if s.get(name) is None:
            problems.append(
                f"sensor[{i}].{name}: missing required key (no preset gives it: "
                f"{SECTIONS['sensor'].keys[name].doc})"
            )
    return netd_origin


def _resolve_paths(data: dict, path: Path | None, problems: list[str]) -> None:
    """File keys become absolute paths (relative ones are relative to the scenario file; a leading
    ``~`` is the user's home, as the docs write the set-up's clips: ``~/.cache/humv-usd/mocap``)."""
    base = path.resolve().parent if path is not None else Path.cwd()

    def resolve(where: str, given: str) -> str:
        try:
            resolved = (base / Path(given).expanduser()).resolve()
            found = resolved.is_file()
        except (OSError, ValueError) as exc:  # a name too long, a NUL byte: not a file either
            problems.append(
                bad_value(where, given, f"not a usable file path ({getattr(exc, 'strerror', None) or exc})")
            )
            return given
        if not found:
            problems.append(bad_value(where, given, f"file not found ({shown(str(resolved))})"))
        return str(resolved)

    def walk(where: str, spec: Section, value) -> None:
        tables = value if spec.array else [value] if value else []
        for i, table in enumerate(tables):
            at = f"{where}[{i}]" if spec.array else where
            for name, key in spec.keys.items():
                if table.get(name) is None:
                    continue
                if key.kind == "path":
                    table[name] = resolve(f"{at}.{name}", table[name])
                elif key.kind == "pathlist":
                    table[name] = [resolve(f"{at}.{name}[{k}]", v) for k, v in enumerate(table[name])]
            for name, sub in spec.subsections.items():
                walk(f"{at}.{name}", sub, table.get(name))

    for section, spec in SECTIONS.items():
        walk(section, spec, data[section])


def validate(raw: dict, path: Path | None = None) -> Scenario:
    """Validate a parsed TOML document; raise :class:`InputError` listing every problem."""
    problems: list[str] = []
    for name in raw:
        if name not in SECTIONS:
            problems.append(
                f"[{shown(name)}]: unknown section{_suggest(name, SECTIONS)}; "
                f"{_allowed(name, SECTIONS, 'sections')}"
            )
    data = {name: _check_section(name, raw.get(name), sec, problems) for name, sec in SECTIONS.items()}
    given_people = raw.get("human") if isinstance(raw.get("human"), list) else []  # else reported above
    for hum, given in zip(data["human"], given_people):
        if isinstance(given, dict) and "clothing" not in given:  # hair on by default (issue 29.2)
            hum["clothing"] = default_hair(hum)
    _check_garments(data, problems)
    netd_origin: list[str] = []
    if not problems:
        _cross_checks(data, problems, netd_origin)
        _resolve_paths(data, path, problems)
    if problems:
        prefix = f"{path}: " if path else ""
        raise InputError("", [prefix + p for p in problems])
    return Scenario(
        data=data,
        path=path,
        given=frozenset(raw) & frozenset(SECTIONS),
        given_keys=_given_keys(raw),
        netd_origin=tuple(netd_origin),
    )


def default_hair(human: dict) -> list[str]:
    """The clothing of a ``[[human]]`` without a ``clothing`` key: head hair, a thermal layer
    (issue 25.5: a bald head reads as hot as the face), chosen by the body's sex as the most
    likely hair group of the population draw (:mod:`humv_usd.human.population`: long or tied
    hair for 60 % of women, short hair for 90 % of men): ``hair_tied`` for a woman or girl (the
    long group's style that stays on the head and neck, so the thermal tool's hair-only q_rad
    pass holds), ``hair_short`` for a man or boy. A design choice, not a statistic. Bald heads
    exist (male-pattern hair loss) and are not drawn: ``clothing = []`` is a bald, unclothed
    person; any ``clothing`` list is worn as given (hair only when listed)."""
    return ["hair_tied"] if human.get("sex") == "female" else ["hair_short"]


def _given_keys(raw: dict) -> frozenset[str]:
    out = set()
    for name, section in raw.items():
        if isinstance(section, dict):
            out |= {f"{name}.{k}" for k in section}
        elif isinstance(section, list):
            out |= {f"{name}[{i}].{k}" for i, t in enumerate(section) if isinstance(t, dict) for k in t}
    return frozenset(out)


#: largest text input read whole (a scenario or sweep TOML file) [bytes]: far above any real
#: scenario (humvvex.toml is 6 kB), far below what would exhaust memory
MAX_TEXT_INPUT_BYTES = 16 * 1024 * 1024


def read_input_bytes(path: str | Path, what: str, limit: int = MAX_TEXT_INPUT_BYTES) -> bytes:
    """The bytes of a user's input file, refused (one line) before reading when it is not a
    regular file (a device such as /dev/zero, a FIFO, a socket, a folder) or over ``limit``.

    Raises
    ------
    FileNotFoundError
        When it does not exist (callers say what was not found).
    InputError
        Not a regular file, too large, or unreadable.
    """
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a device, FIFO or socket"
        raise InputError(f"{path}: the {what} is {kind}; expected a regular file")
    if st.st_size > limit:
        raise InputError(f"{path}: the {what} has {st.st_size} bytes; at most {limit} bytes are read")
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if len(data) > limit:  # it grew while being read
        raise InputError(f"{path}: the {what} has more than {limit} bytes; at most {limit} are read")
    return data


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario TOML file (a regular file of at most
    :data:`MAX_TEXT_INPUT_BYTES`)."""
    path = Path(path)
    try:
        text = read_input_bytes(path, "scenario file").decode("utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: scenario file not found") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: cannot read scenario file ({exc})") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:  # arrays or tables nested thousands deep
        raise InputError(f"{path}: not valid TOML: nested too deeply") from None
    return validate(raw, path)
