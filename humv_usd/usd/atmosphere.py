"""Typed readers and writers of the atmosphere layers (/World/Atmosphere: HumvAtmosphereAPI; its
Paths: HumvAtmospherePathAPI): the only code that knows these attribute names. Every reader and
every writer of a time-varying value takes a time code: the layers time-sample the sky and the
paths when the weather varies (hourly ``weather_csv``), and the thermal tool and the render read
the same sample at the same frame. Without a time code a writer authors the default value (what
readers without a time get).

Writers (the atmosphere tool, :mod:`humv_usd.atmosphere.layer`):

* :func:`define_atmosphere`: the scope with HumvAtmosphereAPI, the model, profile and visibility;
* :func:`write_broadband_sky`: emissivity, temperature and long-wave radiance against zenith;
* :func:`write_spectral_grid`, :func:`write_spectral_sky`, :func:`write_solar_spectrum`: the
  wavelength grid, the sky spectral radiance against zenith, the direct solar spectrum.

Writers (the atmosphere paths tool, :mod:`humv_usd.atmosphere.paths`): :func:`define_paths`,
:func:`define_path_table` (HumvAtmospherePathAPI: sensor, ranges) and :func:`write_path_spectra`
(transmittance, path radiance).

Readers:

* :func:`longwave_sky`: broadband long-wave sky radiance against zenith (the thermal tool's sky);
* :func:`sky_temperature`: effective broadband sky brightness temperature (the render's IR sky);
* :func:`atmosphere_spectra`: sky spectral radiance against zenith, direct solar spectrum;
* :func:`wavelengths`: the wavelength grid of the spectral tables and the path tables
  (:func:`require_wavelengths`: InputError unless it is a given grid);
* :func:`path_table`: one sensor's slant-path transmittance and radiance against range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom, Vt

from humv_usd.constants import TEMPERATURE_RANGE_K
from humv_usd.errors import InputError, bad_value, summary
from humv_usd.physics.sky import extended_sky_table
from humv_usd.usd import schemas as S
from humv_usd.usd.layers import SCOPES, attribute_value
from humv_usd.usd.thermal import check_temperatures

ATMOSPHERE_PATH = SCOPES["atmosphere"]
PATHS = ATMOSPHERE_PATH.AppendChild("Paths")

DEFAULT = Usd.TimeCode.Default()


@dataclass
class AtmosphereSpectra:
    """What ``/World/Atmosphere`` says spectrally at one frame (None when not authored)."""

    model: str | None = None
    wavelengths_um: np.ndarray | None = None  # (W,)
    sky_zenith_deg: np.ndarray | None = None  # (Z,)
    sky_radiance: np.ndarray | None = None  # (Z, W) [W m-2 sr-1 um-1]
    solar_irradiance: np.ndarray | None = None  # (W,) [W m-2 um-1], direct beam, normal incidence


@dataclass
class PathArrays:
    """One sensor's path table as authored: ranges (R,) [m], wavelengths (W,) [um],
    transmittance and path radiance (R, W) [-, W m-2 sr-1 um-1]; ``prim`` where it was found."""

    prim: str
    ranges_m: np.ndarray
    wavelengths_um: np.ndarray
    transmittance: np.ndarray
    radiance: np.ndarray


def _atmosphere(stage) -> Usd.Prim | None:
    if stage is None:
        return None
    prim = stage.GetPrimAtPath(ATMOSPHERE_PATH)
    return prim if prim and prim.IsValid() else None


def float_array(prim, name, time, where_expected, positive=False, ascending=False) -> np.ndarray | None:
    """A float array attribute at ``time`` (None when unauthored or empty); InputError naming
    the attribute when it is not finite, negative (``positive``) or not ascending >= 0."""
    value = attribute_value(prim.GetAttribute(name), time)
    if value is None or len(value) == 0:
        return None
    a = np.asarray(value, dtype=float).ravel()
    where = f"{prim.GetPath()}.{name}"
    if not np.all(np.isfinite(a)) or (positive and np.any(a < 0)):
        raise InputError(bad_value(where, summary(a), where_expected))
    if ascending and (np.any(a < 0) or np.any(np.diff(a) <= 0)):
        raise InputError(bad_value(where, summary(a), where_expected))
    return a


def longwave_sky(stage, time=DEFAULT) -> tuple[np.ndarray, np.ndarray] | None:
    """(zenith angles [deg], broadband long-wave sky radiance [W m^-2 sr^-1]) of
    /World/Atmosphere (``skyZenithAngles``, ``skyLongwaveRadiance``) at time code ``time``
    (default: the layer's default value, frame 0), or None when the stage has no atmosphere
    layer or the layer has no such table.

    Raises :class:`humv_usd.errors.InputError` for a malformed table (lengths differ, angles
    not ascending within 0-90 deg, negative or non-finite radiances).
    """
    prim = _atmosphere(stage)
    if prim is None:
        return None
    z = attribute_value(prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES), time)
    lw = attribute_value(prim.GetAttribute(S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE), time)
    if z is None or lw is None:
        return None
    z, lw = np.asarray(z, dtype=float), np.asarray(lw, dtype=float)
    where = f"{prim.GetPath()}.{S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE}"
    if lw.size != z.size or not np.all(np.isfinite(lw)) or np.any(lw < 0):
        raise InputError(
            bad_value(
                where, f"<{lw.size} values>", f"{z.size} finite radiances >= 0, one per skyZenithAngles"
            )
        )
    try:
        extended_sky_table(z, lw)
    except ValueError:
        raise InputError(
            bad_value(
                f"{prim.GetPath()}.{S.ATMOSPHERE_SKY_ZENITH_ANGLES}",
                str(np.round(z, 3).tolist()),
                "ascending zenith angles within 0-90 deg",
            )
        ) from None
    return z, lw


def sky_temperature(stage, time) -> float:
    """Effective broadband sky brightness temperature ``skyTemperature`` [K] at ``time``;
    InputError when it is missing or outside :data:`TEMPERATURE_RANGE_K`."""
    prim = _atmosphere(stage)
    where = f"{ATMOSPHERE_PATH}.{S.ATMOSPHERE_SKY_TEMPERATURE}"
    value = (
        attribute_value(prim.GetAttribute(S.ATMOSPHERE_SKY_TEMPERATURE), time) if prim is not None else None
    )
    lo, hi = TEMPERATURE_RANGE_K
    if value is None:
        what = "" if prim is not None else f" (no prim at {ATMOSPHERE_PATH})"
        raise InputError(
            bad_value(
                where,
                None,
                f"expected the effective sky brightness temperature in {lo:g}-{hi:g} K (HumvAtmosphereAPI){what}",
            )
        )
    return float(check_temperatures([value], where)[0])


def model_name(stage, time=DEFAULT) -> str | None:
    """The ``humv:atmosphere:model`` token (what computed the layer), or None."""
    prim = _atmosphere(stage)
    value = attribute_value(prim.GetAttribute(S.ATMOSPHERE_MODEL), time) if prim is not None else None
    return str(value) if value else None


def _wavelengths(prim, time):
    return float_array(
        prim,
        S.ATMOSPHERE_WAVELENGTHS,
        time,
        "expected positive, strictly ascending wavelengths [um]",
        ascending=True,
    )


def wavelengths(stage, time=DEFAULT) -> np.ndarray | None:
    """The wavelength grid ``humv:atmosphere:wavelengths`` [um] of /World/Atmosphere at
    ``time`` (None when the stage has no atmosphere layer or no grid); InputError when it is
    not positive and strictly ascending."""
    prim = _atmosphere(stage)
    return None if prim is None else _wavelengths(prim, time)


def atmosphere_spectra(stage, time) -> AtmosphereSpectra:
    """Sky spectral radiance against zenith, solar spectral irradiance and the model token
    of ``/World/Atmosphere`` at ``time`` (None for what is not authored)."""
    out = AtmosphereSpectra()
    prim = _atmosphere(stage)
    if prim is None:
        return out
    out.model = model_name(stage, time)
    wl = _wavelengths(prim, time)
    if wl is None:
        return out
    out.wavelengths_um = wl
    zen = float_array(
        prim,
        S.ATMOSPHERE_SKY_ZENITH_ANGLES,
        time,
        "expected ascending zenith angles in 0-90 deg",
        ascending=True,
    )
    sky = float_array(
        prim,
        S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE,
        time,
        "expected finite spectral radiances >= 0 [W m-2 sr-1 um-1]",
        positive=True,
    )
    if zen is not None and sky is not None:
        if zen[-1] > 90.0 + 1e-6:
            raise InputError(
                bad_value(
                    f"{ATMOSPHERE_PATH}.{S.ATMOSPHERE_SKY_ZENITH_ANGLES}",
                    summary(zen),
                    "expected ascending zenith angles in 0-90 deg",
                )
            )
        if sky.size != zen.size * wl.size:
            raise InputError(
                bad_value(
                    f"{ATMOSPHERE_PATH}.{S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE}",
                    f"<{sky.size} values>",
                    f"expected {zen.size} zenith angles x {wl.size} wavelengths = "
                    f"{zen.size * wl.size} values (row-major)",
                )
            )
        out.sky_zenith_deg, out.sky_radiance = zen, sky.reshape(zen.size, wl.size)
    solar = float_array(
        prim,
        S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE,
        time,
        "expected finite spectral irradiances >= 0 [W m-2 um-1]",
        positive=True,
    )
    if solar is not None:
        if solar.size != wl.size:
            raise InputError(
                bad_value(
                    f"{ATMOSPHERE_PATH}.{S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE}",
                    f"<{solar.size} values>",
                    f"expected {wl.size} values (one per wavelength)",
                )
            )
        out.solar_irradiance = solar
    return out


def require_wavelengths(stage, grid) -> None:
    """InputError unless the stage's wavelength grid is ``grid`` [um] (rtol 1e-6): the path
    tables are authored on the atmosphere layer's wavelengths, and the render reads them together."""
    on_stage = wavelengths(stage)
    if on_stage is None or on_stage.size != grid.size or not np.allclose(on_stage, grid, rtol=1e-6):
        raise InputError(
            bad_value(
                f"{ATMOSPHERE_PATH}.{S.ATMOSPHERE_WAVELENGTHS}",
                None if on_stage is None else summary(on_stage),
                f"expected the grid of the sensors' bands the path tables are computed on, {summary(grid)} "
                "(rebuild the atmosphere layer, or edit it in a user layer without changing its wavelengths)",
            )
        )


def _path_prim(stage, sensor_path: str, sensor_name: str):
    scope = stage.GetPrimAtPath(PATHS)
    if not (scope and scope.IsValid()):
        return None
    for child in scope.GetChildren():
        target = attribute_value(child.GetAttribute(S.ATMOSPHERE_PATH_SENSOR), DEFAULT)
        if target and str(target) == sensor_path:
            return child
    child = scope.GetChild(sensor_name)
    return child if child and child.IsValid() else None


def path_table(stage, sensor_path: str, sensor_name: str, time) -> PathArrays | None:
    """The slant-path table of the sensor at ``sensor_path`` at ``time``, or None.

    Found under ``/World/Atmosphere/Paths`` by ``humv:atmospherePath:sensor`` == the sensor
    prim path, else by the child named like the sensor; it needs ``humv:atmosphere:wavelengths``.
    """
    chosen = _path_prim(stage, sensor_path, sensor_name)
    if chosen is None:
        return None
    wl = _wavelengths(stage.GetPrimAtPath(ATMOSPHERE_PATH), time)
    where = str(chosen.GetPath())
    if wl is None:
        raise InputError(
            bad_value(
                f"{ATMOSPHERE_PATH}.{S.ATMOSPHERE_WAVELENGTHS}",
                None,
                f"expected the wavelength grid [um] of the path table {where}",
            )
        )
    ranges = float_array(
        chosen, S.ATMOSPHERE_PATH_RANGES, time, "expected ascending ranges >= 0 [m]", ascending=True
    )
    tau = float_array(
        chosen, S.ATMOSPHERE_PATH_TRANSMITTANCE, time, "expected transmittances in 0-1", positive=True
    )
    rad = float_array(
        chosen,
        S.ATMOSPHERE_PATH_RADIANCE,
        time,
        "expected finite path radiances >= 0 [W m-2 sr-1 um-1]",
        positive=True,
    )
    named = (
        (S.ATMOSPHERE_PATH_RANGES, ranges),
        (S.ATMOSPHERE_PATH_TRANSMITTANCE, tau),
        (S.ATMOSPHERE_PATH_RADIANCE, rad),
    )
    missing = [n for n, v in named if v is None]
    if missing:
        raise InputError(
            bad_value(f"{where}.{missing[0]}", None, "expected ranges, transmittance and radiance tables")
        )
    for name, a in named[1:]:
        if a.size != ranges.size * wl.size:
            raise InputError(
                bad_value(
                    f"{where}.{name}",
                    f"<{a.size} values>",
                    f"expected {ranges.size} ranges x {wl.size} wavelengths = "
                    f"{ranges.size * wl.size} values (row-major)",
                )
            )
    if np.any(tau > 1.0 + 1e-6):
        raise InputError(
            bad_value(
                f"{where}.{S.ATMOSPHERE_PATH_TRANSMITTANCE}", summary(tau), "expected transmittances in 0-1"
            )
        )
    return PathArrays(
        where,
        ranges,
        wl,
        np.minimum(tau, 1.0).reshape(ranges.size, wl.size),
        rad.reshape(ranges.size, wl.size),
    )


# --- writers (the atmosphere and atmosphere paths tools) ----------------------------------------
def _floats(a) -> Vt.FloatArray:
    """``a`` flattened row-major as float32 (how every table of these layers is stored)."""
    return Vt.FloatArray.FromNumpy(np.ascontiguousarray(np.asarray(a, dtype=np.float32).ravel()))


def define_atmosphere(stage: Usd.Stage, model: str, profile: str, visibility_m: float) -> Usd.Prim:
    """The atmosphere scope (:data:`ATMOSPHERE_PATH`) with HumvAtmosphereAPI applied, and what
    computed it: the ``model`` token (e.g. "lowtran7", "analytic"), the standard ``profile`` and
    the meteorological ``visibility_m`` [m]; the prim the other atmosphere writers write to."""
    prim = UsdGeom.Scope.Define(stage, ATMOSPHERE_PATH).GetPrim()
    prim.ApplyAPI(S.ATMOSPHERE_API)
    prim.GetAttribute(S.ATMOSPHERE_MODEL).Set(model)
    prim.GetAttribute(S.ATMOSPHERE_PROFILE).Set(profile)
    prim.GetAttribute(S.ATMOSPHERE_VISIBILITY).Set(visibility_m)
    return prim


def write_broadband_sky(
    prim: Usd.Prim,
    emissivity: float,
    temperature_k: float,
    longwave_radiance,
    zenith_deg=None,
    time=DEFAULT,
) -> None:
    """Author the effective broadband sky at time code ``time`` (default: the default value):
    ``emissivity`` [-] (stored rounded to 1e-6), brightness ``temperature_k`` [K] (to 1e-4 K),
    and ``longwave_radiance`` [W m-2 sr-1] against the zenith angles ``zenith_deg`` [deg]
    (the angle grid does not vary: authored as a default value, when given)."""
    prim.GetAttribute(S.ATMOSPHERE_SKY_EMISSIVITY).Set(round(float(emissivity), 6), time)
    prim.GetAttribute(S.ATMOSPHERE_SKY_TEMPERATURE).Set(round(float(temperature_k), 4), time)
    if zenith_deg is not None:
        prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).Set(_floats(zenith_deg))
    prim.GetAttribute(S.ATMOSPHERE_SKY_LONGWAVE_RADIANCE).Set(_floats(longwave_radiance), time)


