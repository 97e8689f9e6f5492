"""The sweep file (TOML): a base scenario, overrides, a grid and random draws → variants.

::

    [sweep]
    name = "table1"
    base = "walk.toml"                  # scenario file, relative to this file
    unset = ["human.0.speed_m_s"]       # keys removed from the base (optional)
    count = 1                           # random draws per grid point (default 1)
    seed = 0                            # seed of the random draws

    [set]                               # overrides of every variant (dotted keys)
    "sensor.0.render_resolution" = [256, 192]   # fewer pixels, the same view (the pitch scales;
                                        # "sensor.0.resolution" would crop the field of view)

    [grid]                              # the grid: every combination is a variant
    "human.0.sex" = ["male", "female"]  # a list of values for one key
    [grid.weapon]                       # a named axis: option name -> overrides
    none = {}
    rifle = { "human.0.clothing+" = ["rifle"] }   # "+": append to a list

    [random]                            # drawn per variant (numbers, vectors, date-times, choices)
    "placement.0.heading_deg" = { uniform = [0.0, 360.0] }
    "atmosphere.air_temperature_k" = { normal = [293.0, 5.0] }
    "human.0.build" = { choice = ["slim", "average", "muscular"] }
    "human.1" = { population = { age_yr = [2, 90] } }   # a whole person: sex, age, stature,
                                        # mass, build, proportions, skin tone, hair (ANSUR II /
                                        # CDC growth charts: humv_usd.human.population)

    [render]                            # render settings of every task
    spp = 16                            # omit for the render's automatic quality (IR: to NETD/3)
    frames = "0:30"                     # FIRST:LAST, a list, or omit for every frame
    frames_per_task = 4
    seed = 0
    retries = 2

    [dataset]                           # how the dataset is assembled (no re-render when changed)
    split = { train = 0.8, val = 0.1, test = 0.1 }   # fractions of the variants per split
    split_seed = 0                      # seed of the split's shuffle
    stratify = ["weapon"]               # grid axes whose options each split shares out evenly
    image = "image8"                    # training image of every export: "image8" (the sensor
                                        # chain's 8-bit image), "counts16" (16-bit radiometric
                                        # counts, infrared) or "preview" (the render's PNG)
    detect_classes = ["person", "prop", "panel", "vehicle", "other", "animal", "lamp", "hvac", "fire"]

Splits are by variant (a variant's frames are near-duplicates: a split by frame measures
training-set accuracy). Keys are dotted paths into the scenario: ``section.key`` (``general.start``), ``section.N.key``
for array sections (``human.0.clothing``, ``placement.0.heading_deg``, ``sensor.0.position_m``),
``scene.ground.key``, ``scene.object.N.key``; a trailing index selects a vector element
(``sensor.0.position_m.2``); ``+`` appends to a list (``human.0.clothing+``) or an array section
(``scene.object+``); ``-`` removes a key (``"sensor.0.position_m-" = true``, e.g. for an aerial
platform). Variant ``k`` is grid point ``k // count`` with draw ``k % count``: the random draws are
applied first, then the grid point's options (sets, then appends and removals); a drawn key an
option removed is recorded as None. Its draws use ``numpy.random.default_rng([seed, k])`` so a variant's values do not depend on the
others. ``normal`` draws are truncated to the key's allowed range (redrawn until inside).
Every variant is validated as a scenario before anything runs: a bad axis is one line naming
the axis (:func:`load_sweep` raises :class:`~humv_usd.errors.InputError`).
"""

from __future__ import annotations

import copy
import datetime as dt
import difflib
import itertools
import json
import logging
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from humv_usd.errors import InputError, bad_value, summary
from humv_usd.groundtruth.labels import CLASSES
from humv_usd.human.population import sample_person
from humv_usd.scenario.load import Scenario, read_input_bytes, validate
from humv_usd.scenario.spec import SECTIONS, Key, Section
from humv_usd.sweep.cameras import CameraSampler, apply_view, parse_camera, sample_view, with_sensor_keys

