"""The sky laws (the one module for them) and simple path extinction (closed forms, arrays in).

Effective (broadband, hemispherical) sky emissivity and temperature (Berdahl & Martin 1984), its
angular distribution (Martin & Berdahl 1984) and that law's hemispherical integral, the cloud
mix (Crawford & Duchon 1999), the exact hemispherical irradiance of a sky tabulated against
zenith (the atmosphere layer's ``skyLongwaveRadiance``), and the closed-form extinction terms of
the analytic atmosphere (water-vapour continuum, aerosol from visibility). LOWTRAN7 spectra are
in :mod:`humv_usd.atmosphere.model`; these are its analytic fallback. The thermal tool's sky
radiance model (:mod:`humv_usd.thermal.sky`) builds on these.
"""

from __future__ import annotations

import numpy as np

from humv_usd.constants import BOLTZMANN_CONSTANT, STEFAN_BOLTZMANN

# Magnus coefficients over water, Alduchov & Eskridge (1996): a [-], b [degC]
_MAGNUS_A = 17.625
_MAGNUS_B = 243.04


def dew_point(air_temperature_k, relative_humidity):
    """Dew-point temperature from air temperature and relative humidity (Magnus formula).

    Parameters
    ----------
    air_temperature_k : numeric
        Air temperature [K].
    relative_humidity : numeric
        Relative humidity over water [0-1]; values are clipped to [1e-6, 1].

    Returns
    -------
    numeric
        Dew-point temperature [K].

    Notes
    -----
    With t the air temperature in degC, a = 17.625 and b = 243.04 degC,
    gamma = ln(RH) + a t / (b + t) and T_dp = b gamma / (a - gamma).
    Accurate to about 0.35 K between -40 and +50 degC.

    References
    ----------
    .. [1] Alduchov, O. A., Eskridge, R. E. (1996). Improved Magnus form approximation of
       saturation vapor pressure. J. Appl. Meteor. 35, 601-609.
    """
    t_c = np.asarray(air_temperature_k, dtype=float) - 273.15
    rh = np.clip(np.asarray(relative_humidity, dtype=float), 1e-6, 1.0)
    gamma = np.log(rh) + _MAGNUS_A * t_c / (_MAGNUS_B + t_c)
    return _MAGNUS_B * gamma / (_MAGNUS_A - gamma) + 273.15


def berdahl_martin_emissivity(dew_point_k):
    """Clear-sky effective emissivity from the dew point (Berdahl & Martin 1984).

    Parameters
    ----------
    dew_point_k : numeric
        Dew-point temperature [K].

    Returns
    -------
    numeric
        Hemispherical broadband clear-sky emissivity [0-1], clipped to [0.3, 1].

    Notes
    -----
    eps = 0.711 + 0.56 (T_dp/100) + 0.73 (T_dp/100)^2 with T_dp in degC; fitted to nighttime
    and daytime pyrgeometer data in six US cities, T_dp from -20 to +30 degC. The daytime
    correction (+0.013 cos(2 pi hour/24)) and the pressure correction are below 1.5 % and left out.

    References
    ----------
    .. [1] Berdahl, P., Martin, M. (1984). Emissivity of clear skies. Solar Energy 32(5),
       663-664.
    """
    tdp = (np.asarray(dew_point_k, dtype=float) - 273.15) / 100.0
    return np.clip(0.711 + 0.56 * tdp + 0.73 * tdp * tdp, 0.3, 1.0)


def effective_sky_temperature(air_temperature_k, relative_humidity):
    """Effective sky temperature T_sky = eps_sky^(1/4) T_air (clear sky, Berdahl & Martin).

    Parameters
    ----------
    air_temperature_k : numeric
        Air temperature near the ground [K].
    relative_humidity : numeric
        Relative humidity [0-1].

    Returns
    -------
    tuple of numeric
        (sky temperature [K], sky emissivity [0-1]); sigma T_sky^4 is the downwelling
        longwave irradiance of a blackbody sky with the same total flux.

    References
    ----------
    .. [1] Berdahl, P., Martin, M. (1984). Emissivity of clear skies. Solar Energy 32(5), 663.
    """
    eps = berdahl_martin_emissivity(dew_point(air_temperature_k, relative_humidity))
    return eps**0.25 * np.asarray(air_temperature_k, dtype=float), eps


