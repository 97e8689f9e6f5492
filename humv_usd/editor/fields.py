"""Form fields from the scenario spec (:mod:`humv_usd.scenario.spec`), the one source of truth.

Every key of every section becomes a :class:`Field` with the name the command line uses in its
messages (``sensor[0].netd_k``), its unit, range, default and help text. Nothing here names a
particular key: a key or section added to the spec appears in the editor as it is.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from typing import Any

import tomlkit

from humv_usd.catalog.sensors import PRESETS, scenario_values
from humv_usd.errors import bad_value
from humv_usd.scenario.spec import SECTIONS, SENSOR_PRESET_KEYS, Key, Section

#: unit by key-name suffix, for keys whose help text has no bracketed unit
_SUFFIX_UNITS = (
    ("_m_s", "m/s"),
    ("_um", "µm"),
    ("_mm", "mm"),
    ("_deg", "deg"),
    ("_kg", "kg"),
    ("_yr", "years"),
    ("_pa", "Pa"),
    ("_km", "km"),
    ("_k", "K"),
    ("_s", "s"),
    ("_h", "h"),
    ("_e", "electrons"),
    ("_m", "m"),
)
_BRACKET = re.compile(r"\[([^\[\],]+)\]")


def unit_of(name: str, key: Key) -> str:
    """The unit of a key: the last bracketed word of its help text (``[m]``), else its suffix."""
    found = [u.strip() for u in _BRACKET.findall(key.doc) if not u.strip().startswith(("%", "x "))]
    if found:
        return found[-1]
    if "[%]" in key.doc:
        return "%"
    for suffix, unit in _SUFFIX_UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def range_text(key: Key) -> str:
    """Allowed values as the help line shows them: ``lo..hi``, the choices, or ''."""
    if key.choices:
        return ", ".join(key.choices)
    if key.lo is None and key.hi is None:
        return ""
    lo = int(key.lo) if key.integer and key.lo is not None else key.lo
    hi = int(key.hi) if key.integer and key.hi is not None else key.hi
    text = f"{lo}..{hi}"
    if key.kind == "vec":
        return f"{key.n} values, each {text}"
    if key.kind == "points":
        return f"points of {key.n}, each {text}"
    return text


def value_text(key: Key, value: Any) -> str:
    """The text a field shows for a TOML value (strings bare, everything else as TOML)."""
    if value is None:
        return ""
    if key.kind in ("str", "path", "choice") and isinstance(value, str):
        return value
    if isinstance(value, dict):
        inline = tomlkit.inline_table()
        inline.update(value)
        return inline.as_string().strip()
    return tomlkit.item(value).as_string()


def parse_text(where: str, key: Key, text: str) -> tuple[Any, str | None]:
    """A field's text → (value, problem). Empty text means the key is left out (its default)."""
    text = text.strip() if key.kind not in ("str",) else text
    if text == "":
        return None, None
    if key.kind in ("str", "path", "choice"):
        return text, None
    try:
        return tomllib.loads(f"v = {text}")["v"], None
    except tomllib.TOMLDecodeError as exc:
        reason = str(exc).split(" (at", 1)[0]
        return None, bad_value(where, text, f"not a TOML value ({reason}); e.g. {_example(key)}")


def _example(key: Key) -> str:
    if key.kind == "vec":
        return "[" + ", ".join(["0"] * (key.n or 2)) + "]"
    if key.kind == "points":
        return "[[0, 0], [1, 2]]"
    if key.kind == "strlist":
        return '["a", "b"]'
    if key.kind == "datetime":
        return "2018-10-24T14:05:00"
    return "1" if key.integer or key.kind == "int" else "1.5"


@dataclass(frozen=True)
class Field:
    """One key of one table: where it is (CLI name and document path) and what it allows."""

    where: str  # as the command line names it: "sensor[0].netd_k", "scene.ground.material"
    path: tuple  # into the TOML document: ("sensor", 0, "netd_k")
    name: str
    key: Key

    @property
    def unit(self) -> str:
        return unit_of(self.name, self.key)

    @property
    def allowed(self) -> str:
        return range_text(self.key)

    @property
    def default_text(self) -> str:
        if self.key.required:
            return "required"
        if self.key.default is None or self.key.default == []:
            return "(none)" if self.key.default is None else "[]"
        return value_text(self.key, self.key.default)

    @property
    def help(self) -> str:
        parts = [self.key.doc]
        if self.allowed:
            parts.append(f"Allowed: {self.allowed}.")
        parts.append(f"Default: {self.default_text}.")
        return " ".join(parts)