SWEEP_KEYS = ("name", "base", "unset", "count", "seed")
#: what a ``[camera]`` sampler records per variant (``camera.<name>`` in its parameters)
CAMERA_PARAMS = ("distance_m", "height_m", "azimuth_deg", "pitch_deg", "roll_deg", "person_height_px")
#: most frames ``[render] frames = "FIRST:LAST"`` may name (checked before a list is built)
MAX_FRAMES = 1_000_000
log = logging.getLogger(__name__)
#: ``[dataset]`` keys and defaults (issue 27): splits, the training image, detection classes.
DATASET_KEYS = {
    "split": {"train": 0.8, "val": 0.1, "test": 0.1},
    "split_seed": 0,
    "stratify": [],
    "image": "image8",
    # objects (hard negatives included: warm clutter, issue 30); ground, building, vegetation: stuff
    "detect_classes": ["person", "prop", "panel", "vehicle", "other", "animal", "lamp", "hvac", "fire"],
}
SPLITS = ("train", "val", "test")
IMAGE_CHOICES = ("image8", "counts16", "preview")
RENDER_KEYS = {
    "spp": None,  # the render's automatic quality (infrared: batches until the error is NETD/3)
    "frames": None,
    "frames_per_task": 4,
    "seed": 0,
    "retries": 2,
    "sensors": None,
    "annotators": None,
    "subbands": None,
}
DISTRIBUTIONS = ("uniform", "normal", "choice", "population")
#: options of a ``population`` draw (humv_usd.human.population.sample_person)
POPULATION_OPTIONS = ("age_yr", "p_male", "skin_tones")
#: hair and beard entries a population draw replaces in the person's clothing
_HAIR = ("hair_short", "hair_long", "hair_tied", "beard")
MAX_VARIANTS = 100_000


@dataclass(frozen=True)
class Axis:
    """One grid axis: ``options`` are (label, overrides) in file order."""

    name: str
    options: list[tuple[str, dict[str, Any]]]


@dataclass(frozen=True)
class Draw:
    """One random key: ``kind`` in :data:`DISTRIBUTIONS`, ``args`` its parameters."""

    key: str
    kind: str
    args: Any


@dataclass
class Variant:
    """One scenario of the sweep."""

    index: int
    id: str
    params: dict[str, Any]  # axis name / random key -> label or value
    raw: dict  # the scenario document (TOML values)
    scenario: Scenario | None = None
    render_seed: int = 0


@dataclass
class Sweep:
    name: str
    path: Path
    base_path: Path
    base: dict  # base document after [set] and unset
    axes: list[Axis]
    draws: list[Draw]
    count: int
    seed: int
    render: dict
    variants: list[Variant] = field(default_factory=list)
    #: ``[dataset]`` settings (:data:`DATASET_KEYS`); not part of :meth:`digest`: a new split or
    #: training image re-assembles the same renders
    dataset: dict = field(default_factory=lambda: copy.deepcopy(DATASET_KEYS))
    #: ``[camera]``: a sensor pose drawn per variant (:mod:`humv_usd.sweep.cameras`), or None
    camera: CameraSampler | None = None

    def digest(self) -> str:
        """Hash of what the sweep produces (variants and render settings): a dataset folder
        belongs to one sweep."""
        import hashlib

        doc = {"render": self.render, "variants": [(v.id, _plain(v.raw)) for v in self.variants]}
        return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _plain(value):
    return json.loads(
        json.dumps(value, default=lambda v: v.isoformat() if hasattr(v, "isoformat") else str(v))
    )


def _suggest(name: str, known) -> str:
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


