"""Inputs that once exhausted the machine, hung or ended in a traceback (issue 26): each is
refused with one line and exit code 2, before anything is read whole or written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from humv_usd.cli.main import MAX_FRAMES_PER_CALL, main, parse_frames
from humv_usd.errors import InputError
from humv_usd.scenario.load import MAX_TEXT_INPUT_BYTES

ROOT = Path(__file__).resolve().parents[1]


def _one_line(result) -> str:
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    return lines[0]


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_compose_of_a_device_is_refused_before_reading(tmp_path):
    line = _one_line(CliRunner().invoke(main, ["compose", "/dev/zero", "-o", str(tmp_path / "out")]))
    assert "/dev/zero" in line and "regular file" in line
    assert not (tmp_path / "out").exists()


def test_compose_of_a_fifo_does_not_wait_for_a_writer(tmp_path):
    fifo = tmp_path / "scenario.toml"
    os.mkfifo(fifo)
    r = subprocess.run(
        [sys.executable, "-m", "humv_usd.cli.main", "compose", str(fifo), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
    )
    assert r.returncode == 2 and "regular file" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()


def test_an_oversized_scenario_or_sweep_file_is_refused_by_its_size(tmp_path):
    big = tmp_path / "big.toml"
    with open(big, "wb") as fh:  # sparse: no disk used
        fh.truncate(MAX_TEXT_INPUT_BYTES + 1)
    line = _one_line(CliRunner().invoke(main, ["compose", str(big), "-o", str(tmp_path / "out")]))
    assert f"{MAX_TEXT_INPUT_BYTES + 1} bytes" in line and f"at most {MAX_TEXT_INPUT_BYTES}" in line
    line = _one_line(CliRunner().invoke(main, ["sweep", str(big), "-o", str(tmp_path / "ds"), "--dry-run"]))
    assert "bytes" in line
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[sweep]\nname = "s"\nbase = "/dev/zero"\n')
    line = _one_line(CliRunner().invoke(main, ["sweep", str(sweep), "-o", str(tmp_path / "ds"), "--dry-run"]))
    assert "/dev/zero" in line and "regular file" in line


def test_a_huge_frame_range_is_refused_before_a_list_is_built():
    with pytest.raises(InputError, match="at most 1,000,000 per call"):
        parse_frames("0:99999999999")
    assert parse_frames(f"5:{5 + MAX_FRAMES_PER_CALL - 1}")[-1] == 5 + MAX_FRAMES_PER_CALL - 1
    assert parse_frames("3:5") == [3, 4, 5] and parse_frames("7") == [7]
    for bad in ("5:3", "a:b", "1:2:3", ""):
        if bad:
            with pytest.raises(InputError, match="expected FIRST:LAST"):
                parse_frames(bad)


def test_render_frames_huge_is_one_line(tmp_path):
    stage = tmp_path / "stage.usda"
    stage.write_text("#usda 1.0\n")
    line = _one_line(
        CliRunner().invoke(
            main, ["render", str(stage), "-o", str(tmp_path / "r"), "--frames", "0:99999999999"]
        )
    )
    assert "--frames" in line and "1,000,000" in line


# ------------------------------------------------------------------ the render's memory estimate
#: peak RSS [bytes] of `/usr/bin/time -f %M humv-usd render STAGE -o R --spp N --subbands K
#: --estimator E --yes` on walk.toml's LWIR camera (and the same camera as EO) at 64x48 and
#: 256x192, 2026-11-27 (see humv_usd/pipeline/budget.py): (pixels, spp, K, estimator, EO?, peak)
MEASURED_PEAKS = [
    (64 * 48, 256, 1, "fast", False, 686096e3),
    (64 * 48, 256, 4, "fast", False, 770520e3),
    (64 * 48, 256, 16, "fast", False, 995396e3),
    (64 * 48, 512, 16, "fast", False, 1548228e3),
    (64 * 48, 1024, 16, "fast", False, 2698520e3),
    (256 * 192, 64, 16, "fast", False, 2723584e3),
    (256 * 192, 128, 16, "fast", False, 5044824e3),
    (64 * 48, 1024, 16, "path", False, 355508e3),
    (256 * 192, 64, 16, "path", False, 396124e3),
    (64 * 48, 256, 16, "fast", True, 613820e3),
    (64 * 48, 1024, 16, "fast", True, 1086456e3),
]


@pytest.mark.parametrize(("pixels", "spp", "subbands", "estimator", "eo", "peak"), MEASURED_PEAKS)
def test_the_memory_estimate_covers_the_measured_peak(pixels, spp, subbands, estimator, eo, peak):
    """Above the measured peak (the estimate must stop what cannot fit), within a factor 2.5."""
    from humv_usd.pipeline.budget import render_budget

    w, h = (64, 48) if pixels == 64 * 48 else (256, 192)
    sensors = {"eo_resolutions": [(w, h)]} if eo else {}
    budget = render_budget([] if eo else [(w, h)], 1, spp, estimator=estimator, subbands=subbands, **sensors)
    assert peak * 1.024 <= budget.memory_bytes <= 2.5 * peak * 1.024  # kB of time -f %M are KiB


def _tiny_stage(tmp_path, resolution=(64, 48)):
    from test_render import add_camera, add_material, add_mesh, new_stage, rect_z

    stage = new_stage(tmp_path / "stage.usda")
    add_mesh(
        stage,
        "/World/Scene/ground",
        *rect_z(-5, 5, -5, 5),
        material=add_material(stage, "m", 0.9),
        temperature_k=300.0,
        instance_id=1,
    )
    add_camera(stage, "cam", eye=(0.0, -5.0, 2.0), target=(0.0, 0.0, 0.0), resolution=resolution)
    stage.Save()
    return tmp_path / "stage.usda"


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--spp", "1048576"], "1048576 spp"),  # 64x48 at --spp 1048576 grew to 23.3 GB (OOM kill)
        (["--spp", "65536", "--subbands", "64"], "64 sub-bands"),
    ],
)
def test_every_render_knob_at_its_maximum_is_one_line_before_any_allocation(tmp_path, args, named):
    stage = _tiny_stage(tmp_path)
    out = tmp_path / "r"
    line = _one_line(CliRunner().invoke(main, ["render", str(stage), "-o", str(out), *args]))
    assert named in line and "B of memory" in line and "--spp" in line and "--yes" in line
    assert not out.exists() or not any(out.rglob("*.exr"))


def test_the_editors_spp_check_is_the_renders(tmp_path):
    """The editor refuses a render whose spp the render would refuse, with the same line."""
    import shutil

    from humv_usd.pipeline.budget import MAX_SPP, render_budget, scenario_render_budget
    from humv_usd.scenario import load_scenario

    path = tmp_path / "humvvex.toml"
    shutil.copy(ROOT / "examples" / "humvvex.toml", path)
    scenario = load_scenario(path)
    ir = [s for s in scenario["sensor"] if s["wavelength_um"][0] >= 3.0]
    eo = [s for s in scenario["sensor"] if s["wavelength_um"][0] < 3.0]
    got = scenario_render_budget(scenario, 32)
    want = render_budget(
        [s["resolution"] for s in ir],
        scenario.frame_count,
        32,
        subbands=max(s.get("subbands") or 16 for s in ir),
        eo_resolutions=[s["resolution"] for s in eo],
    )
    assert got == want
    assert scenario_render_budget(scenario, MAX_SPP).memory_bytes > 1e13


@pytest.mark.parametrize("resolution", [(1, 1), (1, 48), (64, 1)])
@pytest.mark.parametrize("spp", [4, None])
def test_one_pixel_wide_or_high_images_render(tmp_path, resolution, spp):
    """Widths and heights of 1 are inside the allowed range (1..16384): they rendered an
    IndexError in the estimator's reflection filter (its windows along a 1-pixel axis)."""
    import numpy as np

    from humv_usd.images import read_exr
    from humv_usd.pipeline.render import render_stage

    stage = _tiny_stage(tmp_path, resolution)
    render_stage(stage, tmp_path / "r", spp=spp)
    channels = read_exr(tmp_path / "r" / "cam" / "0000.exr")
    for values in channels.values():
        assert values.shape == (resolution[1], resolution[0])
    # a 300 K ground of emissivity 0.9 under a 300 K sky: every pixel at 300 K
    assert np.allclose(channels["brightness_temperature"], 300.0, atol=0.5)


