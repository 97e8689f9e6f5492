"""Planck's law: spectral and band radiance of a blackbody, and brightness temperature.

Pure numpy, SI units except wavelengths, which are in micrometres [um] as at every HumV-USD
interface. Spectral radiance is per micrometre, band radiance is the spectral radiance integrated
over a band (optionally weighted by a relative spectral response).

The band integrals use composite Gauss-Legendre quadrature whose panel width follows the
steepness of the Wien tail at the lowest requested temperature, so they are accurate to about
1e-12 relative from 1 K to 5000 K. :func:`brightness_temperature` inverts :func:`band_radiance`
with a monotone table (log radiance against log temperature, cubic Hermite with exact slopes)
followed by Newton steps on the same quadrature, so the two are inverse to rounding.
"""

from __future__ import annotations

import functools

import numpy as np

from humv_usd.constants import (
    BOLTZMANN_CONSTANT,
    EMISSIVITY_WEIGHTING_TEMPERATURE_K,
    PLANCK_CONSTANT,
    SPEED_OF_LIGHT,
)

#: First radiation constant for spectral radiance, 2 h c^2, expressed for wavelengths in um and
#: radiance per um: [W m^-2 sr^-1 um^-1 um^5] = [W m^2 sr^-1] * 1e24 (m^5 -> um^5) * 1e-6 (/m -> /um).
C1L = 2.0 * PLANCK_CONSTANT * SPEED_OF_LIGHT**2 * 1e24
#: Second radiation constant h c / k [um K].
C2 = PLANCK_CONSTANT * SPEED_OF_LIGHT / BOLTZMANN_CONSTANT * 1e6

_GL_ORDER = 8
_GL_X, _GL_W = np.polynomial.legendre.leggauss(_GL_ORDER)
#: Panel width is chosen so the exponent c2/(lambda T) changes by at most this much per panel.
_MAX_EXPONENT_STEP = 1.0
_MIN_PANELS = 8
#: Below this largest exponent hc/(lambda k T) the band sum runs in linear space (no underflow).
_LINEAR_MAX_EXPONENT = 500.0
_MAX_PANELS = 8192


def spectral_radiance(wavelength_um, temperature_k):
    r"""Spectral radiance of a blackbody (Planck's law).

    Parameters
    ----------
    wavelength_um : numeric
        Wavelength [um], > 0.
    temperature_k : numeric
        Temperature [K], > 0. Broadcasts against ``wavelength_um``.

    Returns
    -------
    numeric
        Spectral radiance [W m^-2 sr^-1 um^-1].

    Notes
    -----
    .. math::

        L_\lambda(\lambda, T) = \frac{2 h c^2}{\lambda^5}
            \frac{1}{\exp\left(\frac{h c}{\lambda k T}\right) - 1}

    with the CODATA 2018 values of :math:`h`, :math:`c` and :math:`k` (exact in the SI since
    2019). ``expm1`` keeps the Rayleigh-Jeans end accurate; the Wien end underflows to 0 without
    a warning.

    References
    ----------
    .. [1] M. Planck, "Ueber das Gesetz der Energieverteilung im Normalspectrum", Annalen der
       Physik 309(3), 553-563, 1901.
    .. [2] E. Tiesinga, P. J. Mohr, D. B. Newell, B. N. Taylor, "CODATA recommended values of
       the fundamental physical constants: 2018", Rev. Mod. Phys. 93, 025010, 2021.
    """
    wavelength_um = np.asarray(wavelength_um, dtype=float)
    temperature_k = np.asarray(temperature_k, dtype=float)
    with np.errstate(over="ignore"):
        return C1L / wavelength_um**5 / np.expm1(C2 / (wavelength_um * temperature_k))


def _check_band(band_um):
    band = np.asarray(band_um, dtype=float)
    if band.shape != (2,) or not np.all(np.isfinite(band)) or not 0 < band[0] < band[1]:
        raise ValueError(f"band_um = {band_um!r}: expected (lower, upper) [um] with 0 < lower < upper")
    return float(band[0]), float(band[1])