def martin_berdahl_law(zenith_emissivity, mu):
    """Slab-atmosphere angular law eps(mu) = 1 - (1 - eps_z)^(1/mu) (Martin & Berdahl 1984).

    Parameters
    ----------
    zenith_emissivity : numeric
        Zenith emissivity eps_z [0-1].
    mu : numeric
        Cosine of the zenith angle [-]; mu <= 0 (horizon and below) gives 1.
    """
    # mu -> 0 makes the exponent blow up; (1-eps_z)^inf = 0 -> eps = 1 at the horizon
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        out = 1.0 - np.power(1.0 - zenith_emissivity, 1.0 / np.maximum(mu, 1e-12))
    return np.where(mu > 0, out, 1.0)


_GAUSS: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def hemispherical_martin_berdahl(zenith_emissivity, n: int = 400):
    """Hemispherical emissivity 2 int_0^1 eps(mu) mu dmu of :func:`martin_berdahl_law`
    (Gauss-Legendre in mu with ``n`` nodes; the integrand is bounded and smooth on (0, 1])."""
    if n not in _GAUSS:
        _GAUSS[n] = np.polynomial.legendre.leggauss(n)
    x, w = _GAUSS[n]
    mu = 0.5 * (x + 1.0)
    eps = martin_berdahl_law(np.asarray(zenith_emissivity, dtype=float)[..., None], mu)
    return np.sum(eps * mu * w, axis=-1)  # 2 * 0.5 * sum(...)


def zenith_emissivity_martin_berdahl(sky_emissivity):
    """Zenith emissivity eps_z whose Martin-Berdahl angular law has hemispherical value eps_sky.

    Parameters
    ----------
    sky_emissivity : numeric
        Hemispherical (flux) clear-sky emissivity [0-1].

    Returns
    -------
    numeric
        Zenith emissivity eps_z [0-1] with 2 int eps(theta) cos sin dtheta = eps_sky.

    Notes
    -----
    Solved by bisection (the hemispherical value is monotonic in eps_z). Martin & Berdahl (1984)
    fit eps_z ~ 1 - (1 - eps_sky)^(1/1.8); solving keeps the downwelling flux identical to the
    Berdahl & Martin hemispherical emissivity the rest of the code uses.
    """
    target = np.clip(np.asarray(sky_emissivity, dtype=float), 0.0, 1.0)
    lo, hi = np.zeros_like(target), np.array(target, copy=True)  # eps_z <= eps_sky
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        too_low = hemispherical_martin_berdahl(mid) < target
        lo, hi = np.where(too_low, mid, lo), np.where(too_low, hi, mid)
    return 0.5 * (lo + hi)


def directional_sky_emissivity(zenith_deg, sky_emissivity):
    """Clear-sky emissivity by direction with a given hemispherical value (Martin & Berdahl 1984).

    Parameters
    ----------
    zenith_deg : numeric
        Zenith angle of the viewing direction [deg]; 0 = straight up, >= 90 gives 1.
    sky_emissivity : float
        Hemispherical broadband clear-sky emissivity eps_sky [0-1] (e.g.
        :func:`berdahl_martin_emissivity`).

    Returns
    -------
    numeric
        eps(theta) [0-1] with 2 int_0^(pi/2) eps(theta) cos(theta) sin(theta) dtheta = eps_sky.

    Notes
    -----
    Slab-atmosphere law eps(theta) = 1 - (1 - eps_z)^(1 / cos theta) of Martin & Berdahl
    (1984); the zenith emissivity eps_z is solved (bisection, the hemispherical integral is
    monotonic in eps_z, :func:`zenith_emissivity_martin_berdahl`) so that the downwelling flux
    equals the Berdahl & Martin (1984) value. The thermal tool's
    ``angular_sky_emissivity(model='martin_berdahl')`` is this function.

    References
    ----------
    .. [1] Martin, M., Berdahl, P. (1984). Characteristics of infrared sky radiation in the
       United States. Solar Energy 33(3/4), 321-336.
    """
    mu = np.cos(np.radians(np.asarray(zenith_deg, dtype=float)))
    return martin_berdahl_law(float(zenith_emissivity_martin_berdahl(float(sky_emissivity))), mu)


