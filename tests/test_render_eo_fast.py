"""The fast EO estimator (humv_usd.render.eo_fast): visible sub-bands, CIE weights, the manifest's
relative error, and its bias against Mitsuba's spectral path tracer (the reference) on a small
sunlit scene with coloured surfaces."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from test_render import add_camera, add_mesh, box, rect_y, rect_z
from test_render_eo import reflective
from test_render_radiometry import atmosphere_tables, new_stage, plate, read_exr, sun

from humv_usd.pipeline.render import render_stage
from humv_usd.render import eo_fast
from humv_usd.render.cie import CMF_XYZ

VISIBLE = (0.4, 0.7)


@pytest.mark.parametrize("n", [1, 3, 12, 95])
def test_visible_bins_carry_the_cie_integrals(n):
    bins = eo_fast.visible_bins(n)
    assert len(bins) == n and bins.weights.shape == (3, n)
    assert (np.diff(bins.edges_nm) > 0).all() and bins.edges_nm[0] == 357.5 and bins.edges_nm[-1] == 832.5
    # a constant spectral radiance L gives Y = L (Mitsuba's normalisation), X and Z the CIE ratios
    cmf = np.asarray(CMF_XYZ).reshape(-1, 3)
    q = np.full(cmf.shape[0], 5.0)
    q[[0, -1]] = 2.5
    integrals = (q[:, None] * cmf).sum(axis=0)
    assert_allclose(bins.weights.sum(axis=1), integrals / integrals[1], rtol=1e-12)
    # bins of about equal observer sensitivity (x + y + z), every one non-empty
    assert (np.bincount(bins.index, minlength=n) > 0).all()
    share = bins.weights.sum(axis=0) / bins.weights.sum()
    if 1 < n <= 12:
        assert share.max() < 2.0 / n, share


def test_bin_means_keep_constants_and_weight_by_illumination():
    bins = eo_fast.visible_bins(4)
    assert_allclose(bins.mean(np.full(eo_fast.GRID_NM.size, 0.37)), 0.37, rtol=1e-12)
    # a step reflectance within a bin: the mean leans toward where the light is
    rho = (eo_fast.GRID_NM > 600.0).astype(float)
    red_light = np.where(eo_fast.GRID_NM > 600.0, 10.0, 1.0)
    plain, lit = bins.mean(rho), bins.mean(rho, red_light)
    assert (lit >= plain - 1e-12).all() and (lit > plain + 0.05).any()


def _plate_scene(tmp_path):
    stage = new_stage(tmp_path / "s.usda")
    grey = reflective(stage, "grey", [0.3, 1.0], [0.4, 0.4])
    plate(stage, "/World/p", 1e3, 0.0, grey, 300.0)
    add_camera(
        stage, "eo", (0, -6, 4), (0, 0, 0), fov_x_deg=30, resolution=(40, 30), band=VISIBLE, band_token="EO"
    )
    atmosphere_tables(
        stage, [0.3, 0.9], sky=np.full((2, 2), 80.0), zenith=np.array([0.0, 90.0]), solar=[1200.0, 1200.0]
    )
    sun(stage, (0.3, 0.2, 0.9))
    stage.Save()
    return tmp_path / "s.usda"


def test_manifest_records_the_relative_error_and_the_samples_used(tmp_path):
    stage = _plate_scene(tmp_path)
    auto = render_stage(stage, tmp_path / "auto")
    [eo] = auto["eo_sensors"]
    err = eo["monte_carlo_error_relative"]
    assert eo["estimator"] == "fast" and eo["spp_auto"]
    assert err["mean"] is not None and err["mean"] <= eo_fast.EO_TARGET_RELATIVE
    assert err["spp_used"] and min(err["spp_used"]) >= eo_fast.DEFAULT_EO_SPP
    frame = eo["frames"][0]
    assert frame["monte_carlo_error_relative"]["spp_used"] in err["spp_used"]
    # the automatic quality as in every band (issue 25.3): at least 2 batches (>= 4 replicas per
    # pixel), judged on the image and each labelled region, its verdict per frame and sensor
    q = frame["quality"]
    assert q["batches"] >= 2 and q["replicas_per_pixel"] >= 4 and q["error_dof"] >= 3
    assert (
        q["met"] is True and q["image_met"] is True and q["targets_k"]["mean_k"] == eo_fast.EO_TARGET_RELATIVE
    )
    assert all(r["mean_k"] <= eo_fast.EO_TARGET_RELATIVE for r in q["regions"].values() if r["met"])
    assert eo["quality"]["met"] is True and eo["quality"]["frames_not_met"] == []
    assert {"render", "labels", "write", "cpu"} <= set(frame["timings_s"])
    # the plate under sun and sky: Y = rho (E_sun cos + pi L_sky) / pi, everywhere in view
    ch = read_exr(tmp_path / "auto" / "eo" / "0000.exr")
    cos = 0.9 / np.linalg.norm([0.3, 0.2, 0.9])
    expected = 0.4 * (1.2 * cos + np.pi * 0.08) / np.pi
    sigma = np.sqrt(np.sum(ch["Y_stderr"] ** 2)) / ch["Y"].size
    assert abs(ch["Y"].mean() - expected) < 4 * sigma + 2e-3 * expected
    # a given spp is used exactly; spp 1 renders and says the error is not estimable
    given = render_stage(stage, tmp_path / "four", spp=4)["eo_sensors"][0]
    assert given["monte_carlo_error_relative"]["spp_used"] == [4] and not given["spp_auto"]
    assert given["frames"][0]["quality"]["met"] is None and given["quality"]["met"] is None
    one = render_stage(stage, tmp_path / "one", spp=1)["eo_sensors"][0]
    assert one["monte_carlo_error_relative"]["mean"] is None
    assert "not estimable" in one["monte_carlo_error_relative"]["not_estimable"]
    # the path tracer stays available as the reference
    path = render_stage(stage, tmp_path / "path", spp=4, estimator="path")["eo_sensors"][0]
    assert path["estimator"] == "path" and path["variant"].endswith("spectral")


def _coloured_scene(tmp_path):
    """Sunlit ground, a red wall and a blue box under a bluish sky: coloured interreflections."""
    stage = new_stage(tmp_path / "stage.usda")
    wl = [0.36, 0.45, 0.5, 0.55, 0.6, 0.65, 0.83]
    ground = reflective(stage, "ground", wl, [0.08, 0.12, 0.18, 0.25, 0.3, 0.32, 0.4])
    red = reflective(stage, "red", wl, [0.05, 0.05, 0.06, 0.1, 0.6, 0.75, 0.8])
    blue = reflective(stage, "blue", wl, [0.5, 0.7, 0.5, 0.15, 0.06, 0.05, 0.3])
    add_mesh(stage, "/World/Scene/ground", *rect_z(-40, 40, -40, 40), material=ground, instance_id=1)
    add_mesh(stage, "/World/Scene/wall", *rect_y(-10, 10, 0, 6, 4.0), material=red, instance_id=2)
    add_mesh(stage, "/World/Scene/box", *box((0.0, 1.5, 0.6), 1.2), material=blue, instance_id=3)
    add_camera(
        stage,
        "eo",
        (2.0, -8.0, 2.0),
        (0.0, 1.5, 0.8),
        fov_x_deg=60,
        resolution=(48, 36),
        band=VISIBLE,
        band_token="EO",
    )
    wl_sky = [0.35, 0.45, 0.55, 0.65, 0.85]
    sky = np.array([[120.0, 90.0, 60.0, 40.0, 20.0]] * 2)  # W m-2 sr-1 um-1, bluish, uniform
    atmosphere_tables(
        stage, wl_sky, sky=sky, zenith=np.array([0.0, 90.0]), solar=[900, 1700, 1800, 1600, 1100]
    )
    sun(stage, (-0.4, -0.6, 0.7))
    stage.Save()
    return tmp_path / "stage.usda"


@pytest.mark.slow
def test_fast_eo_is_unbiased_against_the_spectral_path_tracer(tmp_path):
    """Per labelled region and channel, the fast estimator's mean X, Y, Z agree with the 5-nm
    spectral path tracer at high spp within the combined Monte Carlo error plus 0.5 % (the
    spectral binning's allowance, measured ~0.1-0.2 % at the default bins)."""
    stage = _coloured_scene(tmp_path)
    render_stage(stage, tmp_path / "ref", spp=4096, estimator="path", seed=1)
    render_stage(stage, tmp_path / "fast", spp=256, estimator="fast", seed=2)
    ref = read_exr(tmp_path / "ref" / "eo" / "0000.exr")
    fast = read_exr(tmp_path / "fast" / "eo" / "0000.exr")
    assert {1, 2, 3} <= set(np.unique(ref["instance_id"]).astype(int).tolist())
    for region in np.unique(ref["instance_id"]):
        m = ref["instance_id"] == region
        y_sigma = np.sqrt(np.sum(fast["Y_stderr"][m] ** 2) + np.sum(ref["Y_stderr"][m] ** 2)) / m.sum()
        for c in "XYZ":
            r, f = ref[c][m].mean(), fast[c][m].mean()
            sigma = y_sigma * r / ref["Y"][m].mean()  # the channels' errors scale alike
            print(region, c, f"{f / r - 1:+.4f} +- {sigma / r:.4f}")
            assert abs(f - r) <= 4 * sigma + 5e-3 * r, (region, c, f / r - 1, sigma / r)
        assert 4 * y_sigma <= 0.015 * ref["Y"][m].mean(), (region, y_sigma)  # the test can fail
    # far less noise per camera sample than the path tracer
    per_sample = np.nanmean(fast["Y_stderr"]) * np.sqrt(256)
    assert per_sample < 0.5 * np.nanmean(ref["Y_stderr"]) * np.sqrt(4096)


def _uv_sphere(nu: int, nv: int, radius: float = 1.0):
    """A UV sphere (nu segments around, nv from pole to pole) as triangles, wound outward."""
    th = np.linspace(0.0, np.pi, nv + 1)[1:-1]
    ph = 2 * np.pi * np.arange(nu) / nu
    pts = [(0.0, 0.0, radius)]
    pts += [
        (radius * np.sin(t) * np.cos(p), radius * np.sin(t) * np.sin(p), radius * np.cos(t))
        for t in th
        for p in ph
    ]
    pts.append((0.0, 0.0, -radius))
    ring = lambda i, j: 1 + i * nu + j % nu  # noqa: E731
    tris = [[0, ring(0, j), ring(0, j + 1)] for j in range(nu)]
    for i in range(nv - 2):
        for j in range(nu):
            tris += [
                [ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)],
                [ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)],
            ]
    last = len(pts) - 1
    tris += [[last, ring(nv - 2, j + 1), ring(nv - 2, j)] for j in range(nu)]
    return pts, np.asarray(tris)


