"""Light after sunset: twilight, moonlight, starlight and airglow, in plain numpy.

Four sources light a scene once the sun is below the horizon; each is a function of plain
numbers here (the render reads the sun and the site from the stage and the moon's position from
:mod:`humv_usd.environment.moon`):

- **Twilight** (sun 0 to 18 deg below the horizon): the horizontal illuminance of the clear sky
  from the polynomial fits of Janiczek & DeYoung (1987, USNO Circular 171; reproduced in Urban &
  Seidelmann, *Explanatory Supplement to the Astronomical Almanac*, 3rd ed., 2013, sec. 10.8),
  :func:`twilight_illuminance_lux`: about 3.4 lx at -6 deg, 0.008 lx at -12 deg and 6e-4 lx at
  -18 deg, the values the AMS *Glossary of Meteorology* gives for the ends of civil, nautical
  and astronomical twilight. Rendered as a uniform sky of luminance E / pi.
- **Moon**: a directional source whose illuminance at the ground is the USNO fit for the full
  moon against its altitude (atmospheric extinction included), times Allen's phase law
  :math:`10^{-0.4 (0.026|\\alpha| + 4\\times10^{-9}\\alpha^4)}` (Allen, *Astrophysical
  Quantities*, 3rd ed., 1973, p. 144; :math:`\\alpha` the phase angle in degrees) and the
  inverse square of its distance (:func:`moon_illuminance_lux`); its spectrum is the solar one
  reddened by the lunar albedo (:data:`LUNAR_ALBEDO`), with a moonlit sky of
  :data:`MOONLIT_SKY_FRACTION` of its horizontal illuminance.
- **Starlight and airglow** (the natural moonless sky): the zenith sky brightness of a dark site
  in the astronomical bands converted to spectral radiance (:data:`NIGHT_SKY_MAG`,
  :func:`night_sky_radiance`): V 21.9 mag arcsec-2 is 2.7e-6 W m-2 sr-1 um-1 (2e-4 cd m-2) and
  the OH airglow makes the short-wave infrared 20-40 times brighter (H 14.0 mag arcsec-2:
  1.2e-4 W m-2 sr-1 um-1), which is why SWIR cameras see on moonless nights.

Scattered light (twilight and moonlit sky) has the source's spectrum times the Rayleigh
:math:`\\lambda^{-4}` law normalised at 0.55 um (:func:`scattered_shape`; Rayleigh 1899; the
ozone Chappuis band that makes the twilight zenith bluer still is neglected). A luminance or
illuminance becomes a spectrum through the CIE photopic efficiency passed in by the caller
(:func:`scale_to_photometric`, 683 lm W-1).

Validity: clear sky, no light pollution (an urban sky is 10-100 times brighter: Falchi et al.
2016, Sci. Adv. 2:e1600377), site near sea level; the twilight and moonlit skies are uniform
(the real ones are brighter toward the sun or moon), the natural sky has the zenith value
everywhere (airglow brightens toward the horizon, van Rhijn 1921).
"""

from __future__ import annotations

import numpy as np

from humv_usd.constants import SUN_TEMPERATURE_K
from humv_usd.physics import planck

#: Maximum luminous efficacy of photopic vision [lm W-1] (CIE, SI definition of the candela).
KM_LM_PER_W = 683.0

#: USNO Circular 171 (Janiczek & DeYoung 1987) fits of log10 of the horizontal illuminance [lx]
#: by the sun's altitude h [deg]: (h_min, h_max, l0, l1, l2, l3) with
#: log10 E = l0 + l1 x + l2 x^2 + l3 x^3, x = h / 90 (clear sky, sun's centre, refraction
#: included). Continuous across the interval limits to 0.01 in log10 E (tests/test_nightsky.py).
SUN_ILLUMINANCE_FIT = (
    (20.0, 90.0, 3.74, 3.97, -4.07, 1.47),
    (5.0, 20.0, 3.05, 13.28, -45.98, 64.33),
    (-0.8, 5.0, 2.88, 22.26, -207.64, 1034.30),
    (-5.0, -0.8, 2.88, 21.81, -258.11, -858.36),
    (-12.0, -5.0, 2.70, 12.17, -431.69, -1899.83),
    (-18.0, -12.0, 13.84, 262.72, 1447.42, 2797.93),
)
#: The same for the full moon at its mean distance, by the moon's altitude (same source).
MOON_ILLUMINANCE_FIT = (
    (20.0, 90.0, -1.95, 4.06, -4.24, 1.56),
    (5.0, 20.0, -2.58, 12.58, -42.58, 59.06),
    (-0.8, 5.0, -2.79, 24.27, -252.95, 1321.29),
)
#: Mean Earth-Moon distance [km] of the fits (Urban & Seidelmann 2013).
MOON_MEAN_DISTANCE_KM = 384400.0

