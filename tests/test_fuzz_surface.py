"""Issue 26, deliverable 5: hypothesis over three more surfaces a user (or a web page) reaches.

- **The sensor band/wavelength space**: any band token x wavelength range x resolution (x preset)
  either validates, and then the sensors layer compose writes is read back by the render with the
  same band and the same edges inside the band's range (one rule shared by compose and render, no
  reinterpretation), or fails with clean one-line problems; any authored band token x wavelength
  range x resolution on a hand-made camera is read by the render or refused with one line.
- **The render command's knobs** (``--spp``, ``--frames``, ``--resolution``, ``--backend``,
  ``--sensor``, ``--subbands``, ``--estimator``, ``--seed``) through click's CliRunner on a tiny
  stage: a refusal is exit code 2 with one ``humv-usd: error:`` line, no traceback, and no output
  folder at all (nothing half-written); the memory estimate refuses the huge ones before any work.
- **The editor's HTTP and websocket surface** (loopback only): random Host / Origin / token /
  cookie / path / method / body combinations get only the documented answers of
  :mod:`humv_usd.editor.guard` (421 foreign Host, 403 foreign or ``null`` Origin, 403 without the
  token beyond the loopback) or the page's own, never a 500; first against the guard itself
  (many cases, in-process), then a bounded number against a real ``humv-usd edit`` server.

Example counts are bounded and derandomized (the same cases every run); larger counts are
``extended`` tests.
"""

from __future__ import annotations

import copy
import math
import shutil
import socket
import sys
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from pxr import Gf, Sdf, Usd, UsdGeom

from humv_usd.catalog.sensors import PRESETS
from humv_usd.cli.main import main
from humv_usd.editor.guard import TOKEN_COOKIE, RequestGuard
from humv_usd.errors import InputError
from humv_usd.pipeline.budget import MAX_SPP
from humv_usd.scenario import validate
from humv_usd.scenario.spec import BAND_RANGE_UM, BANDS, BANDS_NOT_YET
from humv_usd.sensors import layer as sensors_layer
from humv_usd.usd.sensor import MAX_RESOLUTION, RENDERABLE_UM, read_sensor

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_render import add_camera, add_material, add_mesh, new_stage, rect_y, rect_z  # noqa: E402

BASE = tomllib.loads((ROOT / "examples" / "humvvex_fixed.toml").read_text())
MAX_LINE = 600


def cases(n: int) -> settings:
    """Hypothesis settings for ``n`` cases, the same cases every run (CI stays reproducible), no
    deadline, function-scoped fixtures allowed (they are the same for every case)."""
    return settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )


QUICK = cases(150)


def assert_clean(exc: InputError) -> None:
    assert exc.problems, "an InputError with no problem line"
    for line in exc.problems:
        assert isinstance(line, str) and line.strip() and "\n" not in line, exc.problems
        assert len(line) <= MAX_LINE and "Traceback" not in line, line[:200]


# ------------------------------------------------------------------ (a) band x wavelengths
#: band tokens: the spec's, the ones not rendered yet, near misses, anything
band_tokens = st.one_of(
    st.sampled_from([*BANDS, *BANDS_NOT_YET, "lwir", "LWIR ", "", "EO/IR", "IR", "THERMAL"]),
    st.text(max_size=6),
)
edge = st.one_of(
    st.floats(-1.0, 30.0, allow_nan=False),
    st.sampled_from([0.36, 0.83, 3.0, 5.0, 7.0, 14.0, 0.0, math.nan, math.inf, -math.inf, 1e308, 1001.0]),
)
edges = st.one_of(st.tuples(edge, edge).map(list), st.lists(edge, max_size=3))
resolutions = st.one_of(
    st.sampled_from([[1, 1], [1, 48], [64, 1], [16384, 1], [0, 48], [MAX_RESOLUTION + 1, 2]]),
    st.lists(st.integers(-2, MAX_RESOLUTION + 2), min_size=2, max_size=2),
)


