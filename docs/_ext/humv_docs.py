"""Reference pages of the manual, generated from the project's single sources at build time.

Each ``*_rst`` function returns reStructuredText built from one source, so the manual cannot
drift from the code:

- :func:`scenario_rst`: every scenario key of ``humv_usd/scenario/spec.py`` (type, unit, range,
  default, help and an example value from ``examples/*.toml`` when one sets it);
- :func:`materials_rst`, :func:`garments_rst`, :func:`sensors_rst` (with the dataset viewpoints):
  the catalogues of ``humv_usd/catalog/`` as tables, with each entry's sources;
- :func:`activities_rst`: every activity with its motion, speeds, metabolic rate and source;
- :func:`schemas_rst`: every attribute of the codeless USD schemas (``schemas/generatedSchema.usda``)
  with its type, default, unit and range (taken from the ``Units: … Range: …`` end of its doc).

The CLI reference is sphinx-click's ``click`` directive on ``humv_usd.cli.main:main``.
As a Sphinx extension, the module adds the directive ``.. humv-reference:: NAME`` (NAME one of
:data:`GENERATORS`) and the object types ``scenario-key`` / ``schema-attr`` (roles ``:key:`` and
``:attr:``-like ``:usdattr:``), so a page can link ``:key:`human.clothing``` and a broken link
fails the nitpicky build. ``tests/test_docs.py`` checks the generated text names every key,
command and attribute.
"""

from __future__ import annotations

import inspect
import json
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: key name suffix -> unit, for keys whose help gives none in brackets
SUFFIX_UNITS = {
    "_m": "m",
    "_mm": "mm",
    "_um": "µm",
    "_k": "K",
    "_deg": "deg",
    "_s": "s",
    "_h": "h",
    "_kg": "kg",
    "_yr": "yr",
    "_pa": "Pa",
    "_km": "km",
    "_m_s": "m/s",
    "_e": "electrons",
    "_k_per_s": "K/s",
}


# ---------------------------------------------------------------------------------------- text
def _escape(text: str) -> str:
    """Plain text -> reStructuredText: backslashes, ``*``, ``_``, ``|`` and ``<`` escaped."""
    return re.sub(r"([\\*_|`<>])", r"\\\1", text)


def inline(text: str) -> str:
    """Help text with Markdown-style `code` spans -> reStructuredText (code as literals, the
    rest escaped), on one line."""
    text = " ".join(str(text).split())
    parts = re.split(r"``?([^`]+?)``?", text)
    out = []
    for i, part in enumerate(parts):
        if i % 2:
            out.append(f"``{part.strip()}``" if part.strip() else "")
        else:
            out.append(_escape(part))
    text = "".join(out)
    # a leading "(i)", "2.", "- ", ".. [1]", ":field:", ">>>" or a rule of punctuation would start
    # a list, an explicit markup block, a field list, a doctest or a transition
    block_start = r"\(?\w{1,4}[.)] |[-+*] |#\. |\.\.|:|>>>|[=~^\-]{4,}$"
    return "\\" + text if re.match(block_start, text) else text


def _literal(value) -> str:
    text = str(value)
    return f"``{text}``" if text.strip() else '``""``'


def _heading(title: str, char: str) -> list[str]:
    return [title, char * len(title), ""]


def _table(header: list[str], rows: list[list[str]], widths: list[int] | None = None) -> list[str]:
    """A ``list-table`` (cells already reStructuredText, one line each)."""
    out = [".. list-table::", "   :header-rows: 1"]
    if widths:
        out.append(f"   :widths: {' '.join(str(w) for w in widths)}")
    out.append("")
    for row in [header, *rows]:
        for j, cell in enumerate(row):
            out.append(f"   {'*' if j == 0 else ' '} - {cell if str(cell).strip() else ' '}")
    out.append("")
    return out


def facts(fields: list[tuple[str, str]]) -> str:
    """``(label, value)`` pairs -> one line "**label** value · ..." (empty values left out; a
    label without a value stands alone, e.g. **required**)."""
    parts = [f"**{label}** {value}".strip() for label, value in fields if value or label == "required"]
    return " · ".join(parts)


def _number(x) -> str:
    if isinstance(x, float):
        if x == int(x) and abs(x) < 1e7:
            return str(int(x))
        return f"{x:g}"
    return str(x)