def _check_response(response):
    if response is None:
        return None
    try:
        wl, r = response
    except (TypeError, ValueError):
        raise ValueError("response must be None or a pair (wavelengths_um, values)") from None
    wl = np.asarray(wl, dtype=float).ravel()
    r = np.asarray(r, dtype=float).ravel()
    if wl.size < 2 or wl.size != r.size:
        raise ValueError(f"response: expected two arrays of the same length >= 2, got {wl.size} and {r.size}")
    if not (np.all(np.isfinite(wl)) and np.all(np.isfinite(r))):
        raise ValueError("response: values must be finite")
    if np.any(np.diff(wl) <= 0):
        raise ValueError("response: wavelengths must be strictly ascending")
    if np.any(r < 0):
        raise ValueError("response: values must be >= 0")
    return wl, r


def _panel_count(lower, upper, tmin):
    """Panels so the Wien exponent c2/(lambda T), linear in 1/lambda, changes by at most
    _MAX_EXPONENT_STEP per panel."""
    span = C2 * (1.0 / lower - 1.0 / upper) / max(tmin, 1e-3)
    n = int(np.ceil(span / _MAX_EXPONENT_STEP))
    return int(np.clip(n, _MIN_PANELS, _MAX_PANELS))


def _nodes(band, response, tmin, extra_breaks=()):
    """Quadrature nodes [um] and weights [um] (response folded in) over the band.

    Composite Gauss-Legendre in the wavenumber-like variable u = 1/lambda, in which the Planck
    exponent is linear; panels are equal in u, and also break at the response wavelengths and at
    ``extra_breaks`` inside the band so that tabulated factors have their kinks on panel edges.
    """
    lower, upper = band
    breaks = [lower, upper] + [v for v in extra_breaks if lower < v < upper]
    if response is not None:
        breaks += [v for v in response[0] if lower < v < upper]
    u_breaks = np.unique(1.0 / np.asarray(breaks, dtype=float))  # ascending u
    total = _panel_count(lower, upper, tmin)
    u_span = 1.0 / lower - 1.0 / upper
    xs, ws = [], []
    for a, b in zip(u_breaks[:-1], u_breaks[1:]):
        n = max(1, int(np.ceil(total * (b - a) / u_span)))
        edges = np.linspace(a, b, n + 1)
        half = 0.5 * np.diff(edges)
        mid = 0.5 * (edges[:-1] + edges[1:])
        xs.append((mid[:, None] + half[:, None] * _GL_X[None, :]).ravel())
        ws.append((half[:, None] * _GL_W[None, :]).ravel())
    u = np.concatenate(xs)
    x = 1.0 / u
    w = np.concatenate(ws) * x * x  # d lambda = du / u^2
    if response is not None:
        w = w * np.interp(x, response[0], response[1], left=0.0, right=0.0)
    return x, w


def _log_planck_terms(x_um, t_k):
    """log of the spectral radiance and d log L / d log T at nodes x for temperatures t.

    Shapes: x (n,), t (m,) -> (m, n). Computed in log space so that nothing underflows.
    """
    z = C2 / (x_um[None, :] * t_k[:, None])  # hc / (lambda k T)
    # log(expm1(z)) without overflow: z + log(1 - exp(-z)) = z + log(-expm1(-z))
    log_expm1 = z + np.log(-np.expm1(-z))
    log_l = np.log(C1L) - 5.0 * np.log(x_um)[None, :] - log_expm1
    # d log L / d log T = z / (1 - exp(-z))
    dlog = z / (-np.expm1(-z))
    return log_l, dlog


def _log_band(t_k, band, response, chunk=4096):
    """log band radiance and d log L_band / d log T for a 1-d array of temperatures."""
    t_k = np.asarray(t_k, dtype=float)
    log_l = np.empty_like(t_k)
    dlog = np.empty_like(t_k)
    order = np.argsort(t_k)
    for start in range(0, t_k.size, chunk):
        idx = order[start : start + chunk]
        tt = t_k[idx]
        x, w = _nodes(band, response, float(tt.min()))
        keep = w > 0
        x, w = x[keep], w[keep]
        if x.size == 0:
            log_l[idx] = -np.inf
            dlog[idx] = np.nan
            continue
        if C2 / (x.min() * tt.min()) < _LINEAR_MAX_EXPONENT:
            # fast path: nothing underflows, sum in linear space
            em1 = np.expm1(C2 / (x[None, :] * tt[:, None]))
            wb = (w * C1L / x**5)[None, :] / em1  # w * spectral radiance
            total = wb.sum(axis=1)
            z = C2 / (x[None, :] * tt[:, None])
            log_l[idx] = np.log(total)
            dlog[idx] = (wb * z * (1.0 + 1.0 / em1)).sum(axis=1) / total
            continue
        terms, d = _log_planck_terms(x, tt)
        terms = terms + np.log(w)[None, :]
        peak = terms.max(axis=1, keepdims=True)
        e = np.exp(terms - peak)
        s = e.sum(axis=1)
        log_l[idx] = peak[:, 0] + np.log(s)
        dlog[idx] = (e * d).sum(axis=1) / s
    return log_l, dlog


