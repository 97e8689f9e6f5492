"""The render command's summary lines never fail on a quantity the render could not estimate."""

from humv_usd.cli.main import echo_render_summary


def _manifest(edge_mean, p99):
    return {
        "settings": {"estimator": "fast", "spp": 2},
        "monte_carlo_error": {
            "temperature_stderr_mean_k": 0.005,
            "temperature_stderr_max_k": 0.008,
            "radiance_stderr_mean": 0.0039,
            "radiance_stderr_max": 0.0061,
        },
        "rendered_this_call": [5],
        "timings_s": {"total": 7.5},
        "sensors": [
            {
                "name": "lwir",
                "frames": [5],
                "timings_s": {"render": 0.95},
                "monte_carlo_error_k": {"mean_k": 0.005, "p99_max_k": p99, "edge_mean_k": edge_mean},
            }
        ],
    }


def test_a_tiny_image_without_edge_pixels_says_n_a(capsys):
    """64 x 48 walk frame: every pixel away from edges, no edge pixel: the edge mean is None."""
    echo_render_summary(_manifest(None, 0.0071), "out", "fast")
    line = [x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("lwir:")][0]
    assert "p99 0.0071 K" in line and "edge pixels n/a" in line and "0.95 s render per frame" in line


def test_all_numbers_print_in_kelvin(capsys):
    echo_render_summary(_manifest(2.681, None), "out", "fast")
    out = capsys.readouterr().out
    assert "edge pixels 2.681 K" in out and "p99 n/a" in out and "mean 0.0050 K" in out


def test_a_frame_short_of_its_quality_target_says_so(capsys):
    """Issue 25: a frame that stops at the spp cap without meeting its target says so, per region."""
    manifest = _manifest(0.9, 0.05)
    manifest["sensors"][0]["quality"] = {"met": False, "frames_not_met": [5], "regions_not_met": ["person"]}
    echo_render_summary(manifest, "out", "fast")
    line = [x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("lwir:")][0]
    assert "quality target NOT met in 1 frame(s) at the spp cap (person)" in line
    manifest["sensors"][0]["quality"] = {"met": True, "frames_not_met": [], "regions_not_met": []}
    echo_render_summary(manifest, "out", "fast")
    assert "quality target met" in capsys.readouterr().out


def test_the_person_error_is_printed_with_the_thermal_layers_noise(capsys):
    """Issue 25.3: the line names the person's mean error away from edges (the largest over the
    frames) and, where larger, with the thermal layer's face noise, which the stopping rule does
    not see; no person, nothing."""
    manifest = _manifest(0.9, 0.05)
    person = {"mean_k": 0.0114, "total_error_mean_k": 0.0372}
    manifest["sensors"][0]["frames"] = [
        {"quality": {"regions": {"person": person}}},
        {"quality": {"regions": {"person": {"mean_k": 0.0090, "total_error_mean_k": 0.0301}}}},
    ]
    echo_render_summary(manifest, "out", "fast")
    line = [x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("lwir:")][0]
    assert "person 0.0114 K (0.0372 K with the thermal layer's noise)" in line
    manifest["sensors"][0]["frames"] = [{"quality": {"regions": {"ground": person}}}]
    echo_render_summary(manifest, "out", "fast")
    assert "person" not in capsys.readouterr().out
