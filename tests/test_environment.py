"""Sun and weather at the frame times (humv_usd.environment) and the environment layer."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pandas as pd
import pvlib
import pytest

from humv_usd.environment.sun import Site, cloud_reduction, scenario_sun, sun_at, sun_direction
from humv_usd.environment.weather import scenario_weather, weather_at
from humv_usd.errors import InputError
from humv_usd.scenario import validate


def _scenario(raw, **general):
    raw["general"].update(general)
    return validate(raw)


def test_sun_matches_spa_reference_case(raw):
    """Reda & Andreas (2004) Table A5.1: 2003-10-17 12:30:30 MST, Golden CO -> topocentric
    zenith 50.11162 deg, azimuth 194.34024 deg (820 mbar, 11 degC)."""
    raw["atmosphere"].update(pressure_pa=82000.0, air_temperature_k=284.15)
    sc = _scenario(
        raw,
        start=dt.datetime(2003, 10, 17, 12, 30, 30),
        utc_offset_h=-7.0,
        latitude_deg=39.742476,
        longitude_deg=-105.1786,
        elevation_m=1830.14,
    )
    s = scenario_sun(sc, [0.0])
    assert abs(s.zenith_deg[0] - 50.11162) < 0.01
    assert abs(s.azimuth_deg[0] - 194.34024) < 0.01


def test_sun_matches_pvlib_spa_over_a_day(raw):
    sc = validate(raw)  # humvvex: Fairborn OH, 2018-10-24 14:05 EDT
    t = np.arange(0.0, 86400.0, 3 * 3600.0)
    s = scenario_sun(sc, t)
    g, a = sc["general"], sc["atmosphere"]
    idx = pd.Timestamp("2018-10-24T18:05:00Z") + pd.to_timedelta(t, unit="s")
    ref = pvlib.solarposition.get_solarposition(
        idx,
        g["latitude_deg"],
        g["longitude_deg"],
        altitude=g["elevation_m"],
        pressure=a["pressure_pa"],
        temperature=a["air_temperature_k"] - 273.15,
        method="nrel_numpy",
    )
    assert np.max(np.abs(s.zenith_deg - ref["apparent_zenith"].to_numpy())) < 0.01
    daz = (s.azimuth_deg - ref["azimuth"].to_numpy() + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(daz)) < 0.01
    # direction: unit, z = cos(zenith), east/north from the compass azimuth
    np.testing.assert_allclose(np.linalg.norm(s.direction, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(s.direction[:, 2], np.cos(np.radians(s.zenith_deg)), atol=1e-12)
    np.testing.assert_allclose(sun_direction(90.0, 90.0)[0], [1.0, 0.0, 0.0], atol=1e-12)
    # 14:05 EDT in October: sun in the south-south-west, about 37 deg up
    assert s.up[0] and 185.0 < s.azimuth_deg[0] < 200.0 and 50.0 < s.zenith_deg[0] < 55.0
    assert s.direction[0, 1] < 0 < s.direction[0, 2]


def test_night_has_no_sun(raw):
    sc = validate(raw)
    night = 9 * 3600.0  # 23:05 EDT
    s = scenario_sun(sc, [0.0, night])
    assert s.up.tolist() == [True, False]
    assert s.dni_w_m2[1] == s.dhi_w_m2[1] == s.ghi_w_m2[1] == 0.0
    assert s.zenith_deg[1] > 90.0


def test_clear_sky_irradiance_matches_pvlib_ineichen(raw):
    sc = validate(raw)
    s = scenario_sun(sc, [0.0])
    g = sc["general"]
    loc = pvlib.location.Location(g["latitude_deg"], g["longitude_deg"], altitude=g["elevation_m"])
    ref = loc.get_clearsky(pd.DatetimeIndex([pd.Timestamp("2018-10-24T18:05:00Z")]), model="ineichen")
    # same model; pvlib's Location uses the standard-pressure air mass at the altitude
    assert s.ghi_w_m2[0] == pytest.approx(ref["ghi"].iloc[0], rel=0.02)
    assert s.dni_w_m2[0] == pytest.approx(ref["dni"].iloc[0], rel=0.02)
    cosz = np.cos(np.radians(s.zenith_deg[0]))
    assert s.ghi_w_m2[0] == pytest.approx(s.dni_w_m2[0] * cosz + s.dhi_w_m2[0], rel=1e-9)


def test_cloud_reduction_kasten_czeplak():
    ghi, dhi, dni = cloud_reduction(800.0, 100.0, 30.0, [0.0, 0.5, 1.0])
    assert ghi[0] == 800.0 and dhi[0] == 100.0
    assert ghi[1] == pytest.approx(800.0 * (1 - 0.75 * 0.5**3.4))
    assert ghi[2] == pytest.approx(200.0) and dhi[2] == pytest.approx(200.0)
    assert dni[2] == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.diff(dni) < 0)
    assert dni[0] == pytest.approx(700.0 / np.cos(np.radians(30.0)))


def test_cloud_cover_reduces_scenario_sun(raw):
    raw["atmosphere"]["cloud_cover"] = 1.0
    s = scenario_sun(validate(raw), [0.0])
    assert s.dni_w_m2[0] == pytest.approx(0.0, abs=1e-6) and s.ghi_w_m2[0] > 0


def test_weather_constant(raw):
    w = scenario_weather(validate(raw), [0.0, 10.0])
    assert w.air_temperature_k.tolist() == [289.0, 289.0]
    assert w.wind_direction_deg.tolist() == [225.0, 225.0] and not w.varies


def test_weather_csv_interpolates(raw, tmp_path):
    csv = tmp_path / "w.csv"
    csv.write_text(
        "time,air_temperature_k,wind_direction_deg\n"
        "2018-10-24T14:00:00,288.0,350.0\n"
        "2018-10-24T15:00:00,290.0,10.0\n"
        "2018-10-24T20:00:00+00:00,292.0,10.0\n"
    )  # 16:00 EDT
    raw["atmosphere"]["weather_csv"] = str(csv)
    sc = validate(raw)
    w = scenario_weather(sc, [0.0, 1500.0, 3300.0 + 1800.0])  # 14:05, 14:30, 15:30
    np.testing.assert_allclose(w.air_temperature_k, [288.0 + 2 * 5 / 60, 289.0, 291.0])
    dwind = (w.wind_direction_deg[1] + 180.0) % 360.0 - 180.0
    assert abs(dwind) < 1e-9  # 350 and 10 meet at north, not south
    assert w.relative_humidity.tolist() == [0.45] * 3  # column absent: [atmosphere] value
    assert w.varies
    with pytest.raises(InputError, match="atmosphere.weather_csv"):
        scenario_weather(sc, [3 * 3600.0])  # 17:05, past the series


@pytest.mark.parametrize(
    "text, msg",
    [
        ("time,air_temp\n2018-10-24T14:00:00,1\n", "allowed columns"),
        ("time,relative_humidity\n2018-10-24T14:00:00,1.5\n", "line 2 relative_humidity"),
        ("time,cloud_cover\n2018-10-24T15:00:00,0\n2018-10-24T14:00:00,0\n", "strictly increase"),
        ("time,cloud_cover\nyesterday,0\n", "ISO date-time"),
    ],
)
def test_weather_csv_bad_input(raw, tmp_path, text, msg):
    csv = tmp_path / "w.csv"
    csv.write_text(text)
    raw["atmosphere"]["weather_csv"] = str(csv)
    with pytest.raises(InputError, match=msg):
        scenario_weather(validate(raw), [0.0])


def test_cloud_dni_factor_is_the_ratio_of_cloud_reduction():
    """The atmosphere's DNI / clear DNI (physics.sun.cloud_dni_factor) equals Kasten & Czeplak's
    cloudy over clear DNI for any clear-sky diffuse fraction."""
    from humv_usd.physics.sun import cloud_dni_factor

    n = np.array([0.0, 0.2, 0.5, 0.8, 1.0])
    for kd in (0.1, 0.3, 0.6):
        ghi_c, zen = 700.0, 40.0
        _, _, clear = cloud_reduction(ghi_c, kd * ghi_c, zen, 0.0)
        _, _, cloudy = cloud_reduction(ghi_c, kd * ghi_c, zen, n)
        np.testing.assert_allclose(cloud_dni_factor(n), cloudy / clear, rtol=1e-12, atol=1e-15)
    assert cloud_dni_factor(1.0) == 0.0 and cloud_dni_factor(0.0) == 1.0


def test_weather_at_takes_times_and_a_series_not_the_scenario():
    """weather_at(epoch, times, constants, series): constants where the series has no column,
    linear in time, wind direction through its components (350 and 10 deg average to 0)."""
    from humv_usd.physics.weather import COLUMNS

    const = {k: 1.0 for k in COLUMNS}
    series = (
        np.array([1000.0, 2000.0]),
        {"air_temperature_k": np.array([280.0, 290.0]), "wind_direction_deg": np.array([350.0, 10.0])},
    )
    w = weather_at(1000.0, [0.0, 500.0, 1000.0], const, series)
    np.testing.assert_allclose(w.air_temperature_k, [280.0, 285.0, 290.0])
    assert abs((w.wind_direction_deg[1] + 180.0) % 360.0 - 180.0) < 1e-9
    np.testing.assert_allclose(w.relative_humidity, 1.0)
    with pytest.raises(InputError, match="atmosphere.weather_csv"):
        weather_at(1000.0, [1500.0], const, series, source="w.csv")


def test_sun_at_takes_a_site_and_times():
    """sun_at(site, epoch, times, weather) against pvlib's SPA at the same site and instant."""
    import pandas as pd
    import pvlib

    from humv_usd.physics.weather import COLUMNS

    site = Site(39.80, -84.03, 250.0)
    epoch = pd.Timestamp("2018-10-24T18:05:00Z").timestamp()
    const = {k: 1.0 for k in COLUMNS} | {
        "pressure_pa": 98500.0,
        "air_temperature_k": 289.0,
        "cloud_cover": 0.0,
    }
    w = weather_at(epoch, [0.0, 3600.0], const)
    s = sun_at(site, epoch, [0.0, 3600.0], w)
    ref = pvlib.solarposition.spa_python(
        pd.to_datetime([epoch, epoch + 3600.0], unit="s", utc=True),
        39.80,
        -84.03,
        altitude=250.0,
        pressure=98500.0,
        temperature=289.0 - 273.15,
    )
    np.testing.assert_allclose(s.zenith_deg, ref["apparent_zenith"].to_numpy(), atol=1e-9)
