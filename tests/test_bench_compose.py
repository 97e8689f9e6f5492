"""`humv-usd bench compose` (issue 31.2): the growth fit and the option checks (the composes
themselves are the bench's, not the suite's)."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from humv_usd.bench.compose_cost import growth
from humv_usd.cli.main import main

TABLE1 = Path(__file__).resolve().parents[1] / "examples" / "table1.toml"


def _row(people, frames, thermal_s, cpu_s):
    return {
        "people": people,
        "frames": frames,
        "cpu_s": cpu_s,
        "wall_s": cpu_s,
        "layer_s": {"thermal": thermal_s},
    }


def test_growth_recovers_a_linear_cost():
    # thermal = 2 + 3 (N - 1) + 0.5 (frames - 1); cpu = 5 + 1 (frames - 1), no person term
    rows = [_row(n, f, 2 + 3 * (n - 1) + 0.5 * (f - 1), 5 + (f - 1)) for n in (1, 2, 4) for f in (1, 5)]
    g = growth(rows)
    assert g["thermal"] == {"base": 2.0, "per_person": 3.0, "per_frame": 0.5, "rms_residual": 0.0}
    assert g["cpu_s"]["per_person"] == pytest.approx(0.0, abs=1e-9)
    assert g["cpu_s"]["per_frame"] == pytest.approx(1.0)


def test_per_person_layers_are_summed_per_tool():
    rows = [
        {
            "people": 1,
            "frames": 1,
            "cpu_s": 1.0,
            "wall_s": 1.0,
            "layer_s": {"avatar_p0": 1.0, "atmosphere_paths": 0.5},
        },
        {
            "people": 3,
            "frames": 1,
            "cpu_s": 1.0,
            "wall_s": 1.0,
            "layer_s": {f"avatar_p{i}": 1.0 for i in range(3)},
        },
    ]
    g = growth(rows)
    assert g["avatar_*"]["per_person"] == pytest.approx(1.0) and "avatar_p0" not in g
    assert g["atmosphere_paths"]["base"] == pytest.approx(0.5)


def test_growth_leaves_out_a_term_the_grid_does_not_vary():
    g = growth([_row(1, 1, 2.0, 1.0), _row(1, 9, 6.0, 1.0)])
    assert g["thermal"]["per_person"] is None
    assert g["thermal"]["per_frame"] == pytest.approx(0.5)


@pytest.mark.parametrize(
    ("args", "message"),
    [(["--people", "0"], "each in 1..50"), (["--frames", "2,x"], "expected integers")],
)
def test_bad_counts_are_refused(args, message):
    r = CliRunner().invoke(main, ["bench", "compose", *args])
    assert r.exit_code == 2 and message in r.output


def test_stage_cpu_seconds_finds_the_garment_stacks(tmp_path):
    import cProfile
    import time

    from humv_usd.bench.compose_cost import stage_cpu_seconds
    from humv_usd.physics.garment import stack_steady_state

    prof = cProfile.Profile(time.process_time)
    prof.enable()
    # enough facets for the batched Newton solver to take more than the 0.01 s the rows round to
    stack_steady_state(
        306.0, 290.0, 300.0, 5.0, [[2e-3] * 20000, [1e-3] * 20000], [1e-3, 1e-3], [0.05, 0.05], [0.9, 0.9]
    )
    prof.disable()
    prof.dump_stats(str(tmp_path / "p.prof"))
    s = stage_cpu_seconds(tmp_path / "p.prof")
    assert 0.0 < s["thermal.garment_stacks"] <= s["total"]
    # every layer tool has its row (none of them ran here)
    assert s["thermal"] == 0.0 and s["avatar_*"] == 0.0 and s["environment"] == 0.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--variant", "3"], "only with --scenario"),
        (["--scenario", str(TABLE1), "--variant", "100000"], "has variants 0..167"),
    ],
)
def test_bad_scenario_options_are_refused(args, message):
    r = CliRunner().invoke(main, ["bench", "compose", *args])
    assert r.exit_code == 2 and message in r.output