# ------------------------------------------------------------------ dotted paths
def resolve_key(path: str, base: dict) -> tuple[Key | Section | None, str | None]:
    """The spec entry a dotted path names, and a problem text (None when it resolves).

    Returns a :class:`Key` for a key (or a vector element, as a number key), the
    :class:`Section` for an appendable array section (``scene.object+``)."""
    append = path.endswith("+")
    parts = path.removesuffix("+").removesuffix("-").split(".")
    if not parts or parts[0] not in SECTIONS:
        return (
            None,
            f"unknown section {parts[0]!r}{_suggest(parts[0], SECTIONS)}; sections: {', '.join(SECTIONS)}",
        )
    section: Section = SECTIONS[parts[0]]
    node: Any = base.get(parts[0])
    i = 1
    where = parts[0]
    while True:
        if section.array:
            if i == len(parts):  # the whole array: replaced, or with "+" extended
                return section, None
            if not parts[i].isdigit():
                return None, f"{where}: expected an index (0..), got {parts[i]!r}"
            n = len(node) if isinstance(node, list) else 0
            if int(parts[i]) >= n:
                return None, f"the base scenario has {n} [[{where}]] (indices 0..{n - 1})"
            node = node[int(parts[i])]
            where += f".{parts[i]}"
            i += 1
        if i == len(parts):
            return None, f"{where}: name a key"
        name = parts[i]
        if name in section.subsections:
            section, node = section.subsections[name], (node or {}).get(name)
            where += f".{name}"
            i += 1
            if i == len(parts) and section.array:
                return section, None
            continue
        if name not in section.keys:
            known = list(section.keys) + list(section.subsections)
            return None, f"unknown key {name!r} in {where}{_suggest(name, known)}"
        key = section.keys[name]
        rest = parts[i + 1 :]
        if not rest:
            if append and key.kind not in ("strlist", "points"):
                return None, f"'+' appends to a list; {where}.{name} is a {key.kind}"
            return key, None
        if len(rest) == 1 and rest[0].isdigit() and key.kind == "vec" and int(rest[0]) < (key.n or 0):
            kind = "int" if key.integer else "float"
            return Key(kind, key.doc, lo=key.lo, hi=key.hi, integer=key.integer), None
        return None, f"{where}.{name} has no part {'.'.join(rest)!r}"


def apply(raw: dict, path: str, value: Any) -> None:
    """Set (with a trailing ``+`` extend, with a trailing ``-`` remove) the value at a dotted path
    of a scenario document."""
    if path.endswith("-"):
        remove(raw, path.removesuffix("-"))
        return
    append = path.endswith("+")
    parts = path.removesuffix("+").split(".")
    node: Any = raw
    for part in parts[:-1]:
        if isinstance(node, list):
            node = node[int(part)]
        else:
            node = node.setdefault(part, [] if _is_array(parts, part) else {})
    last = parts[-1]
    value = copy.deepcopy(value)
    if isinstance(node, list):
        node[int(last)] = value
    elif append:
        node.setdefault(last, []).extend(value if isinstance(value, list) else [value])
    else:
        node[last] = value


def _is_array(parts: list[str], part: str) -> bool:
    i = parts.index(part)
    return i + 1 < len(parts) and parts[i + 1].isdigit()


def _present(raw: dict, path: str) -> bool:
    node: Any = raw
    for part in path.split("."):
        try:
            node = node[int(part)] if isinstance(node, list) else node[part]
        except (KeyError, IndexError, ValueError, TypeError):
            return False
    return True


def remove(raw: dict, path: str) -> None:
    parts = path.split(".")
    node: Any = raw
    for part in parts[:-1]:
        node = node[int(part)] if isinstance(node, list) else node.get(part, {})
    if isinstance(node, dict):
        node.pop(parts[-1], None)


