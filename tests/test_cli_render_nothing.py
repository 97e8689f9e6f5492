"""``humv-usd render`` whose every sensor is skipped: one line per sensor naming it and why, exit
2, nothing written (issue 26: it exited 0 with "0 image(s)" and a manifest of nothing)."""

from __future__ import annotations

from click.testing import CliRunner
from test_render_eo import eo_camera
from test_render_radiometry import material, new_stage, plate

from humv_usd.cli.main import main


def test_render_of_only_skipped_sensors_is_an_error_and_writes_nothing(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    plate(stage, "/World/p", 10.0, 0.0, material(stage, "gray", 0.5), 300.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0))  # EO without sun or sky: nothing lights it
    stage.Save()
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["render", str(tmp_path / "s.usda"), "-o", str(out), "-q", "--spp", "2"]
    )
    assert result.exit_code == 2, result.output
    [line] = [x for x in result.output.splitlines() if x.strip()]
    assert line.startswith("humv-usd: error: nothing to render: sensor eo (EO) is skipped: ")
    assert "no visible illumination" in line and "Traceback" not in result.output
    assert not out.exists()  # no manifest, no lock, no folder
