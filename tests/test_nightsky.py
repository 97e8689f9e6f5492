"""Light after sunset: twilight, moon and natural night sky (physics.nightsky, environment.moon),
their render (render.nightlight through the EO render), and the EO chain in low light.

References the expectations come from (not from the code): the AMS Glossary of Meteorology
(horizontal illuminance at the ends of civil, nautical and astronomical twilight), the
Explanatory Supplement's full moon at the zenith (0.267 lx), Allen's table of the Moon's
magnitude against phase angle, USNO's dates of full and new moon, the photometric definition of
the candela (683 lm/W) and the camera equation with Poisson statistics.
"""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest
from pxr import Sdf
from test_render_eo import eo_camera, reflective
from test_render_radiometry import atmosphere_tables, new_stage, plate, read_exr, sun

from humv_usd.environment.moon import moon_at
from humv_usd.physics import nightsky
from humv_usd.physics import sensor as chain
from humv_usd.pipeline.render import render_stage
from humv_usd.render.nightlight import PHOTOPIC

Y_TO_CD = 683.0 * 106.856895  # luminance [cd m-2] of the render's Y [W m-2 sr-1 nm-1]


def luminance(wl_um, spectral_radiance_per_um):
    x = np.linspace(0.36, 0.83, 2000)
    v = np.interp(x, *PHOTOPIC) * np.interp(x, wl_um, spectral_radiance_per_um)
    return 683.0 * float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(x)))


def test_twilight_illuminance_matches_the_ams_glossary():
    """AMS Glossary: civil twilight takes the clear sky from ~585-410 lx (sunset, upper limb at
    -0.83 deg) to ~3.5-2 lx (-6 deg); astronomical twilight from ~0.008 lx (-12 deg) to
    ~6e-4 lx (-18 deg); the sun at the zenith gives about 1.3e5 lx."""
    e = nightsky.twilight_illuminance_lux([-0.83, -6.0, -12.0, -18.0, 90.0, -19.0])
    assert 410.0 <= e[0] <= 585.0
    assert 2.0 <= e[1] <= 3.5
    assert e[2] == pytest.approx(0.008, rel=0.15)
    assert e[3] == pytest.approx(6e-4, rel=0.15)
    assert e[4] == pytest.approx(1.3e5, rel=0.05)
    assert e[5] == 0.0
    # monotonic, and the pieces of the fit join (no step larger than 2 % at their limits)
    h = np.linspace(-18.0, 90.0, 5000)
    assert np.all(np.diff(nightsky.twilight_illuminance_lux(h)) > 0)
    for lo, *_ in nightsky.SUN_ILLUMINANCE_FIT[:-1]:
        a, b = nightsky.twilight_illuminance_lux([lo - 1e-9, lo + 1e-9])
        assert b == pytest.approx(a, rel=0.02)


def test_moon_illuminance_and_phase_law():
    """Full moon at the zenith 0.267 lx (Explanatory Supplement); Allen's table: the Moon is
    2.63 mag fainter at phase angle 90 deg and 1.62 at 60 deg than full."""
    assert float(nightsky.moon_illuminance_lux(90.0, 0.0)) == pytest.approx(0.267, rel=0.02)
    for alpha, dmag in ((90.0, 2.63), (60.0, 1.62)):
        assert -2.5 * math.log10(float(nightsky.moon_phase_factor(alpha))) == pytest.approx(dmag, abs=0.05)
    # closer moon brighter as the inverse square; none below the horizon
    near = nightsky.moon_illuminance_lux(45.0, 0.0, 0.5 * nightsky.MOON_MEAN_DISTANCE_KM)
    assert float(near) == pytest.approx(4.0 * float(nightsky.moon_illuminance_lux(45.0, 0.0)))
    assert float(nightsky.moon_illuminance_lux(-2.0, 0.0)) == 0.0


