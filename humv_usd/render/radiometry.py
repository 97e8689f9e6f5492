"""Spectral radiometry of the render in plain numpy: sub-bands, atmosphere per range, sky, sun.

A sensor band :math:`[\\lambda_1, \\lambda_2]` with relative response :math:`R(\\lambda)` is split
into :math:`N` equal-width sub-bands :math:`k` (those where :math:`R` vanishes are dropped). Each
sub-band is rendered as a gray band (Mitsuba mono variant) and the at-sensor radiance is

.. math::

    L = \\sum_k \\tau_k(r)\\, S_k + P_k(r)

where :math:`S_k` is the rendered surface-leaving radiance of sub-band :math:`k`,
:math:`r` the range of the pixel's surface, and the sub-band quantities are

- emitted: :math:`\\varepsilon_k L_k(T)` with :math:`L_k(T) = \\int_k R\\, B(\\lambda, T)\\,d\\lambda`
  (Planck, exact quadrature) and :math:`\\varepsilon_k` the Planck(300 K)- and response-weighted
  mean emissivity over the sub-band; reflectance :math:`1 - \\varepsilon_k` (Kirchhoff, opaque);
- sky, path radiance, sun: exact integrals :math:`\\int_k R\\, f(\\lambda)\\, d\\lambda` of the
  tabulated spectra (W m-2 sr-1 or W m-2 per sub-band);
- transmittance :math:`\\tau_k`: the Planck(300 K)- and response-weighted mean over the sub-band.

Only the products (emissivity x Planck, reflectance x sky, transmittance x surface radiance) are
approximated by products of sub-band means; the approximation error falls as :math:`N` grows
(:func:`subband_error` measures it against a fine spectral quadrature; ``humv-usd bench render``).

References: Planck's law, see :mod:`humv_usd.physics.planck`; radiative transfer along a path
without scattering into the beam other than the tabulated path radiance,
:math:`L_{sensor} = \\tau L_{surface} + L_{path}` (e.g. Schott, *Remote Sensing: The Image Chain
Approach*, 2nd ed., Oxford UP 2007, eq. 4.62 "big equation").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.compat import trapezoid
from humv_usd.constants import EMISSIVITY_WEIGHTING_TEMPERATURE_K, STEFAN_BOLTZMANN, SUN_TEMPERATURE_K
from humv_usd.physics import planck
from humv_usd.render import cie
from humv_usd.scenario import spec as _spec

#: Sub-bands per IR band when the render option does not say otherwise; chosen from
#: ``humv-usd bench render`` on humvvex (LOWTRAN7 sky and paths) against a 32-sub-band path-tracer
#: reference: with 4 the region means are off by up to 0.04 K (LWIR 640) and 0.05 K (MWIR), the
#: spectral error of the sub-band model; with 16 by at most 0.003 K (LWIR) and 0.017 K (MWIR).
#: The fast estimator traces one path for all sub-bands, so 16 cost about 2.3x the CPU of 4.
#: (The value lives in :mod:`humv_usd.scenario.spec`, the default of the sensor key ``subbands``.)
DEFAULT_SUBBANDS = _spec.DEFAULT_SUBBANDS
#: Largest accepted sub-band count.
MAX_SUBBANDS = _spec.MAX_SUBBANDS
#: Bands ending at or below this wavelength [um] are rendered from reflected light first (NIR,
#: SWIR): a face or sky without a temperature (no thermal layer; the scenario asks for none
#: without a MWIR/LWIR sensor) emits nothing there instead of NaN. At 2.5 um a 310 K surface
#: emits 0.3 % of the radiance of a white one under a 1000 W m-2 sun.
REFLECTIVE_LIMIT_UM = 2.5
#: Uniform quadrature nodes per sub-band (table and response wavelengths are added).
NODES_PER_SUBBAND = 65


def _response_at(response, x):
    if response is None:
        return np.ones_like(x)
    return np.interp(x, response[0], response[1], left=0.0, right=0.0)


def _response_trapezoid(lo: float, hi: float, n: int, tables, response):
    """Trapezoid-rule nodes x [um] and weights R(x) dx [um] over [lo, hi]: ``n`` even nodes plus
    every wavelength of ``tables`` (and of the response table) inside the interval, so the
    piecewise-linear tables are integrated exactly where they break."""
    pts = [np.linspace(lo, hi, n)]
    for table in list(tables) + ([] if response is None else [response[0]]):
        t = np.asarray(table, dtype=float)
        pts.append(t[(t > lo) & (t < hi)])
    x = np.unique(np.concatenate(pts))
    dx = np.diff(x)
    w = np.zeros_like(x)
    w[:-1] += 0.5 * dx
    w[1:] += 0.5 * dx
    return x, w * _response_at(response, x)


class SubBands:
    """Equal-width sub-bands of a sensor band with the sensor response folded into the weights.

    Parameters
    ----------
    band : (float, float)
        Band limits [um].
    response : (wavelengths_um, values) or None
        Relative spectral response (linear, zero outside its table); None is 1 over the band.
    n : int
        Requested sub-band count; sub-bands where the response vanishes are dropped.
    """

    def __init__(self, band, response, n: int):
        self.band = (float(band[0]), float(band[1]))
        self.response = response
        self.requested = int(n)
        edges = np.linspace(self.band[0], self.band[1], int(n) + 1)
        self.bands: list[tuple[float, float]] = []
        self._nodes: list[tuple[np.ndarray, np.ndarray]] = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            x, w = self._quadrature(lo, hi, ())
            if np.sum(w) > 0:
                self.bands.append((float(lo), float(hi)))
                self._nodes.append((x, w))

    def __len__(self) -> int:
        return len(self.bands)

    def _quadrature(self, lo, hi, extra):
        """Trapezoid nodes [um] and weights R(x) dx [um] over [lo, hi], breaks at ``extra``."""
        return _response_trapezoid(lo, hi, NODES_PER_SUBBAND, [extra], self.response)

    def _nodes_for(self, k, wavelengths):
        lo, hi = self.bands[k]
        wl = np.asarray(wavelengths, dtype=float)
        if wl.size > 1 and np.any((wl > lo) & (wl < hi)):
            return self._quadrature(lo, hi, wl)
        return self._nodes[k]

    def integrate(self, wavelengths_um, values) -> np.ndarray:
        """:math:`\\int_k R f\\,d\\lambda` per sub-band of a table ``values`` (..., W) on
        ``wavelengths_um`` (W,) (linear between nodes, held constant beyond the ends); (..., n)."""
        wl = np.asarray(wavelengths_um, dtype=float)
        v = np.asarray(values, dtype=float)
        out = np.empty(v.shape[:-1] + (len(self),))
        for k in range(len(self)):
            x, w = self._nodes_for(k, wl)
            out[..., k] = _interp_last(x, wl, v) @ w
        return out

    def weighted_mean(
        self, wavelengths_um, values, temperature_k: float = EMISSIVITY_WEIGHTING_TEMPERATURE_K
    ) -> np.ndarray:
        """Mean of a table over each sub-band weighted by :math:`R\\,B(\\lambda, T)`; (..., n):
        the band mean of :func:`humv_usd.physics.planck.band_weighted_mean` (the one Planck
        weighting, also the materials' band emissivity) per sub-band."""
        return np.stack(
            [
                planck.band_weighted_mean(wavelengths_um, values, b, self.response, temperature_k)
                for b in self.bands
            ],
            axis=-1,
        )

    def radiance(self, temperature_k) -> np.ndarray:
        """Planck radiance per sub-band :math:`\\int_k R\\,B(\\lambda,T)\\,d\\lambda` [W m-2 sr-1];
        shape ``temperature_k.shape + (n,)``. From each sub-band's cached table
        (:func:`planck.band_radiance_tabulated`: the exact quadrature of :func:`planck.band_radiance`
        to about 1e-9 relative, tested to 1e-6), so per-frame face tables cost an interpolation."""
        t = np.asarray(temperature_k, dtype=float)
        if self.band[1] <= REFLECTIVE_LIMIT_UM and not np.all(np.isfinite(t)):
            out = np.zeros(t.shape + (len(self),))  # NIR/SWIR without a thermal layer: no emission
            known = np.isfinite(t)
            if known.any():
                out[known] = self.radiance(t[known])
            return out
        return np.stack([planck.band_radiance_tabulated(t, b, self.response) for b in self.bands], axis=-1)

    def emissivity(self, wavelengths_um, emissivity) -> np.ndarray:
        """Sub-band emissivity (n,): Planck (EMISSIVITY_WEIGHTING_TEMPERATURE_K) and response weighted
        mean of each sub-band, the band mean every tool uses
        (:func:`humv_usd.physics.planck.band_emissivity`)."""
        wl = np.atleast_1d(np.asarray(wavelengths_um, dtype=float))
        eps = np.atleast_1d(np.asarray(emissivity, dtype=float))
        if wl.size == 1:
            return np.full(len(self), float(eps[0]))
        return np.array([planck.band_emissivity(wl, eps, b, self.response) for b in self.bands])


def _interp_last(x, wl, v):
    """Linear interpolation of v (..., W) from wl to x along the last axis (ends held)."""
    if wl.size == 1:
        return np.repeat(v, x.size, axis=-1)
    idx = np.clip(np.searchsorted(wl, x) - 1, 0, wl.size - 2)
    t = np.clip((x - wl[idx]) / (wl[idx + 1] - wl[idx]), 0.0, 1.0)
    return v[..., idx] * (1.0 - t) + v[..., idx + 1] * t


# --- atmosphere -------------------------------------------------------------------------------


@dataclass
class PathTable:
    """Slant-path transmittance and path radiance of one sensor against range (from the stage)."""

    prim: str
    ranges_m: np.ndarray  # (R,), ascending
    wavelengths_um: np.ndarray  # (W,)
    transmittance: np.ndarray  # (R, W)
    radiance: np.ndarray  # (R, W) [W m-2 sr-1 um-1]

    def reduce(self, sub: SubBands) -> SubBandPath:
        """Sub-band transmittance (weighted mean) and path radiance (integral) against range.

        A zero range (transmittance 1, path radiance 0) is prepended when the table starts
        above 0 m, so short ranges interpolate towards the exact limit.
        """
        tau = sub.weighted_mean(self.wavelengths_um, self.transmittance)
        path = sub.integrate(self.wavelengths_um, self.radiance)
        ranges = self.ranges_m
        if ranges[0] > 0:
            ranges = np.concatenate([[0.0], ranges])
            tau = np.concatenate([np.ones((1, tau.shape[1])), tau])
            path = np.concatenate([np.zeros((1, path.shape[1])), path])
        return SubBandPath(ranges, tau, path)


def range_weights(table_ranges, range_m) -> tuple[np.ndarray, np.ndarray]:
    """Linear-interpolation nodes and weights of ``range_m`` in an ascending table (held beyond
    its ends, as ``np.interp``): (index i, weight t) with value = v[i] (1 - t) + v[i + 1] t.
    Computed once per image and shared by every sub-band / channel."""
    x = np.asarray(table_ranges, dtype=float)
    r = np.asarray(range_m, dtype=float)
    if x.size == 1:
        return np.zeros(r.shape, dtype=np.intp), np.zeros(r.shape)
    i = np.clip(np.searchsorted(x, r, side="right") - 1, 0, x.size - 2)
    t = np.clip((r - x[i]) / (x[i + 1] - x[i]), 0.0, 1.0)
    return i, t


def _lerp(values, weights):
    i, t = weights
    v = np.asarray(values, dtype=float)
    if v.shape[0] == 1:
        return np.broadcast_to(v[0], i.shape + v.shape[1:]).copy()
    t = t.reshape(t.shape + (1,) * (v.ndim - 1))
    return v[i] * (1.0 - t) + v[i + 1] * t


@dataclass
class SubBandPath:
    ranges_m: np.ndarray  # (R,)
    transmittance: np.ndarray  # (R, n)
    radiance: np.ndarray  # (R, n) [W m-2 sr-1]

    def at(self, range_m, k: int, weights=None) -> tuple[np.ndarray, np.ndarray]:
        """(transmittance, path radiance) of sub-band k at ranges ``range_m`` (linear in range,
        held beyond the last table range); ``weights`` = :func:`range_weights` of ``range_m``
        when already known."""
        w = range_weights(self.ranges_m, range_m) if weights is None else weights
        return _lerp(self.transmittance[:, k], w), _lerp(self.radiance[:, k], w)


def apply_path(surface, range_m, path: SubBandPath | None, k: int, weights=None):
    """At-sensor radiance :math:`\\tau_k(r) S + P_k(r)` of sub-band k for pixels that see a
    surface (finite range); sky pixels (infinite range) are returned unchanged, the sky
    radiance being already the at-sensor downwelling value. Also returns :math:`\\tau_k(r)`
    (1 for sky pixels) for the error propagation. ``weights``: :func:`range_weights` of
    ``where(finite, range_m, 0)`` when already known (shared by the sub-bands)."""
    surface = np.asarray(surface, dtype=float)
    if path is None:
        return surface, np.ones_like(surface)
    hit = np.isfinite(range_m)
    tau, lp = path.at(np.where(hit, range_m, 0.0), k, weights)
    tau = np.where(hit, tau, 1.0)
    return np.where(hit, tau * surface + lp, surface), tau


# --- sky --------------------------------------------------------------------------------------

#: Lat-long sky bitmap size (rows span zenith 0..180 deg, about 1 deg apart; the sky depends
#: on zenith only).
SKY_MAP_HEIGHT = 181
SKY_MAP_WIDTH = 8


def sky_latlong(zenith_deg, radiance) -> np.ndarray:
    r"""(SKY_MAP_HEIGHT, SKY_MAP_WIDTH, 3) float32 lat-long bitmap of a sky radiance against zenith.

    Row i holds zenith :math:`i \cdot 180° / (H - 1)`: Mitsuba 3.9's ``envmap`` looks a direction
    up at the continuous row :math:`\theta/\pi\,(H - 1)` and interpolates bilinearly (measured
    with ``Emitter.eval``, tests/test_render_radiometry.py). The radiance is linear in zenith
    between table values and held at the horizon value below the horizon (the scene's ground
    covers what lies below; beyond it the horizon sky is the best estimate). In Mitsuba's
    ``envmap`` local frame row 0 is +Y; the caller rotates +Y to the stage's +Z.
    """
    z = np.asarray(zenith_deg, dtype=float)
    v = np.asarray(radiance, dtype=float)
    rows = np.arange(SKY_MAP_HEIGHT) * 180.0 / (SKY_MAP_HEIGHT - 1)
    col = np.interp(np.minimum(rows, 90.0), z, v)
    return np.ascontiguousarray(
        np.broadcast_to(col[:, None, None], (SKY_MAP_HEIGHT, SKY_MAP_WIDTH, 3)), dtype=np.float32
    )


def hemisphere_mean(zenith_deg, radiance) -> float:
    """Cosine-weighted mean of a zenith-only sky radiance over the upper hemisphere:
    :math:`2\\int_0^{\\pi/2} L(\\theta)\\cos\\theta\\sin\\theta\\,d\\theta` (the radiance of the
    uniform sky giving the same irradiance on a horizontal surface)."""
    th = np.radians(np.linspace(0.0, 90.0, 721))
    v = np.interp(np.degrees(th), np.asarray(zenith_deg, float), np.asarray(radiance, float))
    return float(trapezoid(2.0 * v * np.cos(th) * np.sin(th), th))


# --- spectral error of the sub-band approximation -----------------------------------------------


def facet_radiance(
    sub: SubBands, wavelengths_um, emissivity, temperature_k, sky=None, sun=None, path=None
) -> np.ndarray:
    """At-sensor radiance of an opaque Lambertian facet with the sub-band model.

    :math:`\\sum_k \\tau_k(\\varepsilon_k L_k(T) + (1-\\varepsilon_k)(S_k + E_k\\cos\\theta/\\pi)) + P_k`
    with a uniform sky of spectral radiance ``sky = (wl, L)``, a sun ``sun = (wl, E, cos)`` and
    a path ``path = (wl, tau, P)`` (each optional). Shape of ``temperature_k``.
    """
    t = np.asarray(temperature_k, dtype=float)
    eps = sub.emissivity(wavelengths_um, emissivity)
    surface = eps * sub.radiance(t)
    incident = np.zeros(len(sub))
    if sky is not None:
        incident = incident + sub.integrate(sky[0], sky[1])
    if sun is not None:
        incident = incident + sub.integrate(sun[0], sun[1]) * sun[2] / np.pi
    surface = surface + (1.0 - eps) * incident
    if path is not None:
        surface = surface * sub.weighted_mean(path[0], path[1]) + sub.integrate(path[0], path[2])
    return surface.sum(axis=-1)


#: Nodes of the fine spectral reference over a band (tables' wavelengths are added).
REFERENCE_NODES = 4001


def reference_radiance(
    band, response, wavelengths_um, emissivity, temperature_k, sky=None, sun=None, path=None
) -> np.ndarray:
    r"""Exact (fine-grid) at-sensor radiance of the facet of :func:`facet_radiance`:
    :math:`\int R\,[\tau(\varepsilon B(T) + (1-\varepsilon)(L_{sky} + E\cos\theta/\pi)) + P]\,d\lambda`
    by the trapezoid rule on :data:`REFERENCE_NODES` nodes plus every table wavelength."""
    lo, hi = float(band[0]), float(band[1])
    x, w = _response_trapezoid(
        lo,
        hi,
        REFERENCE_NODES,
        [wavelengths_um] + [t[0] for t in (sky, sun, path) if t is not None],
        response,
    )
    wl = np.atleast_1d(np.asarray(wavelengths_um, dtype=float))
    eps = np.atleast_1d(np.asarray(emissivity, dtype=float))
    e = np.full_like(x, eps[0]) if wl.size == 1 else np.interp(x, wl, eps)
    t = np.asarray(temperature_k, dtype=float)
    surface = e * planck.spectral_radiance(x, t[..., None])
    incident = np.zeros_like(x)
    if sky is not None:
        incident = incident + np.interp(x, sky[0], sky[1])
    if sun is not None:
        incident = incident + np.interp(x, sun[0], sun[1]) * sun[2] / np.pi
    surface = surface + (1.0 - e) * incident
    if path is not None:
        surface = surface * np.interp(x, path[0], path[1]) + np.interp(x, path[0], path[2])
    return surface @ w


def subband_error(
    band,
    response,
    wavelengths_um,
    emissivity,
    temperatures_k,
    n: int,
    sky=None,
    sun=None,
    path=None,
    subbands: SubBands | None = None,
) -> np.ndarray:
    """Brightness-temperature error [K] of the n-sub-band model (:func:`facet_radiance`) against
    the fine spectral reference (:func:`reference_radiance`) for a facet at ``temperatures_k``."""
    sub = SubBands(band, response, n) if subbands is None else subbands
    ref = reference_radiance(band, response, wavelengths_um, emissivity, temperatures_k, sky, sun, path)
    approx = facet_radiance(sub, wavelengths_um, emissivity, temperatures_k, sky, sun, path)
    return planck.brightness_temperature(approx, band, response) - planck.brightness_temperature(
        ref, band, response
    )


# --- one sensor at one frame -----------------------------------------------------------------

#: A spectral table must reach this close to the band edges [fraction of the band width].
COVERAGE_TOLERANCE = 0.02


def covers(wavelengths_um, band) -> bool:
    """True when a wavelength table spans the band (within :data:`COVERAGE_TOLERANCE`)."""
    if wavelengths_um is None or len(wavelengths_um) < 2:
        return False
    tol = COVERAGE_TOLERANCE * (band[1] - band[0])
    return bool(wavelengths_um[0] <= band[0] + tol and wavelengths_um[-1] >= band[1] - tol)


@dataclass
class FrameRadiometry:
    """Per sub-band sky, sun and path of one IR sensor at one frame, and what ran."""

    sky_constant: np.ndarray | None  # (n,) [W m-2 sr-1], constant sky
    sky_maps: list | None  # n lat-long bitmaps [W m-2 sr-1] (envmap sky)
    sun_direction: np.ndarray | None  # (3,) toward the sun
    sun_irradiance: np.ndarray | None  # (n,) [W m-2] normal to the beam
    path: SubBandPath | None
    ran: dict
    #: the frame's lamps per sub-band (:class:`humv_usd.render.lights.LampTable`), None: none
    lamps: object | None = None
    #: the frame's cloud shadows on the sun (:class:`humv_usd.render.light.CloudShadows`), None: none
    clouds: object | None = None


# --- sun without a solar spectral table --------------------------------------------------------

#: What the fallback is, for the manifest (the blackbody is the Sun's nominal effective
#: temperature, IAU 2015 Resolution B3, :data:`humv_usd.constants.SUN_TEMPERATURE_K`).
SUN_FALLBACK_NOTE = (
    f"blackbody {SUN_TEMPERATURE_K:g} K spectral shape scaled so that its integral over all "
    "wavelengths is humv:environment:directNormalIrradiance (approximation: no spectral "
    "atmospheric absorption, e.g. the 2.7 and 4.3 um CO2/H2O bands, so the in-band sun is "
    "overestimated where the atmosphere absorbs)"
)


def blackbody_sun(wavelengths_um, dni_w_m2: float) -> np.ndarray:
    r"""Direct solar spectral irradiance [W m-2 um-1] (beam-normal) from a broadband DNI:
    :math:`E_\lambda = \mathrm{DNI}\,\pi B(\lambda, T_\odot) / (\sigma T_\odot^4)`, whose integral
    over all wavelengths is the DNI (Planck; Stefan-Boltzmann :math:`\int B\,d\lambda = \sigma T^4/\pi`).
    The approximation of :data:`SUN_FALLBACK_NOTE`."""
    t = SUN_TEMPERATURE_K
    return (
        float(dni_w_m2)
        * np.pi
        * planck.spectral_radiance(np.asarray(wavelengths_um, float), t)
        / (STEFAN_BOLTZMANN * t**4)
    )


def blackbody_sun_subbands(sub: SubBands, dni_w_m2: float) -> np.ndarray:
    """:func:`blackbody_sun` integrated per sub-band with the response, exactly (n,) [W m-2]."""
    t = SUN_TEMPERATURE_K
    return float(dni_w_m2) * np.pi * sub.radiance(t) / (STEFAN_BOLTZMANN * t**4)


def frame_radiometry(
    sub: SubBands,
    sky_temperature_k: float,
    spectra=None,
    sun_direction=None,
    path_table: PathTable | None = None,
    dni_w_m2: float | None = None,
) -> FrameRadiometry:
    """Sub-band sky, sun and path terms for one IR sensor at one frame, from what the stage has.

    - sky: the spectral sky table (``spectra.sky_zenith_deg``/``sky_radiance``) integrated per
      sub-band as a lat-long envmap when it covers the band, else a blackbody sky at the
      effective ``sky_temperature_k`` (uniform);
    - sun: ``spectra.solar_irradiance`` integrated per sub-band along ``sun_direction`` when the
      sun is above the horizon and the table covers the band; without such a table, a blackbody
      sun scaled to the broadband ``dni_w_m2`` (:func:`blackbody_sun_subbands`); none at night;
    - path: the sensor's path table reduced to sub-bands (:meth:`PathTable.reduce`), else none.

    ``ran`` records each choice for the manifest.
    """
    ran: dict = {"subbands": [list(b) for b in sub.bands], "subbands_requested": sub.requested}
    band = sub.band
    wl = None if spectra is None else spectra.wavelengths_um
    sky_constant = sky_maps = None
    if spectra is not None and spectra.sky_radiance is not None and covers(wl, band):
        per_k = sub.integrate(wl, spectra.sky_radiance)  # (Z, n)
        sky_maps = [sky_latlong(spectra.sky_zenith_deg, per_k[:, k]) for k in range(len(sub))]
        ran["sky"] = (
            "envmap from humv:atmosphere:skySpectralRadiance (zenith table, held at the horizon value below it)"
        )
    else:
        sky_constant = sub.radiance(float(sky_temperature_k))
        why = (
            "no humv:atmosphere:skySpectralRadiance"
            if spectra is None or spectra.sky_radiance is None
            else "sky table does not cover the band"
        )
        ran["sky"] = f"uniform blackbody at humv:atmosphere:skyTemperature ({why})"
    sun_dir = sun_e = None
    no_table = (
        "no humv:atmosphere:solarSpectralIrradiance"
        if spectra is None or spectra.solar_irradiance is None
        else None
        if covers(wl, band)
        else "solar table does not cover the band"
    )
    if sun_direction is None:
        ran["sun"] = "skipped: no humv:environment:sunDirection"
    elif no_table is not None and not dni_w_m2:
        ran["sun"] = f"skipped: {no_table} (and no humv:environment:directNormalIrradiance)"
    elif sun_direction[2] <= 0.0:
        ran["sun"] = "skipped: sun below the horizon (night)"
    else:
        if no_table is None:
            e, source = sub.integrate(wl, spectra.solar_irradiance), "humv:atmosphere:solarSpectralIrradiance"
        else:
            e = blackbody_sun_subbands(sub, dni_w_m2)
            source = f"{no_table}: DNI {float(dni_w_m2):.4g} W m-2 with a {SUN_FALLBACK_NOTE}"
        if not np.any(e > 0):
            ran["sun"] = "skipped: zero solar irradiance in the band"
        else:
            sun_dir, sun_e = np.asarray(sun_direction, dtype=float), e
            ran["sun"] = (
                f"directional, {float(e.sum()):.4g} W m-2 in band (beam-normal), zenith "
                f"{np.degrees(np.arccos(np.clip(sun_dir[2], -1, 1))):.2f} deg, from {source}"
            )
    path = None
    if path_table is None:
        ran["atmosphere"] = (
            "skipped: no path table under /World/Atmosphere/Paths (no transmittance or path radiance)"
        )
    elif not covers(path_table.wavelengths_um, band):
        ran["atmosphere"] = f"skipped: path table {path_table.prim} does not cover the band"
    else:
        path = path_table.reduce(sub)
        ran["atmosphere"] = (
            f"per pixel by range from {path_table.prim} ({path_table.ranges_m.size} ranges "
            f"{path_table.ranges_m[0]:g}-{path_table.ranges_m[-1]:g} m)"
        )
    return FrameRadiometry(sky_constant, sky_maps, sun_dir, sun_e, path, ran)


# --- EO: the path reduced to the CIE XYZ channels -------------------------------------------------


def cie_1931_cmfs() -> tuple[np.ndarray, np.ndarray]:
    """CIE 1931 2° colour-matching functions: (wavelengths [nm] (W,), x-bar, y-bar, z-bar (W, 3)),
    360-830 nm every nm (colour-science's ``MSDS_CMFS['CIE 1931 2 Degree Standard Observer']``,
    frozen in :mod:`humv_usd.render.cie`)."""

    return cie.CMF_WAVELENGTHS_NM, cie.CMF_XYZ


@dataclass
class XYZPath:
    """Slant path of an EO sensor reduced to the CIE X, Y, Z channels against range."""

    ranges_m: np.ndarray  # (R,)
    transmittance: np.ndarray  # (R, 3)
    radiance: np.ndarray  # (R, 3), same scale as the film's XYZ [W m-2 sr-1 nm-1]; thermal + airlight
    airlight: np.ndarray | None = None  # (R, 3), the Koschmieder airlight part of ``radiance``
    horizon_xyz: np.ndarray | None = None  # (3,), the horizon sky radiance in X, Y, Z

    def at(self, range_m) -> tuple[np.ndarray, np.ndarray]:
        """(transmittance, path radiance), each ``range_m.shape + (3,)`` (linear in range, held
        beyond the last table range)."""
        w = range_weights(self.ranges_m, range_m)
        return _lerp(self.transmittance, w), _lerp(self.radiance, w)


#: Zenith angles [deg] of the sky-table rows that give the horizon sky radiance of the EO airlight.
HORIZON_ZENITH_DEG = (85.0, 90.0)


def horizon_sky(zenith_deg, radiance) -> tuple[np.ndarray, str]:
    r"""Horizon sky spectral radiance :math:`L_h(\lambda)` (W,) from a sky table (Z, W) against
    zenith [deg], in the table's units [W m-2 sr-1 um-1], and which rule gave it.

    The mean of the rows at zenith :data:`HORIZON_ZENITH_DEG` (85-90°, the sky just above the
    horizon that a horizontal line of sight ends on); without such a row, the cosine-weighted
    hemispherical mean (:func:`hemisphere_mean`, the EO render's uniform sky). Below 2.5 um the
    atmosphere layer's sky is isotropic (SPCTRL2 diffuse skylight), so both rules agree there.
    """
    zen = np.asarray(zenith_deg, dtype=float)
    rad = np.asarray(radiance, dtype=float).reshape(zen.size, -1)
    near = (zen >= HORIZON_ZENITH_DEG[0] - 1e-6) & (zen <= HORIZON_ZENITH_DEG[1] + 1e-6)
    if near.any():
        rows = ", ".join(f"{z:g}" for z in zen[near])
        return rad[near].mean(axis=0), f"mean of the sky table's rows at zenith {rows} deg"
    return (
        np.array([hemisphere_mean(zen, rad[:, j]) for j in range(rad.shape[1])]),
        "cosine-weighted hemispherical mean of the sky table (no row at zenith 85-90 deg)",
    )


def reduce_xyz(table: PathTable, horizon=None) -> XYZPath:
    r"""Reduce a spectral path table to the film's X, Y, Z channels, with the Koschmieder airlight.

    With the CIE 1931 colour-matching functions :math:`\bar x_c` (:func:`cie_1931_cmfs`) and the
    film's normalisation (Mitsuba divides every channel by :math:`\int\bar y\,d\lambda`, so a flat
    spectral radiance :math:`L` per nm has :math:`Y = L`):

    .. math::

        \tau_c(r) = \frac{\int \bar x_c\,\tau(\lambda, r)\,d\lambda}{\int \bar x_c\,d\lambda},
        \qquad
        P_c(r) = \frac{\int \bar x_c\,L_{path}(\lambda, r)\,d\lambda}{\int \bar y\,d\lambda}

    (trapezoid on the CIE 5 nm table over 360-830 nm, the tables linear in wavelength and held beyond their
    ends; :math:`L_{path}` converted from per um to per nm). The path radiance is exact; the
    channel transmittance assumes a spectrally flat surface-leaving radiance within each
    channel (an illumination- and reflectance-free weighting, exact when either the
    transmittance or the radiance is flat over the channel; the visible transmittance of the
    scene's ranges varies by well under 1 % across a channel). A zero range (tau 1, P 0) is
    prepended when the table starts above 0 m. Then per pixel
    :math:`XYZ_{sensor} = \tau_{xyz}(r)\,XYZ + P_{xyz}(r)` (:func:`apply_xyz_path`).

    Airlight (``horizon`` = (wavelengths [um], horizon sky radiance :math:`L_h` [W m-2 sr-1 um-1]),
    e.g. :func:`horizon_sky`): the path table's radiance is thermal emission only (LOWTRAN's
    visible path radiance is ≈ 0), so the sunlight and skylight scattered into the line of sight
    is added with Koschmieder's law (Koschmieder 1924, Beitr. Phys. freien Atm. 12, 33-53, 171-181;
    Middleton 1952, *Vision through the atmosphere*, ch. 4): a homogeneous, uniformly lit path
    seen against the horizon sky has

    .. math::

        L(r) = \tau_s(r)\,L_0 + L_h\,(1 - \tau_s(r)),
        \qquad
        P^{air}_c(r) = \frac{\int \bar x_c\,L_h(\lambda)\,(1 - \tau(\lambda, r))\,d\lambda}{\int \bar y\,d\lambda},

    so an object's contrast against the horizon falls as :math:`C(r) = C_0\,\tau_s(r)`, and a
    black object reaches the horizon sky at long range. :math:`\tau_s` should be the scattering
    (aerosol + Rayleigh) transmittance; the full path transmittance is used instead, an
    approximation valid in the visible where molecular absorption is weak (ozone's Chappuis
    band and narrow O2 / water lines, small against the aerosol and Rayleigh extinction of a
    horizontal path near the ground). Further
    approximations: the path is treated as horizontal and uniformly lit (a downward-looking path
    ends on a background darker than the horizon sky, so the airlight is somewhat overstated
    there), and the sun is not given its forward-scattering peak. :math:`P_c` becomes the thermal
    part plus :math:`P^{air}_c`; the airlight alone is kept in :attr:`XYZPath.airlight`.
    """
    wl_nm, cmf = cie_1931_cmfs()
    x_um = wl_nm / 1000.0
    wl = np.asarray(table.wavelengths_um, dtype=float)
    tau_l = _interp_last(x_um, wl, np.asarray(table.transmittance, dtype=float))  # (R, W)
    rad_l = _interp_last(x_um, wl, np.asarray(table.radiance, dtype=float)) / 1000.0
    dx = np.diff(wl_nm)
    w = np.zeros_like(wl_nm)
    w[:-1] += 0.5 * dx
    w[1:] += 0.5 * dx
    wc = cmf * w[:, None]  # (W, 3)
    tau = (tau_l @ wc) / wc.sum(axis=0)
    path = (rad_l @ wc) / wc[:, 1].sum()
    air = horizon_xyz = None
    if horizon is not None:
        h_wl, h_rad = (np.asarray(v, dtype=float) for v in horizon)
        l_h = _interp_last(x_um, h_wl, h_rad[None, :])[0] / 1000.0  # per nm
        horizon_xyz = (l_h @ wc) / wc[:, 1].sum()
        air = ((1.0 - tau_l) * l_h) @ wc / wc[:, 1].sum()
        path = path + air
    ranges = np.asarray(table.ranges_m, dtype=float)
    if ranges[0] > 0:
        ranges = np.concatenate([[0.0], ranges])
        tau = np.concatenate([np.ones((1, 3)), tau])
        path = np.concatenate([np.zeros((1, 3)), path])
        if air is not None:
            air = np.concatenate([np.zeros((1, 3)), air])
    return XYZPath(ranges, tau, path, air, horizon_xyz)


def apply_xyz_path(xyz, range_m, path: XYZPath | None) -> tuple[np.ndarray, np.ndarray]:
    """At-sensor XYZ (H, W, 3) :math:`\\tau_{xyz}(r)\\,XYZ + P_{xyz}(r)` for pixels that see a
    surface (finite range ``range_m`` [m]); sky pixels unchanged (the sky is the at-sensor value).
    XYZ and P in the film's units (W m-2 sr-1 nm-1, CIE-weighted). The transfer equation of a
    homogeneous path (see the module references); the channel reduction is
    :func:`reduce_xyz`'s. Also returns :math:`\\tau_{xyz}` (1 for sky pixels)."""
    xyz = np.asarray(xyz, dtype=float)
    if path is None:
        return xyz, np.ones_like(xyz)
    hit = np.isfinite(range_m)
    tau, lp = path.at(np.where(hit, range_m, 0.0))
    tau = np.where(hit[..., None], tau, 1.0)
    return np.where(hit[..., None], tau * xyz + lp, xyz), tau