# ------------------------------------------------------------------------------------ scenario
def scenario_keys() -> dict[str, object]:
    """Every scenario key by dotted path (``general.name``, ``scene.asset.scale``) -> its Key."""
    from humv_usd.scenario.spec import SECTIONS

    keys = {}

    def walk(prefix, section):
        for name, key in section.keys.items():
            keys[f"{prefix}.{name}"] = key
        for sub_name, sub in section.subsections.items():
            walk(f"{prefix}.{sub_name}", sub)

    for name, section in SECTIONS.items():
        walk(name, section)
    return keys


def key_unit(name: str, key) -> str:
    """The unit of a key: the last ``[...]`` of its help without a comma (not a ``[[table]]``),
    else its name's suffix, else ''."""
    groups = [g for g in re.findall(r"(?<!\[)\[([^\]\[]*)\](?!\])", key.doc) if "," not in g and g.strip()]
    if groups:
        unit = groups[-1].strip()
        return "fraction" if re.fullmatch(r"0\s*-\s*1", unit) else unit
    for suffix in sorted(SUFFIX_UNITS, key=len, reverse=True):
        if name.endswith(suffix):
            return SUFFIX_UNITS[suffix]
    return ""


def key_range(key) -> str:
    if key.choices:
        return ", ".join(_literal(c) for c in key.choices)
    if key.lo is not None or key.hi is not None:
        lo = "−∞" if key.lo is None else _number(key.lo)
        hi = "∞" if key.hi is None else _number(key.hi)
        each = " (each element)" if key.kind in ("vec", "points") else ""
        return f"{lo} … {hi}{each}"
    return ""


def key_type(key) -> str:
    kind = key.kind
    if kind == "vec" and key.n:
        return f"vector of {key.n}"
    if kind == "points" and key.n:
        return f"list of {key.n}-vectors"
    return {
        "strlist": "list of strings",
        "pathlist": "list of paths",
        "map": "table pattern → value",
        "int": "integer",
        "str": "string",
        "datetime": "local date-time",
    }.get(kind, kind)


def key_default(key) -> str:
    if key.required:
        return "required"
    if key.default is None:
        return "(none)"
    value = key.default
    if isinstance(value, float):
        return _literal(_number(value))
    if isinstance(value, list):
        return _literal(_toml_value(value))
    return _literal(value)


def example_values() -> dict[str, tuple[str, object]]:
    """Dotted key -> (example file, value) for the keys the files in ``examples/`` set (the first
    file in name order that sets a key gives its example)."""
    found: dict[str, tuple[str, object]] = {}

    def walk(prefix, table, file):
        for name, value in table.items():
            path = f"{prefix}.{name}" if prefix else name
            if isinstance(value, dict):
                walk(path, value, file)
            elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
                for v in value:
                    walk(path, v, file)
            else:
                found.setdefault(path, (file, value))

    for path in sorted((ROOT / "examples").glob("*.toml")):
        try:
            data = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError):
            continue
        walk("", data, path.name)
    return found


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f'"{k}" = {_toml_value(v)}' for k, v in value.items()) + " }"
    return str(value).replace(" ", "T") if hasattr(value, "isoformat") else str(value)


def scenario_rst() -> str:
    from humv_usd.scenario.spec import SECTIONS

    examples = example_values()
    out = [
        "Every key of a scenario file, generated from ``humv_usd/scenario/spec.py`` (the same table "
        "validates a scenario and builds the editor's forms). A key's *example* is the value the "
        "first file of ``examples/`` that sets it gives it. Units are part of the key names; "
        "a value outside its range is refused by ``humv-usd compose`` (one line naming the key, "
        "the value and the range; exit code 2).",
        "",
    ]

    def section(prefix, sec, title, level):
        form = f"[[{prefix}]]" if sec.array else f"[{prefix}]"
        out.extend(_heading(f"{form}", level))
        what = []
        if sec.doc:
            what.append(inline(sec.doc.strip().rstrip(".")) + ".")
        what.append("A list of tables (repeat the header per entry)." if sec.array else "One table.")
        what.append("Required." if sec.required else "Optional.")
        out.extend([" ".join(what), ""])
        for name, key in sec.keys.items():
            dotted = f"{prefix}.{name}"
            out.append(f".. scenario-key:: {dotted}")
            out.append("")
            fields = [
                ("type", key_type(key)),
                ("unit", inline(key_unit(name, key))),
                ("range", key_range(key)),
                ("default", key_default(key)) if not key.required else ("required", ""),
            ]
            if dotted in examples:
                file, value = examples[dotted]
                fields.append(("example", f"``{name} = {_toml_value(value)}`` ({file})"))
            out.extend([f"   {facts(fields)}", "", f"   {inline(key.doc)}", ""])
        for sub_name, sub in sec.subsections.items():
            section(f"{prefix}.{sub_name}", sub, sub_name, "^")

    for name, sec in SECTIONS.items():
        section(name, sec, name, "-")
    return "\n".join(out)