def cloudy_sky_emissivity(clear_emissivity, cloud_cover):
    """Effective sky emissivity with a cloud fraction (Crawford & Duchon 1999).

    Parameters
    ----------
    clear_emissivity : numeric
        Clear-sky emissivity, hemispherical or directional eps(theta) [0-1].
    cloud_cover : numeric
        Cloud fraction c [0-1] (clipped).

    Returns
    -------
    numeric
        eps = c + (1 - c) eps_clear [0-1].

    Notes
    -----
    The clouds are taken as blackbodies at the screen-level air temperature covering the
    fraction c of the dome (low, optically thick cloud base), so the same mix holds for the
    hemispherical emissivity and, direction by direction, for eps(theta): an overcast sky
    (c = 1) radiates sigma T_air^4. High thin cloud (cirrus) is colder and partly transparent;
    the mix overestimates its emission.

    References
    ----------
    .. [1] Crawford, T. M., Duchon, C. E. (1999). An improved parameterization for estimating
       effective atmospheric emissivity for use in calculating daytime downwelling longwave
       radiation. J. Appl. Meteor. 38, 474-480 (their Eq. 20, clf the cloud fraction).
    """
    c = np.clip(np.asarray(cloud_cover, dtype=float), 0.0, 1.0)
    return c + (1.0 - c) * np.asarray(clear_emissivity, dtype=float)


def extended_sky_table(zenith_deg, radiance):
    """Table nodes [rad] and values extended as np.interp does: constant to 0 and to 90 deg."""
    z = np.asarray(zenith_deg, dtype=float).ravel()
    val = np.asarray(radiance, dtype=float).ravel()
    if z.size == 0 or z.size != val.size or np.any(np.diff(z) <= 0) or z[0] < 0 or z[-1] > 90:
        raise ValueError("sky table: zenith angles must ascend within 0-90 deg, one value each")
    if z[0] > 0:
        z, val = np.r_[0.0, z], np.r_[val[0], val]
    if z[-1] < 90:
        z, val = np.r_[z, 90.0], np.r_[val, val[-1]]
    return np.radians(z), val


def hemispherical_irradiance(zenith_deg, radiance) -> float:
    """Irradiance on a horizontal plane from a sky tabulated against zenith [W m^-2].

    Parameters
    ----------
    zenith_deg : array (Z,)
        Ascending zenith angles of the table [deg] within 0-90.
    radiance : array (Z,)
        Radiance at those angles, azimuthally uniform [W m^-2 sr^-1].

    Returns
    -------
    float
        E = 2 pi int_0^(pi/2) L(theta) cos(theta) sin(theta) dtheta, i.e. pi times the
        cosine-weighted hemispherical mean of L.

    Notes
    -----
    Exact for the interpolant the radiance maps use (:meth:`ClearSky.radiance`): L linear in
    theta between the nodes, constant before the first and after the last node (np.interp).
    On a segment L = a + s theta, with int sin cos = sin^2/2 and
    int theta sin cos = -theta cos(2 theta)/4 + sin(2 theta)/8.
    """
    th, val = extended_sky_table(zenith_deg, radiance)
    a, b = th[:-1], th[1:]
    slope = np.diff(val) / np.diff(th)
    f0 = lambda t: 0.5 * np.sin(t) ** 2  # noqa: E731
    f1 = lambda t: -t * np.cos(2.0 * t) / 4.0 + np.sin(2.0 * t) / 8.0  # noqa: E731
    seg = (val[:-1] - slope * a) * (f0(b) - f0(a)) + slope * (f1(b) - f1(a))
    return float(2.0 * np.pi * seg.sum())


def water_vapour_pressure(air_temperature_k, relative_humidity):
    """Partial pressure of water vapour [Pa]: RH times the Magnus saturation pressure over water.

    e_s = 610.94 exp(17.625 t / (t + 243.04)) Pa with t in degC (Alduchov & Eskridge 1996).
    """
    t_c = np.asarray(air_temperature_k, dtype=float) - 273.15
    return np.clip(relative_humidity, 0.0, 1.0) * 610.94 * np.exp(_MAGNUS_A * t_c / (_MAGNUS_B + t_c))