@QUICK
@given(
    st.one_of(st.none(), st.sampled_from(sorted(PRESETS))),
    st.one_of(st.none(), band_tokens),
    st.one_of(st.none(), edges),
    st.one_of(st.none(), resolutions),
)
# issue 26's cases: EO at 8-14 um rendered visible light; LWIR at 0.4-0.7 and MWIR at 2-5 crashed
@example(None, "EO", [8.0, 14.0], [64, 48])
@example(None, "LWIR", [0.4, 0.7], [64, 48])
@example(None, "MWIR", [2.0, 5.0], [64, 48])
@example("atom1024_lwir", "EO", None, None)  # another band than the preset's: its edges by band
@example(None, "SWIR", [0.9, 1.7], [1, 1])
def test_band_and_wavelengths_validate_as_the_render_reads_them_or_fail_cleanly(preset, band, wl, res):
    doc = copy.deepcopy(BASE)
    table = {"id": "s", "position_m": [0.0, -15.0, 1.6], "look_at_m": [0.0, 0.0, 1.0]}
    given_keys = {"preset": preset, "band": band, "wavelength_um": wl, "resolution": res}
    table.update({k: v for k, v in given_keys.items() if v is not None})
    if preset is None:
        table.setdefault("focal_length_mm", 25.0)
    doc["sensor"] = [table]
    try:
        scenario = validate(doc)
    except InputError as exc:
        assert_clean(exc)
        return
    s = scenario["sensor"][0]
    if band is not None:
        assert s["band"] == band  # never another band
    if wl is not None:
        assert list(s["wavelength_um"]) == wl  # never other edges
    lo, hi = s["wavelength_um"]
    r_lo, r_hi = BAND_RANGE_UM[s["band"]]
    assert r_lo <= lo < hi <= r_hi, (s["band"], lo, hi)
    assert 1 <= s["resolution"][0] <= MAX_RESOLUTION and 1 <= s["resolution"][1] <= MAX_RESOLUTION
    # what compose writes, the render reads as it is: the same band, the same edges, accepted
    stage = Usd.Stage.Open(sensors_layer.build(scenario))
    prim = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Camera))
    model = read_sensor(prim)
    assert model.band == s["band"]
    assert model.wavelength_range_um == pytest.approx((lo, hi), rel=1e-6)
    assert tuple(model.resolution) == tuple(s["resolution"])


@QUICK
@given(
    st.one_of(st.none(), band_tokens),
    st.one_of(st.none(), st.tuples(edge, edge)),
    st.one_of(st.none(), st.tuples(st.integers(-2, MAX_RESOLUTION + 2), st.integers(-2, MAX_RESOLUTION + 2))),
)
@example("EO", (8.0, 14.0), (64, 48))
@example("LWIR", (0.4, 0.7), (64, 48))
@example("MWIR", (2.0, 5.0), (64, 48))
@example(None, (0.9, 1.7), (64, 48))  # an unauthored band: the band whose range holds the edges
@example("LWIR", (8.0, 14.0), (1, 1))
def test_any_authored_band_is_read_as_authored_or_refused_in_one_line(band, wl, res):
    """A hand-made stage (not made by compose): the render's read of the camera."""
    stage = Usd.Stage.CreateInMemory()
    cam = UsdGeom.Camera.Define(stage, "/World/Sensors/cam")
    cam.CreateFocalLengthAttr(25.0)
    cam.CreateHorizontalApertureAttr(10.0)
    cam.CreateVerticalApertureAttr(7.5)
    prim = cam.GetPrim()
    if band is not None:
        prim.CreateAttribute("humv:sensor:band", Sdf.ValueTypeNames.Token).Set(band)
    if wl is not None:
        prim.CreateAttribute("humv:sensor:wavelengthRange", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*wl))
    if res is not None:
        prim.CreateAttribute("humv:sensor:resolution", Sdf.ValueTypeNames.Int2).Set(Gf.Vec2i(*res))
    try:
        model = read_sensor(prim)
    except InputError as exc:
        assert_clean(exc)
        return
    if band is not None:
        assert model.band == band
    assert model.band in RENDERABLE_UM
    lo, hi = model.wavelength_range_um
    a, z = RENDERABLE_UM[model.band]
    assert a <= round(lo, 6) < round(hi, 6) <= z
    if model.skip_reason is None:
        assert 1 <= model.resolution[0] <= MAX_RESOLUTION and 1 <= model.resolution[1] <= MAX_RESOLUTION


# ------------------------------------------------------------------ (b) the render command's knobs
W, H = 64, 48  # the tiny stage's camera; at --spp 2**20 it needs ~2.7 TB: always refused