# ---------------------------------------------------------------------------------- catalogues
def materials_rst() -> str:
    from humv_usd.catalog import materials as m

    out = [
        "The material library of ``humv_usd/catalog/materials.py`` (written to "
        "``layers/materials.usda`` by the materials tool). Emissivities are the spectra's values "
        "(Kirchhoff: ε = 1 − R − T) at the wavelength shown; solar absorptivity is the library's "
        "broadband value. Each entry's sources follow the table.",
        "",
    ]
    from humv_usd.catalog.garments import GARMENTS

    worn = {g.fabric for g in GARMENTS.values()} | set(m.FABRICS) | set(m.EQUIPMENT)
    groups = (
        ("Skin and scene surfaces", {k: v for k, v in m.LIBRARY.items() if k not in worn}),
        ("Fabrics and equipment", {k: v for k, v in m.LIBRARY.items() if k in worn}),
    )
    for title, group in groups:
        out.extend(_heading(title, "-"))
        rows = []
        for name, mat in group.items():
            eps = mat.at([0.55, 4.0, 10.0], "emissivity")
            rows.append(
                [
                    f"``{name}``",
                    mat.label_class,
                    f"{mat.conductivity:g}",
                    f"{mat.density:g}",
                    f"{mat.specific_heat:g}",
                    f"{mat.thickness * 1000:g}",
                    f"{mat.solar_absorptivity:.2f}",
                    f"{eps[0]:.2f} / {eps[1]:.2f} / {eps[2]:.2f}",
                    "opaque" if mat.opaque else "transmits",
                ]
            )
        out.extend(
            _table(
                [
                    "material",
                    "label class",
                    "k [W m⁻¹ K⁻¹]",
                    "ρ [kg m⁻³]",
                    "c [J kg⁻¹ K⁻¹]",
                    "thickness [mm]",
                    "solar abs.",
                    "ε at 0.55 / 4 / 10 µm",
                    "",
                ],
                rows,
            )
        )
        out.extend(_heading(f"Sources: {title.lower()}", "^"))
        for name, mat in group.items():
            out.extend([f"``{name}``", f"   {inline(mat.source)}", ""])
    return "\n".join(out)


def garments_rst() -> str:
    from humv_usd.catalog import garments as g
    from humv_usd.catalog.materials import LIBRARY

    out = [
        "The garments and props of ``humv_usd/catalog/garments.py`` (the names "
        ":key:`human.clothing` takes). Layer 0 is next to the skin; a higher layer goes over a "
        "lower one. Fabrics are entries of the :doc:`material library <materials>`.",
        "",
    ]
    rows = []
    for name, gar in g.GARMENTS.items():
        fabric = gar.fabric
        rows.append(
            [
                f"``{name}``",
                inline(gar.description),
                f"``{fabric}``" if fabric in LIBRARY else inline(fabric),
                str(gar.layer),
                "prop" if gar.is_prop else f"{gar.ease * 1000:g}",
                f"{gar.thickness * 1000:g}",
            ]
        )
    out.extend(
        _table(
            ["garment", "description", "fabric", "layer", "ease [mm]", "thickness [mm]"],
            rows,
            [14, 46, 14, 6, 10, 10],
        )
    )
    if g.ALIASES:
        out.extend(_heading("Aliases", "-"))
        out.extend(_table(["alias", "garment"], [[f"``{a}``", f"``{b}``"] for a, b in g.ALIASES.items()]))
    out.extend(_heading("Outfits of the seed's Table 1", "-"))
    out.extend(
        _table(
            ["outfit", "garments"],
            [[f"``{k}``", ", ".join(f"``{x}``" for x in v)] for k, v in g.OUTFITS.items()],
        )
    )
    return "\n".join(out)


