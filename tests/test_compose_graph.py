"""compose as a layer graph: build order from the tools' UPSTREAM, per-layer cache keys (only the
layers whose inputs changed are rebuilt, and those reading them), hand edits kept or refused,
user sublayers kept and stronger."""

from __future__ import annotations

import copy
import json
import shutil
import subprocess
import sys

import pytest
from conftest import HUMVVEX, HUMVVEX_LAYERS, ROOT
from pxr import Sdf, Usd, UsdGeom

from humv_usd.errors import InputError
from humv_usd.pipeline import graph
from humv_usd.pipeline.compose import compose, plan
from humv_usd.scenario import validate
from humv_usd.scenario.inputs import inputs_key, read_values
from humv_usd.scene import layer as scene_layer

ALL = list(HUMVVEX_LAYERS)


@pytest.fixture(scope="module")
def base(tmp_path_factory, humvvex_raw):
    """humvvex composed once; each test works on a copy."""
    out = tmp_path_factory.mktemp("graph") / "base"
    report = compose(validate(humvvex_raw), out)
    assert report.rebuilt == list(report.states) and set(report.rebuilt) == set(ALL)
    return out


@pytest.fixture
def out(base, tmp_path):
    dst = tmp_path / "o"
    shutil.copytree(base, dst)
    return dst


def test_build_order_respects_upstream(humvvex_raw):
    scenario = validate(humvvex_raw)
    nodes = graph.layer_graph(scenario, plan(scenario)[0])
    order = graph.build_order(nodes)
    assert sorted(order) == sorted(ALL)
    for name in order:
        assert all(order.index(u) < order.index(name) for u in nodes[name].upstream), name
    assert nodes["clothing_p1"].upstream == ("avatar_p1",)
    # the sky reads only the weather and sun; the per-sensor paths read the cameras and scene too
    assert nodes["atmosphere"].upstream == ("environment",)
    assert set(nodes["atmosphere_paths"].upstream) == {"environment", "atmosphere", "scene", "sensors"}
    assert set(nodes["thermal"].upstream) == {
        "environment",
        "atmosphere",
        "materials",
        "scene",
        "avatar_p1",
        "clothing_p1",
        "sensors",  # the ground's shadow edges follow the cameras' pixel footprint (issue 25)
    }
    # strength is its own order: strongest first, not the build order
    assert graph.strength_order(nodes) == [
        "thermal",
        "sensors",
        "clothing_p1",
        "avatar_p1",
        "scene",
        "materials",
        "atmosphere_paths",
        "atmosphere",
        "environment",
    ]


def _tool(name, upstream=()):
    return graph.Tool(name, (), tuple(upstream), "1", None)


def test_plan_gives_an_unplanned_tool_its_layer_when_its_upstream_is_there(humvvex_raw, monkeypatch):
    """A tool the plan has no rule for gets one layer per person when that person's upstream
    layer is planned, and is skipped, with what it needs, when an upstream layer is not."""
    tools = dict(graph.discover_tools())
    tools["gait_{id}"] = _tool("gait_{id}", ["avatar_{id}"])
    tools["lidar"] = _tool("lidar", ["sensors", "radar"])
    monkeypatch.setattr("humv_usd.pipeline.compose.discover_tools", lambda: tools)
    needed, skipped = plan(validate(humvvex_raw))
    assert "gait_p1" in needed and "lidar" not in needed
    assert ("lidar", "needs sensors, radar") in skipped


def test_a_new_tool_slots_in_by_its_declarations():
    """A layer (e.g. sensor paths reading atmosphere and sensors) is built after its upstream
    layers, whatever the order it is listed in, and sits just above its strongest upstream layer."""
    tools = [
        _tool("paths", ["atmosphere", "sensors"]),
        _tool("sensors"),
        _tool("atmosphere"),
        _tool("thermal"),
    ]
    nodes = {t.name: graph.Node(t.name, t, None, t.upstream) for t in tools}
    order = graph.build_order(nodes)
    assert order.index("paths") > max(order.index("atmosphere"), order.index("sensors"))
    assert graph.strength_order(nodes) == ["thermal", "paths", "sensors", "atmosphere"]
    loop = {"a": graph.Node("a", _tool("a"), None, ("b",)), "b": graph.Node("b", _tool("b"), None, ("a",))}
    with pytest.raises(InputError, match="cycle"):
        graph.build_order(loop)


