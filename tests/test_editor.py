"""The HumV editor's parts without a browser: fields from the spec, validation messages equal
to the command line's, tomlkit saving, disk changes, path safety, plan, jobs, preview colours."""

from __future__ import annotations

import difflib
import math
import os
import shutil
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from humv_usd.catalog.sensors import scenario_values
from humv_usd.editor.document import SaveRefused, ScenarioDocument
from humv_usd.editor.fields import Field, all_fields, section_groups, unit_of
from humv_usd.editor.jobs import JobManager
from humv_usd.editor.plan import plan_svg
from humv_usd.editor.preview import COLOUR_MAP, colourise
from humv_usd.editor.safety import MAX_UPLOAD_BYTES, inside, upload_target
from humv_usd.errors import InputError
from humv_usd.scenario import load_scenario
from humv_usd.scenario.spec import SECTIONS, Key

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "humvvex.toml"


@pytest.fixture
def humvvex(tmp_path) -> Path:
    path = tmp_path / "humvvex.toml"
    shutil.copy(EXAMPLE, path)
    return path


def _field(doc: ScenarioDocument, where: str) -> Field:
    return next(f for f in all_fields(doc.raw()) if f.where == where)


def test_every_spec_key_is_a_field(humvvex):
    doc = ScenarioDocument(humvvex)
    wheres = {f.where for f in all_fields(doc.raw())}
    for name, section in SECTIONS.items():
        if section.array:
            count = len(doc.raw().get(name, []))
            expected = {f"{name}[{i}].{k}" for i in range(count) for k in section.keys}
        else:
            expected = {f"{name}.{k}" for k in section.keys}
        assert expected <= wheres, sorted(expected - wheres)
    n_objects = len(doc.raw()["scene"]["object"])
    assert {
        f"scene.object[{i}].{k}"
        for i in range(n_objects)
        for k in SECTIONS["scene"].subsections["object"].keys
    } <= wheres
    assert {f"scene.ground.{k}" for k in SECTIONS["scene"].subsections["ground"].keys} <= wheres


def test_a_new_spec_key_appears_without_editor_code(humvvex, monkeypatch):
    monkeypatch.setitem(
        SECTIONS["thermal"].keys,
        "wetness_k",
        Key("float", "A key added to the spec [K].", default=1.5, lo=0.0, hi=9.0),
    )
    doc = ScenarioDocument(humvvex)
    f = _field(doc, "thermal.wetness_k")
    assert (f.unit, f.allowed, f.default_text) == ("K", "0.0..9.0", "1.5")
    assert "A key added to the spec" in f.help
    doc.set_text(f, "12")
    assert "thermal.wetness_k = 12: allowed range 0.0..9.0" in doc.problems()


def test_units_from_help_text_and_suffix():
    assert unit_of("position_m", SECTIONS["placement"].keys["position_m"]) == "m"
    assert unit_of("latitude_deg", SECTIONS["general"].keys["latitude_deg"]) == "deg north"
    assert unit_of("speed_m_s", SECTIONS["human"].keys["speed_m_s"]) == "m/s"
    assert unit_of("x_k", Key("float", "no bracket")) == "K"


@pytest.mark.parametrize(
    ("where", "text", "toml_line"),
    [
        ("sensor[1].netd_k", "9", "netd_k = 9"),
        ("general.latitude_deg", "95.5", "latitude_deg = 95.5"),
        ("sensor[0].resolution", "[0, 768]", "resolution = [0, 768]"),
        ("human[0].build", "stocky", 'build = "stocky"'),
    ],
)
def test_messages_are_the_command_lines(humvvex, tmp_path, where, text, toml_line):
    """The page's problem equals the line load_scenario (humv-usd compose) prints for the same file."""
    doc = ScenarioDocument(humvvex)
    doc.set_text(_field(doc, where), text)
    page = doc.problems()
    cli_file = tmp_path / "cli.toml"
    cli_file.write_text(doc.text)
    with pytest.raises(InputError) as exc:
        load_scenario(cli_file)
    cli = [p.removeprefix(f"{cli_file}: ") for p in exc.value.problems]
    assert page == cli and len(page) == 1
    assert toml_line in doc.text
    at, other = ScenarioDocument.problems_by_field(page, all_fields(doc.raw()))
    assert list(at) == [where] and not other