def test_night_sky_luminance_and_airglow():
    """A natural dark sky has a zenith luminance of about 2e-4 cd m-2 (V = 21.9 mag arcsec-2;
    Falchi et al. 2016 take 1.7e-4); the OH airglow makes the H band (1.6 um) more than 20 times
    brighter per um than the V band."""
    wl = np.linspace(0.36, 2.5, 500)
    sky = nightsky.night_sky_radiance(wl)
    assert 1.5e-4 <= luminance(wl, sky) <= 3.0e-4
    h, v = nightsky.night_sky_radiance([1.65, 0.55])
    assert h / v > 20.0


def test_photometric_scaling_of_a_flat_spectrum():
    """A flat spectral radiance of 1 W m-2 sr-1 nm-1 has a luminance of 683 x 106.857 cd m-2."""
    wl = np.linspace(0.3, 1.0, 50)
    s = nightsky.scale_to_photometric(wl, np.ones(wl.size), Y_TO_CD, PHOTOPIC)
    np.testing.assert_allclose(s, 1000.0, rtol=2e-3)  # [W m-2 sr-1 um-1]


def test_moon_phase_and_position_at_known_dates():
    """USNO: full moon 2024-01-25 17:54 UTC, new moon 2024-01-11 11:57 UTC. A full moon stands
    opposite the sun: near the eastern horizon at sunset."""
    m = moon_at(52.37, 4.90, 0.0, [dt.datetime(2024, 1, 25, 17, 54), dt.datetime(2024, 1, 11, 11, 57)])
    assert m.illuminated_fraction[0] > 0.99 and m.phase_angle_deg[0] < 12.0
    assert m.illuminated_fraction[1] < 0.01 and m.phase_angle_deg[1] > 168.0
    assert 40.0 < m.azimuth_deg[0] < 110.0 and 0.0 < m.elevation_deg[0] < 30.0
    np.testing.assert_allclose(np.linalg.norm(m.direction, axis=1), 1.0)
    assert m.direction[0, 2] == pytest.approx(math.sin(math.radians(m.elevation_deg[0])))
    assert 356000.0 < m.distance_km[0] < 407000.0


def _eo_model():
    return chain.SensorModel(
        name="e",
        band="EO",
        wavelength_range_um=(0.4, 0.7),
        response_wavelengths_um=np.array([0.4, 0.7]),
        response=np.array([1.0, 1.0]),
        resolution=(64, 48),
        pixel_pitch_m=3.45e-6,
        f_number=2.8,
        focal_length_m=0.012,
        bit_depth=12,
        agc="linear",
    )


def test_eo_chain_in_low_light_is_shot_and_read_noise():
    """Below the light the longest exposure needs, the counts are the photoelectrons of that
    exposure: N_e = pi L / (4 N^2) p^2 t eta lambda / (h c), mean N_e x counts per electron,
    variance (N_e + read^2) x its square (Poisson + Gaussian, EMVA 1288); the 8-bit frame is
    dark and grey, whatever the tiny input's colour."""
    m = _eo_model()
    n_e = 50.0
    per_unit = (
        math.pi
        / (4 * 2.8**2)
        * 106.856895
        * (3.45e-6) ** 2
        * chain.EO_MAX_EXPOSURE_S
        * chain.QUANTUM_EFFICIENCY
        * 0.555e-6
        / (6.62607015e-34 * 299792458.0)
    )
    assert chain.photoelectrons_per_input(m, chain.EO_MAX_EXPOSURE_S) == pytest.approx(per_unit, rel=1e-9)
    x = np.full((48, 64, 3), n_e / per_unit)
    out = chain.apply_chain(x, m, np.random.default_rng(1), psf=False, eo_space="srgb")
    k = m.max_count / m.full_well_e  # counts per electron
    assert "exposure capped" in out.settings["gain_source"]
    assert out.counts.mean() == pytest.approx(n_e * k, rel=0.02)
    assert out.counts.std() == pytest.approx(math.sqrt(n_e + m.read_noise_e**2) * k, rel=0.1)
    # a red-only scene far below the noise floor (the thermal sky's 1e-24): dark, no colour
    red = np.zeros((48, 64, 3))
    red[..., 0] = 1e-20
    img = chain.apply_chain(red, m, np.random.default_rng(2), psf=False, eo_space="srgb").image8
    means = img.reshape(-1, 3).mean(axis=0)
    assert means.max() < 20.0 and means.max() - means.min() < 2.0
    # daylight is exposed as before: 99.5th percentile at 80 % of the full well
    day = chain.apply_chain(
        np.full((48, 64, 3), 0.05), m, np.random.default_rng(3), psf=False, eo_space="srgb"
    )
    assert day.settings["noise"]["saturation_input"] == pytest.approx(0.05 / 0.8)