def test_every_tool_declares_what_it_reads(humvvex_raw):
    tools = graph.discover_tools()
    assert set(tools) == {
        "environment",
        "atmosphere",
        "atmosphere_paths",
        "materials",
        "scene",
        "avatar_{id}",
        "clothing_{id}",
        "sensors",
        "thermal",
    }
    scenario = validate(humvvex_raw)
    for tool in tools.values():
        assert tool.version and tool.reads
        values = read_values(scenario, tool.reads, "p1")
        assert values and all(isinstance(k, str) for k in values)  # every read path resolves


def test_read_values_pick_exactly_what_is_read(raw):
    a = validate(raw)
    raw["sensor"][1]["position_m"] = [0.9, -15.0, 1.6]
    b = validate(raw)
    reads = ("sensor.*.position_m", "human[{id}]", "placement[{id}]", "@ids")
    va, vb = read_values(a, reads, "p1"), read_values(b, reads, "p1")
    assert va["sensor.1.position_m"] == [0.8, -15.0, 1.6] and vb["sensor.1.position_m"] == [0.9, -15.0, 1.6]
    assert {k for k in va if va[k] != vb[k]} == {"sensor.1.position_m"}
    assert va["human[p1].clothing"] == ["hair_short", "tshirt_white", "shorts", "cap", "shoes"]
    assert va["placement[p1].heading_deg"] == 180.0
    assert va["@ids"] == {"human:p1": 1, "ground": 2, "object:warehouse": 3}
    assert inputs_key("1", va, {}) != inputs_key("1", vb, {})
    assert inputs_key("1", va, {}) != inputs_key("2", va, {})  # the tool version enters the key
    assert inputs_key("1", va, {"x": "k1"}) != inputs_key("1", va, {"x": "k2"})


def test_files_named_by_the_scenario_are_read_by_content(raw, tmp_path):
    csv = tmp_path / "w.csv"
    csv.write_text("time,air_temperature_k\n2018-10-24T13:00:00,288.0\n2018-10-24T15:00:00,290.0\n")
    raw["atmosphere"]["weather_csv"] = str(csv)
    before = read_values(validate(raw), ["atmosphere.weather_csv"])
    csv.write_text("time,air_temperature_k\n2018-10-24T13:00:00,288.0\n2018-10-24T15:00:00,291.0\n")
    after = read_values(validate(raw), ["atmosphere.weather_csv"])
    assert before != after and str(csv) in after["atmosphere.weather_csv"]


def test_unchanged_rerun_builds_nothing(out, humvvex_raw, monkeypatch):
    def no_build(*args, **kwargs):
        raise AssertionError("a tool ran on an unchanged scenario")

    monkeypatch.setattr(graph.Tool, "build", no_build)
    mtimes = {p: p.stat().st_mtime_ns for p in out.rglob("*.usda")}
    report = compose(validate(humvvex_raw), out)
    assert report.rebuilt == [] and report.written == []
    assert {s.state for s in report.states.values()} == {"cached"}
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*.usda")} == mtimes
    doc = json.loads((out / "compose.json").read_text())
    assert doc["summary"].startswith("9 layers: 9 cached")
    assert set(doc["ran"]) == {
        "environment",
        "atmosphere",
        "atmosphere_paths",
    }  # carried over from the run that built them


def _edit(raw, key):
    if key == "sensor position":
        raw["sensor"][0]["position_m"] = [0.0, -14.0, 1.6]
    elif key == "clothing":
        raw["human"][0]["clothing"] = ["tshirt_white", "shorts"]
    elif key == "start":
        raw["general"]["start"] = raw["general"]["start"].replace(hour=15)
    elif key == "weather":
        raw["atmosphere"]["air_temperature_k"] = 290.0
    elif key == "sensor netd and agc":
        raw["sensor"][0]["netd_k"] = 0.04
        raw["sensor"][1]["agc"] = "linear"
    return raw


