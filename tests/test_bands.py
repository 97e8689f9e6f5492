"""Any band (issue 24.3): NIR and SWIR through the sub-band pass (reflection and emission,
radiance out), a band the render cannot do refused in one line, the reflective sensor chain.

Closed forms: a white Lambertian plate under a sun beam of spectral irradiance E at zenith angle
theta has radiance int_band E d(lambda) cos(theta) / pi; under a uniform sky of radiance L it has
radiance L (for SWIR at night: the airglow integrated over the band); Poisson photoelectrons.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_render import add_camera
from test_render_eo import reflective
from test_render_radiometry import atmosphere_tables, new_stage, plate, read_exr, sun

from humv_usd.catalog import sensors as catalog
from humv_usd.compat import trapezoid
from humv_usd.errors import InputError
from humv_usd.physics import nightsky
from humv_usd.physics import sensor as chain
from humv_usd.pipeline.render import render_stage

SWIR = (0.9, 1.7)


def _stage(tmp_path, band, token, toward_sun, solar_um=1500.0):
    stage = new_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 3.0], [1.0, 1.0])
    plate(stage, "/World/p", 1e4, 0.0, white, 280.0)
    add_camera(stage, "cam", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0, band=band, band_token=token, up=(0, 1, 0))
    wl = [0.3, 0.9, 4.0]
    atmosphere_tables(
        stage, wl, sky=np.zeros((2, 3)), zenith=np.array([0.0, 90.0]), solar=[solar_um, solar_um, solar_um]
    )
    sun(stage, toward_sun)
    stage.Save()


def test_a_band_the_render_cannot_do_is_refused(tmp_path):
    """band EO at 0.9-1.7 um was rendered as visible light: now one line naming the attribute,
    the value and the allowed range."""
    _stage(tmp_path, SWIR, "EO", (0.0, 0.0, 1.0))
    with pytest.raises(InputError) as err:
        render_stage(tmp_path / "s.usda", tmp_path / "out", spp=2)
    msg = str(err.value)
    assert "\n" not in msg and "humv:sensor:wavelengthRange" in msg
    assert "[0.9, 1.7]" in msg and "band EO: 0.36..0.83" in msg
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.exr"))


@pytest.mark.parametrize("zenith_deg", [0.0, 60.0])
def test_swir_white_plate_under_sun_closed_form(tmp_path, zenith_deg):
    th = math.radians(zenith_deg)
    _stage(tmp_path, SWIR, "SWIR", (math.sin(th), 0.0, math.cos(th)))
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    expected = 1500.0 * (SWIR[1] - SWIR[0]) * math.cos(th) / math.pi  # W m-2 sr-1 (flat response)
    assert ch["radiance"].mean() == pytest.approx(expected, rel=2e-3)
    assert "brightness_temperature" not in ch  # reflected light: radiance, no temperature
    [rec] = manifest["sensors"]
    assert rec["band"] == "SWIR" and rec["frames"][0]["brightness_temperature_mean_k"] is None


def test_swir_moonless_night_is_the_airglow(tmp_path):
    """Sun 40 deg below the horizon, no site (no moon): the white plate has the radiance of the
    natural night sky integrated over 0.9-1.7 um, the OH airglow that lets SWIR see at night:
    about 50 times the visible band's (0.4-0.7 um) for the same plate."""
    h = math.radians(-40.0)
    _stage(tmp_path, SWIR, "SWIR", (math.cos(h), 0.0, math.sin(h)))
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    x = np.linspace(*SWIR, 4001)
    expected = float(trapezoid(nightsky.night_sky_radiance(x), x))
    ch = read_exr(tmp_path / "out" / "cam" / "0000.exr")
    assert ch["radiance"].mean() == pytest.approx(expected, rel=0.01)
    v = np.linspace(0.4, 0.7, 301)
    assert expected > 20 * float(trapezoid(nightsky.night_sky_radiance(v), v))
    frame = manifest["sensors"][0]["frames"][0]
    assert "night_sky" in frame["radiometry"]["night"]
    assert "exposure capped" in frame["sensor_chain"]["settings"]["gain_source"]


def test_reflective_chain_counts_photoelectrons():
    """SWIR preset: N_e = pi L / (4 N^2) p^2 t eta lambda_c / (h c) at the capped exposure; the
    counts' mean and spread are Poisson + read noise of N_e."""
    p = catalog.preset("swir_ingaas640")
    m = chain.SensorModel(
        name="s",
        band="SWIR",
        wavelength_range_um=p.wavelength_um,
        response_wavelengths_um=np.asarray(p.response_wavelengths_um),
        response=np.asarray(p.response),
        resolution=(64, 48),
        pixel_pitch_m=15e-6,
        f_number=1.4,
        focal_length_m=0.025,
        bit_depth=14,
        agc="linear",
        full_well_e=p.full_well_e,
        read_noise_e=p.read_noise_e,
    )
    per_unit = (
        math.pi
        / (4 * 1.4**2)
        * (15e-6) ** 2
        * chain.EO_MAX_EXPOSURE_S
        * 0.75
        * 1.3e-6
        / (6.62607015e-34 * 299792458.0)
    )
    n_e = 2000.0
    out = chain.apply_chain(np.full((48, 64), n_e / per_unit), m, np.random.default_rng(0), psf=False)
    k = m.max_count / m.full_well_e
    assert out.counts.mean() == pytest.approx(n_e * k, rel=0.02)
    assert out.counts.std() == pytest.approx(math.sqrt(n_e + m.read_noise_e**2) * k, rel=0.1)
    assert out.settings["noise"]["exposure_s"] == pytest.approx(chain.EO_MAX_EXPOSURE_S)


