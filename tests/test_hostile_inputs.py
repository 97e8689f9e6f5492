"""Inputs that once exhausted the machine, hung or ended in a traceback (issue 26): each is
refused with one line and exit code 2, before anything is read whole or written."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

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