def water_continuum_absorption(wavelength_um, air_temperature_k, relative_humidity, pressure_pa=101325.0):
    """Water-vapour continuum absorption coefficient in the 8-14 um window [m-1].

    Parameters
    ----------
    wavelength_um : array-like
        Wavelengths [um]; the fit holds for 400-1250 cm-1 (8-25 um), elsewhere the result is 0.
    air_temperature_k, relative_humidity, pressure_pa : float
        Air state.

    Returns
    -------
    array
        k(lambda) [m-1]; the transmittance of a horizontal path of length R is exp(-k R).

    Notes
    -----
    Roberts, Selby & Biberman (1976): C_s(nu) = a + b exp(-beta nu) [cm2 molecule-1 atm-1],
    a = 1.25e-22, b = 1.67e-19, beta = 7.87e-3 cm, at 296 K with the temperature factor
    exp(1800 (1/T - 1/296)); k = C_s n_w (e + gamma (P - e)) / P0 with the foreign-broadening
    ratio gamma = 0.002, n_w the water number density and pressures in atm.

    References
    ----------
    .. [1] Roberts, R. E., Selby, J. E. A., Biberman, L. M. (1976). Infrared continuum
       absorption by atmospheric water vapor in the 8-12 um window. Applied Optics 15(9),
       2085-2090.
    """
    nu = 1.0e4 / np.asarray(wavelength_um, dtype=float)  # [cm-1]
    t = float(air_temperature_k)
    e_pa = float(water_vapour_pressure(t, relative_humidity))
    cs = (1.25e-22 + 1.67e-19 * np.exp(-7.87e-3 * nu)) * np.exp(1800.0 * (1.0 / t - 1.0 / 296.0))
    n_w = e_pa / (BOLTZMANN_CONSTANT * t) * 1e-6  # [molecules cm-3]
    broad_atm = (e_pa + 0.002 * (float(pressure_pa) - e_pa)) / 101325.0
    k_cm = cs * n_w * broad_atm  # [cm-1]
    return np.where((nu >= 400.0) & (nu <= 1250.0), k_cm * 100.0, 0.0)


def aerosol_extinction(wavelength_um, visibility_km):
    """Aerosol extinction coefficient from the visibility (Koschmieder, Kruse) [m-1].

    beta(lambda) = (3.912 / V) (lambda / 0.55 um)^(-q) with q = 1.6 (V > 50 km), 1.3
    (6-50 km), 0.585 V^(1/3) (V < 6 km) (Kruse et al. 1962); the Rayleigh part 0.0116 km-1
    at 0.55 um is removed from the Koschmieder extinction (Elterman 1968).

    References
    ----------
    .. [1] Koschmieder, H. (1924). Theorie der horizontalen Sichtweite. Beitr. Phys. freien
       Atmos. 12, 33-53.
    .. [2] Kruse, P. W., McGlauchlin, L. D., McQuistan, R. B. (1962). Elements of Infrared
       Technology. Wiley, New York.
    """
    v = float(visibility_km)
    q = 1.6 if v > 50.0 else 1.3 if v > 6.0 else 0.585 * v ** (1.0 / 3.0)
    beta550 = max(3.912 / v - 0.0116, 0.0) * 1e-3  # [m-1]
    return beta550 * (np.asarray(wavelength_um, dtype=float) / 0.55) ** (-q)


def _vapour_hpa(air_temperature_k, relative_humidity):
    return water_vapour_pressure(air_temperature_k, relative_humidity) / 100.0


def brunt_emissivity(air_temperature_k, relative_humidity):
    """Clear-sky emissivity of Brunt (1932): eps = 0.52 + 0.065 sqrt(e), e in [hPa].

    Parameters
    ----------
    air_temperature_k : numeric
        Screen-level air temperature [K].
    relative_humidity : numeric
        Relative humidity [0-1].

    Returns
    -------
    numeric
        Broadband hemispherical clear-sky emissivity [0-1] (downwelling long wave eps sigma T^4).

    References
    ----------
    .. [1] Brunt, D. (1932). Notes on radiation in the atmosphere. Q. J. R. Meteorol. Soc. 58,
       389-420 (coefficients as tabulated by Flerchinger et al. 2009, Water Resour. Res. 45,
       W03423, Table 1).
    """
    return 0.52 + 0.065 * np.sqrt(_vapour_hpa(air_temperature_k, relative_humidity))