def sensors_rst() -> str:
    from humv_usd.catalog import sensors as s

    out = [
        "The sensor presets of ``humv_usd/catalog/sensors.py``: a ``[[sensor]]`` table with "
        ":key:`sensor.preset` takes every value below unless the table sets it. Values its source "
        "calls *typical* represent the class of camera, not one product's data sheet.",
        "",
    ]
    rows = []
    for name, p in s.PRESETS.items():
        hfov, vfov = p.fov_deg
        rows.append(
            [
                f"``{name}``",
                p.band,
                f"{p.wavelength_um[0]:g}–{p.wavelength_um[1]:g}",
                f"{p.resolution[0]}×{p.resolution[1]}",
                f"{p.pixel_pitch_um:g}",
                f"{p.focal_length_mm:g}",
                f"{p.f_number:g}",
                f"{hfov:.1f}×{vfov:.1f}",
                f"{p.netd_k * 1000:g}" if p.netd_k else "–",
                str(p.bit_depth),
                p.agc,
            ]
        )
    out.extend(
        _table(
            [
                "preset",
                "band",
                "λ [µm]",
                "pixels",
                "pitch [µm]",
                "focal [mm]",
                "f/#",
                "FOV [deg]",
                "NETD [mK]",
                "bits",
                "AGC",
            ],
            rows,
        )
    )
    out.extend(_heading("Descriptions and sources", "-"))
    for name, p in s.PRESETS.items():
        out.extend([f"``{name}``", f"   {inline(p.description)}. Source: {inline(p.source)}", ""])
    out.extend(viewpoints_rst())
    out.extend(_heading("Platforms", "-"))
    out.extend(
        [
            "Where a sensor stands (:key:`sensor.platform`): "
            + ", ".join(f"``{x}``" for x in s.PLATFORMS)
            + ".",
            "",
        ]
    )
    return "\n".join(out)


def _draw(d) -> str:
    """A viewpoint distribution ``("uniform", lo, hi)`` / ``("normal", mean, sd[, (lo, hi)])`` /
    ``("fixed", v)`` / None as text."""
    if d is None:
        return "aimed at the person"
    kind, *a = d
    if kind == "uniform":
        return f"uniform [{_number(a[0])}, {_number(a[1])}]"
    if kind == "normal":
        cut = f" in [{_number(a[2][0])}, {_number(a[2][1])}]" if len(a) > 2 else ""
        return f"normal({_number(a[0])}, sd {_number(a[1])}){cut}"
    return " ".join(_number(x) if isinstance(x, (int, float)) else str(x) for x in a)


def viewpoints_rst() -> list[str]:
    """The dataset viewpoint presets of ``humv_usd/catalog/viewpoints.py`` (a sweep's
    ``[camera] preset``): the geometry each draws, the camera preset it uses, and what the
    dataset publishes about its people's sizes, with the sources."""
    from humv_usd.catalog.viewpoints import VIEWPOINTS

    out = _heading("Dataset viewpoints", "-")
    out.extend(
        [
            "The camera poses a sweep file's ``[camera]`` table draws with ``preset = NAME`` "
            "(``humv_usd/catalog/viewpoints.py``; see :doc:`../user/cameras`). Distances and "
            "heights in m, angles in deg; ``python -m humv_usd.bench.viewpoints`` compares the "
            "drawn person sizes with the published ones.",
            "",
        ]
    )
    rows = []
    for name, v in VIEWPOINTS.items():
        rows.append(
            [
                f"``{name}``",
                ", ".join(
                    f"``{val}``"
                    if key == "preset"
                    else f"{key} {_number(val) if not isinstance(val, list) else '×'.join(map(str, val))}"
                    for key, val in v.sensor.items()
                ),
                _draw(v.distance_m) if v.distance_m else "from the pitch",
                _draw(v.height_m),
                _draw(v.pitch_deg),
                _draw(v.azimuth_deg),
                _number(v.min_height_px),
            ]
        )
    out.extend(
        _table(["viewpoint", "camera", "distance", "height", "pitch", "azimuth", "min. person [px]"], rows)
    )
    for name, v in VIEWPOINTS.items():
        out.extend(
            [
                f"``{name}``",
                f"   {inline(v.description)}. Published person sizes: {inline(v.published_height_px)}. "
                f"Source: {inline(v.source)}",
                "",
            ]
        )
    return out


