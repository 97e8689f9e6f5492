"""End to end: compose humvvex, render it through the CLI, read the EXR back."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import HUMVVEX, ROOT
from pxr import Usd

from humv_usd import images
from humv_usd.physics.planck import band_radiance, brightness_temperature
from humv_usd.render.export import StageExport
from humv_usd.render.frame import path_table
from humv_usd.render.radiometry import SubBands
from humv_usd.usd.atmosphere import atmosphere_spectra
from humv_usd.usd.layers import open_stage
from humv_usd.usd.sensor import read_camera_pose

pytestmark = pytest.mark.slow


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "humv_usd.cli.main", *args], cwd=ROOT, capture_output=True, text=True
    )


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    out = tmp_path_factory.mktemp("e2e")
    r = run("compose", str(HUMVVEX), "-o", str(out))
    assert r.returncode == 0, r.stderr
    r = run(
        "render",
        str(out / "stage.usda"),
        "-o",
        str(out / "render"),
        "--spp",
        "8",
        "--sensor",
        "atom1024_lwir",
    )
    assert r.returncode == 0, r.stderr
    assert "Monte Carlo error per pixel" in r.stdout
    channels = images.read_exr(out / "render" / "atom1024_lwir" / "0000.exr")  # by logical name
    manifest = json.loads((out / "render" / "manifest.json").read_text())
    return out, channels, manifest


def test_outputs_and_manifest(rendered):
    out, ch, manifest = rendered
    assert set(ch) - set(manifest["ground_truth"]["channels"]) - {"counts"} == {  # counts: sensor chain
        "radiance",
        "brightness_temperature",
        "radiance_stderr",
        "depth",
        "instance_id",
        "R",  # display-only grey preview (issue 12)
        "G",
        "B",
    }
    assert ch["radiance"].shape == (768, 1024)
    png = oiio.ImageBuf(str(out / "render" / "atom1024_lwir" / "0000.png"))
    assert png.spec().format == oiio.UINT8 and png.spec().width == 1024
    for key in ("versions", "settings", "timings_s", "monte_carlo_error"):
        assert key in manifest
    assert manifest["settings"]["spp"] == 8
    err = manifest["monte_carlo_error"]
    assert 0 < err["temperature_stderr_mean_k"] < err["temperature_stderr_max_k"]


def test_labels_and_depth(rendered):
    _, ch, _ = rendered
    ids = ch["instance_id"].astype(int)
    # person 1, ground 2, warehouse 3, sky 0 (humans first, then ground, then objects)
    assert set(np.unique(ids)) == {0, 1, 2, 3}
    person = ids == 1
    assert 2000 < person.sum() < 40000
    # the person stands 15 m in front of the camera (optical-axis depth, body ~0.3 m deep)
    assert np.median(ch["depth"][person]) == pytest.approx(15.0, abs=0.3)
    # the warehouse wall is a plane 25 m ahead, facing the camera: exact per pixel
    wall = ids == 3
    np.testing.assert_allclose(ch["depth"][wall & (ch["depth"] < 25.5)], 25.0, atol=1e-3)
    assert np.all(np.isinf(ch["depth"][ids == 0]))


def test_radiometry(rendered):
    out, ch, manifest = rendered
    band = (8.0, 14.0)
    r = manifest["sensors"][0]["response"]  # the preset's relative spectral response
    resp = (r["wavelengths_um"], r["values"]) if r else None
    sky_k = manifest["sensors"][0]["frames"][0]["sky_temperature_k"]
    ids = ch["instance_id"]
    # sky pixels away from edges (a pixel integrates its whole footprint) see only the uniform
    # sky: exact, no noise
    sky = np.ones_like(ids, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            sky &= np.roll(np.roll(ids, dy, axis=0), dx, axis=1) == 0
    assert sky.sum() > 1000
    stage = open_stage(out / "stage.usda")
    exporter = StageExport(stage)
    [cam] = [s for s in exporter.sensors if s.name == "atom1024_lwir"]
    spectra = atmosphere_spectra(stage, Usd.TimeCode(0))
    sub = SubBands(band, resp, len(manifest["sensors"][0]["subbands_um"]))
    if spectra.sky_radiance is None:
        np.testing.assert_allclose(ch["brightness_temperature"][sky], sky_k, atol=1e-3)
    else:  # the envmap sky: the table's sub-band radiance at each sky pixel's zenith angle
        pose = read_camera_pose(stage.GetPrimAtPath(cam.path), Usd.TimeCode(0))
        h, w = ids.shape
        right = np.cross(pose.forward, pose.up)
        tx = np.tan(np.radians(pose.fov_x_deg) / 2)
        xs, ys = np.meshgrid((np.arange(w) + 0.5) / w * 2 - 1, (1 - (np.arange(h) + 0.5) / h * 2) * h / w)
        dirs = pose.forward + tx * (xs[..., None] * right + ys[..., None] * pose.up)
        zenith = np.degrees(np.arccos(dirs[..., 2] / np.linalg.norm(dirs, axis=-1)))
        l_zen = sub.integrate(spectra.wavelengths_um, spectra.sky_radiance).sum(axis=-1)
        expected = np.interp(zenith[sky], spectra.sky_zenith_deg, l_zen)
        np.testing.assert_allclose(ch["radiance"][sky], expected, rtol=2e-3)
    # skin (eps_band ~ 0.98 at 306.15 K) reflects 2 % of a colder surround: between the two.
    # The shins (between the shorts and the feet) are bare skin.
    person = ch["instance_id"] == 1
    rows = np.where(person.any(axis=1))[0]
    top, height = rows.min(), rows.max() - rows.min()
    shins = person.copy()
    shins[: top + int(0.75 * height)] = False
    shins[top + int(0.92 * height) :] = False
    t_skin = np.median(ch["brightness_temperature"][shins])
    eps = 0.98
    surface = eps * band_radiance(306.15, band, resp) + (1 - eps) * band_radiance(sky_k, band, resp)
    table = path_table(stage, cam, Usd.TimeCode(0))
    assert table is not None  # compose's atmosphere_paths layer
    # 15 m of air in front of the skin (band-effective transmittance)
    tau, path = table.reduce(SubBands(band, resp, 1)).at(15.0, 0)
    surface = tau * surface + path
    lower = brightness_temperature(surface, band, resp)
    assert lower - 0.3 < t_skin < 306.15
    # the image is radiance-consistent: T_b inverts L per pixel
    some = np.s_[::37, ::41]
    np.testing.assert_allclose(
        brightness_temperature(ch["radiance"][some].astype(float), band, resp),
        ch["brightness_temperature"][some],
        rtol=1e-5,
    )


def test_render_bad_stage_exit_2(tmp_path):
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\nnot usd at all {")
    r = run("render", str(bad), "-o", str(tmp_path / "r"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()
