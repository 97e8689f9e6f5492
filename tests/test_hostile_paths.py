"""Issue 15: bad output paths, identifiers, side files and broken layers give one error line and
exit 2 (or check findings, exit 1), never a traceback, and write nothing."""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from pathlib import Path

import pytest
from click.testing import CliRunner
from pxr import Sdf, Usd

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import validate
from humv_usd.scenario.load import ID_MAX_CHARS
from humv_usd.usd.check import check_stage

HUMVVEX = Path(__file__).resolve().parents[1] / "examples" / "humvvex_fixed.toml"


def files_under(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def run(args, cwd=None):
    old = os.getcwd()
    if cwd is not None:
        os.chdir(cwd)
    try:
        return CliRunner().invoke(main, [str(a) for a in args])
    finally:
        os.chdir(old)


def assert_one_error(result, *words):
    """Exit 2, exactly one ``humv-usd: error:`` line on stderr naming ``words``, no traceback."""
    assert result.exit_code == 2, (result.output, result.exception)
    assert not isinstance(result.exception, Exception) or isinstance(result.exception, SystemExit)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("humv-usd: error: "), result.stderr
    assert "Traceback" not in result.output
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def composed(tmp_path_factory, humvvex_raw):
    """A composed humvvex stage (copied per test before it is broken)."""
    out = tmp_path_factory.mktemp("composed") / "o"
    compose(validate(humvvex_raw), out)
    return out


@pytest.fixture
def stage_copy(composed, tmp_path):
    out = tmp_path / "s"
    shutil.copytree(composed, out)
    return out


# ------------------------------------------------------------------ output folders
def _bad_outputs(tmp_path: Path) -> dict[str, tuple[str, str]]:
    """-o value -> (a word the error line must hold, what the case is)."""
    (tmp_path / "afile").write_text("not a folder\n")
    return {
        "": ("expected a folder path", "empty"),
        str(tmp_path / "afile"): ("is a file", "existing file"),
        str(tmp_path / "afile" / "sub"): ("is a file", "a file as parent"),
        "/proc/x": ("cannot write in /proc", "/proc"),
        str(tmp_path / ("a" * 300)): ("at most 255", "300-character name"),
    }


@pytest.mark.parametrize("command", ["compose", "render"])
def test_bad_output_folders_fail_fast(command, tmp_path, stage_copy):
    source = HUMVVEX if command == "compose" else stage_copy / "stage.usda"
    work = tmp_path / "cwd"
    work.mkdir()
    for value, (word, case) in _bad_outputs(tmp_path).items():
        before = files_under(tmp_path)
        result = run([command, source, "-o", value], cwd=work)
        line = assert_one_error(result, "output folder", word)
        assert files_under(tmp_path) == before, case  # nothing written (not in the cwd either)
        assert "a" * 100 not in line, case  # a 300-character name is shortened in the message


@pytest.mark.parametrize("command", ["compose", "render"])
def test_read_only_output_folder(command, tmp_path, stage_copy, monkeypatch):
    """A folder where nothing can be written. Root writes into chmod 555 folders, so the probe's
    failure is simulated the way the kernel reports it (EACCES from mkdir) when run as root."""
    source = HUMVVEX if command == "compose" else stage_copy / "stage.usda"
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.geteuid() == 0:
        real = tempfile.mkdtemp

        def refuse(*args, dir=None, **kwargs):
            if dir is not None and Path(dir) == ro:
                raise PermissionError(13, "Permission denied", str(dir))
            return real(*args, dir=dir, **kwargs)

        monkeypatch.setattr(tempfile, "mkdtemp", refuse)
    try:
        for target in (ro, ro / "new"):
            result = run([command, source, "-o", target])
            assert_one_error(result, "output folder", str(ro), "Permission denied")
            assert files_under(ro) == set()
    finally:
        ro.chmod(0o755)


def test_library_compose_checks_its_folder(raw, tmp_path):
    (tmp_path / "afile").write_text("x")
    with pytest.raises(InputError, match="is a file"):
        compose(validate(raw), tmp_path / "afile")
    with pytest.raises(InputError, match="expected a folder path"):
        compose(validate(raw), "")


def test_writable_folder_probe_leaves_nothing(tmp_path):
    from humv_usd.fileio import check_output_dir

    assert check_output_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert check_output_dir(tmp_path) == tmp_path
    assert files_under(tmp_path) == set()


# ------------------------------------------------------------------ identifiers and side files
def test_long_human_id_is_refused_before_anything_is_written(tmp_path):
    long_id = "p" * 5000
    scenario = tmp_path / "long.toml"
    scenario.write_text(HUMVVEX.read_text().replace('"p1"', f'"{long_id}"'))
    out = tmp_path / "o"
    result = run(["compose", scenario, "-o", out])
    line = assert_one_error(result, "human[0].id", f"at most {ID_MAX_CHARS} characters", "5000 characters")
    assert len(line) < 200
    assert not out.exists()


def test_id_limit_is_inclusive(raw):
    ok = "p" * ID_MAX_CHARS
    raw["human"][0]["id"] = ok
    raw["placement"][0]["human"] = ok
    validate(raw)  # no error at the limit
    raw["human"][0]["id"] = raw["placement"][0]["human"] = ok + "p"
    with pytest.raises(InputError, match=r"human\[0\]\.id"):
        validate(raw)


def test_weather_csv_not_utf8(tmp_path):
    csv = tmp_path / "w.csv"
    csv.write_bytes("time,air_temperature_k\n2018-10-24T13:00:00,288.0\n# café\n".encode("latin-1"))
    text = HUMVVEX.read_text().replace("[atmosphere]", f'[atmosphere]\nweather_csv = "{csv}"', 1)
    scenario = tmp_path / "w.toml"
    scenario.write_text(text)
    out = tmp_path / "o"
    result = run(["compose", scenario, "-o", out])
    assert_one_error(result, "atmosphere.weather_csv", str(csv), "UTF-8")
    assert not out.exists()


# ------------------------------------------------------------------ broken layers: check and render
def truncate(path: Path, size: int) -> None:
    path.write_bytes(path.read_bytes()[:size])


def test_check_reports_truncated_and_missing_layers(stage_copy):
    avatar = stage_copy / "layers" / "avatar_p1.usda"
    truncate(avatar, 50000)
    (stage_copy / "layers" / "thermal.usda").unlink()
    result = run(["check", stage_copy / "stage.usda"])
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output and result.stderr == ""
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 2
    assert any(f"{avatar}: sublayer of" in x and "does not load" in x for x in lines)
    assert any("thermal.usda: sublayer of" in x and x.endswith("not found") for x in lines)


def test_check_on_a_file_that_is_not_usd(tmp_path):
    bad = tmp_path / "stage.usda"
    bad.write_text("#usda 1.0\n(\n  this is not\n")
    result = run(["check", bad])
    assert_one_error(result, str(bad), "cannot open as a USD stage")


@pytest.mark.parametrize("broken", ["truncated", "missing"])
def test_render_refuses_a_stage_with_a_broken_sublayer(stage_copy, tmp_path, broken):
    avatar = stage_copy / "layers" / "avatar_p1.usda"
    if broken == "truncated":
        truncate(avatar, 50000)
    else:
        avatar.unlink()
    out = tmp_path / "render"
    result = run(["render", stage_copy / "stage.usda", "-o", out, "--spp", "1"])
    assert_one_error(result, str(avatar), "does not load" if broken == "truncated" else "not found")
    assert not out.exists()


def test_person_without_body_is_a_check_error(stage_copy):
    path = stage_copy / "layers" / "avatar_p1.usda"
    layer = Sdf.Layer.FindOrOpen(str(path))
    stage = Usd.Stage.Open(layer)
    assert stage.RemovePrim("/World/Humans/p1/Body")
    layer.Save()
    found = check_stage(stage_copy / "stage.usda")
    assert any(
        f.startswith("humv:person: /World/Humans/p1: no body mesh /World/Humans/p1/Body") for f in found
    )


def test_composed_stage_has_no_person_finding(composed):
    assert not [f for f in check_stage(composed / "stage.usda") if f.startswith("humv:person")]


@pytest.mark.parametrize("command", ["check", "render"])
def test_stage_argument_that_is_a_folder(command, composed, tmp_path):
    args = [command, composed] + (["-o", tmp_path / "r"] if command == "render" else [])
    result = run(args)
    assert_one_error(result, str(composed), "is a folder", str(composed / "stage.usda"))
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize(
    "content", [b"", b"#usda 1.0\n(\n", bytes(range(256)) * 8], ids=["empty", "truncated", "binary"]
)
def test_check_and_render_on_files_that_are_not_usd(content, tmp_path):
    bad = tmp_path / "stage.usda"
    bad.write_bytes(content)
    assert_one_error(run(["check", bad]), str(bad), "cannot open as a USD stage")
    assert_one_error(run(["render", bad, "-o", tmp_path / "r"]), str(bad), "cannot open as a USD stage")
    assert not (tmp_path / "r").exists()


# ------------------------------------------------------------------ broken layers in compose's folder
def test_compose_refuses_a_truncated_layer_it_would_keep(stage_copy):
    avatar = stage_copy / "layers" / "avatar_p1.usda"
    truncate(avatar, 50000)  # the inputs key is in the header, so the key still matches
    broken = avatar.read_bytes()
    before = {p: p.stat().st_mtime_ns for p in stage_copy.rglob("*")}
    assert_one_error(
        run(["compose", HUMVVEX, "-o", stage_copy]), str(avatar), "does not load as USD", "--force"
    )
    assert {p: p.stat().st_mtime_ns for p in stage_copy.rglob("*")} == before  # nothing written
    assert avatar.read_bytes() == broken
    result = run(["compose", HUMVVEX, "-o", stage_copy, "--force"])
    assert result.exit_code == 0, result.output
    assert re.search(r"avatar_p1 +written", result.stdout)
    assert check_stage(stage_copy / "stage.usda") == []


def test_compose_on_a_layer_that_is_not_utf8(stage_copy):
    scene = stage_copy / "layers" / "scene.usda"
    scene.write_bytes(bytes(range(128, 256)) * 4)
    assert_one_error(run(["compose", HUMVVEX, "-o", stage_copy]), str(scene), "edited by hand", "--force")
    assert run(["compose", HUMVVEX, "-o", stage_copy, "--force"]).exit_code == 0
    assert check_stage(stage_copy / "stage.usda") == []


def test_compose_names_a_user_sublayer_that_does_not_load(stage_copy):
    user = stage_copy / "mine.usda"
    user.write_text("#usda 1.0\n(\n")
    root = Sdf.Layer.FindOrOpen(str(stage_copy / "stage.usda"))
    root.subLayerPaths.insert(0, "./mine.usda")
    root.Save()
    line = assert_one_error(run(["compose", HUMVVEX, "-o", stage_copy]), "user sublayer ./mine.usda")
    assert "does not load as USD" in line


def test_render_refuses_a_truncated_avatar_layer_in_a_new_process(stage_copy, tmp_path):
    """As a user runs it: USD's own diagnostics (written by C++ straight to stderr, which
    CliRunner does not see) must not add lines either."""
    import subprocess
    import sys

    avatar = stage_copy / "layers" / "avatar_p1.usda"
    truncate(avatar, 50000)
    out = tmp_path / "render"
    r = subprocess.run(
        [sys.executable, "-m", "humv_usd.cli.main", "render", str(stage_copy / "stage.usda"), "-o", str(out)],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])},
    )
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"humv-usd: error: {avatar}: sublayer of"), r.stderr
    assert r.stdout == "" and not out.exists()


