"""The fast EO estimator: CIE X, Y, Z from visible sub-bands on one geometric path.

The EO scene (:mod:`humv_usd.render.eo`: opaque Lambertian surfaces with a spectral reflectance,
a directional sun and a uniform sky, no emission) is the infrared estimator's model with the
emission switched off, so :func:`humv_usd.render.estimator.render_band_fast` renders it: the sun
by a shadow ray, the reflected sky through a control variate, stratified pixel positions and first
reflection directions, Russian roulette, the error from independent replicas and the
same-surface filter of the reflected term (see that module).

Spectral discretisation
-----------------------
The 5-nm grid of the spectral render (:data:`humv_usd.render.eo.EO_WAVELENGTHS_NM`, 360-830 nm)
is split into ``n`` contiguous bins, each holding an equal share of the observer's total
sensitivity :math:`s = \\bar x + \\bar y + \\bar z` (narrow bins where the eye is sensitive).
Per bin k (trapezoid weights :math:`q_i` on the grid):

- channel weights :math:`W_{ck} = \\sum_{i\\in k} q_i \\bar c_i / \\sum_i q_i \\bar y_i`
  (c = x, y, z): a constant spectral radiance L gives Y = L, Mitsuba's normalisation;
- sun irradiance and sky radiance: the s-weighted means over the bin,
  :math:`E_k = \\sum q_i s_i E_i / \\sum q_i s_i`;
- reflectance: the mean weighted by the bin's illumination x sensitivity,
  :math:`\\rho_k = \\sum q_i s_i I_i \\rho_i / \\sum q_i s_i I_i` with
  :math:`I = E_{sun}\\cos\\theta_{sun} + \\pi L_{sky}` (the horizontal irradiance).

Each channel is :math:`C = \\sum_k W_{ck} L_k` of the bins' radiances :math:`L_k` on the same
paths. Within a bin the product of spectra is replaced by the product of bin means: the bias this
leaves against the 5-nm spectral path tracer is measured per labelled region by
``humv-usd bench render`` (the EO part) and chose :data:`DEFAULT_EO_BINS`.

The atmospheric path (Koschmieder airlight included) is applied afterwards per pixel by range on
X, Y, Z as for the path tracer (:func:`humv_usd.render.radiometry.apply_xyz_path`).

Units: spectral radiance and irradiance per nm on the grid [W m-2 sr-1 nm-1, W m-2 nm-1]; X, Y, Z
in Mitsuba's normalisation [W m-2 sr-1 nm-1] (luminance = 683 lm/W x 106.857 nm x Y, see
:mod:`humv_usd.render.eo`).

References
----------
CIE 1931 2-degree standard observer, CIE 015:2018 *Colorimetry*, 4th ed. (the colour-matching
functions, frozen in :mod:`humv_usd.render.cie`); W. Jakob et al., Mitsuba 3 (2022), film
normalisation of Y by the integral of y-bar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from humv_usd.render import estimator as E
from humv_usd.render import lights
from humv_usd.render import quality as Q
from humv_usd.render.cie import CMF_WAVELENGTHS_NM, CMF_XYZ
from humv_usd.render.radiometry import FrameRadiometry

#: Wavelength grid [nm] of the EO spectra (the spectral path tracer's, render.eo.EO_WAVELENGTHS_NM).
GRID_NM = np.arange(360.0, 830.0 + 2.5, 5.0)
#: Visible sub-bands of the fast EO estimator (chosen by the spectral bias, see module notes).
DEFAULT_EO_BINS = 12
#: Camera samples per pixel of one batch of the fast EO estimator (automatic quality).
DEFAULT_EO_SPP = 2
#: Reflection directions per camera sample: at 2 spp one (measured on humvvex eo_rgb 1440x1080,
#: 8 bins, 2 spp: 1 split 0.29 % relative error in 8.9 CPU-s, 2 splits 0.22 % in 12.8, 4 splits
#: 0.16 % in 19.2; the target is 1 %, and 2 spp is the fewest that estimate an error).
DEFAULT_EO_SPLITS = 1
#: Van Cittert steps of the smooth-shaded sun term toward each face's own mean
#: (:func:`humv_usd.render.estimator.corner_table`, the reflected-light bands' value): with the
#: plain blend (0) the render bench person's Y was 0.78 % under the spectral path tracer (z -52;
#: flat faces -0.10 %, Mitsuba's Y normalisation), with 2 steps -0.27 % on a close-up (1: -0.35 %,
#: 3: -0.23 %), continuous, a little more shading within the faces. Now 0: the one-ring gain
#: (:data:`humv_usd.render.estimator.REFLECTIVE_SUN_GAIN_STEPS`) instead, -0.016 % there.
SUN_MEAN_STEPS = E.REFLECTIVE_SUN_MEAN_STEPS
#: Automatic quality (one module, :mod:`humv_usd.render.quality`): the seed offset between the
#: batches of one frame, the target (mean Y error away from edges <= this fraction of mean Y)
#: and the sample cap.
SEED_STRIDE = Q.AUTO_SEED_STRIDE
EO_TARGET_RELATIVE = Q.EO_TARGET_RELATIVE
EO_MAX_SPP = Q.EO_MAX_SPP
#: Distance [m] at which a lamp's irradiance weights the bins' reflectance means (a street
#: lamp's mounting height, EN 13201 residential roads: 4-8 m).
LAMP_WEIGHT_DISTANCE_M = 5.0


def _cmf() -> np.ndarray:
    """(grid, 3) CIE 1931 x-bar, y-bar, z-bar on :data:`GRID_NM`."""
    cmf = np.asarray(CMF_XYZ, dtype=float).reshape(-1, 3)
    assert np.allclose(CMF_WAVELENGTHS_NM, GRID_NM)
    return cmf


def _trapezoid() -> np.ndarray:
    q = np.full(GRID_NM.size, GRID_NM[1] - GRID_NM[0])
    q[[0, -1]] *= 0.5
    return q


@dataclass
class VisibleBins:
    """``n`` contiguous bins of the 5-nm grid: ``index`` (grid,) bin of each node, ``weights``
    (3, n) the CIE X, Y, Z weights per bin, ``edges_nm`` (n + 1,) the bins' limits."""

    index: np.ndarray
    weights: np.ndarray
    edges_nm: np.ndarray

    def __len__(self) -> int:
        return self.weights.shape[1]

    def mean(self, values, weight=None) -> np.ndarray:
        """Per-bin mean (n,) of grid ``values`` weighted by trapezoid x sensitivity x ``weight``."""
        w = _trapezoid() * _cmf().sum(axis=1) * (1.0 if weight is None else np.asarray(weight, float))
        num = np.bincount(self.index, w * np.asarray(values, float), minlength=len(self))
        den = np.bincount(self.index, w, minlength=len(self))
        plain = np.bincount(self.index, np.asarray(values, float), minlength=len(self)) / np.bincount(
            self.index, minlength=len(self)
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0, num / np.where(den > 0, den, 1.0), plain)

    def channel_preserving_mean(self, values) -> np.ndarray:
        r"""Per-bin values (n,) of a spectrum on the grid that give its exact X, Y, Z:
        :meth:`mean` plus the smallest relative change :math:`\delta` (least squares in
        :math:`\delta_k / v_k`) with :math:`\sum_k W_{ck}(v_k + \delta_k) = \sum_i q_i \bar c_i
        s_i / \sum_i q_i \bar y_i` for c = x, y, z (:math:`\delta = D W^T (W D W^T)^+ (t - W v)`,
        :math:`D = \mathrm{diag}(v_k^2)`, the minimum-norm solution of the three constraints).

        For a lamp's line spectrum (a sodium lamp: its self-reversed D line, narrow lines) the
        plain bin mean gives the wrong colour where a colour-matching function changes within a
        bin: Z of an HPS lamp 23 % high, of white LEDs 0.5-1 % (X, Y within 0.3 %); with the
        correction a spectrally flat surface under the lamp (or the lamp seen directly, a window)
        has its exact X, Y, Z and a coloured one the error of its reflectance's variation
        within a bin only."""
        v = self.mean(values)
        cmf, q = _cmf(), _trapezoid()
        target = (q[:, None] * cmf * np.asarray(values, float)[:, None]).sum(axis=0) / float(
            np.sum(q * cmf[:, 1])
        )
        d = np.diag(v**2)
        w = self.weights
        delta = d @ w.T @ np.linalg.pinv(w @ d @ w.T) @ (target - w @ v)
        return np.maximum(v + delta, 0.0)