# ------------------------------------------------------------------ fitness classes
def test_every_fitness_the_spec_offers_has_a_heart_rate():
    """``fitness = "athlete"`` was offered by the spec, avatar --help and the editor and crashed
    compose in the thermal layer (both physiology models take it through heart_rate)."""
    from humv_usd.scenario.spec import FITNESS
    from humv_usd.thermal import physiology as P

    assert set(FITNESS) == set(P.FITNESS)
    rest = {f: float(P.heart_rate(0.0, 75.0, 30.0, f)) for f in FITNESS}
    assert rest["athlete"] == P.FITNESS["athlete"]["resting_hr_bpm"] == 50.0
    work = {f: float(P.heart_rate(600.0, 75.0, 30.0, f)) for f in FITNESS}  # ~ a brisk run
    assert work["athlete"] < work["high"] < work["average"] < work["low"]


# ------------------------------------------------------------------ band and wavelengths together
@pytest.mark.parametrize(
    ("band", "edges", "allowed"),
    [
        ("EO", [8.0, 14.0], "0.36..0.83"),  # rendered visible light
        ("LWIR", [0.4, 0.7], "7..14"),  # crashed the render
        ("MWIR", [2.0, 5.0], "3..5"),  # crashed the render
        ("MWIR", [8.0, 14.0], "3..5"),
    ],
)
def test_band_and_wavelengths_must_agree(humvvex_raw, tmp_path, band, edges, allowed):
    import copy

    import tomlkit

    raw = copy.deepcopy(humvvex_raw)
    raw["sensor"][0].update(band=band, wavelength_um=edges)
    path = tmp_path / "s.toml"
    path.write_text(tomlkit.dumps(raw))
    line = _one_line(CliRunner().invoke(main, ["compose", str(path), "-o", str(tmp_path / "o")]))
    assert f"sensor[0].wavelength_um = {edges}: allowed range for band {band}: {allowed} µm" in line
    assert not (tmp_path / "o").exists()


