"""Issue 15: hostile input found by a machine (hypothesis).

Scenarios drawn from the spec (valid, boundary and invalid values, unicode, huge strings,
NaN/inf, wrong types, missing and unknown keys and sections) either validate or fail with
InputError, one short line per problem, never another exception; valid ones go through what
compose does before it writes (plan, warnings, cache keys). A few go end to end through the
command line (exit 2, one line each, no traceback, nothing written). The same for corrupt
BVH files, weather CSVs and USD layers given to check and render.
"""

from __future__ import annotations

import copy
import datetime as dt
import math
import tomllib
from pathlib import Path

import pytest
import tomlkit
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.pipeline.compose import plan
from humv_usd.scenario import validate
from humv_usd.scenario.inputs import read_values
from humv_usd.scenario.spec import SECTIONS, Key, Section
from humv_usd.scenario.warnings import suspicious

ROOT = Path(__file__).resolve().parents[1]
HUMVVEX = ROOT / "examples" / "humvvex_fixed.toml"  # the closed-form thermal model: fast
BASE = tomllib.loads(HUMVVEX.read_text())
DATA = Path(__file__).resolve().parent / "data"
#: longest problem line we accept: one line a person reads, whatever the input
MAX_LINE = 600

FUZZ = settings(
    max_examples=1000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize=True,  # the same cases every run (CI stays reproducible)
)

# ------------------------------------------------------------------ values from the spec
odd_floats = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, -0.0])
huge_text = st.integers(300, 100_000).map(lambda n: "x" * n)
unicode_text = st.text(min_size=0, max_size=40)
wrong_type = st.one_of(
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    unicode_text,
    huge_text,
    st.lists(st.integers(-5, 5), max_size=4),
    st.dictionaries(st.sampled_from(["a", "id", "x"]), st.integers(), max_size=2),
    st.just(dt.datetime(2018, 10, 24, 14, 5)),
)


def number(key: Key) -> st.SearchStrategy:
    lo = -1e6 if key.lo is None else key.lo
    hi = 1e6 if key.hi is None else key.hi
    if key.kind == "int" or key.integer:
        inside = st.integers(int(math.ceil(lo)), int(math.floor(hi)))
        edges = st.sampled_from([int(math.ceil(lo)) - 1, int(math.floor(hi)) + 1])
    else:
        inside = st.floats(lo, hi, allow_nan=False)
        span = max(abs(hi - lo), 1.0)
        edges = st.sampled_from([lo, hi, lo - 1e-9 * span, hi + 1e-9 * span, lo - span, hi + span])
    return st.one_of(inside, edges, odd_floats)


def value_for(key: Key) -> st.SearchStrategy:
    """Valid, boundary and invalid values of one key."""
    if key.kind in ("float", "int"):
        base = number(key)
    elif key.kind == "choice":
        base = st.one_of(st.sampled_from(list(key.choices) or ["x"]), unicode_text)
    elif key.kind == "vec":
        n = key.n or 3
        base = st.one_of(
            st.lists(number(key), min_size=n, max_size=n), st.lists(number(key), min_size=0, max_size=n + 2)
        )
    elif key.kind == "points":
        n = key.n or 2
        base = st.lists(st.lists(number(key), min_size=n, max_size=n), max_size=4)
    elif key.kind == "strlist":
        base = st.lists(
            st.one_of(unicode_text, st.sampled_from(["tshirt_white", "shorts", "cap", "coco"])), max_size=4
        )
    elif key.kind == "datetime":
        base = st.one_of(st.datetimes(), unicode_text)
    elif key.kind == "path":
        base = st.one_of(unicode_text, st.just("/nonexistent/x.csv"), st.just(str(DATA)), huge_text)
    else:  # str
        base = st.one_of(
            unicode_text, huge_text, st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,70}", fullmatch=True)
        )
    return st.one_of(base, base, wrong_type)  # mostly the key's own kind