def _temperatures(temperature_k):
    t = np.asarray(temperature_k, dtype=float)
    if np.any(~(t > 0)):
        raise ValueError("temperature_k must be > 0 and not NaN")
    return t


def band_radiance(temperature_k, band_um, response=None):
    r"""Blackbody radiance integrated over a spectral band.

    Parameters
    ----------
    temperature_k : numeric
        Temperature [K], > 0.
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)`` [um], [unitless, 0-1],
        linearly interpolated and zero outside its wavelengths. ``None`` means 1 over the band.

    Returns
    -------
    numeric
        Band radiance [W m^-2 sr^-1], same shape as ``temperature_k``.

    Notes
    -----
    .. math::

        L_b(T) = \int_{\lambda_1}^{\lambda_2} R(\lambda)\, L_\lambda(\lambda, T)\, d\lambda

    with :math:`L_\lambda` from :func:`spectral_radiance` (Planck's law, CODATA 2018 constants).
    The response is not normalised: a peak-normalised response gives the in-band radiance seen by
    that sensor. Quadrature: composite 8-point Gauss-Legendre in :math:`1/\lambda`, panels split at
    the response wavelengths and narrow enough that :math:`hc/(\lambda k T)` changes by at most 1
    per panel.

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    .. [2] E. Tiesinga et al., "CODATA recommended values of the fundamental physical constants:
       2018", Rev. Mod. Phys. 93, 025010, 2021.
    """
    band = _check_band(band_um)
    resp = _check_response(response)
    t = _temperatures(temperature_k)
    log_l, _ = _log_band(t.ravel(), band, resp)
    out = np.exp(log_l).reshape(t.shape)
    return out if out.ndim else float(out)


def band_radiance_derivative(temperature_k, band_um, response=None):
    r"""Derivative of :func:`band_radiance` with respect to temperature.

    Parameters
    ----------
    temperature_k : numeric
        Temperature [K], > 0.
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)``, see :func:`band_radiance`.

    Returns
    -------
    numeric
        :math:`dL_b/dT` [W m^-2 sr^-1 K^-1].

    Notes
    -----
    .. math::

        \frac{dL_b}{dT} = \int R\, L_\lambda \frac{x}{T\,(1 - e^{-x})}\, d\lambda,
        \qquad x = \frac{h c}{\lambda k T}

    (Planck's law differentiated in T), same quadrature as :func:`band_radiance`.

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    """
    band = _check_band(band_um)
    resp = _check_response(response)
    t = _temperatures(temperature_k)
    flat = t.ravel()
    log_l, dlog = _log_band(flat, band, resp)
    out = (np.exp(log_l) * dlog / flat).reshape(t.shape)
    return out if out.ndim else float(out)


def band_emissivity(
    wavelengths_um, emissivity, band_um, response=None, temperature_k=EMISSIVITY_WEIGHTING_TEMPERATURE_K
):
    r"""Planck-weighted band average of a spectral emissivity.

    Parameters
    ----------
    wavelengths_um : array-like
        Wavelengths of the emissivity table [um], ascending.
    emissivity : array-like
        Spectral emissivity at those wavelengths [unitless, 0-1]; linear in between, held
        constant beyond the ends (a single value is a gray body).
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)``, see :func:`band_radiance`.
    temperature_k : float, default :data:`humv_usd.constants.EMISSIVITY_WEIGHTING_TEMPERATURE_K` (300)
        Temperature of the weighting blackbody [K].

    Returns
    -------
    float
        Band emissivity [unitless, 0-1].

    Notes
    -----
    .. math::

        \varepsilon_b = \frac{\int \varepsilon(\lambda) R(\lambda) L_\lambda(\lambda, T)\,d\lambda}
                             {\int R(\lambda) L_\lambda(\lambda, T)\,d\lambda}

    The true emitted band radiance of a non-gray surface is only approximately
    :math:`\varepsilon_b L_b(T)` when the surface temperature differs from the weighting
    temperature; narrower sub-bands reduce that error.

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    """
    eps = np.atleast_1d(np.asarray(emissivity, dtype=float))
    if eps.ndim != 1:
        raise ValueError(f"emissivity must be one spectrum, got shape {eps.shape}")
    return float(band_weighted_mean(wavelengths_um, eps, band_um, response, temperature_k))