def test_band_ranges_hold_their_defaults_and_presets():
    from humv_usd.catalog.sensors import PRESETS
    from humv_usd.scenario.spec import BAND_DEFAULT_UM, BAND_RANGE_UM, band_range_problem

    for band, edges in BAND_DEFAULT_UM.items():
        assert band_range_problem("w", band, edges) is None
    for p in PRESETS.values():
        assert band_range_problem("w", p.band, p.wavelength_um) is None, p
    assert set(BAND_RANGE_UM) == set(BAND_DEFAULT_UM)


# ------------------------------------------------------------------ sweep [render] frames
def _sweep_with(tmp_path, render: str, grid: str = '"scene.object.0.temperature_k" = [300.0, 320.0]'):
    from test_sweep import SWEEP, _write

    text = SWEEP.replace('"scene.object.0.temperature_k" = [300.0, 320.0]', grid)
    return _write(tmp_path, text.replace("frames_per_task = 1", f"frames_per_task = 1\n{render}"))


def test_sweep_frames_beyond_every_variant_are_refused(tmp_path):
    """``frames = [0, 500]`` on a two-frame base dropped frame 500 without a word, exit 0."""
    from humv_usd.sweep.spec import load_sweep

    with pytest.raises(InputError) as info:
        load_sweep(_sweep_with(tmp_path, "frames = [0, 500]"))
    (line,) = info.value.problems
    assert "render.frames: [500] beyond the frames of every variant (0..1" in line
    with pytest.raises(InputError, match="at most 1,000,000"):
        load_sweep(_sweep_with(tmp_path, 'frames = "0:99999999999"'))
    result = CliRunner().invoke(
        main,
        ["sweep", str(_sweep_with(tmp_path, "frames = [0, 500]")), "-o", str(tmp_path / "ds"), "--dry-run"],
    )
    assert "beyond the frames of every variant" in _one_line(result)


def test_sweep_frames_some_variants_lack_are_a_warning(tmp_path, caplog):
    import logging

    from humv_usd.sweep.plan import render_tasks
    from humv_usd.sweep.spec import load_sweep

    path = _sweep_with(tmp_path, "frames = [0, 1]", grid='"general.duration_s" = [0.0, 0.25]')
    with caplog.at_level(logging.WARNING, logger="humv_usd.sweep.spec"):
        sweep = load_sweep(path)
    (warning,) = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert "2 of 4 variant(s) have fewer frames (the shortest 0..0)" in warning
    frames = {v.id: [] for v in sweep.variants}
    for task in render_tasks(sweep):
        frames[task.variant] += task.frames
    assert sorted(len(f) for f in frames.values()) == [1, 1, 2, 2]