def write_spectral_grid(prim: Usd.Prim, wavelengths_um, zenith_deg) -> None:
    """Author the grid of the spectral tables: ``wavelengths_um`` (W,) [um] (also the path
    tables' grid) and the sky's zenith angles (Z,) [deg] (shared with the broadband sky)."""
    prim.GetAttribute(S.ATMOSPHERE_WAVELENGTHS).Set(_floats(wavelengths_um))
    prim.GetAttribute(S.ATMOSPHERE_SKY_ZENITH_ANGLES).Set(_floats(zenith_deg))


def write_spectral_sky(prim: Usd.Prim, radiance, time=DEFAULT) -> None:
    """Author the sky spectral radiance (Z, W) [W m-2 sr-1 um-1] (zenith angles x wavelengths,
    row-major) at time code ``time``."""
    prim.GetAttribute(S.ATMOSPHERE_SKY_SPECTRAL_RADIANCE).Set(_floats(radiance), time)


def write_solar_spectrum(prim: Usd.Prim, irradiance, time=DEFAULT) -> None:
    """Author the direct solar spectral irradiance (W,) [W m-2 um-1] (beam, normal incidence)
    at time code ``time``."""
    prim.GetAttribute(S.ATMOSPHERE_SOLAR_SPECTRAL_IRRADIANCE).Set(_floats(irradiance), time)