def band_weighted_mean(
    wavelengths_um, values, band_um, response=None, temperature_k=EMISSIVITY_WEIGHTING_TEMPERATURE_K
):
    r"""Planck- and response-weighted band mean of spectral tables (an emissivity, a path
    transmittance): :math:`\int f R L_\lambda(T)\,d\lambda / \int R L_\lambda(T)\,d\lambda`
    (:func:`band_emissivity` for one spectrum).

    Parameters
    ----------
    wavelengths_um : array-like (W,)
        Wavelengths of the tables [um], ascending.
    values : array-like (..., W)
        Tables on those wavelengths (linear in between, held constant beyond the ends; W = 1 is
        a constant).
    band_um, response, temperature_k
        As :func:`band_emissivity`.

    Returns
    -------
    ndarray (...)
        The band means.

    Notes
    -----
    The quadrature of :func:`band_radiance` (Gauss-Legendre panels in 1/lambda) with a panel
    edge at every table wavelength inside the band, so a piecewise-linear table is integrated
    without a kink inside a panel.
    """
    band = _check_band(band_um)
    resp = _check_response(response)
    wl = np.atleast_1d(np.asarray(wavelengths_um, dtype=float))
    v = np.asarray(values, dtype=float)
    if v.ndim == 0:
        v = v[None]
    if wl.size != v.shape[-1] or wl.size == 0:
        raise ValueError(
            f"wavelengths_um and the tables' last axis must have the same length >= 1, "
            f"got {wl.size} and {v.shape[-1]}"
        )
    if wl.size > 1 and np.any(np.diff(wl) <= 0):
        raise ValueError("wavelengths_um must be strictly ascending")
    x, w = _nodes(band, resp, float(temperature_k), extra_breaks=wl if wl.size > 1 else ())
    lam = spectral_radiance(x, float(temperature_k)) * w
    denominator = lam.sum()
    if not denominator > 0:
        raise ValueError(f"band {band} has no response: cannot weight the emissivity")
    if wl.size == 1:
        return v[..., 0].copy()
    flat = v.reshape(-1, wl.size)
    at_x = np.stack([np.interp(x, wl, row) for row in flat])
    return ((at_x @ lam) / denominator).reshape(v.shape[:-1])


# --- inverse --------------------------------------------------------------------------------

_TABLE_T_MIN = 0.5  # [K]
_TABLE_T_MAX = 20000.0  # [K]
_TABLE_SIZE = 2049
_NEWTON_TOL = 1e-9  # on the last step in log T; the error after it is about its square
_NEWTON_MAX_ITER = 30


def _key(band, response):
    if response is None:
        return band, None
    return band, (tuple(response[0].tolist()), tuple(response[1].tolist()))


@functools.lru_cache(maxsize=256)
def _table(key):
    """log T, log L_band and d log L / d log T on a log-spaced temperature grid."""
    band, resp = key
    response = None if resp is None else (np.asarray(resp[0]), np.asarray(resp[1]))
    log_t = np.linspace(np.log(_TABLE_T_MIN), np.log(_TABLE_T_MAX), _TABLE_SIZE)
    log_l, dlog = _log_band(np.exp(log_t), band, response, chunk=64)
    if not np.all(np.diff(log_l) > 0):  # cannot happen for a band with response > 0
        raise ValueError(f"band {band}: band radiance is not increasing with temperature")
    return log_t, log_l, dlog


def _hermite_inverse(y, table):
    """log T at log radiance y by cubic Hermite interpolation of the table (slopes exact)."""
    log_t, log_l, dlog = table
    i = np.clip(np.searchsorted(log_l, y) - 1, 0, log_l.size - 2)
    y0, y1 = log_l[i], log_l[i + 1]
    s0, s1 = log_t[i], log_t[i + 1]
    m0, m1 = 1.0 / dlog[i], 1.0 / dlog[i + 1]  # d log T / d log L
    h = y1 - y0
    u = (y - y0) / h
    inside = (u >= 0) & (u <= 1)
    h00 = 2 * u**3 - 3 * u**2 + 1
    h10 = u**3 - 2 * u**2 + u
    h01 = -2 * u**3 + 3 * u**2
    h11 = u**3 - u**2
    s = h00 * s0 + h10 * h * m0 + h01 * s1 + h11 * h * m1
    # outside the table: first-order extrapolation, Newton finishes the job
    below = y < log_l[0]
    above = y > log_l[-1]
    s = np.where(below, log_t[0] + (y - log_l[0]) / dlog[0], s)
    s = np.where(above, log_t[-1] + (y - log_l[-1]) / dlog[-1], s)
    return np.where(inside | below | above, s, np.nan)