@dataclass
class Group:
    """One table of the document (a section, a subsection, or one element of an array of tables)."""

    where: str
    path: tuple
    section: Section
    fields: list[Field]
    index: int | None  # position in its array of tables, None for a plain table
    title: str


@dataclass
class ArraySlot:
    """An array of tables a user can add an element to (``[[sensor]]``, ``[[scene.object]]``)."""

    where: str
    path: tuple
    section: Section
    count: int


def _groups(raw: dict, where: str, path: tuple, section: Section, out: list, slots: list) -> None:
    if section.array:
        items = raw if isinstance(raw, list) else []
        slots.append(ArraySlot(where, path, section, len(items)))
        for i, table in enumerate(items):
            _table(
                table if isinstance(table, dict) else {}, f"{where}[{i}]", path + (i,), section, i, out, slots
            )
    else:
        _table(raw if isinstance(raw, dict) else {}, where, path, section, None, out, slots)


def _table(table: dict, where: str, path: tuple, section: Section, index, out: list, slots: list) -> None:
    fields = [Field(f"{where}.{n}", path + (n,), n, k) for n, k in section.keys.items()]
    ident = table.get("id") or table.get("human")
    title = where if index is None else f"{where}  {ident}" if isinstance(ident, str) else where
    out.append(Group(where, path, section, fields, index, title))
    for name, sub in section.subsections.items():
        _groups(table.get(name), f"{where}.{name}", path + (name,), sub, out, slots)


def section_groups(raw: dict, name: str) -> tuple[list[Group], list[ArraySlot]]:
    """The tables of one top-level section of a parsed document (every key, given or not) and
    the arrays of tables in it (to add elements to)."""
    out: list[Group] = []
    slots: list[ArraySlot] = []
    _groups(raw.get(name), name, (name,), SECTIONS[name], out, slots)
    return out, slots


def all_fields(raw: dict) -> list[Field]:
    """Every field of the document, in spec order."""
    return [f for name in SECTIONS for g in section_groups(raw, name)[0] for f in g.fields]


@dataclass(frozen=True)
class ValueSource:
    """Where the value a sensor field stands for comes from, as the Sensor tab shows it.

    ``kind``: ``"user"`` (the table gives it), ``"preset"`` (the table leaves it out and the
    preset's value is used), ``"computed"`` (left out and not the preset's: the band's edges for
    another band than the preset's, the NETD scaled to another f-number, the fallback).
    """

    kind: str
    text: str  # the value the run uses, as the field would show it ('' when not known)
    preset: str | None  # the table's preset, if any
    preset_text: str | None  # the preset's value of this key, if it has one

    @property
    def note(self) -> str:
        """One line under the field: whose value it is."""
        if self.kind == "user":
            if self.preset_text is None:
                return "your value"
            return f"your value (preset {self.preset}: {self.preset_text})"
        if self.kind == "preset":
            return f"from preset {self.preset}: {self.text}"
        return f"computed: {self.text}" + (
            f" (preset {self.preset}: {self.preset_text})" if self.preset_text else ""
        )


def value_source(raw: dict, filled, f: Field) -> ValueSource | None:
    """The source of a ``[[sensor]]`` key a preset can fill (``SENSOR_PRESET_KEYS``), None for
    any other field or a table without a (known) preset.

    Parameters
    ----------
    raw : dict
        The document as written.
    filled : Scenario or None
        The same, validated (the values the run uses), or None while it has problems (then the
        preset's own values are shown).
    f : Field
        The field.
    """
    if len(f.path) != 3 or f.path[0] != "sensor" or f.name not in SENSOR_PRESET_KEYS:
        return None
    tables = raw.get("sensor")
    i = f.path[1]
    if not isinstance(tables, list) or not isinstance(i, int) or i >= len(tables):
        return None
    table = tables[i] if isinstance(tables[i], dict) else {}
    preset = table.get("preset")
    if not isinstance(preset, str) or preset not in PRESETS:
        return None
    preset_value = scenario_values(preset).get(f.name)
    preset_text = None if preset_value is None else value_text(f.key, preset_value)
    given = table.get(f.name)
    if given is not None:
        return ValueSource("user", value_text(f.key, given), preset, preset_text)
    used = preset_value
    sensors = filled["sensor"] if filled is not None else None
    if sensors is not None and i < len(sensors):
        used = sensors[i].get(f.name)
    if used == preset_value and used is not None:
        return ValueSource("preset", preset_text, preset, preset_text)
    return ValueSource("computed", value_text(f.key, used), preset, preset_text)