@pytest.mark.parametrize(
    "band, token, value, stderr, per_band",
    [(VISIBLE, "EO", "Y", "Y_stderr", 1e-3), ((0.9, 1.7), "SWIR", "radiance", "radiance_stderr", 0.8)],
)
def test_smooth_shading_keeps_a_curved_surfaces_sunlit_mean(tmp_path, band, token, value, stderr, per_band):
    """A white faceted sphere (48 x 24 segments, 7.5 deg between neighbouring normals, the
    garments' median) in the sun, seen from above by an EO and a SWIR camera (the reflected-light
    bands): the mean over its pixels away from the outline equals that of its flat faces,
    E rho (n . s) / pi (per nm for EO's Y; over the band for SWIR) with n the labels' geometric
    normal at each pixel centre, within 0.3 % + 4 sigma (measured: EO -0.21 %; flat shading
    -0.12 %, the pixel-centre normals against the pixels' means). Blending the faces' sun terms
    to the corners alone shrank it by ~cos^2 of half the angle between neighbours: -0.66 % here,
    and the render bench person's Y was 0.8 % under the spectral path tracer, which shades the
    flat faces (issue 25; :func:`humv_usd.render.estimator.corner_table`)."""
    e_um = 1500.0
    stage = new_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 3.0], [1.0, 1.0])
    pts, tris = _uv_sphere(48, 24)
    add_mesh(stage, "/World/Scene/ball", pts, [3] * len(tris), tris.ravel(), material=white, instance_id=1)
    # a black ground far below: the reflected light's control variate is ~0 (else the ball's own
    # top faces set the ground radiance it assumes, and the reflected filter's bias shows)
    black = reflective(stage, "black", [0.3, 3.0], [0.0, 0.0])
    add_mesh(stage, "/World/Scene/ground", *rect_z(-200, 200, -200, 200, -5.0), material=black, instance_id=2)
    add_camera(
        stage, "cam", (0, 0, 12), (0, 0, 0), fov_x_deg=11, resolution=(80, 80), band=band, band_token=token,
        up=(0, 1, 0),
    )  # fmt: skip
    atmosphere_tables(stage, [0.3, 0.9, 4.0], solar=[e_um, e_um, e_um])
    s = np.array([0.3, 0.2, 0.9]) / np.linalg.norm([0.3, 0.2, 0.9])
    sun(stage, tuple(s))
    stage.Save()
    render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4, estimator="fast", seed=5)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    ball = ch["instance_id"] == 1
    inner = ball.copy()  # two pixels inside the outline
    for _ in range(2):
        inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
        inner[[0, -1], :] = inner[:, [0, -1]] = False
    n = np.stack([ch["normal_x"], ch["normal_y"], ch["normal_z"]], axis=-1)
    inner &= n[..., 2] > 0.0  # (a few label rays through a shared edge report the far side)
    assert inner.sum() > 2500
    flat = e_um * per_band * np.maximum(n @ s, 0.0) / np.pi
    sigma = np.sqrt(np.sum(ch[stderr][inner] ** 2)) / inner.sum()
    got, want = ch[value][inner].mean(), flat[inner].mean()
    assert abs(got - want) < 4 * sigma + 3e-3 * want, (got / want - 1, sigma / want)