def _invert(radiance, band, response):
    """Brightness temperature [K] and d L_band / d T [W m^-2 sr^-1 K^-1] for radiances > 0."""
    table = _table(_key(band, response))
    y = np.log(radiance)
    s = _hermite_inverse(y, table)
    dlog = np.empty_like(s)
    todo = np.arange(s.size)
    for _ in range(_NEWTON_MAX_ITER):
        if todo.size == 0:
            break
        log_l, d = _log_band(np.exp(s[todo]), band, response)
        step = (log_l - y[todo]) / d
        # guard the first steps far outside the table
        step = np.clip(step, -1.0, 1.0)
        s[todo] -= step
        dlog[todo] = d
        todo = todo[np.abs(step) > _NEWTON_TOL]
    t = np.exp(s)
    return t, radiance * dlog / t


def brightness_temperature(radiance, band_um, response=None):
    r"""Temperature of the blackbody whose band radiance equals the given radiance.

    The exact inverse of :func:`band_radiance` (to rounding) for the same band and response.

    Parameters
    ----------
    radiance : numeric
        Band radiance [W m^-2 sr^-1].
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)``, see :func:`band_radiance`.

    Returns
    -------
    numeric
        Brightness temperature [K]; 0 where ``radiance <= 0``, NaN where it is NaN, inf where
        it is inf.

    Notes
    -----
    Solves :math:`L_b(T_b) = L` for :math:`T_b` (:math:`L_b` from :func:`band_radiance`, Planck's
    law with CODATA 2018 constants). A table of :math:`\ln L_b` against :math:`\ln T` (0.5 K to
    20 000 K, 2049 points, strictly increasing) gives a start by cubic Hermite interpolation with
    the exact slopes :math:`d\ln L_b/d\ln T`; Newton steps on :math:`\ln T` with the same
    quadrature as :func:`band_radiance` polish it to about 1e-15 relative. Radiances outside the table
    are reached by Newton steps from its ends.

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    .. [2] E. Tiesinga et al., Rev. Mod. Phys. 93, 025010, 2021 (CODATA 2018).
    """
    t, _ = _brightness_and_slope(radiance, band_um, response)
    return t if t.ndim else float(t)


def brightness_temperature_sensitivity(radiance, band_um, response=None):
    r"""Brightness temperature and the band radiance derivative there, in one pass.

    Parameters
    ----------
    radiance : numeric
        Band radiance [W m^-2 sr^-1].
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)``, see :func:`band_radiance`.

    Returns
    -------
    temperature_k : numeric
        Brightness temperature [K], as :func:`brightness_temperature`.
    derivative : numeric
        :math:`dL_b/dT` at that temperature [W m^-2 sr^-1 K^-1] (NaN where the temperature is
        0, NaN or inf). A radiance uncertainty divided by it is a temperature uncertainty [K].

    Notes
    -----
    Same solver as :func:`brightness_temperature`; the derivative comes from its last Newton
    step, as :func:`band_radiance_derivative` would give it.

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    """
    t, d = _brightness_and_slope(radiance, band_um, response)
    return (t, d) if t.ndim else (float(t), float(d))


def _brightness_and_slope(radiance, band_um, response):
    band = _check_band(band_um)
    resp = _check_response(response)
    radiance = np.asarray(radiance, dtype=float)
    flat = radiance.ravel()
    t = np.full(flat.shape, np.nan)
    d = np.full(flat.shape, np.nan)
    t[flat <= 0] = 0.0
    t[np.isposinf(flat)] = np.inf
    ok = np.isfinite(flat) & (flat > 0)
    if np.any(ok):
        t[ok], d[ok] = _invert(flat[ok], band, resp)
    return t.reshape(radiance.shape), d.reshape(radiance.shape)


# --- tabulated band radiance and its inverse (per-frame speed) -----------------------------------