# ------------------------------------------------------------------ what check flags, render refuses
@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda s: s.SetMetadata("upAxis", "Y"), "upAxis = 'Y': expected Z"),
        (lambda s: s.SetMetadata("metersPerUnit", 0.01), "metersPerUnit = 0.01: expected 1"),
        (lambda s: s.GetRootLayer().pseudoRoot.ClearInfo("upAxis"), "upAxis = 'Y': expected Z"),
        (
            lambda s: (s.SetStartTimeCode(5), s.SetEndTimeCode(2)),
            "endTimeCode = 2.0: expected >= startTimeCode (5)",
        ),
        (lambda s: s.SetEndTimeCode(1e11), "100,000,000,001 frames; at most 1,000,000"),
    ],
)
def test_render_refuses_what_check_flags(tmp_path, edit, expected):
    from pxr import Usd

    from humv_usd.usd.check import check_stage

    path = _tiny_stage(tmp_path)
    stage = Usd.Stage.Open(str(path))
    edit(stage)
    stage.Save()
    out = tmp_path / "r"
    line = _one_line(CliRunner().invoke(main, ["render", str(path), "-o", str(out)]))
    assert expected in line and str(path) in line
    assert not out.exists() or not any(out.rglob("*.exr"))
    rule = {"upAxis =": "humv:upAxis", "metersPe": "humv:metersPerUnit", "endTimeC": "humv:timeRange"}.get(
        expected[:8]
    )
    if rule:  # check reports the same as an error
        assert any(f.startswith(rule) for f in check_stage(path))


def test_a_long_stage_renders_the_frames_asked_for(tmp_path):
    from pxr import Usd

    from humv_usd.pipeline.preflight import check_stage_for_render

    path = _tiny_stage(tmp_path)
    stage = Usd.Stage.Open(str(path))
    stage.SetEndTimeCode(1e11)
    stage.Save()
    check_stage_for_render(path, frames_given=True)  # --frames 0:3 takes four of them
    with pytest.raises(InputError, match="use --frames"):
        check_stage_for_render(path)


# ------------------------------------------------------------------ scenario values that crashed or were cut
@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (  # pandas' timestamps end in 2262: OutOfBoundsDatetime deep in the sun position
            "start = 2018-10-24T14:05:00",
            "start = 9999-12-31T23:59:59",
            "general.start = '9999-12-31T23:59:59': allowed range 1900-01-01T00:00:00..2200-12-31T23:59:59",
        ),
        ('name = "humvvex"', 'name = "hum\\u0000vvex"', "general.name = 'hum\\x00vvex': contains a NUL"),
        ("seed = 0", "seed = " + "[" * 3000 + "]" * 3000, "not valid TOML: nested too deeply"),
    ],
)
def test_scenario_values_that_crashed_or_were_cut_are_one_line(tmp_path, old, new, expected):
    text = (ROOT / "examples" / "humvvex.toml").read_text()
    assert old in text
    path = tmp_path / "s.toml"
    path.write_text(text.replace(old, new, 1))
    line = _one_line(CliRunner().invoke(main, ["compose", str(path), "-o", str(tmp_path / "o")]))
    assert expected in line
    assert not (tmp_path / "o").exists()


def test_vnir_is_named_as_not_rendered_and_skin_is_no_ground(humvvex_raw):
    import copy

    from humv_usd.scenario.load import validate

    raw = copy.deepcopy(humvvex_raw)
    raw["sensor"][0]["band"] = "VNIR"  # SWIR and NIR are rendered (issue 24.3)
    raw["scene"]["ground"]["material"] = "skin"
    with pytest.raises(InputError) as info:
        validate(raw)
    band = next(p for p in info.value.problems if "band" in p)
    assert "VNIR, 0.4-1.0 µm, is not rendered yet" in band and "did you mean" not in band
    ground = next(p for p in info.value.problems if "ground.material" in p)
    assert "allowed values: concrete," in ground and "skin" not in ground.split("allowed values:")[1]


@pytest.mark.slow
def test_sweep_limit_summary_counts_what_ran(tmp_path):
    """The summary line after ``--limit 1`` said "4 variants" for a dataset holding one."""
    from test_sweep import _write

    path = _write(tmp_path)
    r = CliRunner().invoke(main, ["sweep", str(path), "-o", str(tmp_path / "ds"), "--limit", "1", "--quiet"])
    assert r.exit_code == 0, r.output
    assert "ds: 1 of 4 variants (--limit 1), 2 frames, 2 images" in r.output.splitlines()[-1]