#: Lunar disk reflectance against wavelength [um] relative to 0.55 um: the Moon reddens the
#: sunlight, its albedo roughly tripling from 0.4 to 2.5 um. Representative values read from the
#: ROLO disk reflectance (Kieffer & Stone 2005, Astron. J. 129:2887, fig. 7/8), not data points.
LUNAR_ALBEDO = (
    (0.35, 0.40, 0.55, 0.70, 0.90, 1.10, 1.30, 1.60, 2.00, 2.50),
    (0.65, 0.75, 1.00, 1.22, 1.45, 1.62, 1.75, 1.95, 2.20, 2.40),
)
#: Moonlit-sky horizontal illuminance as a fraction of the moon's own on a horizontal surface:
#: the clear-sky diffuse fraction of sunlight at moderate zenith angles (the same atmosphere
#: scatters moonlight alike; about 0.1-0.2 for a clear sky, e.g. Ineichen & Perez 2002 clear sky).
MOONLIT_SKY_FRACTION = 0.15

#: Natural moonless zenith sky brightness of a dark site [mag arcsec-2] by band centre [um], and
#: each band's Vega zero-point flux [W m-2 um-1]: UBVRI from Benn & Ellison (1998) New Astron.
#: Rev. 42:503 (La Palma, solar minimum; U 22.0, B 22.7, V 21.9, R 21.0, I 20.0) with the
#: Bessell, Castelli & Plez (1998) A&A 333:231 zero points; J, H, Ks typical of dark sites
#: (16.0, 14.0, 13.0; e.g. Cuby, Lidman & Moutou 2000, The Messenger 101:2, Paranal; the OH
#: Meinel airglow, varying by +-0.5 mag over a night) with the Cohen, Wheaton & Megeath (2003)
#: AJ 126:1090 2MASS zero points. Ks includes some thermal sky; beyond 2.2 um the value is held.
NIGHT_SKY_MAG = (
    # (centre um, mag arcsec-2, zero point W m-2 um-1)
    (0.36, 22.0, 4.175e-8),
    (0.44, 22.7, 6.32e-8),
    (0.55, 21.9, 3.631e-8),
    (0.64, 21.0, 2.177e-8),
    (0.79, 20.0, 1.126e-8),
    (1.235, 16.0, 3.129e-9),
    (1.662, 14.0, 1.133e-9),
    (2.159, 13.0, 4.283e-10),
)
#: One square arcsecond [sr].
ARCSEC2_SR = (np.pi / (180.0 * 3600.0)) ** 2


def _fit(table, h_deg):
    h = np.asarray(h_deg, dtype=float)
    out = np.full(h.shape, -np.inf)
    for lo, hi, a, b, c, d in table:
        sel = (h >= lo) & (h <= hi) & ~np.isfinite(out)
        x = h[sel] / 90.0
        out[sel] = a + b * x + c * x**2 + d * x**3
    return out


def twilight_illuminance_lux(sun_elevation_deg) -> np.ndarray:
    """Horizontal illuminance of the clear sky [lx] with the sun at ``sun_elevation_deg``.

    Parameters
    ----------
    sun_elevation_deg : numeric
        Apparent altitude of the sun's centre [deg], -90..90.

    Returns
    -------
    numeric
        USNO Circular 171 fit (:data:`SUN_ILLUMINANCE_FIT`); above the horizon it includes the
        direct sun, between 0 and -18 deg it is the twilight sky alone; 0 below -18 deg
        (astronomical night: the natural sky, :func:`night_sky_radiance`, takes over).

    References
    ----------
    Janiczek, P. M., DeYoung, J. A. (1987). Computer programs for sun and moon illuminance with
    contingent tables and diagrams. U.S. Naval Observatory Circular No. 171.
    """
    return np.power(10.0, _fit(SUN_ILLUMINANCE_FIT, sun_elevation_deg))


def moon_phase_factor(phase_angle_deg) -> np.ndarray:
    """Moon brightness relative to full (phase angle 0): Allen's magnitude law
    :math:`m(\\alpha) - m(0) = 0.026|\\alpha| + 4\\times10^{-9}\\alpha^4` [deg] (Allen 1973, p. 144;
    good to about 0.1 mag up to |alpha| ~ 150 deg)."""
    a = np.abs(np.asarray(phase_angle_deg, dtype=float))
    return np.power(10.0, -0.4 * (0.026 * a + 4e-9 * a**4))