@pytest.fixture(scope="module")
def tiny_stage(tmp_path_factory) -> Path:
    """A ground at 290 K, a wall at 305 K, one LWIR camera (64x48), one frame."""
    path = tmp_path_factory.mktemp("tiny") / "stage.usda"
    stage = new_stage(path)
    m = add_material(stage, "m", 0.95)
    add_mesh(stage, "/World/Scene/ground", *rect_z(-20, 20, -5, 40), material=m, temperature_k=290.0)
    add_mesh(stage, "/World/Scene/wall", *rect_y(-1, 1, 0, 2, 5.0), material=m, temperature_k=305.0)
    add_camera(stage, "cam", (0, -5, 1.5), (0, 5, 1.0), resolution=(W, H))
    stage.GetRootLayer().Save()
    return path


#: each knob: values that pass and values that must be refused
KNOBS = {
    # (--spp 2**20 is refused by the memory estimate only at the stage's own 64x48: an example)
    "--spp": (["1", "2"], ["0", "-3", "x", "1.5", str(MAX_SPP + 1), "99999999999999999999"]),
    "--frames": (
        ["0", "0:0", "0,0"],
        ["1", "-1", "5:2", "0:99999999999", "a", "", ",", "0:", ":", "1e3", "0:1000000000", "\u0663"],
    ),
    "--resolution": (
        ["4x3", "1x1", "8x1"],
        ["0x0", "x", "8x", "-1x5", "1e3x2", "4X3X2", "16385x1", "16384x16384", "\u00b2x3", "4x\u00b9"],
    ),
    "--subbands": (["1", "2"], ["0", "65", "-1", "x"]),
    "--sensor": (["cam", "/World/Sensors/cam"], ["nope", "", "/World", "cam/.."]),
    "--estimator": (["fast"], ["fastest", "", "PATH"]),
    "--seed": (["0", "7"], ["-1", str(2**31), "x"]),
    "--backend": ([], ["gpu", "", "metal", "cuda_ad_mono"]),  # valid ones: explicit examples below
}


@st.composite
def refused_knobs(draw) -> list[str]:
    """Render options with at least one refused value (every example is a refusal, fast)."""
    names = draw(st.lists(st.sampled_from(sorted(KNOBS)), min_size=1, max_size=4, unique=True))
    bad = draw(st.sampled_from(names))
    args = []
    for name in names:
        good, refused = KNOBS[name]
        pool = refused if name == bad or not good else good
        args += [name, draw(st.sampled_from(pool))]
    return args


def _assert_refused(result, out: Path) -> None:
    assert result.exit_code == 2, (result.exit_code, result.output[-600:], repr(result.exception))
    lines = result.stderr.strip().splitlines()
    assert len(lines) >= 1 and "Traceback" not in result.output
    errors = [line for line in lines if line.startswith(("humv-usd: error:", "Error:"))]
    assert errors and len(errors[0]) <= MAX_LINE, lines
    # nothing half-written: no output folder (no lock, no .frames, no manifest)
    assert not out.exists() or not any(out.iterdir()), sorted(p.name for p in out.iterdir())


@cases(60)
@given(refused_knobs())
@example(["--spp", str(MAX_SPP)])  # 2.7 TB; issue 26: the OOM killer ended it; now the estimate refuses
@example(["--frames", "0:99999999999"])  # issue 26: MemoryError building the frame list
# found by this test (2026-11-27): on a camera without an authored pixel pitch --resolution was
# skipped without a word, so this rendered the stage's 64x48 with exit 0; now it is 16384x16384,
# whose estimate (14.7 TB) is refused
@example(["--resolution", "16384x16384", "--spp", "64"])
@example(["--subbands", "64", "--spp", "65536"])  # 441 GB
@example(["--resolution", "\u00b2x3"])  # found by this test: int('²') raised ValueError (rc 1)
def test_refused_render_knobs_are_one_line_and_write_nothing(tiny_stage, tmp_path_factory, args):
    out = tmp_path_factory.mktemp("knobs") / "render"
    result = CliRunner().invoke(main, ["render", str(tiny_stage), "-o", str(out), "-q", *args])
    _assert_refused(result, out)