# ------------------------------------------------------------------ keys that do nothing
def test_keys_that_do_nothing_in_their_context_are_warned(humvvex_raw):
    import copy

    from humv_usd.scenario.load import validate
    from humv_usd.scenario.warnings import suspicious

    raw = copy.deepcopy(humvvex_raw)
    assert suspicious(validate(copy.deepcopy(raw))) == []
    raw["sensor"][0]["altitude_m"] = 50.0  # a tripod camera
    raw["thermal"] = {"model": "fixed", "radiation_rays": 256}
    raw["human"].append(dict(raw["human"][0], id="p2"))
    place = dict(raw["placement"][0], human="p2")
    place["position_m"] = [place["position_m"][0] + 0.3, *place["position_m"][1:]]
    raw["placement"].append(place)
    lines = suspicious(validate(raw))
    assert any(line.startswith("sensor[0].altitude_m: ignored on a tripod camera") for line in lines)
    assert any(
        line.startswith("thermal.radiation_rays: ignored with thermal.model = 'fixed'") for line in lines
    )
    assert any("stand 0.30 m apart" in line for line in lines), lines
    del raw["scene"]
    assert any(line.startswith("[scene]: not given") for line in suspicious(validate(raw)))


@pytest.mark.parametrize(
    ("rows", "expected"),
    [
        ([[0.0] * 4] * 4, "last column: expected [0, 0, 0, 1]"),
        ([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]], "determinant of the 3x3 part"),
        ([[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "last column: expected [0, 0, 0, 1]"),
    ],
)
def test_a_zero_or_projective_asset_transform_is_refused(rows, expected):
    """An all-zero or projective transform was accepted (the asset vanished or divided by w)."""
    from humv_usd.scenario.load import validate

    text = (ROOT / "examples" / "street.toml").read_text()
    import tomllib

    raw = tomllib.loads(text)
    asset = raw["scene"]["asset"][0]
    asset.pop("position_m", None)
    asset.pop("heading_deg", None)
    asset["transform"] = [[float(v) for v in r] for r in rows]
    with pytest.raises(InputError) as info:
        validate(raw, ROOT / "examples" / "street.toml")
    assert any("scene.asset[0].transform" in p and expected in p for p in info.value.problems), info.value


def test_an_unknown_garment_is_reported_with_the_other_problems(humvvex_raw):
    """It was reported only in a second pass, after every other problem had been fixed."""
    import copy

    from humv_usd.scenario.load import validate

    raw = copy.deepcopy(humvvex_raw)
    raw["human"][0]["clothing"] = ["tshirt_blak"]
    raw["general"]["latitude_deg"] = 95.0  # a first-pass problem
    with pytest.raises(InputError) as info:
        validate(raw)
    problems = info.value.problems
    assert any(p.startswith("general.latitude_deg = 95.0") for p in problems)
    assert any(p.startswith("human[0].clothing[0] = 'tshirt_blak'") and "did you mean" in p for p in problems)


def test_an_output_that_is_a_dangling_symlink_or_a_loop_is_one_line(tmp_path):
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    scenario = tmp_path / "s.toml"
    scenario.write_text((ROOT / "examples" / "humvvex.toml").read_text())
    for out in ("dangling", "loop1", "dangling/sub"):
        line = _one_line(CliRunner().invoke(main, ["compose", str(scenario), "-o", str(tmp_path / out)]))
        assert "symbolic link to a missing target or a loop" in line, line
    assert not (tmp_path / "missing").exists()


def test_a_z_up_bvh_gets_a_horizontal_facing_axis(humvvex_raw):
    """The documented bvh_up_axis = "Z" could never work: the facing axis stayed Z (one line
    naming neither key nor file)."""
    import copy

    from humv_usd.human.bvh import axis_matrix
    from humv_usd.scenario.load import validate

    raw = copy.deepcopy(humvvex_raw)
    raw["human"][0]["bvh_up_axis"] = "Z"
    human = validate(copy.deepcopy(raw))["human"][0]
    assert human["bvh_forward_axis"] == "-Y"
    a = axis_matrix(human["bvh_up_axis"], human["bvh_forward_axis"])
    # Z-up, facing -Y is already our frame (up +Z, facing -Y): the identity
    assert np.allclose(a, np.eye(3))
    raw["human"][0]["bvh_forward_axis"] = "-Z"
    with pytest.raises(InputError) as info:
        validate(raw)
    (line,) = [p for p in info.value.problems if "bvh_forward_axis" in p]
    assert "human[0].bvh_forward_axis = '-Z': the same axis as human[0].bvh_up_axis = 'Z'" in line
