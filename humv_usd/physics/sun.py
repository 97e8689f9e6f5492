"""The sun at n times as plain arrays (:class:`SunState`: the shape the environment tool writes
and :mod:`humv_usd.usd.environment` reads back), its direction and the cloud reduction of the
broadband irradiance (Kasten & Czeplak 1980).

Stage frame: x east, y north, z up; azimuth is a compass angle (0 = north, 90 = east).
"""

from __future__ import annotations

import functools
import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from humv_usd.compat import trapezoid


@dataclass
class SunState:
    """The sun at n times.

    times_s (n,) [s after frame 0]; zenith_deg, azimuth_deg (n,) apparent, compass azimuth;
    direction (n, 3) unit vector toward the sun (x east, y north, z up); dni_w_m2, dhi_w_m2,
    ghi_w_m2 (n,) [W m-2] broadband, cloud-reduced; up (n,) bool (apparent elevation > 0).
    """

    times_s: np.ndarray
    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    direction: np.ndarray
    dni_w_m2: np.ndarray
    dhi_w_m2: np.ndarray
    ghi_w_m2: np.ndarray
    up: np.ndarray


def sun_direction(zenith_deg, azimuth_deg) -> np.ndarray:
    """Unit vector(s) toward the sun in the stage frame (x east, y north, z up), shape (n, 3)."""
    z, a = np.radians(np.atleast_1d(zenith_deg)), np.radians(np.atleast_1d(azimuth_deg))
    return np.stack([np.sin(z) * np.sin(a), np.sin(z) * np.cos(a), np.cos(z)], axis=-1)


def cloud_reduction(ghi_clear, dhi_clear, zenith_deg, cloud_cover):
    """Global, diffuse and direct-normal irradiance under a cloud cover (Kasten & Czeplak 1980).

    Parameters
    ----------
    ghi_clear, dhi_clear : array-like
        Clear-sky global and diffuse horizontal irradiance [W m-2].
    zenith_deg : array-like
        Solar zenith angle [deg].
    cloud_cover : array-like
        Cloud cover fraction N [0-1] (octas / 8).

    Returns
    -------
    tuple of arrays
        (GHI, DHI, DNI) [W m-2].

    Notes
    -----
    GHI = GHI_clear (1 - 0.75 N^3.4) and the diffuse fraction D/G = 0.3 + 0.7 N^2 (Kasten &
    Czeplak's fits to ten years of Hamburg data). Their clear-sky diffuse fraction 0.3 is replaced
    by the clear-sky model's own D/G, so that N = 0 returns the clear sky unchanged:
    D/G = kd_clear + (1 - kd_clear) N^2, which equals Kasten & Czeplak's law for kd_clear = 0.3.
    DNI = (GHI - DHI) / cos(zenith).

    References
    ----------
    .. [1] Kasten, F., Czeplak, G. (1980). Solar and terrestrial radiation dependent on the
       amount and type of cloud. Solar Energy 24, 177-189.
    """
    ghi_c = np.asarray(ghi_clear, dtype=float)
    n = np.clip(np.asarray(cloud_cover, dtype=float), 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        kd_clear = np.where(ghi_c > 0, np.asarray(dhi_clear, dtype=float) / ghi_c, 1.0)
    ghi = ghi_c * (1.0 - 0.75 * n**3.4)
    dhi = ghi * np.clip(kd_clear + (1.0 - kd_clear) * n * n, 0.0, 1.0)
    cosz = np.cos(np.radians(np.asarray(zenith_deg, dtype=float)))
    with np.errstate(divide="ignore", invalid="ignore"):
        dni = np.where(cosz > 1e-6, (ghi - dhi) / cosz, 0.0)
    return ghi, dhi, np.maximum(dni, 0.0)


def cloud_dni_factor(cloud_cover) -> np.ndarray:
    """Direct-normal irradiance under a cloud cover over the clear-sky one, DNI / DNI_clear.

    Parameters
    ----------
    cloud_cover : array-like
        Cloud cover fraction N [0-1].

    Returns
    -------
    array
        (1 - 0.75 N^3.4) (1 - N^2): :func:`cloud_reduction`'s DNI over its N = 0 value, which
        does not depend on the clear-sky diffuse fraction (GHI - DHI = GHI_clear (1 - 0.75
        N^3.4) (1 - kd_clear) (1 - N^2); Kasten & Czeplak 1980).
    """
    n = np.clip(np.asarray(cloud_cover, dtype=float), 0.0, 1.0)
    return (1.0 - 0.75 * n**3.4) * (1.0 - n * n)


#: below this DNI / DNI_clear (:func:`cloud_dni_factor`: cover above ~0.97) the sky is overcast:
#: no cloud gaps, the beam stays the layer's uniform value (the thermal tool's cloud shadows and
#: the render's)
OVERCAST_DNI_FACTOR = 0.05


@functools.lru_cache(maxsize=1)
def reference_solar_spectrum() -> tuple[np.ndarray, np.ndarray]:
    """The reference sun of broadband solar absorptivities: (wavelengths [um] (0.28-4),
    spectral irradiance [W m^-2 um^-1]).

    ASTM G173-03 global tilted spectrum (AM 1.5, 37 deg sun-facing tilt, 1000 W m^-2 total),
    the standard terrestrial sun of solar-absorptance ratings (ASTM E903): the table pvlib ships
    (``pvlib/data/ASTMG173.csv``, what :func:`pvlib.spectrum.get_reference_spectra` reads), read
    here with numpy so that reading a material does not import pvlib and pandas.

    References
    ----------
    .. [1] ASTM G173-03 (2020). Standard tables for reference solar spectral irradiances: direct
       normal and hemispherical on 37 deg tilted surface. ASTM International.
    """
    spec = importlib.util.find_spec("pvlib")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("pvlib (ASTM G173 reference spectrum) is not installed")
    table = Path(list(spec.submodule_search_locations)[0]) / "data" / "ASTMG173.csv"
    data = np.loadtxt(table, delimiter=",", skiprows=2, usecols=(0, 2))
    return data[:, 0] / 1000.0, data[:, 1] * 1000.0


def solar_absorptivity(wavelengths_um, reflectance, transmittance=None) -> float:
    """Broadband solar absorptivity of a spectrum: 1 - (R + T) weighted by the reference sun.

    Parameters
    ----------
    wavelengths_um : array (W,)
        Ascending wavelengths of the tables [um]; they must reach 0.5 um and 2.5 um.
    reflectance, transmittance : array (W,)
        Directional-hemispherical reflectance and transmittance [0-1] (transmittance None:
        opaque), interpolated linearly and held beyond the table's ends.

    Returns
    -------
    float
        alpha_s = int (1 - R - T) E dlambda / int E dlambda over 0.28-4 um, E the ASTM G173
        global spectrum (:func:`reference_solar_spectrum`), trapezoid on its grid.
    """
    wl = np.asarray(wavelengths_um, dtype=float)
    if wl.size < 2 or wl[0] > 0.5 or wl[-1] < 2.5:
        raise ValueError("solar absorptivity needs a spectrum from 0.5 um (or less) to 2.5 um (or more)")
    ref_wl, ref_e = reference_solar_spectrum()
    lost = np.interp(ref_wl, wl, np.asarray(reflectance, dtype=float))
    if transmittance is not None:
        lost = lost + np.interp(ref_wl, wl, np.asarray(transmittance, dtype=float))
    return float(1.0 - trapezoid(lost * ref_e, ref_wl) / trapezoid(ref_e, ref_wl))