def test_text_that_is_not_a_value_is_named_and_not_saved(humvvex):
    doc = ScenarioDocument(humvvex)
    before = humvvex.read_bytes()
    problem = doc.set_text(_field(doc, "sensor[0].position_m"), "[1, 2")
    assert problem.startswith("sensor[0].position_m = '[1, 2': not a TOML value")
    with pytest.raises(SaveRefused):
        doc.save()
    assert humvvex.read_bytes() == before


def test_save_keeps_comments_and_order(humvvex):
    doc = ScenarioDocument(humvvex)
    original = humvvex.read_text().splitlines()
    doc.set_text(_field(doc, "sensor[0].bit_depth"), "12")
    doc.set_text(_field(doc, "thermal.spin_up_s"), "600.0")
    assert doc.save() == []
    saved = humvvex.read_text().splitlines()
    diff = [line for line in difflib.ndiff(original, saved) if line[:1] in "+-"]
    assert diff == [
        "- bit_depth = 14                 # a table value wins over the preset's (here the same)",
        "+ bit_depth = 12                 # a table value wins over the preset's (here the same)",
        "+ spin_up_s = 600.0",
    ]
    thermal = saved.index("[thermal]                      # tab (vi)")
    assert saved.index("spin_up_s = 600.0") == thermal + 3  # after the table's last key
    assert load_scenario(humvvex)["thermal"]["spin_up_s"] == 600.0
    assert not list(humvvex.parent.glob(".humvvex.*"))  # no temporary file left


def test_invalid_scenario_cannot_replace_a_valid_file(humvvex):
    doc = ScenarioDocument(humvvex)
    before = humvvex.read_bytes()
    doc.set_text(_field(doc, "general.fps"), "0")
    with pytest.raises(SaveRefused, match="would replace a valid humvvex.toml"):
        doc.save()
    assert humvvex.read_bytes() == before
    doc.set_text(_field(doc, "general.fps"), "25.0")
    doc.save()
    assert load_scenario(humvvex)["general"]["fps"] == 25.0


def test_new_file_and_array_tables(tmp_path):
    path = tmp_path / "new.toml"
    doc = ScenarioDocument(path)
    assert not path.exists() and doc.problems() == []
    i = doc.add_table(("sensor",))
    assert "sensor[0].id: missing required key" in " ".join(doc.problems())
    fields = {f.where: f for f in all_fields(doc.raw())}
    doc.set_text(fields["sensor[0].id"], "cam")
    doc.set_text(fields["sensor[0].preset"], "lwir640_12um")
    doc.set_text(fields["sensor[0].position_m"], "[0, -10, 1.5]")
    doc.set_text(fields["sensor[0].look_at_m"], "[0, 0, 1]")
    doc.add_table(("scene", "object"))
    doc.remove_table(("scene", "object"), 0)
    assert doc.problems() == [] and i == 0
    doc.save()
    assert load_scenario(path)["sensor"][0]["resolution"] == [640, 512]
    groups, slots = section_groups(doc.raw(), "scene")
    tables = [f"scene.{n}" for n, sub in SECTIONS["scene"].subsections.items() if not sub.array]
    assert [g.where for g in groups] == ["scene", *tables] and "scene.ground" in tables
    expected = [f"scene.{n}" for n, sub in SECTIONS["scene"].subsections.items() if sub.array]
    # every array of [scene] gets a slot (nested ones of its tables too, e.g. scene.terrain.cut)
    assert "scene.object" in expected and set(expected) <= {s.where for s in slots}


def test_change_on_disk_is_detected(humvvex):
    doc = ScenarioDocument(humvvex)
    assert not doc.disk_changed()
    humvvex.write_text(humvvex.read_text().replace('name = "humvvex"', 'name = "other"'))
    assert doc.disk_changed()
    doc.set_text(_field(doc, "general.seed"), "3")
    with pytest.raises(SaveRefused, match="changed on disk"):
        doc.save()
    assert 'name = "other"' in humvvex.read_text()
    doc.save(overwrite_disk_change=True)
    assert load_scenario(humvvex)["general"]["seed"] == 3 and not doc.disk_changed()
    doc.reload()
    assert doc.raw()["general"]["name"] == "humvvex"