def band_table(band_um, response=None):
    """The cached table of a band (and response): log T [ln K] on a uniform grid (0.5 K to
    20 000 K, 2049 points), log band radiance and d log L_band / d log T there (exact quadrature).
    Built once per band and response (about 10 ms), shared by :func:`band_radiance_tabulated`,
    :func:`brightness_temperature_tabulated` and the Newton start of :func:`brightness_temperature`."""
    return _table(_key(_check_band(band_um), _check_response(response)))


def _segment(x, grid):
    """Index i of the uniform-grid segment [grid[i], grid[i+1]] holding x (clipped) and the
    position u = (x - grid[i]) / step in it."""
    step = grid[1] - grid[0]
    f = (x - grid[0]) / step
    i = np.clip(f.astype(np.intp), 0, grid.size - 2)
    return i, f - i


def _hermite(u, y0, y1, m0, m1, h):
    """Cubic Hermite on a segment of width h: values y0, y1 and slopes m0, m1 at its ends."""
    u2 = u * u
    u3 = u2 * u
    return (
        (2 * u3 - 3 * u2 + 1) * y0 + (u3 - 2 * u2 + u) * h * m0 + (-2 * u3 + 3 * u2) * y1 + (u3 - u2) * h * m1
    )


def band_radiance_tabulated(temperature_k, band_um, response=None):
    r""":func:`band_radiance` from the band's table (:func:`band_table`): the same value to about
    1e-9 relative, at the cost of an interpolation.

    Parameters
    ----------
    temperature_k : numeric
        Temperature [K], > 0.
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)``, see :func:`band_radiance`.

    Returns
    -------
    numeric
        Band radiance [W m^-2 sr^-1], same shape as ``temperature_k``.

    Notes
    -----
    Cubic Hermite interpolation of :math:`\ln L_b` against :math:`\ln T` with the exact slopes
    :math:`d\ln L_b/d\ln T` on a uniform grid of step 0.0052 (0.5 K to 20 000 K); the
    interpolation error is about :math:`h^4/384\,|d^4 \ln L_b/d(\ln T)^4|`, below 1e-8 relative
    over the grid (``tests/test_planck.py`` checks 1e-6 against :func:`band_radiance`).
    Temperatures outside the grid take the exact quadrature.

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    """
    t = _temperatures(temperature_k)
    log_t, log_l, dlog = band_table(band_um, response)
    flat = t.ravel()
    s = np.log(flat)
    i, u = _segment(s, log_t)
    out = np.exp(_hermite(u, log_l[i], log_l[i + 1], dlog[i], dlog[i + 1], log_t[1] - log_t[0]))
    outside = (s < log_t[0]) | (s > log_t[-1])
    if np.any(outside):
        out[outside] = band_radiance(flat[outside], band_um, response)
    out = out.reshape(t.shape)
    return out if out.ndim else float(out)


def brightness_temperature_tabulated(radiance, band_um, response=None):
    r"""Brightness temperature and :math:`dL_b/dT` there, from the band's table: what
    :func:`brightness_temperature_sensitivity` gives (to < 1e-4 K and 1e-4 relative, tested), about
    ten times faster, for whole frames.

    Parameters
    ----------
    radiance : numeric
        Band radiance [W m^-2 sr^-1].
    band_um : array-like of 2 floats
        Band limits (lower, upper) [um].
    response : tuple of two array-like, optional
        Relative spectral response ``(wavelengths_um, values)``, see :func:`band_radiance`.

    Returns
    -------
    temperature_k : numeric
        Brightness temperature [K]; 0 where ``radiance <= 0``, NaN where NaN, inf where inf.
    derivative : numeric
        :math:`dL_b/dT` [W m^-2 sr^-1 K^-1] (NaN where the temperature is 0, NaN or inf).

    Notes
    -----
    :math:`\ln T` at :math:`\ln L` by cubic Hermite interpolation of the table of
    :func:`band_table` with the exact slopes :math:`d\ln T/d\ln L = 1/(d\ln L_b/d\ln T)`
    (error about 1e-9 in :math:`\ln T`); :math:`d\ln L_b/d\ln T` at that temperature by linear
    interpolation (error about :math:`h^2/8` = 3e-6 relative), so
    :math:`dL_b/dT = L\,(d\ln L_b/d\ln T)/T`. Radiances beyond the table (below 0.5 K or above
    20 000 K) take the exact inversion (Newton on the quadrature).

    References
    ----------
    .. [1] M. Planck, Annalen der Physik 309(3), 553-563, 1901.
    """
    band = _check_band(band_um)
    resp = _check_response(response)
    radiance = np.asarray(radiance, dtype=float)
    flat = radiance.ravel()
    table = _inverse_table(_key(band, resp))
    y0, y1 = table.y_first, table.y_last
    with np.errstate(divide="ignore", invalid="ignore"):
        y = np.log(flat)
    if flat.size and y.min() >= y0 and y.max() <= y1:  # a frame: every radiance in the table
        t, d = _tabulated_inverse(y, flat, table)
    else:
        t = np.full(flat.shape, np.nan)
        d = np.full(flat.shape, np.nan)
        t[flat <= 0] = 0.0
        t[np.isposinf(flat)] = np.inf
        ok = np.isfinite(flat) & (flat > 0)
        inside = ok & (y >= y0) & (y <= y1)
        if np.any(inside):
            t[inside], d[inside] = _tabulated_inverse(y[inside], flat[inside], table)
        beyond = ok & ~inside
        if np.any(beyond):  # below 0.5 K or above 20 000 K: the exact inversion
            t[beyond], d[beyond] = _invert(flat[beyond], band, resp)
    t, d = t.reshape(radiance.shape), d.reshape(radiance.shape)
    return (t, d) if t.ndim else (float(t), float(d))