# ------------------------------------------------------------------------------------ activities
def activities_rst() -> str:
    """Every :key:`human.activity` (``humv_usd/human/motion.py`` ``ACTIVITIES``) with its motion
    model, speeds and metabolic rate, the numbers read from ``motion.py`` and ``poses.py``."""
    from humv_usd.human import motion as M
    from humv_usd.human import poses as P

    compendium = "Ainsworth et al. 2011, Compendium of Physical Activities, Med Sci Sports Exerc 43:1575-1581"
    acsm = "ACSM's Guidelines for Exercise Testing and Prescription, 10th ed., 2018, ch. 6"
    out = [
        "The activities of :key:`human.activity`, generated from ``humv_usd/human/motion.py`` "
        "(``ACTIVITIES``, speeds, rates) and ``humv_usd/human/poses.py`` (key-pose sequences and "
        "their MET). The models and their sources are on :doc:`../physics/motion`; the metabolic "
        "rate drives the thermal model (1 MET = "
        f"{_number(M.MET_ML_KG_MIN)} mL O2/kg/min).",
        "",
    ]
    rows = []
    for a in M.ACTIVITIES:
        speed = ""
        if a in M.SPEED_RANGE:
            lo, hi = M.SPEED_RANGE[a]
            speed = f"{_number(M.DEFAULT_SPEED[a])} ({_number(lo)}–{_number(hi)})"
        if a in ("walk", "run"):
            motion, rate, src = (
                "gait cycle, feet planted on the ground",
                "ACSM VO2 equation of the speed and grade",
                acsm,
            )
        elif a == "carry":
            motion, rate, src = "the walk, both hands holding a box in front", "the walk's", acsm
        elif a == "stand":
            motion, rate, src = "feet planted, sway and breathing", f"{_number(M.MET_STAND)} MET", compendium
        elif a == "standTurn":
            motion = "standing, stepping round a turn"
            rate, src = (
                f"{_number(M.MET_STAND)} MET, {_number(M.MET_STEPPING)} MET while stepping",
                compendium,
            )
        elif a == "postExercise":
            met = inspect.signature(M.make_motion).parameters["exercise_met"].default
            motion = f"standing after exercise at {_number(met)} MET"
            taus = ", ".join(f"{_number(f)} × e^(−t/{_number(tau)} s)" for f, tau in M.EPOC)
            rate = f"decays to {_number(M.MET_STAND)} MET: excess × ({taus})"
            src = "Ozyener et al. 2001, J Physiol 533:891-902; Borsheim & Bahr 2003, Sports Med 33:1037-1060"
        else:
            keys = P.SEQUENCES[a]
            motion = "key poses: " + " → ".join(
                f"{k.name} ({_number(d)} s)" if d else k.name for k, d in keys
            )
            held = P.MET_POSE.get(keys[-1][0].name, P.MET_TRANSITION)
            rate = f"{_number(held)} MET held, {_number(P.MET_TRANSITION)} MET in transitions"
            src = compendium
        rows.append([f"``{a}``", motion, speed or "–", rate, src])  # plain text written here
    out.extend(
        _table(["activity", "motion", "speed [m/s] default (range)", "metabolic rate", "source"], rows)
    )
    return "\n".join(out)


# ------------------------------------------------------------------------------------- schemas
_UNITS_RANGE = re.compile(r"Units:\s*(?P<unit>.+?)\.\s*Range:\s*(?P<range>.+?)\.?\s*$", re.S)


def schema_classes() -> dict[str, dict]:
    """Schema class -> {"doc", "attributes": {name: {"type", "default", "unit", "range", "doc"}}}
    from ``schemas/generatedSchema.usda``."""
    from pxr import Sdf

    layer = Sdf.Layer.OpenAsAnonymous(str(ROOT / "schemas" / "generatedSchema.usda"))
    classes = {}
    for prim in layer.rootPrims:
        attrs = {}
        for prop in prim.properties:
            doc = " ".join((prop.documentation or "").split())
            m = _UNITS_RANGE.search(doc)
            attrs[prop.name] = {
                "type": str(getattr(prop, "typeName", "")),
                "default": getattr(prop, "default", None),
                "unit": m.group("unit") if m else "",
                "range": m.group("range") if m else "",
                "doc": doc[: m.start()].strip() if m else doc,
                "tokens": list(prop.GetInfo("allowedTokens")) if prop.HasInfo("allowedTokens") else [],
            }
        classes[prim.name] = {"doc": " ".join((prim.documentation or "").split()), "attributes": attrs}
    return classes