def test_paths_outside_the_folders_are_refused(tmp_path):
    root = tmp_path / "scenario"
    (root / "sub").mkdir(parents=True)
    (root / "sub" / "ok.bvh").write_text("x")
    (tmp_path / "secret.txt").write_text("x")
    os.symlink(tmp_path / "secret.txt", root / "link.txt")
    assert inside(root, "sub/ok.bvh") == (root / "sub" / "ok.bvh").resolve()
    for bad in ("../secret.txt", "sub/../../secret.txt", str(tmp_path / "secret.txt"), "link.txt", "a\x00b"):
        with pytest.raises(InputError):
            inside(root, bad)
    with pytest.raises(InputError, match="at most"):
        upload_target(root, "walk.bvh", MAX_UPLOAD_BYTES + 1)
    for name in ("../walk.bvh", "x/walk.bvh", "run.sh", ".hidden.bvh"):
        with pytest.raises(InputError):
            upload_target(root, name, 10)
    assert upload_target(root, "walk 1.bvh", 10) == (root / "walk 1.bvh").resolve()


def test_file_keys_outside_the_scenario_folder_are_problems(humvvex, tmp_path):
    outside = tmp_path.parent / "elsewhere.csv"
    doc = ScenarioDocument(humvvex)
    doc.set_text(_field(doc, "atmosphere.weather_csv"), f"../{outside.name}")
    assert any(p.startswith("atmosphere.weather_csv = ") and "outside" in p for p in doc.problems())


def _polygon(g) -> np.ndarray:
    poly = g.find("{http://www.w3.org/2000/svg}polygon")
    return np.array([[float(v) for v in p.split(",")] for p in poly.get("points").split()])