def test_a_backend_this_machine_lacks_is_one_line(tiny_stage, tmp_path):
    """--backend cuda without a GPU (its own process: Mitsuba picks its variant once)."""
    import subprocess

    from humv_usd.mode import _cuda_driver

    if _cuda_driver() is not None:
        pytest.skip("this machine has a CUDA driver")
    out = tmp_path / "render"
    r = subprocess.run(
        [sys.executable, "-m", "humv_usd.cli.main", "render", str(tiny_stage), "-o", str(out), "-q"]
        + ["--backend", "cuda", "--resolution", "4x3", "--spp", "1", "--subbands", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 2, (r.returncode, r.stderr[-1500:])
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("humv-usd: error: ") and "cuda" in lines[0], lines
    assert not out.exists() or not any(out.iterdir())


@st.composite
def any_knobs(draw) -> list[str]:
    names = draw(st.lists(st.sampled_from(sorted(KNOBS)), max_size=5, unique=True))
    args = []
    for name in names:
        good, refused = KNOBS[name]
        args += [name, draw(st.sampled_from(good + refused))]
    if "--resolution" not in names:
        args += ["--resolution", draw(st.sampled_from(["4x3", "2x2"]))]
    return args


@pytest.mark.extended
@cases(40)
@given(any_knobs())
def test_render_knobs_render_completely_or_refuse_cleanly(tiny_stage, tmp_path_factory, args):
    """Valid knobs render (a manifest and one EXR per frame and sensor); refused ones as above."""
    out = tmp_path_factory.mktemp("knobs") / "render"
    result = CliRunner().invoke(main, ["render", str(tiny_stage), "-o", str(out), "-q", *args])
    if result.exit_code == 0:
        assert (out / "manifest.json").is_file() and list((out / "cam").glob("0000.exr"))
        assert not (out / ".lock").exists()
    else:
        _assert_refused(result, out)


# ------------------------------------------------------------------ (c) the editor's HTTP surface
PORT = 8765
OWN = f"127.0.0.1:{PORT}"
hosts = st.one_of(
    st.sampled_from(
        [OWN, f"localhost:{PORT}", f"[::1]:{PORT}", "evil.example", f"evil.example:{PORT}", "127.0.0.1"]
        + [f"127.0.0.1:{PORT + 1}", f"x@{OWN}", f"{OWN}/x", f"LOCALHOST:{PORT}", "", ":", f"[::1:{PORT}"]
    ),
    st.text(max_size=20),
)
origins = st.one_of(
    st.none(),
    st.sampled_from(
        [f"http://{OWN}", "null", f"https://{OWN}", "http://evil.example", f"http://{OWN}/x", "http://[::1"]
        + [f"http://localhost:{PORT}", "file://", f"http://{OWN}:1", "http://user@127.0.0.1:8765"]
    ),
    st.text(max_size=20),
)
tokens = st.one_of(st.none(), st.just("secret-token"), st.text(max_size=12))
paths = st.one_of(
    st.sampled_from(
        [
            "/",
            "/files/scenario/humvvex.toml",
            "/files/scenario/../../etc/passwd",
            "/files/scenario/%2e%2e/%2e%2e/etc/passwd",
            "/files/out/x",
            "/files/scenario/",
            "/_nicegui_ws/socket.io/?EIO=4&transport=polling",
            "/_nicegui/client/x/y",
            "/favicon.ico",
            "/nope",
            "//evil.example/",
            "/?token=x&token=y",
            "/files/scenario/" + "a" * 5000,
            "/files/scenario/%00",
        ]
    ),
    st.text(st.characters(min_codepoint=33, max_codepoint=126), max_size=30).map(lambda t: "/" + t),
)
methods = st.sampled_from(["GET", "POST", "PUT", "DELETE", "HEAD", "OPTIONS", "PATCH", "TRACE"])


def _headers(host, origin, token_cookie, extra_hosts=0):
    headers = [(b"host", host.encode("utf-8", "surrogateescape"))] * (1 + extra_hosts)
    if origin is not None:
        headers.append((b"origin", origin.encode("utf-8", "surrogateescape")))
    if token_cookie is not None:
        headers.append((b"cookie", f"{TOKEN_COOKIE}={token_cookie}".encode("utf-8", "surrogateescape")))
    return headers


def _guard_answer(guard: RequestGuard, scope: dict) -> tuple[str, int | None]:
    """Run the guard on one request: ("app", None) when it passes it on, else (type, status)."""
    import asyncio

    sent: list[dict] = []

    async def app(scope, receive, send):
        sent.append({"type": "passed"})

    async def receive():
        return {"type": "http.request", "body": b"", "more_body": False}

    async def send(message):
        sent.append(message)

    guard.app = app
    asyncio.run(guard(scope, receive, send))
    first = sent[0]
    if first["type"] == "passed":
        return "app", None
    if first["type"] == "websocket.close":
        return "close", first["code"]
    return "http", first["status"]


@settings(max_examples=250, deadline=None, derandomize=True)
@given(
    st.sampled_from(["127.0.0.1", "127.0.0.2", "0.0.0.0"]),
    st.sampled_from(["http", "websocket"]),
    hosts,
    origins,
    tokens,
    tokens,
    st.integers(0, 1),
)
# found by this test (2026-11-27), both a 500 from a real server: a broken IPv6 literal in the
# Origin (urlsplit raised ValueError) and a token with a non-ASCII character (compare_digest
# raised TypeError on ?token=%80)
@example("127.0.0.1", "http", OWN, "http://[::1", None, None, 0)
@example("127.0.0.2", "http", OWN, None, "\x80", None, 0)
@example("127.0.0.2", "websocket", OWN, None, None, "\u00e9t\u00e9", 0)
def test_the_guard_answers_only_the_documented_statuses(bind, kind, host, origin, query_token, cookie, extra):
    token = None if bind == "127.0.0.1" else "secret-token"
    guard = RequestGuard(None, host=bind, port=PORT, token=token)
    query = b"" if query_token is None else b"token=" + query_token.encode("utf-8", "surrogateescape")
    scope = {
        "type": kind,
        "path": "/",
        "query_string": query,
        "headers": _headers(host, origin, cookie, extra),
    }
    how, status = _guard_answer(guard, scope)
    own_host = host.strip().lower() in (OWN, f"localhost:{PORT}", f"[::1]:{PORT}") or (
        bind != "127.0.0.1" and host.strip().lower().endswith(f":{PORT}")
    )
    if extra or not own_host:
        if bind == "0.0.0.0" and not extra and host.strip().endswith(f":{PORT}"):
            pass  # a wildcard bind accepts any name with the port (the token guards it)
        else:
            assert (how, status) in (("http", 421), ("close", 1008)), (host, how, status)
            return
    if how == "app":
        # passed on: the Host is ours, the Origin (if any) is the same origin, the token given
        assert origin is None or origin.lower().rstrip("/") == f"http://{host.strip().lower()}"
        if token:
            assert query_token == token or (not query_token and cookie == token)
        return
    assert (how, status) in (("http", 421), ("http", 403), ("close", 1008)), (how, status)


def raw_request(port: int, method: str, path: str, headers: list[tuple[str, str]], body: bytes) -> int:
    """Status of one raw HTTP/1.1 request (any header bytes; a closed connection: 0)."""
    lines = [f"{method} {path} HTTP/1.1", *(f"{k}: {v}" for k, v in headers)]
    if body:
        lines.append(f"Content-Length: {len(body)}")
    lines.append("Connection: close")
    data = ("\r\n".join(lines) + "\r\n\r\n").encode("utf-8", "surrogateescape") + body
    with socket.create_connection(("127.0.0.1", port), timeout=15) as s:
        s.sendall(data)
        first = s.makefile("rb").readline().decode("latin-1")
    parts = first.split()
    return int(parts[1]) if len(parts) >= 2 and parts[1].isdigit() else 0


# the same strategies against a real server: tests/test_editor_security.py (its server)


@pytest.mark.extended
@cases(20)
@given(
    st.sampled_from([*BANDS, "VNIR", "XX"]),
    st.one_of(st.tuples(edge, edge), st.sampled_from([(8.0, 14.0), (3.0, 5.0), (0.4, 0.7), (0.75, 1.0)])),
    st.sampled_from(["1x1", "4x3", "8x1"]),
    st.sampled_from(["1", "2", "3"]),
)
@example("LWIR", (8.0, 14.0), "4x3", "2")
@example("MWIR", (3.0, 5.0), "1x1", "1")
@example("NIR", (0.75, 1.0), "4x3", "1")
@example("EO", (8.0, 14.0), "4x3", "1")  # issue 26: rendered visible light
def test_band_wavelengths_resolution_and_spp_through_the_render(tmp_path_factory, band, wl, res, spp):
    """End to end on a hand-made stage: rendered as authored (the manifest's band and edges, the
    image's size) or refused with one line, exit 2, nothing written."""
    import json

    folder = tmp_path_factory.mktemp("band")
    stage = new_stage(folder / "stage.usda")
    m = add_material(stage, "m", 0.95, wavelengths=(0.3, 20.0))
    add_mesh(stage, "/World/Scene/ground", *rect_z(-20, 20, -5, 40), material=m, temperature_k=290.0)
    add_camera(stage, "cam", (0, -5, 1.5), (0, 5, 1.0), band=wl, band_token=band)
    stage.GetRootLayer().Save()
    out = folder / "render"
    args = ["render", str(folder / "stage.usda"), "-o", str(out), "-q", "--resolution", res, "--spp", spp]
    result = CliRunner().invoke(main, args)
    if result.exit_code != 0:
        _assert_refused(result, out)
        return
    manifest = json.loads((out / "manifest.json").read_text())
    (sensor,) = manifest["sensors"] + manifest["eo_sensors"] + manifest["skipped_sensors"]
    assert sensor["band"] == band
    if "reason" in sensor:  # skipped, and said so (an EO camera on this stage has no sun or sky)
        assert sensor["reason"] and "cam" in result.stdout
    else:
        assert sensor["wavelength_range_um"] == pytest.approx(list(wl), rel=1e-6)


# ------------------------------------------------------------------ (c') the editor's form fields
#: what a person (or a page script) may type into a field: values, TOML fragments, junk
typed_text = st.one_of(
    st.sampled_from(
        ["", " ", "1", "-1", "0", "1e400", "nan", "inf", "[1, 2]", "[1, 2, 3]", "[]", "[[0, 0], [1, 2]]"]
        + ['"x"', "true", "{a = 1}", "[1, [2]]", "2018-10-24T14:05:00", "1979-05-27", "0x10", "1_000"]
        + ["LWIR", "atom1024_lwir", "nope", "a = 1\nb = 2", "[", "]]", "'''", "\x00", "é", "1" * 400]
    ),
    st.text(max_size=30),
)


@cases(40)  # ~0.2 s each (validation, the save and its read-back); 400 under extended
@given(st.data())
def test_any_text_in_any_field_is_a_problem_line_or_a_value(tmp_path_factory, data):
    _form_case(tmp_path_factory, data)


@pytest.mark.extended
@cases(400)
@given(st.data())
def test_any_text_in_any_field_more_cases(tmp_path_factory, data):
    _form_case(tmp_path_factory, data)


def _form_case(tmp_path_factory, data) -> None:
    """The editor's form (what its websocket events carry): any text typed into one to three
    fields of humvvex never raises; every problem is one line; the Sensor tab's sources are
    computed for any state; a valid document saves and reads back the same."""
    from humv_usd.editor.document import SaveRefused, ScenarioDocument
    from humv_usd.editor.fields import all_fields, value_source

    folder = tmp_path_factory.mktemp("form")
    path = folder / "humvvex.toml"
    shutil.copy(ROOT / "examples" / "humvvex_fixed.toml", path)
    doc = ScenarioDocument(path)
    for _ in range(data.draw(st.integers(1, 3))):
        fields = all_fields(doc.raw())
        field = data.draw(st.sampled_from(fields))
        problem = doc.set_text(field, data.draw(typed_text))
        assert problem is None or ("\n" not in problem and len(problem) <= MAX_LINE), problem
    problems = doc.problems()
    for line in problems:
        assert isinstance(line, str) and "\n" not in line and len(line) <= MAX_LINE, line[:300]
    scenario = doc.scenario()
    for f in [f for f in all_fields(doc.raw()) if f.path[0] == "sensor"]:
        source = value_source(doc.raw(), scenario, f)
        assert source is None or source.kind in ("user", "preset", "computed")
    if not problems:
        assert scenario is not None
        doc.save()
        assert ScenarioDocument(path).raw() == doc.raw()
    else:
        try:
            doc.save()
        except SaveRefused as exc:
            assert str(exc).strip()  # a reason, not an empty refusal