def moon_illuminance_lux(moon_elevation_deg, phase_angle_deg, distance_km=MOON_MEAN_DISTANCE_KM):
    """Illuminance of the moon on a surface normal to its beam at the ground [lx].

    Parameters
    ----------
    moon_elevation_deg : numeric
        Apparent altitude of the moon [deg]; 0 below -0.8 deg.
    phase_angle_deg : numeric
        Sun-Moon-Earth angle [deg] (0 = full, 180 = new).
    distance_km : numeric
        Earth-Moon distance [km].

    Notes
    -----
    USNO Circular 171 (Janiczek & DeYoung 1987) fit of the full moon's horizontal illuminance
    against altitude (:data:`MOON_ILLUMINANCE_FIT`, extinction included; 0.27 lx at the zenith)
    divided by sin(altitude) (the fit is on a horizontal surface; clipped at 1 deg), times
    :func:`moon_phase_factor` and :math:`(d_0/d)^2`.
    """
    h = np.asarray(moon_elevation_deg, dtype=float)
    horizontal = np.power(10.0, _fit(MOON_ILLUMINANCE_FIT, h))
    normal = horizontal / np.sin(np.radians(np.clip(h, 1.0, 90.0)))
    return (
        normal * moon_phase_factor(phase_angle_deg) * (MOON_MEAN_DISTANCE_KM / np.asarray(distance_km)) ** 2
    )


def solar_shape(wavelengths_um) -> np.ndarray:
    """Relative solar spectrum: a blackbody at the Sun's effective temperature (IAU 2015
    Resolution B3, 5772 K), arbitrary scale."""
    return planck.spectral_radiance(np.asarray(wavelengths_um, float), SUN_TEMPERATURE_K)


def moon_shape(wavelengths_um) -> np.ndarray:
    """Relative spectrum of moonlight: :func:`solar_shape` times :data:`LUNAR_ALBEDO`."""
    wl = np.asarray(wavelengths_um, float)
    return solar_shape(wl) * np.interp(wl, *LUNAR_ALBEDO)


def scattered_shape(wavelengths_um, source_shape) -> np.ndarray:
    """Relative spectrum of a clear sky lit by a source of relative spectrum ``source_shape``:
    Rayleigh's :math:`(\\lambda / 0.55\\,\\mu m)^{-4}` times the source (Rayleigh 1899)."""
    wl = np.asarray(wavelengths_um, float)
    return np.asarray(source_shape, float) * (wl / 0.55) ** -4


def scale_to_photometric(wavelengths_um, shape, photometric, photopic) -> np.ndarray:
    """The spectrum of relative shape ``shape`` whose photometric value is ``photometric``.

    Parameters
    ----------
    wavelengths_um, shape : array (W,)
        The relative spectrum on its grid [um].
    photometric : float
        Luminance [cd m-2] (gives spectral radiance [W m-2 sr-1 um-1]) or illuminance [lx]
        (gives spectral irradiance [W m-2 um-1]).
    photopic : (wavelengths_um, V)
        The CIE photopic luminous efficiency (e.g. the CIE 1931 y-bar).

    Notes
    -----
    :math:`X_v = K_m \\int V(\\lambda) S(\\lambda) d\\lambda`, :math:`K_m` = 683 lm W-1; the
    integral on the union of both grids (trapezoid), the shape linear between its nodes.
    """
    wl = np.asarray(wavelengths_um, float)
    s = np.asarray(shape, float)
    vw, v = (np.asarray(a, float) for a in photopic)
    x = np.union1d(vw, wl[(wl > vw[0]) & (wl < vw[-1])])
    integrand = np.interp(x, vw, v) * np.interp(x, wl, s, left=0.0, right=0.0)
    per = KM_LM_PER_W * float(np.sum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(x)))
    if per <= 0:
        return np.zeros_like(s)
    return s * (float(photometric) / per)


def night_sky_radiance(wavelengths_um) -> np.ndarray:
    """Natural moonless clear-sky spectral radiance (starlight, zodiacal light, airglow)
    [W m-2 sr-1 um-1] at ``wavelengths_um``: :data:`NIGHT_SKY_MAG` converted with
    :math:`L_\\lambda = F_0 10^{-0.4 m} / (1\\,\\mathrm{arcsec}^2)`, log-linear between the band
    centres, held beyond the first and last."""
    c = np.array([r[0] for r in NIGHT_SKY_MAG])
    val = np.array([r[2] * 10.0 ** (-0.4 * r[1]) / ARCSEC2_SR for r in NIGHT_SKY_MAG])
    return np.exp(np.interp(np.asarray(wavelengths_um, float), c, np.log(val)))