def schemas_rst() -> str:
    out = [
        "Every attribute of the HumV codeless schemas, generated from "
        "``schemas/generatedSchema.usda`` (made from ``schemas/schema.usda`` by ``make schemas``). "
        "Units and ranges are the ones each attribute's documentation states. All are API schemas "
        "(``prim.ApplyAPI``); :doc:`../user/usd-tools` shows how other USD tools load them.",
        "",
    ]
    for cls, info in schema_classes().items():
        out.extend(_heading(cls, "-"))
        out.extend([inline(info["doc"]), ""])
        for name, a in info["attributes"].items():
            out.append(f".. schema-attr:: {name}")
            out.append("")
            fields = [
                ("type", f"``{a['type']}``"),
                ("unit", inline(a["unit"])),
                ("range", inline(a["range"])),
                ("default", _literal(a["default"]) if a["default"] is not None else ""),
            ]
            out.extend([f"   {facts(fields)}", "", f"   {inline(a['doc'])}", ""])
    return "\n".join(out)


# ------------------------------------------------------------------------------ physics pages
_ROLE = re.compile(r":(?:py:)?(?:mod|func|class|data|meth|attr|math|obj|exc):`~?([^`]+)`")
_BULLET = re.compile(r"^(?:[-*•]|\d+\.|\(\w{1,3}\))\s+")
_NUMPYDOC = re.compile(r"^-{3,}$")
#: *emphasis* as reStructuredText reads it: not inside a word, no space inside the asterisks
_EMPHASIS = re.compile(r"(?<![\w*\\])\*([^*\s](?:[^*\n]*[^*\s])?)\*(?![\w*])")
#: numpydoc sections whose blocks are entries (a head line, its description indented)
_ENTRY_SECTIONS = (
    "Parameters",
    "Other Parameters",
    "Returns",
    "Yields",
    "Raises",
    "Attributes",
    "References",
    "See Also",
)