def visible_bins(n: int) -> VisibleBins:
    """Split the grid into ``n`` bins of equal observer sensitivity (x-bar + y-bar + z-bar)."""
    n = int(n)
    if not 1 <= n <= GRID_NM.size:
        raise ValueError(f"bins: {n}, expected 1..{GRID_NM.size}")
    cmf, q = _cmf(), _trapezoid()
    s = q * cmf.sum(axis=1)
    cum = np.cumsum(s) - 0.5 * s  # the sensitivity below each node's centre
    target = np.minimum((cum / s.sum() * n).astype(int), n - 1)
    # contiguous and none empty: step by at most one bin per node, and leave a node for each
    # bin still to come (the wings, where the observer is nearly blind, get one node each)
    size = GRID_NM.size
    index = np.zeros(size, dtype=int)
    for i in range(1, size):
        index[i] = max(min(max(index[i - 1], target[i]), index[i - 1] + 1), n - (size - i))
    m = n
    weights = np.stack([np.bincount(index, q * cmf[:, c], minlength=m) for c in range(3)])
    weights /= float(np.sum(q * cmf[:, 1]))
    first = np.searchsorted(index, np.arange(m))
    edges = np.append(GRID_NM[first] - 2.5, GRID_NM[-1] + 2.5)
    return VisibleBins(index=index, weights=weights, edges_nm=edges)


