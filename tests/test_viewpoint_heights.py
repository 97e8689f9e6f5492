"""The camera sampler's dataset presets against the person heights the datasets publish (issue 28):
where a preset carries the dataset's published bin fractions, the sampled histogram is close to it
(total variation distance), and every published table is a histogram."""

from __future__ import annotations

import numpy as np
import pytest

from humv_usd.bench.viewpoints import bin_fractions, compare, sample_boxes, sample_heights
from humv_usd.catalog.viewpoints import VIEWPOINTS


@pytest.mark.parametrize("name", [n for n, p in VIEWPOINTS.items() if p.published_bins_px])
def test_published_bins_are_histograms(name):
    edges, fractions = VIEWPOINTS[name].published_bins_px
    assert np.all(np.diff(edges) > 0)
    if fractions:
        assert len(fractions) == len(edges) - 1 and all(f >= 0 for f in fractions)
        assert sum(fractions) == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("name", [n for n, p in VIEWPOINTS.items() if p.published_area_bins_px2])
def test_published_area_bins_are_histograms(name):
    edges, fractions = VIEWPOINTS[name].published_area_bins_px2
    assert np.all(np.diff(edges) > 0) and len(fractions) == len(edges) - 1
    assert all(f >= 0 for f in fractions) and sum(fractions) == pytest.approx(1.0, abs=1e-3)


def test_bin_fractions():
    assert bin_fractions([1.0, 5.0, 5.0, 50.0], [0.0, 2.0, 10.0, 100.0]).tolist() == [0.25, 0.5, 0.25]


# before the tuning (13 mm lens; 5-45 m) the distances were 0.89 and 0.19
@pytest.mark.parametrize("name", ["hit_uav", "kaist"])
def test_sampled_heights_follow_the_published_histogram(name):
    """HIT-UAV's 12,312 annotated person boxes (median 20 px) and KAIST's test-set scale bins
    (28 / 65 / 7 % far / medium / near): 200 sampled poses of the preset within a total
    variation distance of 0.2 of the published fractions (HIT-UAV 0.13-0.16, KAIST 0.03-0.09
    over 200-1,000 draws)."""
    r = compare(name, 200)
    assert r["tv_distance"] < 0.2, r


def test_ltd_box_areas_follow_the_published_size_groups():
    """LTD's 5.8 million human boxes (Seasons in Drift challenge 2022): 97.0 % under 1,024 px^2.
    The boxes re-projected from the drawn poses have the heights the sampler recorded, and 200
    poses fall within a total variation distance of 0.2 of the published groups (0.05-0.11
    over 200-1,000 draws; the preset is estimated, not fitted)."""
    heights, widths = sample_boxes("ltd", 20)
    assert np.allclose(heights, sample_heights("ltd", 20), atol=1e-3)
    assert np.all((widths > 0) & (widths < heights))  # a standing person's box
    r = compare("ltd", 200)
    assert r["area_tv_distance"] < 0.2, r


def test_draws_are_seeded_per_variant():
    assert np.array_equal(sample_heights("kaist", 5), sample_heights("kaist", 5))
    assert not np.array_equal(sample_heights("kaist", 5, seed=1), sample_heights("kaist", 5))