def prose_rst(doc: str) -> str:
    """A docstring as written (plain text with `code`, bullets, ``::`` blocks and numpydoc
    section headers) -> safe reStructuredText: paragraphs and list items escaped (:func:`inline`),
    indented blocks as literal blocks, section headers as bold lines. Nothing in the docstring can
    break the build, whatever markup it uses."""
    import inspect

    maths: list[str] = []

    def keep_math(m):
        maths.append(" ".join(m.group(1).split()))
        return f"\x00{len(maths) - 1}\x00"

    def tex(line: str) -> str:  # placeholders back as plain text (literal and math blocks)
        line = re.sub("\x01(\\d+)\x01", lambda m: f"*{emphasis[int(m.group(1))]}*", line)
        return re.sub("\x00(\\d+)\x00", lambda m: maths[int(m.group(1))], line)

    # a TeX command in a non-raw docstring lost its backslash to an escape ("\\rceil" -> CR + "ceil")
    doc = (doc or "").translate({0x07: "\\a", 0x08: "\\b", 0x0B: "\\v", 0x0C: "\\f", 0x0D: "\\r"})
    emphasis: list[str] = []

    def keep_emphasis(m):
        emphasis.append(m.group(1))
        return f"\x01{len(emphasis) - 1}\x01"

    text = re.sub(r":math:`([^`]+)`", keep_math, inspect.cleandoc(doc))
    text = _EMPHASIS.sub(keep_emphasis, text)
    text = _ROLE.sub(lambda m: "`" + m.group(1) + "`", text)
    out: list[str] = []
    literal_next = math_next = False
    section = ""
    for block in re.split(r"\n\s*\n", text):
        lines = [ln.rstrip() for ln in block.splitlines() if ln.strip()]
        if not lines:
            continue
        if lines[0].strip().startswith(".. math::"):
            first = lines[0].strip()[len(".. math::") :].strip()
            body = ([first] if first else []) + [ln.strip() for ln in lines[1:]]
            if body:
                out.extend([".. math::", ""] + [f"   {tex(ln)}" for ln in body] + [""])
            else:
                math_next = True
            continue
        if math_next:
            math_next = False
            if all(ln.startswith((" ", "\t")) for ln in lines):
                out.extend([".. math::", ""] + [f"   {tex(ln.strip())}" for ln in lines] + [""])
                continue
        if len(lines) >= 2 and _NUMPYDOC.match(lines[1].strip()):
            section = lines[0].strip()
            out.extend([f"**{inline(section)}**", ""])
            lines = lines[2:]
            if not lines:
                continue
        if section in _ENTRY_SECTIONS and not lines[0].startswith((" ", "\t")):
            entries: list[list[str]] = []
            for ln in lines:
                if ln.startswith((" ", "\t")) and entries:
                    entries[-1][1] += " " + ln.strip()
                else:
                    entries.append([ln.strip(), ""])
            for head, desc in entries:
                if section in ("References", "See Also"):
                    ref = re.sub(r"^\.\.\s+", "", f"{head} {desc}").strip()
                    out.append(f"- {inline(ref)}")
                else:
                    out.append(f"- ``{head}``" + (f": {inline(desc.strip())}" if desc.strip() else ""))
            out.append("")
            continue
        if literal_next or all(ln.startswith((" ", "\t")) for ln in lines):
            out.extend(["::", ""] + [f"    {tex(ln)}" for ln in lines] + [""])
            literal_next = False
            continue
        if _BULLET.match(lines[0].lstrip()):
            items: list[str] = []
            for ln in lines:
                if _BULLET.match(ln.lstrip()) and (not items or len(ln) - len(ln.lstrip()) <= 1):
                    items.append(_BULLET.sub("", ln.lstrip()))
                else:
                    items[-1] += " " + ln.strip()
            out.extend([f"- {inline(item)}" for item in items] + [""])
            continue
        para = " ".join(ln.strip() for ln in lines)
        if para.endswith("::"):
            para, literal_next = para[:-1], True
        out.extend([inline(para), ""])
    # inline maths back as roles; "\ " (escaped, removed whitespace) lets a role touch words
    rst = "\n".join(out)
    # inside a code span, emphasis is the asterisks as written
    rst = re.sub(r"``.+?``", lambda m: tex(m.group(0)), rst)
    rst = re.sub("\x01(\\d+)\x01", lambda m: "\\ *" + _escape(emphasis[int(m.group(1))]) + "*\\ ", rst)
    return re.sub("\x00(\\d+)\x00", lambda m: "\\ :math:`" + maths[int(m.group(1))] + "`\\ ", rst)


def _module_file(module: str) -> Path:
    path = ROOT.joinpath(*module.split("."))
    return path / "__init__.py" if path.is_dir() else path.with_suffix(".py")


def module_rst(*modules: str) -> str:
    """Each module's docstring, then its public functions and classes (signature and docstring),
    read from the source with ``ast`` (nothing imported)."""
    import ast

    out = []
    for module in modules:
        path = _module_file(module)
        tree = ast.parse(path.read_text(), str(path))
        out.extend(_heading(f"``{module}``", "-"))
        out.extend([prose_rst(ast.get_docstring(tree, clean=False) or ""), ""])
        for node in tree.body:
            if not isinstance(node, (ast.FunctionDef, ast.ClassDef)) or node.name.startswith("_"):
                continue
            doc = ast.get_docstring(node, clean=False)
            if not doc:
                continue
            if isinstance(node, ast.FunctionDef):
                args = ast.unparse(node.args)
                title = f"{node.name}({args})"
            else:
                title = f"class {node.name}"
            out.extend([".. rubric:: " + node.name, "", f"``{' '.join(title.split())}``", ""])
            out.extend([prose_rst(doc), ""])
    return "\n".join(out)