def bin_illumination(bins: VisibleBins, sun_nm, sky_nm, sun_direction) -> FrameRadiometry:
    """The frame's sun (beam-normal irradiance per nm on the grid, or None) and uniform sky
    (radiance per nm, or None) as per-bin values in the infrared estimator's form."""
    n = len(bins)
    sky = np.zeros(n) if sky_nm is None else bins.mean(sky_nm)
    on = sun_nm is not None and sun_direction is not None
    return FrameRadiometry(
        sky_constant=sky,
        sky_maps=None,
        sun_direction=np.asarray(sun_direction, float) if on else None,
        sun_irradiance=bins.mean(sun_nm) if on else None,
        path=None,
        ran={},
    )


def horizontal_irradiance(sun_nm, sky_nm, sun_direction, lamps=()) -> np.ndarray:
    """Spectral irradiance on a horizontal surface [W m-2 nm-1]: sun x cos(zenith) + pi x sky
    (the weight of a material's reflectance within a bin), plus each lamp's
    (:class:`humv_usd.usd.lights.Lamp`) at :data:`LAMP_WEIGHT_DISTANCE_M` on its axis (a window:
    pi x its radiance), so that a lamp-lit surface's bin reflectance is weighted by the lamps'
    spectra (an HPS lamp's lines) rather than the night sky's."""
    out = np.zeros(GRID_NM.size)
    if sun_nm is not None and sun_direction is not None:
        out = out + np.asarray(sun_nm, float) * max(float(sun_direction[2]), 0.0)
    if sky_nm is not None:
        out = out + np.pi * np.asarray(sky_nm, float)
    for lamp in lamps:
        if lamp.kind == "rect":
            out = out + np.pi * lights.spectral_per_nm(lamp, lamp.luminance, GRID_NM)
        else:
            i_nm = lights.spectral_per_nm(lamp, lights.luminous_intensity_cd(lamp), GRID_NM)
            out = out + i_nm / LAMP_WEIGHT_DISTANCE_M**2
    if not np.any(out > 0):
        out = np.ones(GRID_NM.size)
    return out


class _NoEmission:
    """The sub-band model of a reflective-only band: n bins, zero emitted radiance; with the
    ``bins``, their means of a spectral table (:meth:`weighted_mean`, e.g. water's Fresnel
    reflectance for the puddles' mirrors)."""

    def __init__(self, n: int, bins: VisibleBins | None = None):
        self.n = int(n)
        self.bins = bins

    def weighted_mean(self, wavelengths_um, values) -> np.ndarray:
        """Per-bin means (..., n) of a table (..., W) on ``wavelengths_um`` (linear on the 5-nm
        grid, held beyond its ends), weighted as :meth:`VisibleBins.mean`; None without bins."""
        if self.bins is None:
            return None
        v = np.asarray(values, float)
        flat = v.reshape(-1, v.shape[-1])
        grid = GRID_NM / 1000.0
        rows = [self.bins.mean(np.interp(grid, wavelengths_um, row)) for row in flat]
        return np.asarray(rows).reshape(v.shape[:-1] + (self.n,))

    def __len__(self) -> int:
        return self.n

    def radiance(self, temperature_k) -> np.ndarray:
        return np.zeros(np.shape(temperature_k) + (self.n,))


def reflectance_tables(scene, reflectance_of, n: int) -> E.FaceTables:
    """The estimator's per-triangle tables of the EO scene: no emission, each part's per-bin
    reflectance (``reflectance_of(material)`` -> (n,)) on all its triangles."""
    rho, offset = [], [0]
    for part in scene.parts:
        t = len(part.triangles)
        rho.append(np.broadcast_to(np.asarray(reflectance_of(part.material), float).reshape(1, n), (t, n)))
        offset.append(offset[-1] + t)
    reflectance = np.concatenate(rho) if rho else np.zeros((0, n))
    return E.FaceTables(np.zeros_like(reflectance), reflectance, np.asarray(offset[:-1]))


def render_xyz_fast(
    scene, sensor_id, state, bins: VisibleBins, reflectance_of, light: FrameRadiometry, spp, seed, splits=None
):
    """CIE X, Y, Z (H, W, 3) [W m-2 sr-1 nm-1] and their standard errors (H, W, 3) of one EO
    sensor (before the atmospheric path): the infrared estimator on a mono scene
    (:class:`humv_usd.render.ir.IRScene`) of the same parts, with the bins as sub-bands and the
    CIE weights as its output channels. ``reflectance_of(material)`` -> (n,) per-bin reflectance."""
    n = len(bins)
    rad, err = E.render_band_fast(
        scene,
        sensor_id,
        state,
        _NoEmission(n, bins),
        None,
        light,
        spp=spp,
        seed=seed,
        splits=DEFAULT_EO_SPLITS if splits is None else int(splits),
        weights=bins.weights,
        tables=reflectance_tables(scene, reflectance_of, n),
        sun_mean_steps=SUN_MEAN_STEPS,
        sun_gain_steps=E.REFLECTIVE_SUN_GAIN_STEPS,
        dark_gain_steps=E.REFLECTIVE_DARK_GAIN_STEPS,
    )
    return np.moveaxis(np.asarray(rad), 0, -1), np.moveaxis(np.asarray(err), 0, -1)
