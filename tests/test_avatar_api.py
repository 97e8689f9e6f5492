"""The avatar tool on its own: author_avatar (Python API) and `humv-usd avatar` (CLI)."""

from __future__ import annotations

import pytest
from click.testing import CliRunner
from conftest import ROOT
from pxr import Usd

from humv_usd.avatar.api import author_avatar, avatar_scenario_dict
from humv_usd.cli.avatar_cmd import avatar, option_message
from humv_usd.errors import InputError
from humv_usd.pipeline.compose import compose
from humv_usd.scenario import load_scenario, validate
from humv_usd.usd import schemas as S


def avatar_prim(path, human_id="p1"):
    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    prim = stage.GetPrimAtPath(f"/World/Humans/{human_id}")
    assert prim.IsValid()
    return stage, prim


def test_api_writes_a_layer_with_the_requested_person(tmp_path):
    out = tmp_path / "sub" / "anna.usda"  # the folder is created
    path = author_avatar(
        out,
        id="anna",
        sex="female",
        age_yr=41,
        stature_m=1.62,
        mass_kg=58,
        build="slim",
        fitness="high",
        activity="walk",
        fps=15,
        duration_s=2,
    )
    assert path == out and out.is_file()
    stage, prim = avatar_prim(out, "anna")
    assert prim.HasAPI(S.AVATAR_API)
    assert prim.GetAttribute(S.AVATAR_STATURE).Get() == pytest.approx(1.62)
    assert prim.GetAttribute(S.AVATAR_MASS).Get() == pytest.approx(58)
    assert prim.GetAttribute(S.AVATAR_SEX).Get() == "female"
    assert prim.GetAttribute(S.AVATAR_ACTIVITY).Get() == "walk"
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert stage.GetTimeCodesPerSecond() == 15
    assert stage.GetEndTimeCode() == 30  # round(2 * 15) + 1 frames
    assert not list(tmp_path.glob("sub/.*"))  # no temp files left behind


def test_api_layer_is_the_one_compose_writes(tmp_path):
    kwargs = dict(id="p7", stature_m=1.9, mass_kg=95, position_m=(1.0, -2.0, 0.0), heading_deg=45.0)
    path = author_avatar(tmp_path / "alone.usda", **kwargs)
    compose(validate(avatar_scenario_dict(**kwargs)), tmp_path / "composed")
    assert path.read_text() == (tmp_path / "composed" / "layers" / "avatar_p7.usda").read_text()


def test_api_rewrite_keeps_an_unchanged_file(tmp_path):
    out = tmp_path / "p1.usda"
    author_avatar(out)
    before = out.stat().st_mtime_ns
    author_avatar(out)
    assert out.stat().st_mtime_ns == before


@pytest.mark.parametrize(
    "kwargs, line",
    [
        (dict(stature_m=3.0), "human[0].stature_m = 3.0: allowed range 0.7..2.3"),
        (dict(sex="mail"), "human[0].sex = 'mail': allowed values: male, female (did you mean 'male'?)"),
        (
            dict(position_m=(0, 0)),
            "placement[0].position_m = [0, 0]: expected 3 numbers, each in -10000.0..10000.0",
        ),
        (dict(fps=0), "general.fps = 0: allowed range 0.01..1000.0"),
        (dict(id="1st"), "human[0].id = '1st': expected letters, digits and _ (not starting with a digit)"),
    ],
)
def test_api_bad_value_names_the_key_and_writes_nothing(tmp_path, kwargs, line):
    with pytest.raises(InputError) as info:
        author_avatar(tmp_path / "p1.usda", **kwargs)
    assert info.value.problems == [line]
    assert list(tmp_path.iterdir()) == []


def test_api_bad_output_path(tmp_path):
    with pytest.raises(InputError) as info:
        author_avatar(tmp_path / "p1.txt", mass_kg=500)
    assert info.value.problems == [
        f"out_path = '{tmp_path / 'p1.txt'}': expected a USD text layer file ending in .usda or .usd",
        "human[0].mass_kg = 500: allowed range 7.0..250.0",
    ]
    with pytest.raises(InputError, match=r"^out_path = .*: is a folder"):
        author_avatar(tmp_path)


def test_cli_writes_the_layer(tmp_path):
    out = tmp_path / "p1.usda"
    result = CliRunner().invoke(
        avatar,
        [
            "-o",
            str(out),
            "--sex",
            "female",
            "--age",
            "25",
            "--stature",
            "1.68",
            "--mass",
            "60",
            "--build",
            "slim",
            "--activity",
            "run",
            "--fps",
            "10",
            "--duration",
            "1",
        ],
    )
    assert result.exit_code == 0, result.output
    assert str(out) in result.output
    stage, prim = avatar_prim(out)
    assert prim.GetAttribute(S.AVATAR_STATURE).Get() == pytest.approx(1.68)
    assert prim.GetAttribute(S.AVATAR_ACTIVITY).Get() == "run"
    assert stage.GetEndTimeCode() == 10


def test_cli_bad_value_is_one_line_naming_the_option_exit_2(tmp_path):
    out = tmp_path / "p1.usda"
    result = CliRunner().invoke(avatar, ["-o", str(out), "--stature", "3"])
    assert result.exit_code == 2
    assert result.stderr.splitlines() == ["humv-usd: error: --stature = 3.0: allowed range 0.7..2.3"]
    assert "Traceback" not in result.output
    assert not out.exists()


def test_cli_options_map_to_scenario_keys():
    assert (
        option_message("placement[0].position_m[2] = 1e6: allowed range -10000.0..10000.0")
        == "--position[2] = 1e6: allowed range -10000.0..10000.0"
    )
    assert (
        option_message("general.duration_s = -1.0: allowed range 0.0..86400.0")
        == "--duration = -1.0: allowed range 0.0..86400.0"
    )
    assert option_message("out_path = 'a.txt': expected ...") == "-o/--out = 'a.txt': expected ..."
    assert option_message("something else") == "something else"


def test_cli_requires_out():
    result = CliRunner().invoke(avatar, [])
    assert result.exit_code == 2
    assert "--out" in result.output


def test_walk_example_loads():
    s = load_scenario(ROOT / "examples" / "walk.toml")
    assert s["human"][0]["activity"] == "walk"
    assert s["general"]["duration_s"] == 2.0 and s["general"]["fps"] == 15.0
    assert s.frame_count == 31
    assert [x["id"] for x in s.infrared_sensors] == ["atom1024_lwir"]