def _tables(section_name: str, section: Section, doc: dict):
    """(path into doc, Section) of every table of a section present in ``doc``."""
    raw = doc.get(section_name)
    if isinstance(raw, list):
        return [((section_name, i), section) for i in range(len(raw))]
    if isinstance(raw, dict):
        out = [((section_name,), section)]
        for sub_name, sub in section.subsections.items():
            value = raw.get(sub_name)
            if isinstance(value, list):
                out += [((section_name, sub_name, i), sub) for i in range(len(value))]
            elif isinstance(value, dict):
                out.append(((section_name, sub_name), sub))
        return out
    return []


def _at(doc, path):
    for p in path:
        doc = doc[p]
    return doc


@st.composite
def scenarios(draw) -> dict:
    """humvvex.toml with one to four edits drawn from the spec."""
    doc = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 4))):
        tables = [t for name, sec in SECTIONS.items() for t in _tables(name, sec, doc)]
        kind = draw(
            st.sampled_from(
                ["set"] * 8
                + [
                    "delete key",
                    "unknown key",
                    "delete section",
                    "unknown section",
                    "empty array",
                    "section type",
                ]
            )
        )
        if kind in ("set", "delete key", "unknown key") and tables:
            path, section = draw(st.sampled_from(tables))
            table = _at(doc, path)
            if not isinstance(table, dict):
                continue
            if kind == "set":
                name = draw(st.sampled_from(sorted(section.keys)))
                table[name] = draw(value_for(section.keys[name]))
            elif kind == "delete key" and table:
                table.pop(draw(st.sampled_from(sorted(table))))
            else:
                table[draw(st.one_of(unicode_text, huge_text))] = draw(wrong_type)
        elif kind == "delete section" and doc:
            doc.pop(draw(st.sampled_from(sorted(doc))))
        elif kind == "unknown section":
            doc[draw(unicode_text)] = {"x": 1}
        elif kind == "empty array":
            doc[draw(st.sampled_from(["human", "placement", "sensor"]))] = []
        else:
            doc[draw(st.sampled_from(sorted(SECTIONS)))] = draw(wrong_type)
    return doc


def assert_clean(exc: InputError) -> None:
    assert exc.problems, "an InputError with no problem line"
    for line in exc.problems:
        assert isinstance(line, str) and line.strip(), exc.problems
        assert "\n" not in line, line[:200]
        assert len(line) <= MAX_LINE, f"{len(line)} characters: {line[:200]}..."
        assert "Traceback" not in line


@FUZZ
@given(scenarios())
def test_drawn_scenarios_validate_or_fail_cleanly(doc):
    try:
        scenario = validate(doc)
    except InputError as exc:
        assert_clean(exc)
        return
    # what compose does before it writes anything: plan, warnings, each layer's inputs
    needed, _ = plan(scenario)
    assert "environment" in needed
    for line in suspicious(scenario):
        assert "\n" not in line and len(line) <= MAX_LINE
    for reads in (("general",), ("human[{id}]",), ("sensor.*.position_m",)):
        for h in scenario["human"] or [None]:
            read_values(scenario, reads, None if h is None else h["id"])
    scenario.digest()