def define_paths(stage: Usd.Stage) -> None:
    """The path tables' scope :data:`PATHS` in a layer of its own: an over of the atmosphere
    scope (the atmosphere layer defines it) and the ``Paths`` scope."""
    stage.OverridePrim(ATMOSPHERE_PATH)
    UsdGeom.Scope.Define(stage, PATHS)


def define_path_table(stage: Usd.Stage, name: str, sensor_path, ranges_m) -> Usd.Prim:
    """The path table ``PATHS/name`` with HumvAtmospherePathAPI applied: the prim path of the
    sensor it belongs to (``sensor_path``, how :func:`path_table` finds it) and its ranges (R,)
    [m], ascending; :func:`write_path_spectra` writes its tables."""
    prim = UsdGeom.Scope.Define(stage, PATHS.AppendChild(name)).GetPrim()
    prim.ApplyAPI(S.ATMOSPHERE_PATH_API)
    prim.GetAttribute(S.ATMOSPHERE_PATH_SENSOR).Set(str(sensor_path))
    prim.GetAttribute(S.ATMOSPHERE_PATH_RANGES).Set(_floats(ranges_m))
    return prim


def write_path_spectra(prim: Usd.Prim, transmittance, radiance, time=DEFAULT) -> None:
    """Author a path table's ``transmittance`` [-] (clipped to 0-1) and path ``radiance``
    [W m-2 sr-1 um-1] (clipped to >= 0), both (R, W) (ranges x wavelengths, row-major), at time
    code ``time``."""
    prim.GetAttribute(S.ATMOSPHERE_PATH_TRANSMITTANCE).Set(_floats(np.clip(transmittance, 0.0, 1.0)), time)
    prim.GetAttribute(S.ATMOSPHERE_PATH_RADIANCE).Set(_floats(np.maximum(radiance, 0.0)), time)