# ------------------------------------------------------------------ loading
def _read_toml(path: Path, what: str) -> dict:
    try:
        return tomllib.loads(read_input_bytes(path, what).decode("utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: {what} not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise InputError(f"{path}: not valid TOML: nested too deeply") from None


def _check_int(where: str, value, lo: int, hi: int, problems: list[str]) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        problems.append(bad_value(where, value, f"expected an integer in {lo}..{hi}"))
        return lo
    return value


def _parse_frames(value, problems: list[str]):
    if value is None:
        return None
    if isinstance(value, int) and not isinstance(value, bool):
        return [value]
    if isinstance(value, str):
        try:
            if ":" in value:
                a, b = (int(x) for x in value.split(":", 1))
                if b - a + 1 > MAX_FRAMES:  # checked before a list is built
                    problems.append(
                        bad_value("render.frames", value, f"{b - a + 1:,} frames; at most {MAX_FRAMES:,}")
                    )
                    return None
                if b >= a >= 0:
                    return list(range(a, b + 1))
            else:
                return [int(x) for x in value.split(",") if x.strip()]
        except ValueError:
            pass
    if isinstance(value, list) and value and all(isinstance(v, int) and v >= 0 for v in value):
        return sorted(set(value))
    problems.append(bad_value("render.frames", value, "expected FIRST:LAST, a list of frames or one frame"))
    return None


def _section_table(section: str, table, defaults: dict, problems: list[str]) -> dict:
    """A copy of ``defaults`` updated by ``table`` (a sweep file section), one problem line per
    unknown key or a table that is not one."""
    out = copy.deepcopy(defaults)
    if not isinstance(table, dict):
        problems.append(bad_value(f"[{section}]", table, "expected a table"))
        return out
    for name, value in table.items():
        if name not in defaults:
            problems.append(
                f"{section}.{name}: unknown key{_suggest(name, defaults)}; allowed: {', '.join(defaults)}"
            )
            continue
        out[name] = value
    return out


def _render_settings(table, problems: list[str]) -> dict:
    out = _section_table("render", table, RENDER_KEYS, problems)
    if out["spp"] is not None:
        out["spp"] = _check_int("render.spp", out["spp"], 1, 1 << 20, problems)
    out["frames_per_task"] = _check_int(
        "render.frames_per_task", out["frames_per_task"], 1, 100_000, problems
    )
    out["seed"] = _check_int("render.seed", out["seed"], 0, 2**31 - 1, problems)
    out["retries"] = _check_int("render.retries", out["retries"], 0, 100, problems)
    if out["subbands"] is not None:
        out["subbands"] = _check_int("render.subbands", out["subbands"], 1, 64, problems)
    for name in ("sensors", "annotators"):
        v = out[name]
        if v is not None and (not isinstance(v, list) or not all(isinstance(s, str) for s in v)):
            problems.append(bad_value(f"render.{name}", v, "expected a list of names"))
    out["frames"] = _parse_frames(out["frames"], problems)
    return out


def _dataset_settings(table, problems: list[str]) -> dict:
    """``[dataset]`` checked against :data:`DATASET_KEYS` (one line per problem)."""
    out = _section_table("dataset", table, DATASET_KEYS, problems)
    split = out["split"]
    if (
        not isinstance(split, dict)
        or not split
        or not set(split) <= set(SPLITS)
        or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v <= 1 for v in split.values()
        )
        or abs(sum(split.values()) - 1.0) > 1e-6
        or not split.get("train")
    ):
        problems.append(
            bad_value(
                "dataset.split",
                split,
                "expected { train = F, val = F, test = F }: fractions in [0, 1] summing to 1, train > 0",
            )
        )
        out["split"] = dict(DATASET_KEYS["split"])
    else:
        out["split"] = {k: float(split.get(k, 0.0)) for k in SPLITS}
    out["split_seed"] = _check_int("dataset.split_seed", out["split_seed"], 0, 2**31 - 1, problems)
    if not isinstance(out["stratify"], list) or not all(isinstance(a, str) for a in out["stratify"]):
        problems.append(bad_value("dataset.stratify", out["stratify"], "expected a list of grid axis names"))
        out["stratify"] = []
    if out["image"] not in IMAGE_CHOICES:
        problems.append(bad_value("dataset.image", out["image"], f"one of {', '.join(IMAGE_CHOICES)}"))
        out["image"] = DATASET_KEYS["image"]
    classes = out["detect_classes"]
    objects = [c for c in CLASSES if c != "background"]
    if not isinstance(classes, list) or not classes or not all(c in objects for c in classes):
        problems.append(bad_value("dataset.detect_classes", classes, f"a list of {', '.join(objects)}"))
        out["detect_classes"] = list(DATASET_KEYS["detect_classes"])
    return out


def _axes(grid, problems: list[str]) -> list[Axis]:
    axes = []
    if not isinstance(grid, dict):
        problems.append(bad_value("[grid]", grid, "expected a table"))
        return axes
    for name, value in grid.items():
        if isinstance(value, list):
            if not value:
                problems.append(f"grid axis '{name}': no values")
                continue
            axes.append(Axis(name, [(_label(v), {name: v}) for v in value]))
        elif isinstance(value, dict):
            if not value or not all(isinstance(o, dict) for o in value.values()):
                problems.append(
                    f"grid axis '{name}': expected option = {{ key = value, ... }} tables, one per option"
                )
                continue
            axes.append(Axis(name, list(value.items())))
        else:
            problems.append(
                bad_value(
                    f"grid axis '{name}'", value, "expected a list of values or a table of named options"
                )
            )
    return axes


def _label(value) -> Any:
    if isinstance(value, (list, dict)):
        return json.dumps(_plain(value))
    return value.isoformat() if isinstance(value, dt.datetime) else value


def _draws(table, problems: list[str]) -> list[Draw]:
    out = []
    if not isinstance(table, dict):
        problems.append(bad_value("[random]", table, "expected a table"))
        return out
    for key, value in table.items():
        if not isinstance(value, dict) or len(value) != 1 or next(iter(value)) not in DISTRIBUTIONS:
            problems.append(
                f"random '{key}' = {value!r}: expected one of {{ uniform = [low, high] }}, "
                "{ normal = [mean, sd] }, { choice = [values...] }, { population = { age_yr = [lo, hi], "
                "p_male = 0.5, skin_tones = [...] } }"
            )
            continue
        kind, args = next(iter(value.items()))
        if kind == "population":
            _check_population(key, args, problems)
        out.append(Draw(key, kind, args))
    return out


def _check_population(key: str, args, problems: list[str]) -> None:
    """A ``population`` draw: on a person (``human.N``) with known options that the sampler takes."""
    where = f"random '{key}' population"
    parts = key.split(".")
    if len(parts) != 2 or parts[0] != "human" or not parts[1].isdigit():
        problems.append(f"{where}: draws a whole person; name one, e.g. 'human.0'")
        return
    if not isinstance(args, dict) or set(args) - set(POPULATION_OPTIONS):
        problems.append(bad_value(where, args, f"expected a table of {', '.join(POPULATION_OPTIONS)}"))
        return
    try:
        sample_person(np.random.default_rng(0), **args)
    except (TypeError, ValueError) as exc:
        problems.append(f"{where}: {exc}")


def population_values(draw: Draw, raw: dict, rng: np.random.Generator) -> dict[str, Any]:
    """Dotted keys -> values of one person drawn from the population
    (:func:`humv_usd.human.population.sample_person`; the sampled hair replaces any hair or
    beard of the base person's clothing, the rest of the clothing is kept; :func:`expand` puts the
    same hair back into an outfit that a later draw or a grid option sets)."""
    person = sample_person(rng, **(draw.args or {}))
    i = int(draw.key.split(".")[1])
    base = (raw.get("human") or [{}])[i].get("clothing") or []
    person["clothing"] = person["clothing"] + [g for g in base if g not in _HAIR]
    return {f"{draw.key}.{k}": v for k, v in person.items()}


def _check_draw(draw: Draw, key: Key, problems: list[str]) -> None:
    """Distribution parameters against the key's type and allowed range (one line naming it)."""
    where = f"random '{draw.key}'"
    if draw.kind == "choice":
        if not isinstance(draw.args, list) or not draw.args:
            problems.append(bad_value(f"{where} choice", draw.args, "expected a non-empty list of values"))
        return
    numeric = key.kind in ("float", "int", "vec")
    if key.kind == "datetime":
        ok = (
            draw.kind == "uniform"
            and isinstance(draw.args, list)
            and len(draw.args) == 2
            and all(isinstance(v, dt.datetime) and v.tzinfo is None for v in draw.args)
            and draw.args[0] <= draw.args[1]
        )
        if not ok:
            problems.append(
                bad_value(
                    f"{where} {draw.kind}",
                    _plain(draw.args),
                    "expected uniform = [earliest, latest] local date-times",
                )
            )
        return
    if not numeric:
        problems.append(f"{where}: {draw.kind} draws numbers; the key is a {key.kind} (use choice)")
        return
    n = key.n if key.kind == "vec" else None
    a, b = (draw.args + [None, None])[:2] if isinstance(draw.args, list) else (None, None)

    def vals(x):
        if n is None:
            return [x] if isinstance(x, (int, float)) and not isinstance(x, bool) else None
        return (
            x if isinstance(x, list) and len(x) == n and all(isinstance(v, (int, float)) for v in x) else None
        )

    if not isinstance(draw.args, list) or len(draw.args) != 2 or vals(a) is None or vals(b) is None:
        shape = "numbers" if n is None else f"lists of {n} numbers"
        problems.append(bad_value(f"{where} {draw.kind}", draw.args, f"expected two {shape}"))
        return
    rng_text = f"{key.lo:g}..{key.hi:g}" if key.lo is not None and key.hi is not None else "any"
    inside = lambda v: (key.lo is None or v >= key.lo) and (key.hi is None or v <= key.hi)  # noqa: E731
    if draw.kind == "uniform":
        if any(x > y for x, y in zip(vals(a), vals(b))):
            problems.append(bad_value(f"{where} uniform", draw.args, "expected [low, high] with low <= high"))
        elif not all(inside(v) for v in vals(a) + vals(b)):
            problems.append(
                bad_value(f"{where} uniform", draw.args, f"outside the key's allowed range {rng_text}")
            )
    else:  # normal: the mean inside the range, sd >= 0
        if not all(inside(v) for v in vals(a)):
            problems.append(
                bad_value(f"{where} normal mean", a, f"outside the key's allowed range {rng_text}")
            )
        if any(s < 0 or not math.isfinite(s) for s in vals(b)):
            problems.append(bad_value(f"{where} normal sd", b, "expected sd >= 0"))


def draw_value(draw: Draw, key: Key, rng: np.random.Generator):
    """One value of a random key (see the module doc)."""
    if draw.kind == "choice":
        return copy.deepcopy(draw.args[int(rng.integers(len(draw.args)))])
    if key.kind == "datetime":
        lo, hi = draw.args
        seconds = (hi - lo).total_seconds()
        return lo + dt.timedelta(seconds=round(float(rng.uniform(0.0, seconds))))
    a, b = draw.args
    vec = key.kind == "vec"
    a_arr, b_arr = np.atleast_1d(np.asarray(a, float)), np.atleast_1d(np.asarray(b, float))
    if draw.kind == "uniform":
        x = rng.uniform(a_arr, b_arr)
    else:
        lo = -np.inf if key.lo is None else key.lo
        hi = np.inf if key.hi is None else key.hi
        x = rng.normal(a_arr, b_arr)
        for _ in range(1000):  # truncated normal: redraw what fell outside the allowed range
            bad = (x < lo) | (x > hi)
            if not bad.any():
                break
            x[bad] = rng.normal(a_arr, b_arr)[bad]
        x = np.clip(x, lo, hi)
    out = [int(round(v)) if key.integer or key.kind == "int" else round(float(v), 6) for v in x]
    return out if vec else out[0]


# ------------------------------------------------------------------ expanding and validating
def load_sweep(path: str | Path) -> Sweep:
    """Read a sweep file, expand and validate every variant; InputError lists every problem."""
    path = Path(path)
    doc = _read_toml(path, "sweep file")
    problems: list[str] = []
    for section in doc:
        if section not in ("sweep", "set", "grid", "random", "render", "dataset", "camera"):
            problems.append(
                f"[{section}]: unknown section"
                f"{_suggest(section, ['sweep', 'set', 'grid', 'random', 'render', 'dataset', 'camera'])}; "
                "allowed: sweep, set, grid, random, render, dataset, camera"
            )
    head = doc.get("sweep", {})
    for name in head:
        if name not in SWEEP_KEYS:
            problems.append(
                f"sweep.{name}: unknown key{_suggest(name, SWEEP_KEYS)}; allowed: {', '.join(SWEEP_KEYS)}"
            )
    if "base" not in head or not isinstance(head.get("base"), str):
        problems.append("sweep.base: missing (the base scenario file, relative to the sweep file)")
        raise InputError("", [f"{path}: {p}" for p in problems])
    base_path = (path.resolve().parent / head["base"]).resolve()
    base = _read_toml(base_path, "base scenario (sweep.base)")
    name = head.get("name", path.stem)
    count = _check_int("sweep.count", head.get("count", 1), 1, MAX_VARIANTS, problems)
    seed = _check_int("sweep.seed", head.get("seed", 0), 0, 2**31 - 1, problems)
    render = _render_settings(doc.get("render", {}), problems)
    dataset = _dataset_settings(doc.get("dataset", {}), problems)
    unset = head.get("unset", [])
    if not isinstance(unset, list) or not all(isinstance(u, str) for u in unset):
        problems.append(bad_value("sweep.unset", unset, "expected a list of dotted keys"))
        unset = []
    for key in unset:
        spec, why = resolve_key(key, base)
        if spec is None:
            problems.append(f"sweep.unset '{key}': {why}")
        else:
            remove(base, key)
    settings = doc.get("set", {})
    for key, value in settings.items() if isinstance(settings, dict) else []:
        spec, why = resolve_key(key, base)
        if spec is None:
            problems.append(f"set '{key}': {why}")
        else:
            apply(base, key, value)
    axes = _axes(doc.get("grid", {}), problems)
    draws = _draws(doc.get("random", {}), problems)
    camera = parse_camera(doc["camera"], problems) if "camera" in doc else None
    if camera is not None and not 0 <= camera.sensor < len(base.get("sensor", [])):
        problems.append(
            bad_value(
                "camera.sensor",
                camera.sensor,
                f"expected a [[sensor]] index 0..{len(base.get('sensor', [])) - 1}",
            )
        )
    if problems:
        raise InputError("", [f"{path}: {p}" for p in problems])

    sweep = Sweep(
        name, path, base_path, base, axes, draws, count, seed, render, dataset=dataset, camera=camera
    )
    for axis in dataset["stratify"]:
        if axis not in {a.name for a in axes}:
            problems.append(
                f"dataset.stratify: {axis!r} is not a grid axis"
                f"{_suggest(axis, [a.name for a in axes])}; grid axes: {', '.join(a.name for a in axes) or 'none'}"
            )
    _check_base(sweep)
    _check_axes(sweep, problems)
    if problems:
        raise InputError("", [f"{path}: {p}" for p in problems])
    sweep.variants = expand(sweep)
    _validate_variants(sweep, problems)
    if not problems:
        _check_frames(sweep, problems)
    if problems:
        raise InputError("", [f"{path}: {p}" for p in problems])
    return sweep


def _check_frames(sweep: Sweep, problems: list[str]) -> None:
    """``[render] frames`` against the variants' frame ranges: a frame no variant has is an error
    (``frames = [0, 500]`` on a one-frame base dropped frame 500 without a word); frames that
    only some variants have (a duration axis) are rendered where they exist, with one warning."""
    frames = sweep.render["frames"]
    if not frames or not sweep.variants:
        return
    counts = [v.scenario.frame_count for v in sweep.variants]
    longest, shortest = max(counts), min(counts)
    beyond = [f for f in frames if f >= longest]
    if beyond:
        problems.append(
            f"render.frames: {summary(beyond)} beyond the frames of every variant "
            f"(0..{longest - 1}: general.duration_s x general.fps)"
        )
    elif max(frames) >= shortest:
        short = sum(1 for n in counts if n <= max(frames))
        log.warning(
            "%s: render.frames up to %d: %d of %d variant(s) have fewer frames (the shortest 0..%d) "
            "and render only the frames they have",
            sweep.path,
            max(frames),
            short,
            len(counts),
            shortest - 1,
        )


def _validate(raw: dict, sweep: Sweep) -> tuple[Scenario | None, list[str]]:
    try:
        return validate(copy.deepcopy(raw), sweep.base_path), []
    except InputError as exc:
        prefix = f"{sweep.base_path}: "
        return None, [p.removeprefix(prefix) for p in exc.problems]


def _check_base(sweep: Sweep) -> None:
    _, problems = _validate(sweep.base, sweep)
    if problems:
        raise InputError(
            "", [f"{sweep.path}: base scenario {sweep.base_path.name} (after [set]): {p}" for p in problems]
        )


def _check_axes(sweep: Sweep, problems: list[str]) -> None:
    """Each axis key resolves; each option, applied alone to the base, gives a valid scenario;
    each random key's parameters fit its allowed range."""
    for axis in sweep.axes:
        for label, overrides in axis.options:
            bad = False
            for key in overrides:
                spec, why = resolve_key(key, sweep.base)
                if spec is None:
                    problems.append(f"grid axis '{axis.name}' key '{key}': {why}")
                    bad = True
            if bad:
                break
            raw = copy.deepcopy(sweep.base)
            for key, value in overrides.items():
                apply(raw, key, value)
            _, found = _validate(raw, sweep)
            problems.extend(f"grid axis '{axis.name}' = {_label(label)!s}: {p}" for p in found)
    for draw in sweep.draws:
        if draw.kind == "population":
            n = len(sweep.base.get("human") or [])
            if int(draw.key.split(".")[1]) >= n:
                problems.append(f"random '{draw.key}': the base scenario has {n} [[human]]")
            continue
        spec, why = resolve_key(draw.key, sweep.base)
        if spec is None or not isinstance(spec, Key):
            problems.append(f"random '{draw.key}': {why or 'expected a key'}")
            continue
        _check_draw(draw, spec, problems)
        if draw.kind == "choice" and isinstance(draw.args, list):
            for value in draw.args:
                raw = copy.deepcopy(sweep.base)
                apply(raw, draw.key, value)
                _, found = _validate(raw, sweep)
                problems.extend(f"random '{draw.key}' choice {_label(value)!s}: {p}" for p in found)


def grid_size(sweep: Sweep) -> int:
    return math.prod(len(a.options) for a in sweep.axes) if sweep.axes else 1


def expand(sweep: Sweep) -> list[Variant]:
    """Every variant: each grid point × ``count`` draws (see the module doc)."""
    total = grid_size(sweep) * sweep.count
    if total > MAX_VARIANTS:
        raise InputError(
            f"{sweep.path}: {total} variants (grid {grid_size(sweep)} x count {sweep.count}); at most {MAX_VARIANTS}"
        )
    keys = {d.key: resolve_key(d.key, sweep.base)[0] for d in sweep.draws if d.kind != "population"}
    width = max(4, len(str(total - 1)))
    variants = []
    points = itertools.product(*[a.options for a in sweep.axes]) if sweep.axes else [()]
    for g, point in enumerate(points):
        for j in range(sweep.count):
            k = g * sweep.count + j
            raw = copy.deepcopy(sweep.base)
            params: dict[str, Any] = {axis.name: _label(label) for axis, (label, _) in zip(sweep.axes, point)}
            rng = np.random.default_rng([sweep.seed, k])
            drawn, hair_of = {}, {}
            for draw in sweep.draws:  # first: a grid option may set or remove a drawn key
                values = (
                    population_values(draw, raw, rng)
                    if draw.kind == "population"
                    else {draw.key: draw_value(draw, keys[draw.key], rng)}
                )
                if draw.kind == "population":
                    hair_of[draw.key] = [g for g in values[f"{draw.key}.clothing"] if g in _HAIR]
                for key, value in values.items():
                    drawn[key] = value
                    apply(raw, key, value)
            later = []
            for _, overrides in point:
                for key, value in overrides.items():
                    if key.endswith(("+", "-")):
                        later.append((key, value))
                    else:
                        apply(raw, key, value)
            for key, value in later:  # appends and removals after every set: axis order does not matter
                apply(raw, key, value)
            for key, hair in hair_of.items():  # a drawn person keeps their hair under any outfit
                person = raw["human"][int(key.split(".")[1])]
                if person.get("clothing") is not None:
                    person["clothing"] = hair + [g for g in person["clothing"] if g not in _HAIR]
                    drawn[f"{key}.clothing"] = person["clothing"]
            for key, value in drawn.items():
                params[key] = _label(value) if _present(raw, key) else None
            if sweep.camera is not None:  # last: the pose fits the variant's person and sensor
                raw = _sample_camera(sweep, raw, k, params)
            seed = (sweep.render["seed"] + 1_000_003 * k) % 2**31
            variants.append(Variant(k, f"v{k:0{width}d}", params, raw, render_seed=seed))
    return variants


def _sample_camera(sweep: Sweep, raw: dict, k: int, params: dict) -> dict:
    """The variant ``raw`` with the ``[camera]`` pose drawn (``default_rng([seed, k, 28])``); its
    values go into ``params`` as ``camera.<name>``. A variant that is not a valid scenario is left
    for :func:`_validate_variants` to report."""
    raw = with_sensor_keys(raw, sweep.camera)
    scenario, found = _validate(raw, sweep)
    if found:
        return raw
    try:
        view = sample_view(sweep.camera, scenario, np.random.default_rng([sweep.seed, k, 28]))
    except InputError as exc:
        raise InputError(f"{sweep.path}: variant {k}: {exc}") from None
    apply_view(raw, sweep.camera, view)
    params.update({f"camera.{name}": view[name] for name in CAMERA_PARAMS})
    return raw


def _validate_variants(sweep: Sweep, problems: list[str], limit: int = 20) -> None:
    bad = 0
    for v in sweep.variants:
        v.scenario, found = _validate(v.raw, sweep)
        if found:
            bad += 1
            if bad <= limit:
                where = ", ".join(f"{k}={val}" for k, val in v.params.items())
                problems.extend(f"variant {v.id} ({where}): {p}" for p in found)
    if bad > limit:
        problems.append(f"... and {bad - limit} more invalid variants")
