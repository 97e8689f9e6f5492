"""Sensor chain: optics PSF, detector noise, quantization to counts, gain/offset and AGC.

Pure numpy (scipy for the FFT convolution and the Bessel function); no USD except in
:func:`humv_usd.usd.sensor.read_sensor_model`. The render calls it once per sensor and frame::

    model = read_sensor_model(camera_prim)          # once per sensor
    out = apply_chain(radiance, model, rng)             # per frame
    out.counts   # uint16 raw counts (bit_depth bits): the 14/16-bit output
    out.image8   # uint8 after AGC: the 8-bit output
    out.settings # JSON-able dict for the manifest

Input of :func:`apply_chain`:

* **IR (MWIR, LWIR)**: band radiance at the aperture, ``(H, W)`` [W m^-2 sr^-1], integrated over
  the sensor's relative spectral response (``humv:sensor:response``) exactly as
  :func:`humv_usd.physics.planck.band_radiance` does with that response (peak-normalised,
  not area-normalised).
* **EO**: linear *camera RGB*, ``(H, W, 3)``: per-channel radiance integrated over the
  channel responses ``humv:sensor:channelResponse`` (R, G, B) [W m^-2 sr^-1] or any quantity
  proportional to it (the exposure is automatic unless ``gain`` is authored). Use
  :func:`integrate_response` to get it from a spectral image (or Mitsuba's ``specfilm`` with
  these curves). A linear sRGB image is accepted with ``eo_space="srgb"`` (no colour matrix).

Chain order (per frame): PSF convolution (diffraction of the circular pupil, band-averaged,
integrated over the pixel footprint) -> detector noise (IR: Gaussian with sigma set by the
NETD; EO: photon shot noise + read noise in electrons) -> counts = clip(round(gain L + offset),
0, 2^bits - 1) -> AGC to 8 bits (none, linear percentile stretch, histogram equalisation).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import fft as sp_fft
from scipy import special

from humv_usd.physics import planck

BANDS = ("EO", "MWIR", "LWIR")
#: A sensor is infrared (rendered by the IR render) when its band starts at or above this
#: wavelength [um]; below it, or with band "EO", it is rendered spectrally in the visible.
INFRARED_MIN_UM = 3.0
AGC_MODES = ("none", "linear", "histogram")
EO_SPACES = ("camera", "srgb")
#: Temperatures [K] spanned by the counts when no gain/offset is authored for an IR sensor
#: (-40 degC to +100 degC, the usual "high gain" range of uncooled cores).
DEFAULT_SPAN_K = (233.15, 373.15)
#: Fraction of the full well reached by the 99.5th percentile of an EO image under auto exposure.
EO_AUTO_EXPOSURE_FILL = 0.8
EO_AUTO_EXPOSURE_PERCENTILE = 99.5
#: Encircled energy the truncated PSF kernel keeps before renormalisation.
PSF_ENERGY = 0.99
PSF_MAX_RADIUS_PX = 48


@dataclass(frozen=True)
class SensorModel:
    """Radiometric model of one camera (what HumvSensorAPI and the UsdGeom.Camera say).

    Attributes
    ----------
    name : str
        Camera prim name (output folder).
    band : str
        "EO", "MWIR" or "LWIR".
    wavelength_range_um : tuple of 2 floats
        Band edges [um].
    response_wavelengths_um, response : ndarray
        Relative spectral response, peak 1 [um], [0-1]; flat over the band when not authored.
    channel_response : ndarray or None
        EO only: (3, N) responses of the R, G, B channels at ``response_wavelengths_um``.
    resolution : tuple of 2 ints
        (width, height) [px].
    pixel_pitch_m : float
        Detector pitch [m] (fill factor 1: the pixel footprint is a pitch x pitch box).
    f_number : float
        Focal ratio N = f / D.
    focal_length_m : float
        Focal length [m].
    netd_k : float
        Noise-equivalent temperature difference [K] at ``reference_temperature_k`` (IR).
    bit_depth : int
        Bits of the raw counts (8-16).
    gain : float or None
        Counts per W m^-2 sr^-1 (IR) or per input unit (EO); None = automatic (IR: counts span
        DEFAULT_SPAN_K; EO: auto exposure).
    offset : float
        Counts at zero radiance.
    agc : str
        "none", "linear" or "histogram" (8-bit output).
    agc_percentiles : tuple of 2 floats
        Low/high percentiles of the linear stretch [%].
    full_well_e, read_noise_e : float
        EO only: full-well capacity and read noise [electrons].
    reference_temperature_k : float
        Scene temperature at which the NETD is specified [K].
    netd_note : str
        How the NETD was derived, when it was (e.g. scaled to an overridden f-number by the
        sensors layer; the ``humv:netdScaling`` customData of ``humv:sensor:netd``); else "".
    path : str
        The camera prim's path ("" for a model not read from a stage).
    subbands : int or None
        ``humv:sensor:subbands`` when authored (IR), else None (the render's default).
    skip_reason : str or None
        Why the render skips this camera (e.g. not a perspective projection); None: rendered.
    response_authored : bool
        Whether the stage gives a spectral response (else the flat band is assumed).
    """

    name: str
    band: str
    wavelength_range_um: tuple[float, float]
    response_wavelengths_um: np.ndarray
    response: np.ndarray
    resolution: tuple[int, int]
    pixel_pitch_m: float
    f_number: float
    focal_length_m: float
    netd_k: float = 0.05
    bit_depth: int = 14
    gain: float | None = None
    offset: float = 0.0
    agc: str = "linear"
    agc_percentiles: tuple[float, float] = (1.0, 99.0)
    channel_response: np.ndarray | None = None
    full_well_e: float = 10500.0
    read_noise_e: float = 2.5
    reference_temperature_k: float = 300.0
    preset: str = ""
    netd_note: str = ""
    path: str = ""
    subbands: int | None = None
    skip_reason: str | None = None
    response_authored: bool = True

    def __post_init__(self):
        if self.band not in BANDS:
            raise ValueError(f"band = {self.band!r}: allowed values: {', '.join(BANDS)}")
        if self.agc not in AGC_MODES:
            raise ValueError(f"agc = {self.agc!r}: allowed values: {', '.join(AGC_MODES)}")
        if not 1 <= int(self.bit_depth) <= 16:
            raise ValueError(f"bit_depth = {self.bit_depth!r}: allowed range 1..16")
        for key in ("pixel_pitch_m", "f_number", "focal_length_m"):
            if not getattr(self, key) > 0:
                raise ValueError(f"{key} = {getattr(self, key)!r}: expected > 0")
        if self.netd_k < 0:
            raise ValueError(f"netd_k = {self.netd_k!r}: expected >= 0")
        if self.gain is not None and not self.gain > 0:
            raise ValueError(f"gain = {self.gain!r}: expected > 0")
        lo, hi = self.agc_percentiles
        if not 0 <= lo < hi <= 100:
            raise ValueError(f"agc_percentiles = {self.agc_percentiles!r}: expected 0 <= low < high <= 100")

    # --- derived -------------------------------------------------------------------------------
    @property
    def is_infrared(self) -> bool:
        return self.band != "EO"

    @property
    def max_count(self) -> int:
        return (1 << int(self.bit_depth)) - 1

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Full horizontal and vertical field of view [deg]."""
        w, h = self.resolution
        f = self.focal_length_m
        return (
            math.degrees(2 * math.atan(0.5 * w * self.pixel_pitch_m / f)),
            math.degrees(2 * math.atan(0.5 * h * self.pixel_pitch_m / f)),
        )

    @property
    def ifov_rad(self) -> float:
        """Instantaneous field of view of one pixel, pitch / focal length [rad]."""
        return self.pixel_pitch_m / self.focal_length_m

    @property
    def kind(self) -> str:
        """ "EO" (spectral render in the visible) or "IR" (sub-band render)."""
        return "EO" if (self.band == "EO" or self.wavelength_range_um[0] < INFRARED_MIN_UM) else "IR"

    @property
    def rendered(self) -> bool:
        return self.skip_reason is None

    @property
    def band_response(self):
        """(wavelengths_um, response) when the stage gives one, else None (flat over the band),
        as the render's radiometry takes it."""
        return self.response_pair if self.response_authored else None

    @property
    def response_pair(self):
        """(wavelengths_um, response) as :mod:`humv_usd.physics.planck` takes it."""
        return self.response_wavelengths_um, self.response


@dataclass
class ChainOutput:
    """Result of :func:`apply_chain` for one frame.

    counts : uint16 ndarray (H, W) or (H, W, 3)
        Raw digital counts, 0 .. 2^bit_depth - 1 (the 14/16-bit output).
    image8 : uint8 ndarray, same shape
        Display image after AGC (EO: colour-corrected and sRGB-encoded).
    radiance : float ndarray
        Radiance after PSF and noise, before quantization (input units).
    noise_sigma : float
        IR: temporal noise sigma [W m^-2 sr^-1] (= NETD x dL/dT at the reference temperature);
        EO: noise sigma at half full well, in input units.
    settings : dict
        JSON-able record of everything used (PSF, noise, gain, offset, AGC levels, saturation).
    """

    counts: np.ndarray
    image8: np.ndarray
    radiance: np.ndarray
    noise_sigma: float
    settings: dict[str, Any] = field(default_factory=dict)


# ============================================================================ optics
def airy_psf(r_um, wavelength_um, f_number):
    r"""Irradiance point-spread function of an aberration-free circular pupil (Airy pattern).

    Parameters
    ----------
    r_um : numeric
        Radius in the focal plane [um].
    wavelength_um : float
        Wavelength [um].
    f_number : float
        Focal ratio N = f/D.

    Returns
    -------
    numeric
        PSF [um^-2], normalised so that its integral over the plane is 1.

    Notes
    -----
    .. math::

        h(r) = \frac{\pi}{4 (\lambda N)^2}\left[\frac{2 J_1(v)}{v}\right]^2,
        \qquad v = \frac{\pi r}{\lambda N}

    (Fraunhofer diffraction by a circular aperture; :math:`\int_0^\infty 4J_1^2(v)/v\,dv = 2`
    gives the normalisation). First zero at :math:`1.22\lambda N`, full width at half maximum
    :math:`1.029\lambda N`.

    References
    ----------
    .. [1] J. W. Goodman, Introduction to Fourier Optics, 3rd ed., Roberts & Co., 2005, §4.4.2.
    .. [2] G. D. Boreman, Modulation Transfer Function in Optical and Electro-Optical Systems,
       SPIE Press TT52, 2001, ch. 1-2 (diffraction and detector-footprint MTF).
    """
    lam_n = float(wavelength_um) * float(f_number)
    v = np.pi * np.asarray(r_um, dtype=float) / lam_n
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.where(v == 0.0, 1.0, 2.0 * special.j1(v) / np.where(v == 0.0, 1.0, v))
    return a * a * np.pi / (4.0 * lam_n * lam_n)


def airy_encircled_energy(r_um, wavelength_um, f_number):
    r"""Fraction of the Airy pattern's energy within radius r: :math:`1 - J_0^2(v) - J_1^2(v)`.

    References
    ----------
    .. [1] M. Born, E. Wolf, Principles of Optics, 7th ed., Cambridge, 1999, §8.5.2, Eq. (51)
       (Lord Rayleigh's result).
    """
    v = np.pi * np.asarray(r_um, dtype=float) / (float(wavelength_um) * float(f_number))
    return 1.0 - special.j0(v) ** 2 - special.j1(v) ** 2


def _default_wavelengths(model: SensorModel, n=24) -> np.ndarray:
    lo, hi = model.wavelength_range_um
    return np.linspace(lo, hi, n + 1)[:-1] + 0.5 * (hi - lo) / n


def psf_weights(model: SensorModel, wavelengths_um, channel: int | None = None) -> np.ndarray:
    """Relative weight of each wavelength in the band-averaged PSF (sums to 1).

    IR: response x Planck spectral radiance at the model's reference temperature (the energy
    spectrum the detector sees from a scene near that temperature); EO: the (channel) response
    (a flat-spectrum scene). Wavelength intervals are taken as the spacing of the given samples.
    """
    wl = np.atleast_1d(np.asarray(wavelengths_um, dtype=float))
    if channel is not None and model.channel_response is not None:
        curve = model.channel_response[channel]
    else:
        curve = model.response
    w = np.interp(wl, model.response_wavelengths_um, curve, left=0.0, right=0.0)
    if model.is_infrared:
        w = w * planck.spectral_radiance(wl, model.reference_temperature_k)
    if wl.size > 1:
        w = w * np.gradient(wl)
    total = w.sum()
    if not total > 0:
        raise ValueError(f"sensor {model.name!r}: the response is zero at all PSF wavelengths")
    return w / total


def psf_kernel(
    model: SensorModel,
    wavelengths_um=None,
    *,
    pixel_footprint: bool = True,
    channel: int | None = None,
    energy: float = PSF_ENERGY,
    max_radius_px: int = PSF_MAX_RADIUS_PX,
) -> np.ndarray:
    r"""Discrete optics + detector PSF on the pixel grid: a square, odd-sized kernel summing to 1.

    Parameters
    ----------
    model : SensorModel
        Uses ``f_number``, ``pixel_pitch_m`` and the (channel) response.
    wavelengths_um : array-like, optional
        Wavelengths [um] over which the Airy pattern is averaged (e.g. the render's sub-band
        centres); default 24 evenly spaced over the band.
    pixel_footprint : bool, default True
        Integrate over each pixel's area (convolution with the pitch x pitch box of a detector
        of fill factor 1) rather than point-sample at pixel centres.
    channel : int, optional
        EO: 0, 1, 2 for R, G, B channel weights.
    energy : float, default 0.99
        The kernel radius holds this fraction of the longest wavelength's Airy energy
        (:func:`airy_encircled_energy`); the truncated kernel is renormalised to sum 1.
    max_radius_px : int, default 48
        Upper limit of the kernel radius [px].

    Returns
    -------
    ndarray (2k+1, 2k+1)
        Fraction of a point source's power landing in each pixel, centred.

    Notes
    -----
    .. math::

        K[m, n] = \sum_i w_i \iint_{\text{pixel}(m,n)} h_{\lambda_i}(x, y)\,dx\,dy

    with :math:`h_\lambda` the Airy pattern (:func:`airy_psf`) and :math:`w_i` from
    :func:`psf_weights`. Integrating over the pixel is the convolution of the optical PSF with
    the detector footprint, sampled at pixel centres; the system MTF is the product of the
    diffraction MTF and :math:`|\mathrm{sinc}(p\,\xi)|` (Boreman 2001, ch. 2). The pixel
    integral uses a q x q midpoint rule with sub-samples no wider than :math:`\lambda_{min} N/4`.

    References
    ----------
    .. [1] J. W. Goodman, Introduction to Fourier Optics, 3rd ed., 2005, §4.4.2 and §6.3.
    .. [2] G. D. Boreman, Modulation Transfer Function in Optical and Electro-Optical Systems,
       SPIE Press, 2001.
    """
    wl = (
        _default_wavelengths(model)
        if wavelengths_um is None
        else np.atleast_1d(np.asarray(wavelengths_um, dtype=float))
    )
    w = psf_weights(model, wl, channel)
    keep = w > 0
    wl, w = wl[keep], w[keep]
    n = model.f_number
    pitch_um = model.pixel_pitch_m * 1e6
    lam_max = float(wl.max())
    # radius holding `energy` of the longest wavelength (encircled energy grows with r)
    r = np.linspace(0.0, (max_radius_px + 1) * pitch_um, 20000)
    ee = airy_encircled_energy(r, lam_max, n)
    inside = np.nonzero(ee >= energy)[0]
    r_need = r[inside[0]] if inside.size else r[-1]
    radius = int(min(max_radius_px, max(1, math.ceil(r_need / pitch_um))))
    if pixel_footprint:
        q = int(min(41, max(3, math.ceil(pitch_um / (float(wl.min()) * n / 4.0)))))
        q += (q + 1) % 2  # odd: one sub-sample at the pixel centre
    else:
        q = 1
    sub = (np.arange(q) + 0.5) / q - 0.5  # sub-sample offsets within a pixel [px]
    centres = np.arange(-radius, radius + 1, dtype=float)
    axis = (centres[:, None] + sub[None, :]).ravel() * pitch_um  # [um]
    # the grid is symmetric about its centre sample: evaluate one quadrant and mirror it
    c = axis.size // 2
    half = axis[c:]
    rr = np.sqrt(half[:, None] ** 2 + half[None, :] ** 2)
    quadrant = np.zeros_like(rr)
    for lam, weight in zip(wl, w):
        quadrant += weight * airy_psf(rr, lam, n)
    fine = np.empty((axis.size, axis.size))
    fine[c:, c:] = quadrant
    fine[: c + 1, c:] = quadrant[::-1, :]
    fine[c:, : c + 1] = quadrant[:, ::-1]
    fine[: c + 1, : c + 1] = quadrant[::-1, ::-1]
    size = 2 * radius + 1
    # mean over the q x q sub-samples x pixel area = integral over the pixel
    kernel = fine.reshape(size, q, size, q).mean(axis=(1, 3)) * pitch_um * pitch_um
    return kernel / kernel.sum()


_KERNELS: dict[tuple, np.ndarray] = {}


def cached_psf_kernel(model: SensorModel, wavelengths_um=None, channel: int | None = None) -> np.ndarray:
    """:func:`psf_kernel` memoised on everything it depends on (the chain runs every frame)."""
    curve = (
        model.response
        if channel is None or model.channel_response is None
        else model.channel_response[channel]
    )
    key = (
        model.band,
        float(model.f_number),
        float(model.pixel_pitch_m),
        float(model.reference_temperature_k),
        tuple(model.response_wavelengths_um.tolist()),
        tuple(np.asarray(curve).tolist()),
        model.wavelength_range_um,
        None if wavelengths_um is None else tuple(np.atleast_1d(wavelengths_um).tolist()),
    )
    kernel = _KERNELS.get(key)
    if kernel is None:
        if len(_KERNELS) > 64:
            _KERNELS.clear()
        kernel = _KERNELS[key] = psf_kernel(model, wavelengths_um, channel=channel)
    return kernel


def kernel_fwhm_px(kernel: np.ndarray) -> float:
    """Full width at half maximum of a centred kernel along its central row [px] (linear
    interpolation between samples)."""
    row = np.asarray(kernel, dtype=float)[kernel.shape[0] // 2]
    c = row.size // 2
    half = row[c] / 2.0
    right = row[c:]
    i = int(np.argmax(right < half))
    if i == 0:
        return float("nan")
    x = (i - 1) + (right[i - 1] - half) / (right[i - 1] - right[i])
    return 2.0 * x


def convolve_psf(image: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Convolve a 2-D image with a PSF kernel, edges extended (reflect) so that borders keep
    their level. FFT convolution on fast transform sizes (what ``scipy.signal.fftconvolve(...,
    mode="valid")`` does, without importing scipy.signal)."""
    k = kernel.shape[0] // 2
    padded = np.pad(np.asarray(image, dtype=float), k, mode="reflect")
    full = [a + b - 1 for a, b in zip(padded.shape, kernel.shape)]
    fast = [sp_fft.next_fast_len(n, True) for n in full]
    out = sp_fft.irfft2(
        sp_fft.rfft2(padded, fast) * sp_fft.rfft2(np.asarray(kernel, dtype=float), fast), fast
    )
    h, w = np.shape(image)
    return out[2 * k : 2 * k + h, 2 * k : 2 * k + w]


# ============================================================================ radiometry
def integrate_response(wavelengths_um, spectral_radiance, model: SensorModel) -> np.ndarray:
    r"""Band (IR) or channel (EO) radiance of a spectral image.

    Parameters
    ----------
    wavelengths_um : array-like (K,)
        Ascending sample wavelengths [um].
    spectral_radiance : ndarray (..., K)
        Spectral radiance [W m^-2 sr^-1 um^-1] at those wavelengths.
    model : SensorModel

    Returns
    -------
    ndarray
        IR: (...,) band radiance; EO: (..., 3) channel radiances [W m^-2 sr^-1].

    Notes
    -----
    :math:`L_c = \int R_c(\lambda) L_\lambda\,d\lambda` by the trapezoidal rule on the given
    samples (response interpolated linearly, zero outside its table).
    """
    wl = np.asarray(wavelengths_um, dtype=float)
    spec = np.asarray(spectral_radiance, dtype=float)
    curves = (
        model.channel_response
        if (not model.is_infrared and model.channel_response is not None)
        else model.response[None, :]
    )
    r = np.stack([np.interp(wl, model.response_wavelengths_um, c, left=0.0, right=0.0) for c in curves])
    out = np.stack([np.trapz(spec * rc, wl, axis=-1) for rc in r], axis=-1)
    return out[..., 0] if model.is_infrared else out


def noise_sigma_radiance(model: SensorModel, reference_temperature_k: float | None = None) -> float:
    r"""Temporal noise of an IR sensor as band radiance [W m^-2 sr^-1].

    Notes
    -----
    .. math::

        \sigma_L = \mathrm{NETD}\;\left.\frac{dL_b}{dT}\right|_{T_{ref}}

    NETD is the temperature change of a blackbody scene that gives a signal change equal to
    the temporal noise (Dereniak & Boreman 1996, §5.8; Vollmer & Möllmann 2017, §2.5.4), so the
    radiance noise is the NETD times the band radiance derivative (response-weighted,
    :func:`humv_usd.physics.planck.band_radiance_derivative`). Treated as signal-independent
    (detector-limited); fixed-pattern noise is not modelled.

    References
    ----------
    .. [1] E. L. Dereniak, G. D. Boreman, Infrared Detectors and Systems, Wiley, 1996.
    .. [2] M. Vollmer, K.-P. Möllmann, Infrared Thermal Imaging, 2nd ed., Wiley-VCH, 2017.
    """
    t_ref = model.reference_temperature_k if reference_temperature_k is None else reference_temperature_k
    return float(model.netd_k) * planck.band_radiance_derivative(
        t_ref, model.wavelength_range_um, model.response_pair
    )


def default_gain_offset(model: SensorModel, span_k=DEFAULT_SPAN_K) -> tuple[float, float]:
    """Gain [counts per W m^-2 sr^-1] and offset [counts] mapping blackbody band radiances at
    ``span_k`` (low, high) [K] to counts 0 and 2^bits - 1 (a linear radiometric calibration)."""
    lo, hi = (planck.band_radiance(t, model.wavelength_range_um, model.response_pair) for t in span_k)
    gain = model.max_count / (hi - lo)
    return float(gain), float(-gain * lo)


def counts_to_radiance(counts, gain: float, offset: float) -> np.ndarray:
    """Invert the quantizer: radiance = (counts - offset) / gain (to within 1/(2 gain))."""
    return (np.asarray(counts, dtype=float) - offset) / gain


def quantize(radiance, gain: float, offset: float, bit_depth: int) -> np.ndarray:
    """counts = clip(round(gain L + offset), 0, 2^bits - 1) as uint16 (an ideal linear ADC)."""
    top = (1 << int(bit_depth)) - 1
    c = np.rint(gain * np.asarray(radiance, dtype=float) + offset)
    return np.clip(np.nan_to_num(c, nan=0.0), 0, top).astype(np.uint16)


# ============================================================================ AGC
def agc_levels(counts, mode: str, percentiles=(1.0, 99.0), bit_depth: int = 14) -> tuple[float, float]:
    """Black and white levels [counts] of the 8-bit mapping (linear and none modes)."""
    c = np.asarray(counts, dtype=float)
    if mode == "none":
        return 0.0, float((1 << int(bit_depth)) - 1)
    lo, hi = np.percentile(c, percentiles)
    if hi <= lo:
        hi = lo + 1.0
    return float(lo), float(hi)


def agc(counts, mode: str = "linear", percentiles=(1.0, 99.0), bit_depth: int = 14):
    """Automatic gain control: raw counts -> 8-bit display values.

    Modes
    -----
    none
        Fixed: the top 8 of ``bit_depth`` bits (counts x 255 / (2^bits - 1)).
    linear
        Linear stretch between the low and high percentiles of the frame (clipped), the usual
        "linear AGC" of thermal cores.
    histogram
        Histogram equalisation: each count maps to 255 x its cumulative frequency
        (Gonzalez & Woods, Digital Image Processing, 4th ed., §3.3.1).

    Returns
    -------
    image8 : uint8 ndarray
    levels : dict
        What was used (mode, black/white level), for the manifest.
    """
    c = np.asarray(counts)
    if mode == "histogram":
        flat = c.ravel().astype(np.int64)
        hist = np.bincount(flat, minlength=(1 << int(bit_depth)))
        cdf = np.cumsum(hist).astype(float)
        cdf_min = cdf[hist > 0][0]
        denom = max(cdf[-1] - cdf_min, 1.0)
        lut = np.clip(np.rint((cdf - cdf_min) / denom * 255.0), 0, 255).astype(np.uint8)
        return lut[flat].reshape(c.shape), {"mode": mode, "levels": int(np.count_nonzero(hist))}
    if mode not in ("none", "linear"):
        raise ValueError(f"invalid AGC mode {mode!r}: allowed {', '.join(AGC_MODES)}")
    lo, hi = agc_levels(c, mode, percentiles, bit_depth)
    x = (c.astype(float) - lo) / (hi - lo)
    img = np.clip(np.rint(x * 255.0), 0, 255).astype(np.uint8)
    info = {"mode": mode, "black_count": lo, "white_count": hi}
    if mode == "linear":
        info["percentiles"] = [float(p) for p in percentiles]
    return img, info


# ============================================================================ EO colour
def srgb_encode(linear):
    """sRGB transfer function (IEC 61966-2-1:1999) of linear values in 0-1."""
    x = np.clip(np.asarray(linear, dtype=float), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


@functools.lru_cache(maxsize=8)
def _ccm_cached(wl: tuple, curves: tuple) -> np.ndarray:
    import colour  # colour-science, only for EO

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    lam_nm = np.arange(400.0, 701.0, 5.0)
    xyz_bar = cmfs.copy().align(colour.SpectralShape(400, 700, 5)).values  # (K, 3)
    s_d65 = d65.copy().align(colour.SpectralShape(400, 700, 5)).values
    xyz_to_srgb = colour.models.RGB_COLOURSPACE_sRGB.matrix_XYZ_to_RGB
    target = xyz_bar @ xyz_to_srgb.T  # sRGB colour-matching functions (K, 3)
    cam = np.stack(
        [np.interp(lam_nm / 1000.0, np.asarray(wl), np.asarray(c), left=0, right=0) for c in curves], axis=1
    )  # (K, 3)
    # least-squares M with cam @ M.T ~ target, weighted by D65 (Luther-Ives fit)
    sw = np.sqrt(s_d65)[:, None]
    m_t, *_ = np.linalg.lstsq(cam * sw, target * sw, rcond=None)
    m = m_t.T
    # white balance: D65 white -> equal sRGB values
    white_cam = (cam * s_d65[:, None]).sum(axis=0)
    white = m @ white_cam
    return m / white[:, None] * white.mean()


def colour_correction_matrix(model: SensorModel) -> np.ndarray:
    r"""3x3 matrix from linear camera RGB to linear sRGB, white-balanced to D65.

    Notes
    -----
    Least-squares fit of the camera's channel responses to the sRGB colour-matching functions
    (CIE 1931 2° CMFs times the IEC 61966-2-1 XYZ->sRGB matrix), weighted by the CIE D65
    spectrum over 400-700 nm (the Luther-Ives condition, Wandell 1995, Foundations of Vision,
    ch. 4; colour-science supplies the CMFs and D65), rows scaled so that D65 maps to grey.
    """
    if model.channel_response is None or model.channel_response.shape[0] != 3:
        return np.eye(3)
    return _ccm_cached(
        tuple(model.response_wavelengths_um.tolist()),
        tuple(tuple(c) for c in model.channel_response.tolist()),
    )


# ============================================================================ chain
def apply_chain(
    radiance,
    model: SensorModel,
    rng: np.random.Generator,
    *,
    reference_temperature_k: float | None = None,
    psf: bool = True,
    noise: bool = True,
    eo_space: str = "camera",
    psf_wavelengths_um=None,
) -> ChainOutput:
    r"""Run the sensor chain on one frame.

    Parameters
    ----------
    radiance : ndarray
        IR: (H, W) band radiance at the aperture [W m^-2 sr^-1] (response-weighted as
        :func:`humv_usd.physics.planck.band_radiance`). EO: (H, W, 3) linear camera RGB
        (channel radiances) or, with ``eo_space="srgb"``, linear sRGB.
    model : SensorModel
    rng : numpy.random.Generator
        Noise source (seed it from the scenario seed, sensor and frame for repeatability).
    reference_temperature_k : float, optional
        Scene temperature at which the NETD converts to radiance noise [K]; default the
        sensor's ``humv:sensor:referenceTemperature`` (``model.reference_temperature_k``).
    psf, noise : bool
        Switch the optics/detector PSF and the noise off (for tests and ground truth).
    eo_space : {"camera", "srgb"}
        What an EO input holds (camera RGB gets the colour-correction matrix before display).
    psf_wavelengths_um : array-like, optional
        Wavelengths of the band-averaged PSF (default: 24 across the band).

    Returns
    -------
    ChainOutput

    Notes
    -----
    1. PSF: :func:`psf_kernel` (Airy pattern averaged over the band, integrated over the pixel
       footprint; Goodman 2005, Boreman 2001), FFT convolution with reflected edges.
    2. Noise. IR: additive Gaussian, :math:`\sigma_L` from :func:`noise_sigma_radiance`.
       EO: signal in electrons :math:`e = L\,FW/L_{sat}`, Poisson shot noise plus Gaussian read
       noise (EMVA 1288 Release 4.0 linear camera model), back to input units.
    3. Counts: :func:`quantize` with the authored gain/offset, else IR
       :func:`default_gain_offset` and EO auto exposure (the 99.5th percentile at 80 % of full
       well; gain = (2^bits-1)/L_sat).
    4. 8-bit: :func:`agc` on the counts. EO: black level = offset, white level from the AGC
       (percentile of the brightest channel, or full scale for "none"; "histogram" equalises
       the luminance and scales RGB with it), then the colour matrix and the sRGB encoding.
    """
    if eo_space not in EO_SPACES:
        raise ValueError(f"eo_space = {eo_space!r}: allowed values: {', '.join(EO_SPACES)}")
    x = np.asarray(radiance, dtype=float)
    if model.is_infrared and x.ndim != 2:
        raise ValueError(f"sensor {model.name!r}: IR radiance must be (H, W), got shape {x.shape}")
    if not model.is_infrared and (x.ndim != 3 or x.shape[2] != 3):
        raise ValueError(f"sensor {model.name!r}: EO input must be (H, W, 3), got shape {x.shape}")
    bad = ~np.isfinite(x)
    if bad.any():  # one NaN would spread over the whole frame through the FFT convolution
        x = np.where(bad, 0.0, x)
    settings: dict[str, Any] = {
        "band": model.band,
        "preset": model.preset,
        "bit_depth": int(model.bit_depth),
        "nonfinite_inputs_zeroed": int(bad.sum()),
    }

    # 1. optics and pixel footprint
    if psf:
        if model.is_infrared:
            kernel = cached_psf_kernel(model, psf_wavelengths_um)
            x = convolve_psf(x, kernel)
            kernels = [kernel]
        else:
            kernels = [
                cached_psf_kernel(
                    model, psf_wavelengths_um, c if model.channel_response is not None else None
                )
                for c in range(3)
            ]
            x = np.stack([convolve_psf(x[..., c], kernels[c]) for c in range(3)], axis=-1)
        pitch_um = model.pixel_pitch_m * 1e6
        settings["psf"] = {
            "model": "Airy (circular pupil) x pixel footprint",
            "kernel_px": int(kernels[0].shape[0]),
            "fwhm_um": [round(kernel_fwhm_px(k) * pitch_um, 4) for k in kernels],
            "f_number": model.f_number,
            "pixel_pitch_um": pitch_um,
        }
    else:
        settings["psf"] = None

    # 2-3. noise, gain/offset, counts
    if reference_temperature_k is None:
        reference_temperature_k = float(model.reference_temperature_k)
    if model.is_infrared:
        sigma = noise_sigma_radiance(model, reference_temperature_k) if noise else 0.0
        if sigma > 0:
            x = x + rng.normal(0.0, sigma, size=x.shape)
        if model.gain is None:
            gain, offset = default_gain_offset(model)
            gain_source = f"default: {DEFAULT_SPAN_K[0]:g}-{DEFAULT_SPAN_K[1]:g} K span"
        else:
            gain, offset, gain_source = model.gain, model.offset, "authored"
        settings["noise"] = {
            "model": "Gaussian, NETD-calibrated",
            "netd_k": model.netd_k,
            **({"netd_source": model.netd_note} if model.netd_note else {}),
            "reference_temperature_k": reference_temperature_k,
            "sigma_radiance": sigma,
        }
        noise_sigma = sigma
    else:
        if model.gain is None:
            level = float(np.percentile(x.max(axis=-1), EO_AUTO_EXPOSURE_PERCENTILE)) if x.size else 0.0
            l_sat = level / EO_AUTO_EXPOSURE_FILL if level > 0 else 1.0
            gain_source = (
                f"auto exposure: {EO_AUTO_EXPOSURE_PERCENTILE:g}th percentile at "
                f"{EO_AUTO_EXPOSURE_FILL:.0%} of full well"
            )
            offset = model.offset
            gain = (model.max_count - offset) / l_sat
        else:
            gain, offset, gain_source = model.gain, model.offset, "authored"
            l_sat = (model.max_count - offset) / gain
        e_per_unit = model.full_well_e / l_sat
        if noise:
            electrons = np.clip(x, 0.0, None) * e_per_unit
            electrons = rng.poisson(electrons).astype(float) + rng.normal(
                0.0, model.read_noise_e, size=x.shape
            )
            x = electrons / e_per_unit
        half = 0.5 * model.full_well_e
        noise_sigma = math.sqrt(half + model.read_noise_e**2) / e_per_unit if noise else 0.0
        settings["noise"] = {
            "model": "shot (Poisson) + read (Gaussian), EMVA 1288",
            "full_well_e": model.full_well_e,
            "read_noise_e": model.read_noise_e,
            "saturation_input": l_sat,
        }
    counts = quantize(x, gain, offset, model.bit_depth)
    settings.update(
        gain=float(gain),
        offset=float(offset),
        gain_source=gain_source,
        saturated_fraction=float(np.mean(counts == model.max_count)),
        noise_sigma=float(noise_sigma),
    )

    # 4. AGC -> 8 bit
    if model.is_infrared:
        image8, info = agc(counts, model.agc, model.agc_percentiles, model.bit_depth)
    else:
        image8, info = _eo_display(counts, model, offset, eo_space)
    settings["agc"] = info
    return ChainOutput(
        counts=counts, image8=image8, radiance=x, noise_sigma=float(noise_sigma), settings=settings
    )


def _eo_display(counts, model: SensorModel, black: float, eo_space: str):
    lin = np.clip(counts.astype(float) - black, 0.0, None)
    full = model.max_count - black
    if model.agc == "none":
        white = full
        info = {"mode": "none", "white_count": float(full + black)}
    else:
        white = float(np.percentile(lin.max(axis=-1), model.agc_percentiles[1]))
        white = white if white > 0 else full
        info = {"mode": model.agc, "white_count": white + black, "percentile": model.agc_percentiles[1]}
    m = colour_correction_matrix(model) if eo_space == "camera" else np.eye(3)
    if model.agc != "histogram" and np.array_equal(m, np.eye(3)):
        # per-channel map of the integer counts: a lookup table gives the very same values
        levels = np.clip(np.arange(model.max_count + 1, dtype=float) - black, 0.0, None) / white
        lut = np.clip(np.rint(srgb_encode(levels) * 255.0), 0, 255).astype(np.uint8)
        info["colour_matrix"] = np.round(m, 6).tolist()
        return lut[np.minimum(counts, model.max_count)], info
    rgb = lin / white
    rgb = rgb @ m.T
    if model.agc == "histogram":
        lum = np.clip(rgb @ np.array([0.2126, 0.7152, 0.0722]), 0.0, None)
        q = np.clip(np.rint(lum / max(lum.max(), 1e-12) * 4095), 0, 4095).astype(np.uint16)
        eq, _ = agc(q, "histogram", bit_depth=12)
        target = eq.astype(float) / 255.0
        scale = np.where(lum > 0, target / np.where(lum > 0, lum, 1.0), 0.0)
        rgb = rgb * scale[..., None]
    info["colour_matrix"] = np.round(m, 6).tolist()
    image8 = np.clip(np.rint(srgb_encode(rgb) * 255.0), 0, 255).astype(np.uint8)
    return image8, info