def test_reflective_presets_fit_their_bands():
    from humv_usd.scenario.spec import BAND_RANGE_UM, SENSOR_PRESETS

    for name in ("swir_ingaas640", "nir_imx273"):
        p = catalog.preset(name)
        lo, hi = BAND_RANGE_UM[p.band]
        assert lo <= p.wavelength_um[0] < p.wavelength_um[1] <= hi and name in SENSOR_PRESETS
        assert catalog.calibration(name)[0] is None  # auto exposure


def test_reflective_band_faces_without_temperature_emit_nothing():
    """Without a thermal layer (no MWIR/LWIR sensor asks for one) a face's temperature is NaN:
    below 2.5 um it emits nothing; a thermal band still refuses it."""
    from humv_usd.physics import planck
    from humv_usd.render.radiometry import SubBands

    sub = SubBands(SWIR, None, 1)
    out = sub.radiance(np.array([np.nan, 300.0]))
    assert np.all(out[0] == 0.0)
    np.testing.assert_allclose(out[1].sum(), planck.band_radiance(300.0, SWIR), rtol=1e-6)
    with pytest.raises(ValueError):
        SubBands((8.0, 14.0), None, 1).radiance(np.array([np.nan]))


def test_fabrics_show_their_swir_absorption_bands():
    """Fabrics on the coarse grid went straight from 1.0 to 2.5 um; now cotton dips at the
    1.94 um water/O-H combination band and polyester at its 1.66 um C-H overtone below their
    neighbours (Workman & Weyer 2008), the coarse nodes unchanged, still opaque (R + eps = 1)."""
    from humv_usd.catalog.materials import LIBRARY, WAVELENGTHS_UM

    cotton, pet = LIBRARY["cotton_white"], LIBRARY["polyester"]
    r = cotton.at([1.73, 1.94, 2.1])
    straight = np.interp(1.94, [1.0, 2.5], cotton.at([1.0, 2.5]))  # the coarse table's line
    assert r[1] < min(r[0], r[2]) and r[1] < 0.8 * straight
    p = pet.at([1.45, 1.65, 1.94])
    assert p[1] < min(p[0], p[2])
    for m in (cotton, pet, LIBRARY["wool"], LIBRARY["hair_dark"]):
        np.testing.assert_allclose(np.asarray(m.reflectance), np.asarray(m.at(WAVELENGTHS_UM)), atol=1e-6)
        np.testing.assert_allclose(np.add(m.spectrum_reflectance, m.spectrum_emissivity), 1.0, atol=1e-6)
        assert sum(1.0 < w < 2.5 for w in m.spectrum_wavelengths) >= 7


def test_reflective_display_keeps_a_dark_frame_dark():
    """A SWIR frame of a few hundred photoelectrons (170 ke- well) is shown dark: the display
    gain is capped at 24 dB as the EO display's, not stretched to full range."""
    p = catalog.preset("swir_ingaas640")
    m = chain.SensorModel(
        name="s",
        band="SWIR",
        wavelength_range_um=p.wavelength_um,
        response_wavelengths_um=np.asarray(p.response_wavelengths_um),
        response=np.asarray(p.response),
        resolution=(64, 48),
        pixel_pitch_m=15e-6,
        f_number=1.4,
        focal_length_m=0.025,
        bit_depth=14,
        agc="linear",
        full_well_e=p.full_well_e,
        read_noise_e=p.read_noise_e,
    )
    per_unit = chain.photoelectrons_per_input(m, chain.EO_MAX_EXPOSURE_S)
    out = chain.apply_chain(np.full((48, 64), 600.0 / per_unit), m, np.random.default_rng(0), psf=False)
    # 600 e- of 170 ke- x 16 = 5.6 % of the display range
    assert out.image8.mean() == pytest.approx(255 * 600 / 170000 * chain.EO_MAX_DISPLAY_GAIN, rel=0.05)


def test_swir_automatic_quality_is_relative_to_the_radiance(tmp_path):
    """A NIR/SWIR camera has no NETD: its automatic quality and its reported error are relative
    to the mean radiance (as the EO camera's), never a brightness temperature of reflected light
    read "in K"."""
    from click.testing import CliRunner

    from humv_usd.cli.main import main

    _stage(tmp_path, SWIR, "SWIR", (0.3, 0.0, 0.95))
    result = CliRunner().invoke(main, ["render", str(tmp_path / "s.usda"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    [rec] = manifest["sensors"]
    err = rec["monte_carlo_error_k"]
    assert err["unit"].startswith("relative to the mean radiance") and "relative" in err["definition"]
    assert 0.0 <= err["mean_k"] <= 0.01 and rec["quality"]["met"] is True
    frame = rec["frames"][0]["quality"]
    assert frame["targets_k"]["mean_k"] == pytest.approx(0.01) and frame["batches"] >= 2
    assert "% of the mean radiance" in err["spp_rule"]
    assert "% of the mean radiance" in result.output and " K, p99" not in result.output.split("cam:")[-1]
    # no temperature error of reflected light anywhere (the summary's K line is the thermal cameras')
    assert manifest["monte_carlo_error"]["temperature_stderr_mean_k"] is None
    assert rec["frames"][0]["monte_carlo_error"]["temperature_stderr_mean_k"] is None
    assert manifest["monte_carlo_error"]["radiance_stderr_mean"] is not None  # the radiance error stays
    assert "Monte Carlo error per pixel" not in result.output and "not estimable" not in result.output