def test_plan_shows_every_sensor_with_its_field_of_view(humvvex):
    scenario = load_scenario(humvvex)
    root = ET.fromstring(plan_svg(scenario, 193.8, 52.7))
    ns = "{http://www.w3.org/2000/svg}"
    sensors = {g.get("data-id"): g for g in root.iter(f"{ns}g") if g.get("class") == "sensor"}
    assert list(sensors) == [s["id"] for s in scenario["sensor"]]
    assert [g.get("data-id") for g in root.iter(f"{ns}g") if g.get("class") == "person"] == ["p1"]
    assert [g.get("data-id") for g in root.iter(f"{ns}g") if g.get("class") == "object"] == ["warehouse"]
    assert float(next(g for g in root.iter(f"{ns}g") if g.get("class") == "sun").get("data-azimuth")) == 193.8
    # the frustum's opening angle is the preset's horizontal field of view: 2 atan(w p / 2 f)
    preset = scenario_values("atom1024_lwir")
    fov = 2 * math.atan(
        preset["resolution"][0] * preset["pixel_pitch_um"] * 1e-3 / (2 * preset["focal_length_mm"])
    )
    apex, left, right = _polygon(sensors["atom1024_lwir"])
    a, b = left - apex, right - apex
    angle = math.acos(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    assert angle == pytest.approx(fov, abs=2e-3)
    # the camera looks north (up on the plan): the wedge opens towards smaller y
    assert (left[1] + right[1]) / 2 < apex[1]


def test_plan_aerial_orbit_and_walk_path(humvvex):
    text = (
        humvvex.read_text()
        .replace(
            "position_m = [-1.6, -15.0, 1.6]\nlook_at_m = [0.0, 0.0, 1.0]",
            'platform = "aerial"\nlook_at_m = [0.0, 0.0, 0.0]\norbit_radius_m = 50.0',
        )
        .replace('activity = "stand"', 'activity = "walk"')
        .replace(
            "heading_deg = 180.0            # facing south, towards the camera",
            "heading_deg = 90.0\nwaypoints_m = [[5.0, 0.0], [5.0, 5.0]]",
        )
    )
    humvvex.write_text(text)
    svg = plan_svg(load_scenario(humvvex))
    root = ET.fromstring(svg)
    ns = "{http://www.w3.org/2000/svg}"
    orbit = next(c for c in root.iter(f"{ns}circle") if c.get("class") == "orbit")
    walk = next(p for p in root.iter(f"{ns}polyline") if p.get("class") == "walk")
    assert float(orbit.get("r")) > 0 and len(walk.get("points").split()) == 3


def test_jobs_run_argument_lists_and_cancel(tmp_path):
    jobs = JobManager()
    with pytest.raises(TypeError):
        jobs.start("compose", ["echo hi; rm -rf /"], tmp_path, tmp_path)  # a string, not argument lists
    py = sys.executable
    job = jobs.start(
        "compose", [[py, "-c", "print('one')"], [py, "-c", "print('two; $(x)')"]], tmp_path, tmp_path
    )
    _wait(job)
    assert job.state == "done" and "one" in job.lines and "two; $(x)" in job.lines and job.progress == 1.0
    failed = jobs.start(
        "render", [[py, "-c", "import sys; sys.exit(3)"], [py, "-c", "print('never')"]], tmp_path, tmp_path
    )
    _wait(failed)
    assert failed.state == "failed" and failed.returncode == 3 and "never" not in failed.lines
    slow = jobs.start(
        "render", [[py, "-c", "import time; print('go', flush=True); time.sleep(60)"]], tmp_path, tmp_path
    )
    while "go" not in slow.lines:
        time.sleep(0.05)
    slow.cancel()
    _wait(slow)
    assert slow.state == "cancelled" and slow.seconds < 30
    assert jobs.latest() is slow and jobs.latest("compose") is job


def test_warm_jobs_run_humv_usd_in_one_process_with_its_exit_codes(tmp_path):
    """Preview jobs run their humv-usd steps in the warm worker (cli.warm): the same output and
    exit codes as the command line, one process for every step, a failing step stops the job,
    cancel ends the worker and the next step starts a new one."""
    from humv_usd.editor.jobs import humv_command

    jobs = JobManager()
    try:
        missing = str(tmp_path / "missing.toml")
        job = jobs.start(
            "preview",
            [humv_command("--version"), humv_command("compose", missing, "-o", str(tmp_path / "o"))],
            tmp_path,
            tmp_path,
            warm=True,
        )
        _wait(job)
        assert any("version" in line for line in job.lines)
        errors = [line for line in job.lines if line.startswith("humv-usd: error:")]
        assert (
            job.state == "failed" and job.returncode == 2 and len(errors) == 1 and "missing.toml" in errors[0]
        )
        worker = jobs._warm
        again = jobs.start("preview", [humv_command("--version")], tmp_path, tmp_path, warm=True)
        _wait(again)
        assert again.state == "done" and jobs._warm is worker  # the same process, still warm
        again.cancel()  # a finished job: nothing to stop
        assert worker.poll() is None
    finally:
        jobs.shutdown()
    assert worker.poll() is not None  # the server's shutdown ends the worker


def test_warm_worker_reads_layers_changed_on_disk(tmp_path):
    """A stage a reference cycle keeps alive keeps its layers in USD's registry, and
    Usd.Stage.Open then reuses them: the warm worker's render after a NETD edit read the
    sensors layer from before the edit. fresh_layers() makes the next command read the file."""
    import gc

    from pxr import Usd

    from humv_usd.cli.warm import fresh_layers

    path = tmp_path / "s.usda"
    path.write_text('#usda 1.0\ndef "A" {\n    float netd = 0.05\n}\n')

    class Holder:  # a cycle, as some object graph in a command may leave behind
        pass

    holder = Holder()
    holder.me, holder.stage = holder, Usd.Stage.Open(str(path))
    del holder
    gc.disable()
    try:
        path.write_text('#usda 1.0\ndef "A" {\n    float netd = 0.04\n}\n')
        stage = Usd.Stage.Open(str(path))
        stale = stage.GetPrimAtPath("/A").GetAttribute("netd").Get()
        del stage
        fresh_layers()
        stage = Usd.Stage.Open(str(path))
        now = stage.GetPrimAtPath("/A").GetAttribute("netd").Get()
    finally:
        gc.enable()
    assert stale == pytest.approx(0.05) and now == pytest.approx(0.04)


def _wait(job, limit: float = 60.0) -> None:
    t0 = time.time()
    while not job.finished:
        assert time.time() - t0 < limit
        time.sleep(0.05)
    time.sleep(0.05)  # the final line


def test_preview_colours_span_the_levels():
    from matplotlib import colormaps

    t = np.array([[280.0, 300.0, np.nan], [250.0, 320.0, 290.0]])
    rgb = colourise(t, 280.0, 300.0)
    cmap = colormaps[COLOUR_MAP]
    assert rgb.dtype == np.uint8 and rgb.shape == (2, 3, 3)
    np.testing.assert_array_equal(rgb[0, 0], np.rint(np.array(cmap(0.0)[:3]) * 255))
    np.testing.assert_array_equal(rgb[0, 1], np.rint(np.array(cmap(1.0)[:3]) * 255))
    np.testing.assert_array_equal(rgb[0, 2], [0, 0, 0])
    np.testing.assert_array_equal(rgb[1, 0], rgb[0, 0])  # clipped below
    np.testing.assert_array_equal(rgb[1, 2], np.rint(np.array(cmap(0.5)[:3]) * 255))


@pytest.mark.slow
def test_stage_view_has_every_mesh_triangle_and_camera(humvvex, tmp_path):
    """The GLB of the 3D view holds the composed stage's triangles (counted with pxr) and its cameras."""
    import trimesh
    from pxr import Usd, UsdGeom

    from humv_usd.editor.stage3d import stage_view
    from humv_usd.pipeline.compose import compose

    out = tmp_path / "out"
    compose(load_scenario(humvvex), out)
    view = stage_view(out / "stage.usda", out / ".editor" / "stage.glb")
    stage = Usd.Stage.Open(str(out / "stage.usda"))
    expected = 0
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(prim)
            n = int(np.sum(np.asarray(mesh.GetFaceVertexCountsAttr().Get()) - 2))
            expected += n * (2 if mesh.GetDoubleSidedAttr().Get() else 1)
    assert view.triangles == expected
    loaded = trimesh.load(view.glb, force="scene")
    assert sum(len(g.faces) for g in loaded.geometry.values()) == expected
    assert [c.name for c in view.cameras] == [s["id"] for s in load_scenario(humvvex)["sensor"]]
    np.testing.assert_allclose(view.cameras[0].origin, [0.0, -15.0, 1.6], atol=1e-6)
    # the view shows every rendered mesh, the ground's horizon rings included: its bounds are the
    # GLB's, out to [scene.ground] horizon_m (20 km by default, square rings) around the 120 m
    # ground
    np.testing.assert_allclose(np.asarray(view.bounds), loaded.bounds, atol=1e-3)
    horizon = load_scenario(humvvex)["scene"]["ground"]["horizon_m"]
    assert horizon == 20000.0
    np.testing.assert_allclose(view.bounds[0][:2], [-horizon, -horizon])
    np.testing.assert_allclose(view.bounds[1][:2], [horizon, horizon])
    # the view is framed on view.focus: the person (about 1.78 m tall at the origin) and the four
    # cameras 15 m south, never the horizon
    lo, hi = view.focus
    assert np.all(hi - lo < 30.0) and lo[1] == pytest.approx(-15.0) and 1.6 < hi[2] < 2.1
    assert lo[2] == pytest.approx(0.0, abs=0.05) and hi[0] == pytest.approx(0.8, abs=0.5)


def test_full_preview_is_the_real_compose_and_a_small_forced_render(humvvex, tmp_path):
    """The full-quality preview composes the scenario file itself into the output folder (one
    layer cache with Compose and the 3D view) and renders frame 0 of one sensor, binned to at
    most PREVIEW_WIDTH_PX columns, with --force (before 2026-11-27: a one-sensor binned copy
    composed apart at full cost, and every preview after an edit failed: the render refused a
    folder rendered from another stage)."""
    from humv_usd.editor.preview import PREVIEW_WIDTH_PX, preview_commands, preview_resolution

    scenario = load_scenario(humvvex)
    # lwir640: 640x512 at 12 um -> k = 2: 320x256 (24 um pitch, the same field of view)
    assert preview_resolution(scenario, "lwir640") == (320, 256)
    # atom1024: 1024x768 -> k = ceil(1024 / 320) = 4: 256x192
    assert preview_resolution(scenario, "atom1024_lwir") == (256, 192)
    # the EO camera 1440x1080 at 3.45 um -> k = 5: 288x216
    assert preview_resolution(scenario, "eo_rgb") == (288, 216)
    for s in scenario["sensor"]:
        w, h = preview_resolution(scenario, s["id"])
        assert w <= PREVIEW_WIDTH_PX and abs(w / h - s["resolution"][0] / s["resolution"][1]) < 0.02
    out = tmp_path / "out"
    compose, render = preview_commands(humvvex, out, "lwir640", (320, 256), "full")
    assert compose == ["compose", str(humvvex), "-o", str(out)]
    assert render[:3] == ["render", str(out / "stage.usda"), "-o"] and render[3] == str(out / "preview")
    opts = dict(zip(render[4::2], render[5::2]))
    assert opts["--resolution"] == "320x256" and opts["--sensor"] == "lwir640" and opts["--frames"] == "0"
    assert "--force" in render


def test_fast_preview_is_a_cheaper_copy_in_its_own_folder(humvvex, tmp_path):
    """Issue 26 (7): the fast preview composes a preview-quality copy of the scenario into a
    folder of its own (never the real layers): every sensor at its preview size
    (render_resolution: same field of view), frame 0 only, the thermal layer's knobs lowered but
    never raised, file keys absolute, and it says so."""
    import tomllib

    from humv_usd.editor.preview import (
        PREVIEW_SCENARIO,
        PREVIEW_STAGE_DIR,
        preview_commands,
        preview_notes,
        preview_scenario,
    )
    from humv_usd.scenario.load import validate

    raw = tomllib.loads(humvvex.read_text())
    raw["general"]["duration_s"] = 2.0
    raw["thermal"]["radiation_resolution"] = 16  # already cheaper than the preview's 24: kept
    raw["human"][0]["bvh"] = "motion/walk.bvh"  # a relative file key
    before = tomllib.loads(humvvex.read_text())
    scenario = validate({**raw, "human": before["human"]}, humvvex)
    pv = preview_scenario(raw, scenario, humvvex.parent)
    assert raw["thermal"] == {"model": "jos3", "radiation_resolution": 16} and len(raw["sensor"]) == 4
    # every sensor at its preview size (the copy is the same whichever sensor is previewed)
    sizes = {s["id"]: s["render_resolution"] for s in pv["sensor"]}
    assert sizes == {
        "atom1024_lwir": [256, 192],
        "lwir640": [320, 256],
        "mwir_insb": [320, 256],
        "eo_rgb": [288, 216],
    }
    assert pv["general"]["duration_s"] == 0.0 and "editor preview (fast" in pv["general"]["description"]
    assert pv["thermal"] == {
        "model": "jos3",
        "radiation_resolution": 16,
        "radiation_rays": 8,
        "surface_cell_m": 0.5,
    }
    assert pv["human"][0]["bvh"] == str((humvvex.parent / "motion" / "walk.bvh").resolve())
    pv["human"][0].pop("bvh")
    checked = validate(pv, tmp_path / "elsewhere" / "preview.toml")  # valid wherever it lives
    assert checked.frame_count == 1 and list(checked["sensor"][1]["render_resolution"]) == [320, 256]
    notes = preview_notes(scenario)
    assert SECTIONS["thermal"].keys["radiation_rays"].default is None  # automatic: from the cameras
    assert (
        "thermal.radiation_rays 8 (scenario: auto)" in notes and "frame 0 only (scenario: 61 frames)" in notes
    )
    assert not any("radiation_resolution" in n for n in notes)
    # the fixed model has no radiation balance: only the scene's cells are coarser
    raw["thermal"] = {"model": "fixed", "surface_cell_m": 2.0}
    fixed = validate({**raw, "human": before["human"]}, humvvex)
    assert preview_scenario(raw, fixed, humvvex.parent)["thermal"] == raw["thermal"]
    out = tmp_path / "out"
    compose, render = preview_commands(out / PREVIEW_SCENARIO, out, "lwir640", (320, 256))
    stage_dir = out / PREVIEW_STAGE_DIR
    assert compose == ["compose", str(out / PREVIEW_SCENARIO), "-o", str(stage_dir)]
    assert stage_dir != out and out not in [Path(x) for x in compose]  # never the real layers
    assert render[:4] == ["render", str(stage_dir / "stage.usda"), "-o", str(out / "preview")]
    assert "--resolution" not in render and "--force" in render
    with pytest.raises(ValueError, match="quality"):
        preview_commands(humvvex, out, "lwir640", (320, 256), "best")


def test_a_file_that_is_not_toml_is_shown_and_never_replaced(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("[general\nname = 'x'\n")
    doc = ScenarioDocument(path)
    assert len(doc.problems()) == 1 and "not valid TOML" in doc.problems()[0]
    with pytest.raises(SaveRefused):
        doc.save()
    assert path.read_text() == "[general\nname = 'x'\n"


def test_edit_command_bad_output_folder_is_one_line(tmp_path):
    from click.testing import CliRunner

    from humv_usd.cli.main import main

    a_file = tmp_path / "file.txt"
    a_file.write_text("x")
    result = CliRunner().invoke(main, ["edit", str(tmp_path / "s.toml"), "-o", str(a_file), "--port", "1"])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "output folder" in result.output


def test_job_progress_counts_the_files_a_step_writes(tmp_path):
    py = sys.executable
    code = (
        "import pathlib, time, sys; d = pathlib.Path(sys.argv[1]) / 'cam'; d.mkdir(parents=True);"
        "[(d / f'{i:04d}.exr').write_text('x') for i in range(2)]; print('two', flush=True); time.sleep(60)"
    )
    jobs = JobManager()
    job = jobs.start(
        "render",
        [[py, "-c", "print('compose')"], [py, "-c", code, str(tmp_path / "render")]],
        tmp_path,
        tmp_path,
        watch=(1, tmp_path / "render", "*/[0-9][0-9][0-9][0-9].exr", 4),
    )
    t0 = time.time()
    while "two" not in job.lines:
        assert time.time() - t0 < 60
        time.sleep(0.05)
    assert job.files_done() == (2, 4) and job.progress == pytest.approx((1 + 0.5) / 2)
    job.cancel()
    _wait(job)
    assert job.state == "cancelled"


def test_every_change_counts_so_pages_follow(humvvex):
    doc = ScenarioDocument(humvvex)
    v0 = doc.version
    doc.set_text(_field(doc, "general.seed"), "0")  # same value: no change
    assert doc.version == v0
    doc.set_text(_field(doc, "general.seed"), "5")
    doc.add_table(("human",))
    doc.remove_table(("human",), 1)
    doc.reload()
    assert doc.version == v0 + 4


def test_sensor_fields_say_whether_a_value_is_the_presets_or_the_users(humvvex):
    """Issue 26 (7): the Sensor tab showed preset values as blank fields. A key the table leaves
    out shows the preset's value as such (values from the catalogue, not from the page); a key the
    table gives is the user's, with the preset's beside it; a value neither (NETD at another
    f-number) is 'computed'."""
    from humv_usd.editor.fields import value_source

    doc = ScenarioDocument(humvvex)

    def source(where):
        return value_source(doc.raw(), doc.scenario(), _field(doc, where))

    atom = scenario_values("atom1024_lwir")
    res = source("sensor[0].resolution")
    assert (res.kind, res.preset) == ("preset", "atom1024_lwir")
    assert res.text == "[1024, 768]" and atom["resolution"] == [1024, 768]
    assert "preset atom1024_lwir" in res.note and "1024" in res.note
    bits = source("sensor[0].bit_depth")  # humvvex gives bit_depth = 14 in the table
    assert (bits.kind, bits.text, bits.preset_text) == ("user", "14", str(atom["bit_depth"]))
    assert bits.note == f"your value (preset atom1024_lwir: {atom['bit_depth']})"
    assert source("sensor[0].position_m") is None  # no preset gives a position
    assert source("general.name") is None
    # another f-number: the NETD is scaled, (4 N^2 + 1) / (4 N0^2 + 1) (catalog.sensors)
    doc.set_text(_field(doc, "sensor[1].f_number"), "2.0")
    lwir640 = scenario_values("lwir640_12um")
    netd = source("sensor[1].netd_k")
    expected = lwir640["netd_k"] * (4 * 2.0**2 + 1) / (4 * lwir640["f_number"] ** 2 + 1)
    assert netd.kind == "computed" and float(netd.text) == pytest.approx(expected)
    assert source("sensor[1].f_number").kind == "user"
    # another preset: every left-out key follows it
    doc.set_text(_field(doc, "sensor[0].preset"), "lwir640_12um")
    assert source("sensor[0].resolution").text == "[640, 512]"
    assert source("sensor[0].pixel_pitch_um").text == str(lwir640["pixel_pitch_um"])
    # while the scenario has problems, the preset's own values are shown
    doc.set_text(_field(doc, "general.fps"), "-1")
    assert doc.scenario() is None
    assert source("sensor[0].resolution").kind == "preset"


def _ndc(eye, target, points, fov_y_deg, aspect):
    """Normalised device coordinates of points seen by a look-at perspective camera (Z up)."""
    f = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    v = np.asarray(points, dtype=float) - eye
    depth = v @ f
    ty = math.tan(math.radians(fov_y_deg) / 2)
    return np.stack([(v @ right) / (depth * aspect * ty), (v @ up) / (depth * ty)], axis=1), depth


def test_the_3d_view_is_framed_on_the_people_and_sensors_not_the_horizon():
    """Issue 26 (7): the view framed the whole ground (now rings to 20 km) and showed a dot.
    humvvex's layout: a person at the origin, four cameras 15 m south; the ground's bounds 40 km."""
    from humv_usd.editor.stage3d import VIEW_ASPECT, VIEW_FOV_Y_DEG, StageCamera, StageView, framing

    person = (np.array([-0.3, -0.2, 0.0]), np.array([0.3, 0.2, 1.8]))
    cams = [
        StageCamera(
            f"c{i}", np.array([x, -15.0, 1.6]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0, 1]), 30.0
        )
        for i, x in enumerate((0.0, 0.8, -0.8, -1.6))
    ]
    points = [c.origin for c in cams] + list(person)
    focus = (np.min(points, axis=0), np.max(points, axis=0))
    ground = (np.array([-20000.0, -20000.0, 0.0]), np.array([20000.0, 20000.0, 8.0]))
    view = StageView(Path("x.glb"), 7, 100, cams, ground, focus)
    eye, target = framing(view)
    corners = [
        [x, y, z] for x in (focus[0][0], focus[1][0]) for y in (focus[0][1], focus[1][1]) for z in (0, 1.8)
    ]
    ndc, depth = _ndc(eye, target, corners + [c.origin for c in cams], VIEW_FOV_Y_DEG, VIEW_ASPECT)
    assert np.all(depth > 0) and np.all(np.abs(ndc) <= 1.0), ndc  # everyone and every camera in view
    assert np.abs(ndc).max() > 0.8  # and fill it, not a corner of it
    top, feet = _ndc(eye, target, [[0, 0, 1.8], [0, 0, 0]], VIEW_FOV_Y_DEG, VIEW_ASPECT)[0]
    assert top[1] - feet[1] > 0.2  # the person is > 10 % of the view's height (a 40 km frame: 0.01 %)
    assert eye[2] > 1.8 and abs(eye[0]) > 5.0  # above, from the side of the cameras' line of sight
    # without people or cameras: the bounds
    eye2, target2 = framing(StageView(Path("x.glb"), 1, 2, [], ground, None))
    np.testing.assert_allclose(target2, [0.0, 0.0, 4.0])


def test_preview_bench_edits_are_valid_and_its_folder_is_its_own(humvvex, tmp_path):
    """``humv-usd bench preview``: each edit changes what it names and leaves a valid scenario;
    the bench never empties a folder it did not make, and names unknown edits (exit 2)."""
    from click.testing import CliRunner

    from humv_usd.bench.preview import EDITS
    from humv_usd.cli.main import main

    doc = ScenarioDocument(humvvex)
    first = doc.scenario()
    for name, _, edit in EDITS:
        if edit is not None:
            edit(doc)
            assert not doc.problems(), (name, doc.problems())
    last = doc.scenario()
    assert last["placement"][0]["heading_deg"] == pytest.approx(
        (first["placement"][0]["heading_deg"] + 10) % 360
    )
    assert last["human"][0]["activity"] != first["human"][0]["activity"]
    assert (last["general"]["start"] - first["general"]["start"]).total_seconds() == 3600.0
    assert last["atmosphere"]["air_temperature_k"] == pytest.approx(
        first["atmosphere"]["air_temperature_k"] + 2
    )
    assert last["sensor"][0]["netd_k"] == pytest.approx(0.8 * first["sensor"][0]["netd_k"])
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "keep.txt").write_text("x")
    result = CliRunner().invoke(main, ["bench", "preview", str(humvvex), "-o", str(mine)])
    assert result.exit_code == 2 and "not a folder of this bench" in result.output
    assert (mine / "keep.txt").read_text() == "x"
    result = CliRunner().invoke(main, ["bench", "preview", str(humvvex), "--edits", "cold,spin"])
    assert result.exit_code == 2 and "unknown spin" in result.output