# which layers a single-key edit of humvvex rebuilds. The sensors' path tables are their own
# layer (atmosphere_paths), so a sensor move leaves the sky; the thermal layer refines the
# ground's shadow edges to the cameras' pixel footprint (issue 25), so it follows the cameras;
# the clock and the weather change the sky, the paths and the temperatures.
REBUILT = {
    "sensor position": {"sensors", "atmosphere_paths", "thermal"},
    "clothing": {"materials", "clothing_p1", "thermal"},  # the avatar reads no garment but the rifle
    "start": {"environment", "atmosphere", "atmosphere_paths", "thermal"},
    "weather": {"environment", "atmosphere", "atmosphere_paths", "thermal"},
    # the image chain is read by the render alone (sensors.layer.RENDER_ONLY): the layers built on
    # the sensors layer see its key without it (issue 26: the editor's preview rebuilt thermal)
    "sensor netd and agc": {"sensors"},
}


@pytest.mark.parametrize("key", list(REBUILT))
def test_single_key_edit_rebuilds_exactly_what_reads_it(out, raw, key):
    report = compose(validate(_edit(raw, key)), out)
    assert set(report.rebuilt) == REBUILT[key]
    assert set(report.written) <= REBUILT[key] | {"stage"}
    doc = {e["name"]: e for e in json.loads((out / "compose.json").read_text())["layers"]}
    for name in ALL:
        assert doc[name]["state"] == ("rebuilt" if name in REBUILT[key] else "cached")
        assert (
            Sdf.Layer.OpenAsAnonymous(str(out / "layers" / f"{name}.usda")).customLayerData["humv:inputsKey"]
            == doc[name]["key"]
        )
    if key == "sensor position":
        assert doc["sensors"]["why"] == "inputs changed: sensor.0.position_m"
        assert doc["atmosphere_paths"]["why"] == "upstream changed: sensors"
        assert doc["atmosphere"]["why"] == doc["avatar_p1"]["why"] == "cached"
        assert doc["thermal"]["why"] == "upstream changed: sensors"
    if key == "clothing":
        assert doc["clothing_p1"]["why"] == "inputs changed: human[p1].clothing"
    if key == "sensor netd and agc":
        assert doc["sensors"]["why"] == "inputs changed: @netdOrigin, sensor.0.netd_k, sensor.1.agc"
        assert doc["thermal"]["why"] == doc["atmosphere_paths"]["why"] == "cached"
        from humv_usd.sweep.plan import layer_keys  # the sweep predicts the same keys

        assert layer_keys(validate(raw)) == {n: doc[n]["key"] for n in ALL}


def test_scene_reads_the_clock_and_air_only_for_warm_clutter(raw):
    """The scene layer's key follows the start time and the air only when there is clutter (its
    held temperatures); humvvex has none, so its scene stays cached (REBUILT above)."""

    def key(edit, clutter):
        r = copy.deepcopy(raw)
        if clutter:
            r["scene"]["clutter"] = [{"id": "rex", "kind": "dog", "position_m": [1.0, 2.0, 0.0]}]
        if edit == "weather":
            r["atmosphere"]["air_temperature_k"] = 290.0
        elif edit == "start":
            r["general"]["start"] = r["general"]["start"].replace(hour=15)
        return inputs_key(scene_layer.VERSION, read_values(validate(r), scene_layer.READS), {})

    for edit in ("weather", "start"):
        assert key(edit, clutter=False) == key(None, clutter=False)
        assert key(edit, clutter=True) != key(None, clutter=True)


def test_key_records_upstream_and_reads(out):
    doc = {e["name"]: e for e in json.loads((out / "compose.json").read_text())["layers"]}
    assert doc["clothing_p1"]["upstream"] == {"avatar_p1": doc["avatar_p1"]["key"]}
    assert "human[{id}].stature_m" in doc["avatar_p1"]["reads"]
    assert "human[{id}].clothing" not in doc["avatar_p1"]["reads"]
    assert doc["sensors"]["inputs"]["sensor.0.position_m"] == [0.0, -15.0, 1.6]


def _hand_edit(path, old, new):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new))


def test_hand_edit_kept_while_inputs_unchanged_and_read_downstream(out, humvvex_raw):
    layer = out / "layers" / "avatar_p1.usda"
    _hand_edit(layer, "HumV-USD avatar layer for p1", "HumV-USD avatar layer for p1 (hand edited)")
    edited = layer.read_text()
    report = compose(validate(humvvex_raw), out)
    assert report.states["avatar_p1"].state == "kept hand edit"
    assert layer.read_text() == edited
    # the layers that read the avatar are rebuilt on the edited file; a second run keeps all
    assert set(report.rebuilt) == {"clothing_p1", "thermal"}
    assert report.states["thermal"].why == "upstream changed: avatar_p1, clothing_p1"
    again = compose(validate(humvvex_raw), out)
    assert again.rebuilt == [] and again.states["avatar_p1"].state == "kept hand edit"