class _InverseTable:
    """Per-segment cubic coefficients of log T against log L, and a uniform index in log L."""

    def __init__(self, log_t, log_l, dlog):
        h = np.diff(log_l)
        s0, s1 = log_t[:-1], log_t[1:]
        m0, m1 = 1.0 / dlog[:-1], 1.0 / dlog[1:]  # d log T / d log L at the segment's ends
        # Hermite in Horner form on u = (y - y_i) / h_i: s = c0 + u (c1 + u (c2 + u c3))
        c1 = h * m0
        c2 = 3.0 * (s1 - s0) - h * (2.0 * m0 + m1)
        c3 = 2.0 * (s0 - s1) + h * (m0 + m1)
        step = log_t[1] - log_t[0]
        # columns: y_i, 1/h_i, c0..c3, d log L/d log T at the start, its change per unit of (s - s_i)/step
        self.rows = np.stack([log_l[:-1], 1.0 / h, s0, c1, c2, c3, dlog[:-1], np.diff(dlog)], axis=1)
        self.columns = [np.ascontiguousarray(c) for c in self.rows.T]
        self.inv_step = 1.0 / step
        self.y_first, self.y_last = float(log_l[0]), float(log_l[-1])
        # index: bins narrower than every segment, so a bin holds at most one segment start
        self.dy = 0.5 * float(h.min())
        bins = int(np.ceil((self.y_last - self.y_first) / self.dy)) + 1
        starts = self.y_first + self.dy * np.arange(bins)
        self.first = np.clip(np.searchsorted(log_l, starts, side="right") - 1, 0, h.size - 1).astype(np.int32)
        self.next_start = np.append(log_l[1:-1], np.inf)  # where segment i ends (the last: never)


@functools.lru_cache(maxsize=32)
def _inverse_table(key) -> _InverseTable:
    return _InverseTable(*_table(key))


def _tabulated_inverse(y, radiance, table: _InverseTable):
    """(T [K], dL/dT) at log radiances ``y`` inside the table (:func:`brightness_temperature_tabulated`).
    One column of the table gathered at a time, arithmetic in place (a frame's million pixels:
    3x faster than gathering whole rows; the same numbers)."""
    cols = table.columns
    j = ((y - table.y_first) * (1.0 / table.dy)).astype(np.intp)
    np.minimum(j, table.first.size - 1, out=j)
    i = table.first.take(j).astype(np.intp)
    i += y >= table.next_start.take(i)  # a bin starts in one segment and may end in the next
    u = y - cols[0].take(i)
    u *= cols[1].take(i)
    s = cols[5].take(i)  # Horner: c0 + u (c1 + u (c2 + u c3))
    for k in (4, 3):
        s *= u
        s += cols[k].take(i)
    s *= u
    c0 = cols[2].take(i)
    s += c0
    slope = s - c0  # d log L / d log T, linear in log T
    slope *= table.inv_step
    slope *= cols[7].take(i)
    slope += cols[6].take(i)
    t = np.exp(s)
    slope *= radiance
    slope /= t
    return t, slope
