"""The editor against other web pages and other hosts (issue 26): real ``humv-usd edit`` servers
answering real HTTP requests and websocket handshakes with foreign Host and Origin headers
(DNS rebinding, cross-origin reads, socket.io from another site), the token on every channel,
uploads that never replace a file silently, sweep bases confined to the scenario's folder."""

from __future__ import annotations

import http.client
import importlib.util
import shutil
import socket
import sys
import time
from pathlib import Path

import pytest
import tomlkit
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from humv_usd.editor.document import SaveRefused, ScenarioDocument
from humv_usd.editor.fields import all_fields
from humv_usd.editor.guard import split_host
from humv_usd.editor.safety import UploadExists, store_upload, sweep_base
from humv_usd.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
import test_fuzz_surface as fz  # noqa: E402  (its strategies of hosts, origins, paths)

EXAMPLE = ROOT / "examples" / "humvvex.toml"


def _helpers():
    spec = importlib.util.spec_from_file_location(
        "editor_screenshots", ROOT / "tools" / "editor_screenshots.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _get(port: int, path: str, headers: dict, address: str = "127.0.0.1") -> tuple[int, bytes]:
    conn = http.client.HTTPConnection(address, port, timeout=10)
    try:
        conn.request("GET", path, headers=headers)
        r = conn.getresponse()
        return r.status, r.read()
    finally:
        conn.close()


def _handshake(port: int, path: str, headers: dict, address: str = "127.0.0.1") -> int:
    """Status code of a raw websocket opening handshake (RFC 6455 §4.1)."""
    lines = [
        f"GET {path} HTTP/1.1",
        "Connection: Upgrade",
        "Upgrade: websocket",
        "Sec-WebSocket-Version: 13",
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
        *(f"{k}: {v}" for k, v in headers.items()),
    ]
    with socket.create_connection((address, port), timeout=10) as s:
        s.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        first = s.makefile("rb").readline().decode()
    return int(first.split()[1])


WS = "/_nicegui_ws/socket.io/?EIO=4&transport=websocket"
POLL = "/_nicegui_ws/socket.io/?EIO=4&transport=polling"


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A loopback editor without token: (port, scenario)."""
    folder = tmp_path_factory.mktemp("editor")
    scenario = folder / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    with _helpers().editor_server(scenario, folder / "out") as (url, _, _):
        yield int(url.rsplit(":", 1)[1].strip("/")), scenario


def test_split_host():
    assert split_host("127.0.0.1:8765") == ("127.0.0.1", 8765)
    assert split_host("[::1]:9") == ("::1", 9)
    assert split_host("LocalHost") == ("localhost", 80)
    for bad in ("", "a:b", "a:0", "a:70000", "::1", "[::1", "[::1]x", "a/b:1", "u@a:1", ":80"):
        assert split_host(bad) is None, bad


def test_foreign_host_is_refused_everywhere(server):
    """DNS rebinding: a page on evil.example resolved to 127.0.0.1 sends Host: evil.example."""
    port, _ = server
    ok = f"127.0.0.1:{port}"
    assert _get(port, "/files/scenario/humvvex.toml", {"Host": ok})[0] == 200
    assert _get(port, "/files/scenario/humvvex.toml", {"Host": f"localhost:{port}"})[0] == 200
    for host in (
        "evil.example",
        f"evil.example:{port}",
        "127.0.0.1",
        f"127.0.0.1:{port + 1}",
        f"x@127.0.0.1:{port}",
    ):
        for path in ("/", "/files/scenario/humvvex.toml", "/files/out/x", POLL, "/favicon.ico"):
            status, body = _get(port, path, {"Host": host})
            assert status == 421, (host, path, status)
            assert b"humvvex" not in body and b"[general]" not in body
        assert _handshake(port, WS, {"Host": host, "Origin": f"http://{host}"}) == 403


def test_foreign_origin_is_refused(server):
    port, _ = server
    host = f"127.0.0.1:{port}"
    for origin in (
        "http://evil.example",
        f"http://evil.example:{port}",
        "null",
        f"https://{host}",
        "http://127.0.0.1",
    ):
        status, body = _get(port, "/files/scenario/humvvex.toml", {"Host": host, "Origin": origin})
        assert status == 403 and b"[general]" not in body, origin
        assert _get(port, POLL, {"Host": host, "Origin": origin})[0] == 403, origin
        assert _handshake(port, WS, {"Host": host, "Origin": origin}) == 403, origin
    # the editor's own page: same origin passes on every channel
    same = {"Host": host, "Origin": f"http://{host}"}
    status, body = _get(port, "/files/scenario/humvvex.toml", same)
    assert status == 200 and b"[general]" in body
    assert _get(port, POLL, same)[0] == 200
    assert _handshake(port, WS, same) == 101


@pytest.mark.slow
def test_token_on_every_channel_beyond_the_loopback(tmp_path):
    scenario = tmp_path / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    helpers = _helpers()
    with helpers.editor_server(
        scenario, tmp_path / "out", extra=("--host", "127.0.0.2"), check_url=False
    ) as (
        _,
        _,
        proc,
    ):
        address = proc.stdout.readline().split("-> ", 1)[1].strip()
        port = int(address.split(":")[2].split("/")[0])
        token = address.split("token=", 1)[1]
        host = f"127.0.0.2:{port}"
        for _ in range(600):
            try:
                status, _ = _get(port, f"/?token={token}", {"Host": host}, "127.0.0.2")
                break
            except OSError:
                time.sleep(0.1)
        assert status == 200
        cookie = {"Cookie": f"humv_editor_token={token}"}
        same = {"Host": host, "Origin": f"http://{host}"}
        assert _get(port, POLL, same, "127.0.0.2")[0] == 403
        assert _handshake(port, WS, same, "127.0.0.2") == 403
        assert _get(port, POLL, {**same, "Cookie": "humv_editor_token=wrong"}, "127.0.0.2")[0] == 403
        assert _get(port, POLL, {**same, **cookie}, "127.0.0.2")[0] == 200
        assert _handshake(port, WS, {**same, **cookie}, "127.0.0.2") == 101
        # the token does not excuse a foreign Host or Origin
        assert _get(port, f"/?token={token}", {"Host": "evil.example"}, "127.0.0.2")[0] == 421
        assert (
            _handshake(port, WS, {"Host": host, "Origin": "http://evil.example", **cookie}, "127.0.0.2")
            == 403
        )


# -- uploads ---------------------------------------------------------------------------------------
def test_upload_never_replaces_a_file_silently(tmp_path):
    (tmp_path / "walk.bvh").write_bytes(b"old")
    with pytest.raises(UploadExists):
        store_upload(tmp_path, "walk.bvh", b"new")
    assert (tmp_path / "walk.bvh").read_bytes() == b"old"
    store_upload(tmp_path, "walk.bvh", b"new", replace=True)
    assert (tmp_path / "walk.bvh").read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.bvh"]  # no temp file left
    store_upload(tmp_path, "run.bvh", b"x")
    assert (tmp_path / "run.bvh").read_bytes() == b"x"


def test_upload_named_like_the_scenario_needs_valid_bytes(tmp_path):
    scenario = tmp_path / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    before = scenario.read_bytes()
    doc = ScenarioDocument(scenario)
    with pytest.raises(UploadExists):
        store_upload(tmp_path, "humvvex.toml", b"garbage", check=doc.check_replacement)
    for bad in (b"\xff\xfe not text", b"[general\n", b'[general]\nname = "x"\n'):
        with pytest.raises(SaveRefused, match="the file is kept"):
            store_upload(tmp_path, "humvvex.toml", bad, replace=True, check=doc.check_replacement)
        assert scenario.read_bytes() == before
    valid = before.replace(b'name = "', b'name = "new ', 1)
    assert valid != before
    store_upload(tmp_path, "humvvex.toml", valid, replace=True, check=doc.check_replacement)
    assert scenario.read_bytes() == valid
    # other files are not checked as scenarios
    store_upload(tmp_path, "other.toml", b"[sweep]\n", check=doc.check_replacement)


# -- sweep bases -----------------------------------------------------------------------------------
def test_sweep_base_outside_the_folder_is_refused(tmp_path):
    folder = tmp_path / "scenarios"
    folder.mkdir()
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "leak.toml").write_text("[general]\n")
    sweep_file = folder / "sweep.toml"
    for base in ("../outside/leak.toml", str(tmp_path / "outside" / "leak.toml")):
        doc = tomlkit.parse(f'[sweep]\nname = "s"\nbase = "{base}"\n')
        with pytest.raises(InputError, match="sweep.base"):
            sweep_base(folder, sweep_file, doc)
    (folder / "sub").mkdir()
    (folder / "link.toml").symlink_to(tmp_path / "outside" / "leak.toml")
    with pytest.raises(InputError, match="outside"):
        sweep_base(folder, sweep_file, tomlkit.parse('[sweep]\nbase = "link.toml"\n'))
    ok = sweep_base(folder, folder / "sub" / "s.toml", tomlkit.parse('[sweep]\nbase = "../walk.toml"\n'))
    assert ok == (folder / "walk.toml").resolve()
    assert sweep_base(folder, sweep_file, tomlkit.parse("[sweep]\n")) is None


def test_a_scenario_replaced_by_a_folder_or_fifo_is_one_problem_not_a_traceback(tmp_path):
    """The page polls the file every 0.5 s: a folder there logged a traceback each time while
    the page still said valid; a FIFO would hang the server."""
    import os

    scenario = tmp_path / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    doc = ScenarioDocument(scenario)
    assert doc.problems() == []
    scenario.unlink()
    scenario.mkdir()
    assert doc.disk_changed()  # no exception
    doc.reload()
    (problem,) = doc.problems()
    assert "is a folder" in problem and not doc.disk_changed()
    with pytest.raises(SaveRefused):
        doc.save()
    assert scenario.is_dir()
    scenario.rmdir()
    os.mkfifo(scenario)
    doc.reload()  # returns at once
    (problem,) = doc.problems()
    assert "FIFO" in problem


def test_file_keys_may_name_a_library_folder_read_only(tmp_path):
    """A studio's shared asset library: compose reads it, the editor refused it."""
    folder = tmp_path / "scenarios"
    folder.mkdir()
    library = tmp_path / "library"
    library.mkdir()
    (library / "weather.csv").write_text("time,air_temperature_k\n")
    scenario = folder / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    for libraries, allowed in (((), False), ((library,), True)):
        doc = ScenarioDocument(scenario, libraries)
        field = next(f for f in all_fields(doc.raw()) if f.where == "atmosphere.weather_csv")
        for text in ("../library/weather.csv", str(library / "weather.csv")):
            doc.set_text(field, text)
            outside = [
                p for p in doc.problems() if p.startswith("atmosphere.weather_csv") and "only there" in p
            ]
            outside += [p for p in doc.problems() if "expected a path relative to" in p]
            assert (outside == []) == allowed, (libraries, text, outside)
        doc.set_text(field, "../elsewhere/weather.csv")  # outside both
        assert any("outside" in p for p in doc.problems())
    # uploads still go only into the scenario's folder
    with pytest.raises(InputError):
        store_upload(folder, "../library/x.csv", b"x")


@settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(
    fz.methods,
    fz.paths,
    st.sampled_from(["own", "localhost", "foreign", "none"]),
    fz.origins,
    fz.tokens,
    st.binary(max_size=64),
    st.booleans(),
)
@example("GET", "/", "own", "http://[::1", None, b"", False)  # a 500 before (urlsplit ValueError)
@example("GET", WS, "own", "http://[::1", None, b"", True)
def test_random_requests_and_handshakes_never_get_a_500(
    server, method, path, host_kind, origin, token, body, ws
):
    """Issue 26 deliverable 5: random methods, paths, Host, Origin, cookies, bodies and websocket
    upgrades against the real server get the documented answers, never a 5xx."""
    port, _ = server
    host = {
        "own": f"127.0.0.1:{port}",
        "localhost": f"localhost:{port}",
        "foreign": "evil.example",
        "none": None,
    }[host_kind]
    headers = [("Host", host)] if host is not None else []
    if origin is not None:
        origin = origin.replace(str(fz.PORT), str(port))
        headers.append(("Origin", origin))
    if token is not None:
        headers.append(("Cookie", f"{fz.TOKEN_COOKIE}={token}"))
    if ws:
        method, body = "GET", b""
        headers += [
            ("Connection", "Upgrade"),
            ("Upgrade", "websocket"),
            ("Sec-WebSocket-Version", "13"),
            ("Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="),
        ]
    headers = [(k, v) for k, v in headers if not any(c in v for c in "\r\n\x00")]
    status = fz.raw_request(port, method, path.replace("\r", "").replace("\n", ""), headers, body)
    assert status > 0 and not 500 <= status < 600, (method, path, headers, status)
    if host_kind in ("foreign", "none"):
        assert status in (400, 403, 421), status  # h11 answers a missing Host with 400
    elif origin is not None and status not in (400, 421):
        if origin.lower().rstrip("/") != f"http://{host}".lower():
            assert status == 403, (origin, status)