def test_hand_edit_in_the_way_stops_compose_and_force_overwrites(out, raw):
    layer = out / "layers" / "sensors.usda"
    _hand_edit(layer, "focalLength = ", "focalLength = 1")
    edited = layer.read_text()
    mtimes = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    scenario = validate(_edit(raw, "sensor position"))
    with pytest.raises(InputError) as err:
        compose(scenario, out)
    (line,) = err.value.problems
    assert str(layer) in line and "--force" in line and "user layer" in line
    assert "inputs changed: sensor.0.position_m" in line
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == mtimes  # nothing written
    report = compose(scenario, out, force=True)
    assert "sensors" in report.rebuilt and layer.read_text() != edited
    assert "hand edit overwritten" in report.states["sensors"].why


USER_LAYER = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Z"
)

over "World"
{
    over "Sensors"
    {
        over "atom1024_lwir"
        {
            float focalLength = 99
        }
    }
}
"""


def test_user_sublayer_survives_reruns_and_wins(out, raw):
    (out / "fix.usda").write_text(USER_LAYER)
    root = Sdf.Layer.FindOrOpen(str(out / "stage.usda"))
    root.subLayerPaths.insert(0, "./fix.usda")
    root.Save()
    report = compose(validate(raw), out)
    assert report.user_layers == ["./fix.usda"]
    # tools reading the stage see the user layer: its content enters their keys (the atmosphere
    # reads weather and sun off the stage, its paths the cameras and scene too)
    assert set(report.rebuilt) == {"atmosphere", "atmosphere_paths", "clothing_p1", "thermal"}
    report = compose(validate(_edit(raw, "sensor position")), out)
    assert "sensors" in report.rebuilt
    text = (out / "stage.usda").read_text()
    assert text.index("./fix.usda") < text.index("./layers/thermal.usda")
    stage = Usd.Stage.Open(str(out / "stage.usda"), Usd.Stage.LoadAll)
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/World/Sensors/atom1024_lwir"))
    assert cam.GetFocalLengthAttr().Get() == pytest.approx(99.0)
    assert compose(validate(raw), out).user_layers == ["./fix.usda"]


def test_root_edited_by_hand_is_refused_when_it_would_change(out, raw):
    _hand_edit(out / "stage.usda", "composed by humv-usd compose", "composed by hand")
    assert compose(validate(raw), out).written == []  # nothing to change: the edit stays
    assert "composed by hand" in (out / "stage.usda").read_text()
    raw["general"]["description"] = "another"
    with pytest.raises(InputError, match="stage.usda: edited by hand"):
        compose(validate(raw), out)


@pytest.mark.slow
def test_cli_refuses_hand_edit_with_one_line_exit_2(out, tmp_path):
    _hand_edit(out / "layers" / "sensors.usda", "focalLength = ", "focalLength = 1")
    toml = tmp_path / "moved.toml"
    text = HUMVVEX.read_text()
    toml.write_text(text.replace("position_m = [0.0, -15.0, 1.6]", "position_m = [0.0, -14.0, 1.6]"))
    run = [sys.executable, "-m", "humv_usd.cli.main", "compose", str(toml), "-o", str(out)]
    r = subprocess.run(run, cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--force" in r.stderr
    r = subprocess.run([*run, "--force"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (
        r.stdout.strip().splitlines()[-1].endswith("s)")
        and "3 rebuilt (sensors, atmosphere_paths, thermal), 6 cached" in r.stdout
    )


def test_hand_edited_layer_the_scenario_drops_is_not_removed_silently(out, raw):
    layer = out / "layers" / "sensors.usda"
    _hand_edit(layer, "focalLength = ", "focalLength = 1")
    del raw["sensor"]
    with pytest.raises(InputError, match="sensors.usda: edited by hand, and the scenario no longer has"):
        compose(validate(raw), out)
    assert layer.is_file()
    report = compose(validate(raw), out, force=True)
    assert not layer.exists() and "sensors.usda" in report.removed