# ------------------------------------------------------------------ the other commands' output paths
def _bad_files(tmp_path: Path) -> dict[str, tuple[str, str]]:
    """-o/--png value -> (a word the error line must hold, what the case is)."""
    (tmp_path / "afile").write_text("not a folder\n")
    (tmp_path / "adir").mkdir()
    return {
        "": ("expected a file path", "empty"),
        str(tmp_path / "adir"): ("is a folder", "an existing folder"),
        str(tmp_path / "afile" / "x.json"): ("is a file", "a file as parent"),
        "/proc/x/y.json": ("cannot write in /proc", "/proc"),
        str(tmp_path / ("a" * 300 + ".json")): ("at most 255", "300-character name"),
    }


@pytest.mark.parametrize("command", ["avatar", "coco-merge", "bench thermal"])
def test_bad_output_files_fail_fast(command, tmp_path):
    (tmp_path / "in.json").write_text('{"images": [], "annotations": [], "categories": []}\n')
    work = tmp_path / "cwd"
    work.mkdir()
    for value, (word, case) in _bad_files(tmp_path).items():
        before = files_under(tmp_path)
        args = {
            "avatar": ["avatar", "-o", value],
            "coco-merge": ["coco-merge", tmp_path / "in.json", "-o", value],
            "bench thermal": ["bench", "thermal", "--quick", "--png", value],
        }[command]
        result = run(args, cwd=work)
        assert_one_error(result, word)
        assert files_under(tmp_path) == before, case


