"""Scene surfaces with water (issue 30.2/30.4): a lawn against asphalt at a Bavarian summer
noon, a dry lawn, and paving wet by rain near the wet-bulb temperature, through the thermal
tool's surface solve (:func:`humv_usd.thermal.surfaces.surface_temperatures`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pxr import Usd
from scipy.optimize import brentq

from humv_usd.constants import STEFAN_BOLTZMANN as SIGMA
from humv_usd.materials.layer import LIBRARY_FILE
from humv_usd.physics import evaporation as ev
from humv_usd.thermal import surfaces as SF
from humv_usd.usd.materials import read_material
from humv_usd.usd.paths import material_path

_LIBRARY = Usd.Stage.Open(str(LIBRARY_FILE))
GROUND = "/World/Scene/Ground"


def _ground(material):
    m = read_material(_LIBRARY.GetPrimAtPath(material_path(material)))
    soil = read_material(_LIBRARY.GetPrimAtPath(material_path("soil")))
    pts = np.array([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], dtype=float)
    return SF.SceneMesh(
        GROUND, pts, np.array([[0, 1, 2], [0, 2, 3]]), np.array([0, 0]), 1, m, None, True, soil
    )


def _summer_day(days=2):
    """Clear 21 June at 48 N (Bavaria): solar noon elevation 65.5 deg, GHI about 880 W m-2;
    air 17-27 degC peaking at 15:00, RH 0.45 at the peak (dew point held), wind 2 m/s."""
    t = np.arange(-days * 86400.0, 1.0, 600.0) + 12.5 * 3600.0  # ends at 12:30 local solar time
    hour = (t / 3600.0) % 24.0
    lat, dec = np.radians(48.0), np.radians(23.44)
    ha = np.radians(15.0 * (hour - 12.0))
    sin_el = np.sin(lat) * np.sin(dec) + np.cos(lat) * np.cos(dec) * np.cos(ha)
    el = np.arcsin(np.clip(sin_el, -1, 1))
    up = sin_el > 0.02
    az = np.arctan2(np.sin(ha), np.cos(ha) * np.sin(lat) - np.tan(dec) * np.cos(lat))  # from south
    s = np.stack([-np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)], axis=1)
    dni = np.where(up, 1000.0 * np.exp(-0.14 / np.maximum(sin_el, 0.05)), 0.0)
    dhi = np.where(up, 100.0 * np.sqrt(np.maximum(sin_el, 0.0)), 0.0)
    ghi = dni * np.maximum(sin_el, 0.0) + dhi
    air = 295.15 + 5.0 * np.cos(2 * np.pi * (hour - 15.0) / 24.0)
    e_a = 0.45 * ev.saturation_vapour_pressure(300.15)
    rh = e_a / ev.saturation_vapour_pressure(air)
    one = np.ones_like(t)
    f = SF.SurfaceForcing(t - t[-1], air, rh, 2.0 * one, s, up, dni, dhi, ghi)
    return f, float(ghi[-1]), float(air[-1])


def _noon(material, **water):
    f, ghi, air = _summer_day()
    f = dataclasses.replace(f, **water)
    out, diag = SF.surface_temperatures(None, [_ground(material)], f.times_s, 0.0, forcing=f, exchange=False)
    assert diag["slabMaxResidual_W_m2"] < 1e-5
    return float(out[GROUND][-1, 0]), ghi, air


def test_lawn_near_air_asphalt_hot_dry_lawn_hot():
    lawn, ghi, air = _noon("grass", soil_moisture=1.0)
    assert 820.0 < ghi < 950.0 and abs(air - 299.6) < 0.5  # the day we meant
    asphalt, _, _ = _noon("asphalt")
    dry_lawn, _, _ = _noon("grass", soil_moisture=0.0)
    # a watered lawn: the field reference, 30-35 degC under 27 degC air at a Bavarian
    # noon (radiometric turf temperatures some 3-9 K above the air in full sun; a transpiring
    # crop canopy sits closer, -2..+4 K: Idso 1982, Agric. Meteorol. 27:59)
    assert 303.15 - 1.0 < lawn < 308.15 + 1.0 and lawn - air < 9.0, lawn - 273.15
    # the same sod without water heats like a dry slab (the 49.5 degC of before issue 30)
    assert dry_lawn > lawn + 8.0
    # dark asphalt is far hotter at noon (field contrasts of 15-25 K between turf and asphalt)
    assert asphalt > lawn + 12.0


def test_paving_wet_by_rain_sits_near_the_wet_bulb():
    # an overcast rainy afternoon: no sun, a sky at the air temperature (eps_sky = 1), rain on
    n = 300
    t = np.arange(n) * 600.0 - (n - 1) * 600.0
    one = np.ones(n)
    air, rh = 288.15, 0.7
    f = SF.SurfaceForcing(
        t,
        air * one,
        rh * one,
        3.0 * one,
        np.tile([0.0, 0.0, 1.0], (n, 1)),
        np.zeros(n, bool),
        0 * one,
        0 * one,
        0 * one,
    )
    eps_sky = SF.SurfaceForcing.sky_longwave.fget(f) / (SIGMA * air**4)
    f = dataclasses.replace(f, sky_longwave_factor=1.0 / eps_sky, rain_kg_m2_s=np.full(n, 2.0 / 3600.0))
    out, _ = SF.surface_temperatures(None, [_ground("concrete")], t, 0.0, forcing=f, exchange=False)
    wet = float(out[GROUND][-1, 0])
    tw = float(ev.wet_bulb_temperature(air, rh))
    assert air - tw > 2.5  # the reference is well below the air
    # closed form: the psychrometer with the long-wave exchange with a sky at the air
    # temperature in parallel with convection, e_s(T) - e_a = gamma (1 + h_r / h)(T_a - T),
    # h_r = 4 eps sigma T_a^3 (Monteith & Unsworth 2013, section 13.1); the soil below (held
    # at the mean air temperature) adds a little more
    eps = SF.longwave_emissivity(_ground("concrete").material)
    h = 2.8 + 3.0 * 3.0
    gamma_star = ev.psychrometric_constant(101325.0, air) * (1.0 + 4 * eps * SIGMA * air**3 / h)
    e_a = rh * ev.saturation_vapour_pressure(air)
    tw_rad = brentq(lambda x: ev.saturation_vapour_pressure(x) - e_a - gamma_star * (air - x), 250.0, air)
    assert tw < tw_rad < wet < tw_rad + 0.25, (wet - 273.15, tw_rad - 273.15, tw - 273.15)
    dry, _ = SF.surface_temperatures(
        None, [_ground("concrete")], t, 0.0, forcing=dataclasses.replace(f, rain_kg_m2_s=None), exchange=False
    )
    assert abs(float(dry[GROUND][-1, 0]) - air) < 0.5  # dry under an air-temperature sky: the air


def test_snow_melts_at_zero_under_the_sun_and_cools_below_it_at_night():
    f, _, _ = _summer_day()
    t_noon, _, _ = _noon("snow")
    assert t_noon == pytest.approx(273.15, abs=1e-9)  # the surplus melts it: held at 0 degC
    # a clear winter night at -5 degC air: radiative cooling below the air, not held
    n = 144
    t = np.arange(n) * 600.0 - (n - 1) * 600.0
    one = np.ones(n)
    night = SF.SurfaceForcing(
        t,
        268.15 * one,
        0.7 * one,
        1.0 * one,
        np.tile([0.0, 0.0, -1.0], (n, 1)),
        np.zeros(n, bool),
        0 * one,
        0 * one,
        0 * one,
    )
    out, diag = SF.surface_temperatures(None, [_ground("snow")], t, 0.0, forcing=night, exchange=False)
    cold = float(out[GROUND][-1, 0])
    assert cold < 268.15 - 2.0  # snow under a clear sky: several K below the air
    assert diag["slabMaxResidual_W_m2"] < 1e-5