def _night_stage(tmp_path, toward_sun, start=None):
    stage = new_stage(tmp_path / "s.usda")
    white = reflective(stage, "white", [0.3, 3.0], [1.0, 1.0])
    plate(stage, "/World/p", 1e4, 0.0, white, 280.0)
    eo_camera(stage, "eo", (0, 0, 10), (0, 0, 0), fov_x_deg=10.0)
    wl = [0.3, 0.9, 4.0]
    atmosphere_tables(stage, wl, sky=np.zeros((2, 3)), zenith=np.array([0.0, 90.0]), solar=[0.0, 0.0, 0.0])
    sun(stage, toward_sun)
    if start is not None:
        world = stage.GetPrimAtPath("/World")
        for name, kind, value in (
            ("humv:scenario:startTime", Sdf.ValueTypeNames.String, start),
            ("humv:scenario:latitude", Sdf.ValueTypeNames.Double, 52.37),
            ("humv:scenario:longitude", Sdf.ValueTypeNames.Double, 4.90),
            ("humv:scenario:elevation", Sdf.ValueTypeNames.Double, 0.0),
        ):
            world.CreateAttribute(name, kind).Set(value)
    stage.Save()
    return stage


def test_dusk_frame_is_the_twilight_sky_on_a_white_plate(tmp_path):
    """Sun 6 deg below the horizon, no site (no moon): a white Lambertian plane under a uniform
    sky has the sky's radiance, whose luminance is E_twilight / pi (+ the natural night sky,
    2e-4 cd m-2); the twilight sky is blue (Rayleigh), never the thermal sky's red."""
    h = math.radians(-6.0)
    _night_stage(tmp_path, (math.cos(h), 0.0, math.sin(h)))
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    expected = float(nightsky.twilight_illuminance_lux(-6.0)) / math.pi
    assert ch["Y"].mean() * Y_TO_CD == pytest.approx(expected, rel=0.01)
    assert ch["B"].mean() > ch["G"].mean() > ch["R"].mean() > 0
    frame = manifest["eo_sensors"][0]["frames"][0]
    assert "twilight" in frame["illumination"]["night"]
    assert frame["illumination"]["night"]["moon"].startswith("skipped")


def test_moonlit_night_is_the_moon_on_a_white_plate(tmp_path):
    """Full moon high over Amsterdam (2026-11-24 23:00 CET, altitude 57 deg): a white plate's
    luminance is E_moon cos(z) (1 + moonlit-sky fraction) / pi plus the night sky; the sensor
    chain's frame is dark and noisy (fewer electrons than the well holds)."""
    _night_stage(tmp_path, (0.0, 0.3, -0.95), start="2026-11-24T23:00:00+01:00")
    manifest = render_stage(tmp_path / "s.usda", tmp_path / "out", spp=4)
    frame = manifest["eo_sensors"][0]["frames"][0]
    assert frame["illumination"]["night"]["moon"].startswith("directional")
    m = moon_at(52.37, 4.90, 0.0, [dt.datetime(2026, 11, 24, 22, 0)])
    e = float(nightsky.moon_illuminance_lux(m.elevation_deg[0], m.phase_angle_deg[0], m.distance_km[0]))
    e_h = e * math.sin(math.radians(m.elevation_deg[0]))
    expected = e_h * (1 + nightsky.MOONLIT_SKY_FRACTION) / math.pi
    ch = read_exr(tmp_path / "out" / "eo" / "0000.exr")
    assert 0.05 < expected < 0.1  # white paper under a full moon (~0.25 lx): ~0.08 cd m-2
    assert ch["Y"].mean() * Y_TO_CD == pytest.approx(expected, rel=0.02)
    assert "exposure capped" in frame["sensor_chain"]["settings"]["gain_source"]