# ------------------------------------------------------------------ end to end, a few
@settings(
    max_examples=6,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(scenarios())
def test_drawn_invalid_scenarios_through_the_cli(tmp_path_factory, doc):
    if isinstance(doc.get("general"), dict):  # always a refusal here (valid ones compose elsewhere)
        doc["general"]["fuzz_unknown_key"] = 1
    else:
        doc["fuzz_unknown_section"] = {"x": 1}
    with pytest.raises(InputError):
        validate(doc)
    folder = tmp_path_factory.mktemp("cli")
    try:
        text = tomlkit.dumps(doc)
    except Exception:  # noqa: BLE001 (tomlkit cannot write every drawn value, e.g. huge ints)
        return
    (folder / "s.toml").write_text(text, encoding="utf-8")
    result = CliRunner().invoke(main, ["compose", str(folder / "s.toml"), "-o", str(folder / "out")])
    assert result.exit_code == 2, (result.output, result.exception)
    lines = result.stderr.strip().splitlines()
    assert lines and all(line.startswith("humv-usd: error: ") for line in lines), result.stderr[:500]
    assert "Traceback" not in result.output
    assert not (folder / "out").exists()


# ------------------------------------------------------------------ corrupt files
BVH_TEXT = (DATA / "knee_bend_cmu.bvh").read_text()


@st.composite
def corrupt_text(draw, text: str) -> str:
    """``text`` truncated, with a span deleted, duplicated or replaced by garbage."""
    n = len(text)
    a = draw(st.integers(0, n))
    b = draw(st.integers(a, min(n, a + 200)))
    how = draw(st.sampled_from(["truncate", "delete", "duplicate", "garbage", "numbers"]))
    if how == "truncate":
        return text[:a]
    if how == "delete":
        return text[:a] + text[b:]
    if how == "duplicate":
        return text[:b] + text[a:b] + text[b:]
    if how == "numbers":
        return text[:a] + draw(st.sampled_from(["nan", "inf", "-1e400", "1e999", "--", "0x10"])) + text[b:]
    return text[:a] + draw(st.text(max_size=30)) + text[b:]


@settings(max_examples=200, deadline=None, derandomize=True)
@given(corrupt_text(BVH_TEXT))
def test_corrupt_bvh_parses_or_fails_cleanly(text):
    from humv_usd.human.bvh import parse_bvh

    try:
        parse_bvh(text, "fuzz.bvh")
    except InputError as exc:
        assert_clean(exc)


CSV_TEXT = (
    "time,air_temperature_k,relative_humidity,wind_speed_m_s,cloud_cover\n"
    "2018-10-24T13:00:00,288.0,0.5,3.0,0.1\n"
    "2018-10-24T14:00:00,289.0,0.45,3.5,0.0\n"
    "2018-10-24T15:00:00,289.5,0.4,4.0,0.0\n"
)


@settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(st.one_of(corrupt_text(CSV_TEXT), st.binary(max_size=200).map(lambda b: b.decode("latin-1"))))
def test_corrupt_weather_csv_reads_or_fails_cleanly(tmp_path_factory, text):
    from humv_usd.scenario.weather_csv import read_weather_csv

    path = tmp_path_factory.mktemp("csv") / "w.csv"
    path.write_bytes(text.encode("utf-8", errors="surrogateescape"))
    try:
        read_weather_csv(path, validate(copy.deepcopy(BASE)))
    except InputError as exc:
        assert_clean(exc)


@pytest.fixture(scope="module")
def composed(tmp_path_factory):
    from humv_usd.pipeline.compose import compose

    out = tmp_path_factory.mktemp("composed") / "o"
    compose(validate(copy.deepcopy(BASE)), out)
    return out


LAYERS = ["materials", "sensors", "scene", "environment"]


@pytest.mark.slow
@settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(st.sampled_from(LAYERS), st.data())
def test_corrupt_layers_are_findings_or_one_line(composed, tmp_path_factory, layer, data):
    """check never crashes on a corrupt layer; render's gate (open_stage) refuses it with one
    line or opens a stage."""
    import shutil

    from humv_usd.usd.check import check_stage
    from humv_usd.usd.layers import open_stage

    out = tmp_path_factory.mktemp("broken") / "o"
    shutil.copytree(composed, out)
    path = out / "layers" / f"{layer}.usda"
    path.write_text(data.draw(corrupt_text(path.read_text())), encoding="utf-8")
    try:
        findings = check_stage(out / "stage.usda")
        assert all("\n" not in f for f in findings)
    except InputError as exc:
        assert_clean(exc)
    try:
        open_stage(out / "stage.usda")
    except InputError as exc:
        assert_clean(exc)