def brutsaert_emissivity(air_temperature_k, relative_humidity):
    """Clear-sky emissivity of Brutsaert (1975): eps = 1.24 (e / T)^(1/7), e [hPa], T [K].

    References
    ----------
    .. [1] Brutsaert, W. (1975). On a derivable formula for long-wave radiation from clear
       skies. Water Resour. Res. 11(5), 742-744.
    """
    t = np.asarray(air_temperature_k, dtype=float)
    return 1.24 * (_vapour_hpa(t, relative_humidity) / t) ** (1.0 / 7.0)


def swinbank_emissivity(air_temperature_k, relative_humidity=None):
    """Clear-sky emissivity of Swinbank (1963): eps = 9.365e-6 T^2 (T [K]; humidity unused).

    References
    ----------
    .. [1] Swinbank, W. C. (1963). Long-wave radiation from clear skies. Q. J. R. Meteorol.
       Soc. 89, 339-348.
    """
    t = np.asarray(air_temperature_k, dtype=float)
    return 9.365e-6 * t * t


def idso_jackson_emissivity(air_temperature_k, relative_humidity=None):
    """Clear-sky emissivity of Idso & Jackson (1969): eps = 1 - 0.261 exp(-7.77e-4 (273 - T)^2).

    References
    ----------
    .. [1] Idso, S. B., Jackson, R. D. (1969). Thermal radiation from the atmosphere.
       J. Geophys. Res. 74, 5397-5403.
    """
    t = np.asarray(air_temperature_k, dtype=float)
    return 1.0 - 0.261 * np.exp(-7.77e-4 * (273.0 - t) ** 2)


def idso_emissivity(air_temperature_k, relative_humidity):
    """Clear-sky emissivity of Idso (1981): eps = 0.70 + 5.95e-5 e exp(1500 / T), e [hPa].

    References
    ----------
    .. [1] Idso, S. B. (1981). A set of equations for full spectrum and 8- to 14-um and 10.5-
       to 12.5-um thermal radiation from cloudless skies. Water Resour. Res. 17(2), 295-304.
    """
    t = np.asarray(air_temperature_k, dtype=float)
    return 0.70 + 5.95e-5 * _vapour_hpa(t, relative_humidity) * np.exp(1500.0 / t)


def prata_emissivity(air_temperature_k, relative_humidity):
    """Clear-sky emissivity of Prata (1996): eps = 1 - (1 + w) exp(-sqrt(1.2 + 3 w)),
    w = 46.5 e / T the precipitable water [cm] (e [hPa], T [K]).

    References
    ----------
    .. [1] Prata, A. J. (1996). A new long-wave formula for estimating downward clear-sky
       radiation at the surface. Q. J. R. Meteorol. Soc. 122, 1127-1151.
    """
    t = np.asarray(air_temperature_k, dtype=float)
    w = 46.5 * _vapour_hpa(t, relative_humidity) / t
    return 1.0 - (1.0 + w) * np.exp(-np.sqrt(1.2 + 3.0 * w))


def dilley_obrien_emissivity(air_temperature_k, relative_humidity):
    """Clear-sky emissivity from Dilley & O'Brien (1998):
    L = 59.38 + 113.7 (T / 273.16)^6 + 96.96 sqrt(w / 25) [W m^-2], w = 4650 e / T the
    precipitable water [kg m^-2] (e [kPa], T [K]); eps = L / (sigma T^4).

    References
    ----------
    .. [1] Dilley, A. C., O'Brien, D. M. (1998). Estimating downward clear sky long-wave
       irradiance at the surface from screen temperature and precipitable water. Q. J. R.
       Meteorol. Soc. 124, 1391-1401.
    """
    t = np.asarray(air_temperature_k, dtype=float)
    w = 4650.0 * _vapour_hpa(t, relative_humidity) / 10.0 / t
    flux = 59.38 + 113.7 * (t / 273.16) ** 6 + 96.96 * np.sqrt(w / 25.0)
    return flux / (STEFAN_BOLTZMANN * t**4)