def test_regions_refuses_a_read_only_render_folder(tmp_path, monkeypatch):
    ro = tmp_path / "render"
    ro.mkdir()
    real = tempfile.mkdtemp

    def refuse(*args, dir=None, **kwargs):  # the kernel's answer in a read-only folder (also as root)
        if dir is not None and Path(dir) == ro:
            raise PermissionError(13, "Permission denied", str(dir))
        return real(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkdtemp", refuse)
    assert_one_error(run(["regions", ro]), "render folder", "Permission denied")


# ------------------------------------------------------------------ runs that cannot fit this machine
def test_compose_that_cannot_fit_is_refused_with_its_estimate(tmp_path):
    scenario = tmp_path / "day.toml"
    text = HUMVVEX.read_text().replace("fps = 30.0", "fps = 1000.0")
    scenario.write_text(text.replace("duration_s = 0.0 ", "duration_s = 86400.0 "))
    result = run(["compose", scenario, "-o", tmp_path / "o"])
    line = assert_one_error(result, "86,400,001 frame(s)", "of memory", "general.duration_s", "--yes")
    assert "TB" in line
    assert not (tmp_path / "o").exists()


def test_render_that_cannot_fit_is_refused_before_writing(tmp_path):
    from test_render import add_camera, add_material, add_mesh, new_stage, rect_z

    from humv_usd.pipeline.budget import render_budget, require_fits
    from humv_usd.pipeline.render import render_stage

    stage = new_stage(tmp_path / "stage.usda")
    add_mesh(
        stage,
        "/World/Scene/ground",
        *rect_z(-5, 5, -5, 5),
        material=add_material(stage, "m", 0.9),
        temperature_k=300.0,
        instance_id=1,
    )
    add_camera(stage, "huge", eye=(0.0, -5.0, 2.0), target=(0.0, 0.0, 0.0), resolution=(16384, 16384))
    stage.Save()
    with pytest.raises(InputError) as err:
        render_stage(tmp_path / "stage.usda", tmp_path / "r", spp=1)
    assert "268,435,456 pixels" in str(err.value) and "sensor.resolution" in str(err.value)
    assert "--yes" in str(err.value) and len(err.value.problems) == 1
    assert not (tmp_path / "r").exists()
    require_fits(render_budget([(16384, 16384)], 1, 1), tmp_path, yes=True)  # --yes goes ahead