# ------------------------------------------------------------------------------------ gallery
def gallery_rst() -> str:
    """The images ``make gallery`` wrote (``docs/gallery/gallery.json``), per example and sensor:
    the render's preview and its label overlay side by side."""
    index = ROOT / "docs" / "gallery" / "gallery.json"
    if not index.is_file():
        return "No gallery yet: ``make gallery`` renders it.\n"
    entries = json.loads(index.read_text())
    out = []
    for example in dict.fromkeys(e["example"] for e in entries):
        out.extend(_heading(f"``examples/{example}.toml``", "-"))
        for e in (e for e in entries if e["example"] == example):
            w, h = e["resolution"]
            what = f"{e['band']} · ``{e['sensor']}``" + (
                f" (preset ``{e['preset']}``)" if e["preset"] else ""
            )
            out.extend([f".. rubric:: {what}", ""])
            out.extend(
                _table(
                    ["render", "labels"],
                    [[f"|{e['image']}|", f"|{e['labels']}|"]],
                )
            )
            out.extend(
                [
                    f"{w}×{h} pixels, frame 0, the render's automatic quality.",
                    "",
                    f".. |{e['image']}| image:: /gallery/{e['image']}",
                    f"   :alt: {e['band']} render of {example}, sensor {e['sensor']}",
                    "",
                    f".. |{e['labels']}| image:: /gallery/{e['labels']}",
                    f"   :alt: labels of {example}, sensor {e['sensor']}",
                    "",
                ]
            )
    return "\n".join(out)


# --------------------------------------------------------------------------------- CLI (check)
def cli_commands() -> list[str]:
    """Every command path of ``humv-usd`` (``compose``, ``bench render``), for the test that the
    sphinx-click page names each."""
    import click

    from humv_usd.cli.main import main

    paths = []

    def walk(cmd, prefix):
        if isinstance(cmd, click.Group):
            for name, sub in sorted(cmd.commands.items()):
                paths.append(f"{prefix} {name}".strip())
                walk(sub, f"{prefix} {name}")

    walk(main, "")
    return paths


#: the files each generator reads (the page is rebuilt when one changes)
SOURCES = {
    "scenario": ["humv_usd/scenario/spec.py", "examples/*.toml"],
    "materials": ["humv_usd/catalog/materials.py", "humv_usd/catalog/garments.py"],
    "garments": ["humv_usd/catalog/garments.py", "humv_usd/catalog/materials.py"],
    "sensors": ["humv_usd/catalog/sensors.py", "humv_usd/catalog/viewpoints.py"],
    "activities": ["humv_usd/human/motion.py", "humv_usd/human/poses.py"],
    "schemas": ["schemas/generatedSchema.usda"],
    "gallery": ["docs/gallery/gallery.json"],
}
#: physics pages: the page's ``humv-reference:: module A B`` lists its modules (their files are
#: the dependencies)

GENERATORS = {
    "scenario": scenario_rst,
    "materials": materials_rst,
    "garments": garments_rst,
    "sensors": sensors_rst,
    "activities": activities_rst,
    "schemas": schemas_rst,
    "module": module_rst,
    "gallery": gallery_rst,
}


# ------------------------------------------------------------------------------ Sphinx glue
def setup(app):
    from docutils import nodes
    from docutils.parsers.rst import Directive, directives
    from docutils.statemachine import StringList
    from sphinx.util.nodes import nested_parse_with_titles

    class Reference(Directive):
        required_arguments = 1
        optional_arguments = 20
        has_content = False

        def run(self):
            name = self.arguments[0]
            if name not in GENERATORS:
                raise self.error(f"humv-reference: unknown {name!r}; known: {', '.join(GENERATORS)}")
            env = self.state.document.settings.env
            env.note_dependency(__file__)
            args = self.arguments[1:]
            if name == "module":
                paths = [_module_file(m) for m in args]
            else:
                paths = [p for pattern in SOURCES[name] for p in sorted(ROOT.glob(pattern))]
            for path in paths:
                env.note_dependency(str(path))
            text = GENERATORS[name](*args)
            source = f"<humv-reference {name}>"
            lines = StringList(text.splitlines(), source=source)
            node = nodes.container()
            node.document = self.state.document
            nested_parse_with_titles(self.state, lines, node)
            return node.children

    directives.register_directive("humv-reference", Reference)
    app.add_object_type(
        "scenario-key",
        "key",
        indextemplate="pair: %s; scenario key",
        doc_field_types=[],
    )
    app.add_object_type("schema-attr", "usdattr", indextemplate="pair: %s; USD attribute")
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