def empirical_sky_emissivities(air_temperature_k, relative_humidity) -> dict:
    """The clear-sky emissivity of each empirical formula from screen-level air temperature
    and humidity: Brunt (1932), Swinbank (1963), Idso & Jackson (1969), Brutsaert (1975),
    Idso (1981), Berdahl & Martin (1984), Prata (1996), Dilley & O'Brien (1998). Their spread is the usual check of a
    modelled downwelling long wave (Flerchinger et al. 2009, Water Resour. Res. 45, W03423:
    the formulas scatter by +-5 % around clear-sky pyrgeometer data)."""
    t, rh = air_temperature_k, relative_humidity
    return {
        "brunt": brunt_emissivity(t, rh),
        "swinbank": swinbank_emissivity(t),
        "idsoJackson": idso_jackson_emissivity(t),
        "brutsaert": brutsaert_emissivity(t, rh),
        "idso": idso_emissivity(t, rh),
        "berdahlMartin": effective_sky_temperature(t, rh)[1],
        "prata": prata_emissivity(t, rh),
        "dilleyObrien": dilley_obrien_emissivity(t, rh),
    }


def tilted_irradiance(zenith_deg, radiance, tilt_deg):
    """Irradiance from the sky on planes tilted from the horizontal [W m^-2].

    Parameters
    ----------
    zenith_deg, radiance : array (Z,)
        The sky against zenith [deg] (ascending within 0-90) and its radiance, azimuthally
        uniform [W m^-2 sr^-1] (the atmosphere layer's ``skyLongwaveRadiance``), interpolated
        as :func:`hemispherical_irradiance` does (np.interp, held beyond the nodes).
    tilt_deg : numeric
        Angle between each plane's normal and the zenith [deg], 0 (facing up) to 180.

    Returns
    -------
    numpy.ndarray
        E(beta) = int_sky L(theta) max(0, cos(beta) cos(theta) + sin(beta) sin(theta)
        cos(phi)) dOmega over the sky hemisphere (theta < 90 deg) only; the ground's share
        is the caller's.

    Notes
    -----
    The azimuthal integral is closed: with a = cos(beta) cos(theta), b = sin(beta) sin(theta),
    K = 2 pi a for a >= b, 0 for a <= -b, else 2 (a phi0 + b sin phi0), phi0 = arccos(-a/b).
    The zenith integral of L(theta) sin(theta) K is Gauss-Legendre (24 points) on the pieces
    between the table's nodes and the kink at theta = |90 deg - beta|, so it is exact to
    rounding for the interpolated table. An isotropic sky gives E = E_h (1 + cos beta) / 2
    (Duffie & Beckman 2013, Eq. 2.16.2); the real clear sky is brighter towards the horizon
    (Martin & Berdahl 1984), so walls see more than half the horizontal sky irradiance.
    """
    th_nodes, val = extended_sky_table(zenith_deg, radiance)
    x, w = np.polynomial.legendre.leggauss(24)
    out = []
    for beta in np.radians(np.atleast_1d(np.asarray(tilt_deg, dtype=float))):
        kinks = [k for k in (np.pi / 2 - beta, beta - np.pi / 2) if 0.0 < k < np.pi / 2]
        br = np.unique(np.r_[th_nodes, kinks])
        lo, hi = br[:-1, None], br[1:, None]
        th = (0.5 * (hi - lo) * x[None, :] + 0.5 * (hi + lo)).ravel()
        wt = (0.5 * (hi - lo) * w[None, :]).ravel()
        a, b = np.cos(beta) * np.cos(th), np.sin(beta) * np.sin(th)
        with np.errstate(divide="ignore", invalid="ignore"):
            phi0 = np.arccos(np.clip(-a / np.where(b > 0, b, 1.0), -1.0, 1.0))
        k = np.where(a >= b, 2 * np.pi * a, np.where(a <= -b, 0.0, 2.0 * (a * phi0 + b * np.sin(phi0))))
        out.append(float(np.sum(wt * np.interp(th, th_nodes, val) * np.sin(th) * k)))
    return np.asarray(out)