def test_clouds_dim_the_night_and_hide_the_moon(tmp_path):
    """Kasten & Czeplak (1980) as for the sun: overcast (N = 1) leaves 1 - 0.75 = 25 % of each
    source's global light, all of it diffuse (no moon beam); N = 0 is the clear sky."""
    from humv_usd.render.nightlight import night_light

    stage = _night_stage(tmp_path, (0.0, 0.3, -0.95), start="2026-11-24T23:00:00+01:00")
    down = np.array([0.0, 0.3, -0.95]) / np.linalg.norm([0.0, 0.3, -0.95])
    wl = np.linspace(0.38, 0.78, 81)
    clear = night_light(stage, 0.0, down, wl, cloud_cover=0.0)
    overcast = night_light(stage, 0.0, down, wl, cloud_cover=1.0)
    assert clear.moon_direction is not None and overcast.moon_direction is None
    e_h = luminance(wl, clear.moon_irradiance) * clear.moon_direction[2]
    clear_global = math.pi * luminance(wl, clear.sky) + e_h
    assert math.pi * luminance(wl, overcast.sky) == pytest.approx(0.25 * clear_global, rel=0.01)
    assert night_light(stage, 0.0, down, wl).ran["clouds"].startswith("clear")  # no weather on the stage


def test_amsterdam_dusk_scenario_is_not_red(tmp_path):
    """The reported case end to end: an EO camera at Amsterdam on 2026-11-10 at 17:30 CET (sun
    -5.6 deg, clear) wrote a saturated pure-red frame (mean RGB 250, 0, 0: the thermal sky's
    1e-24 red tail under an unbounded auto exposure). Now the twilight sky lights the scene:
    the camera's frame is dim (far from saturated), bluish like the twilight sky, and says so."""
    from PIL import Image

    from humv_usd.pipeline.compose import compose
    from humv_usd.scenario import validate

    raw = {
        "general": {
            "name": "dusk",
            "start": dt.datetime(2026, 11, 10, 17, 30),
            "utc_offset_h": 1.0,
            "latitude_deg": 52.37,
            "longitude_deg": 4.90,
            "fps": 1.0,
        },
        "scene": {
            "ground": {"material": "concrete", "size_m": [40.0, 40.0]},
            "object": [
                {
                    "id": "wall",
                    "material": "painted_metal",
                    "center_m": [0.0, 6.0, 0.0],
                    "size_m": [8.0, 0.5, 4.0],
                }
            ],
        },
        "sensor": [
            {
                "id": "eo",
                "preset": "rgb_imx273",
                "position_m": [0.0, -8.0, 1.6],
                "look_at_m": [0.0, 6.0, 1.0],
                "resolution": [32, 24],
                "focal_length_mm": 0.5,
            }
        ],
    }
    compose(validate(raw), tmp_path / "c")
    manifest = render_stage(tmp_path / "c" / "stage.usda", tmp_path / "r", spp=2)
    frame = manifest["eo_sensors"][0]["frames"][0]
    assert "sun at -5.6" in frame["illumination"]["night"]["twilight"]
    img = np.asarray(Image.open(tmp_path / "r" / "eo" / "0000_image8.png"), float).reshape(-1, 3).mean(axis=0)
    assert img.max() < 250 and img[2] > img[0] and img[1] > 0.5 * img[0]  # not red: the twilight sky's blue
    assert frame["sensor_chain"]["settings"]["saturated_fraction"] == 0.0
