"""Sensor chain: optics PSF, detector noise, quantization to counts, gain/offset and AGC.

Pure numpy (scipy for the FFT convolution and the Bessel function); no USD (the model comes
from :func:`humv_usd.usd.sensor.read_sensor`, the render's one checked read of the sensor prim,
carried to the chain by :class:`humv_usd.pipeline.chains.SensorChains`). Per sensor and frame::

    model = read_sensor(camera_prim)                # once per sensor and render
    out = apply_chain(radiance, model, rng)             # per frame
    out.counts   # uint16 raw counts (bit_depth bits): the 14/16-bit output
    out.image8   # uint8 after AGC: the 8-bit output
    out.settings # JSON-able dict for the manifest

Input of :func:`apply_chain`:

* **IR (MWIR, LWIR)**: band radiance at the aperture, ``(H, W)`` [W m^-2 sr^-1], integrated over
  the sensor's relative spectral response (``humv:sensor:response``) exactly as
  :func:`humv_usd.physics.planck.band_radiance` does with that response (peak-normalised,
  not area-normalised).
* **NIR, SWIR** (reflected light, :data:`REFLECTIVE_BANDS`): band radiance ``(H, W)`` as for IR;
  the noise is photon shot noise + read noise of the photoelectrons an auto exposure capped at
  :data:`EO_MAX_EXPOSURE_S` collects (:func:`photoelectrons_per_input`), not a NETD.
* **EO**: linear *camera RGB*, ``(H, W, 3)``: per-channel radiance integrated over the
  channel responses ``humv:sensor:channelResponse`` (R, G, B) [W m^-2 sr^-1] or any quantity
  proportional to it (the exposure is automatic unless ``gain`` is authored). Use
  :func:`integrate_response` to get it from a spectral image (or Mitsuba's ``specfilm`` with
  these curves). A linear sRGB image is accepted with ``eo_space="srgb"`` (no colour matrix).

Chain order (per frame): PSF convolution (diffraction of the circular pupil, band-averaged,
integrated over the pixel footprint) -> vignetting (cos^4 of the field angle, off by default)
-> IR: bolometer lag across frames (first order, off by default) -> IR: residual fixed-pattern
noise and its drift since the last flat-field correction (off by default) -> detector noise (IR:
Gaussian with sigma set by the NETD; EO: photon shot noise + read noise in electrons) -> counts =
clip(round(gain L + offset), 0, 2^bits - 1) -> AGC to 8 bits (none, linear percentile stretch,
histogram equalisation, plateau equalisation) -> JPEG compression of the 8-bit image (off by
default). Every artefact stage acts on the chain's copy: the render's radiometric images and the
labels never pass through it. EO rolling shutter (``rolling_shutter_s``) is an image warp of
the one instant the render draws per frame, by the pixels' motion (:func:`rolling_shutter`), not
a render per row time.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import fft as sp_fft
from scipy import ndimage, special

from humv_usd.compat import trapezoid
from humv_usd.constants import PLANCK_CONSTANT, SPEED_OF_LIGHT
from humv_usd.physics import planck

BANDS = ("EO", "NIR", "SWIR", "MWIR", "LWIR")
#: Bands rendered by the sub-band pass whose signal is reflected light: the chain counts their
#: photoelectrons (shot + read noise, exposure) instead of a NETD; their output is radiance.
REFLECTIVE_BANDS = ("NIR", "SWIR")
#: A sensor is infrared (rendered by the IR render) when its band starts at or above this
#: wavelength [um]; below it, or with band "EO", it is rendered spectrally in the visible.
INFRARED_MIN_UM = 3.0
AGC_MODES = ("none", "linear", "histogram", "plateau")
VIGNETTING_MODES = ("none", "cos4")
#: what ``motion_blur`` may be: none, or camera (the platform's motion during the integration
#: window, from the camera's pose over time; the scene is taken as static)
MOTION_BLUR_MODES = ("none", "camera")
#: Plateau of the plateau-equalisation AGC as a fraction of the frame's pixels per histogram bin
#: (1 count wide): 250 pixels per bin at 640 x 512, the value usually quoted as the Tau 2's
#: default plateau (FLIR Tau 2 product specification 102-PS242-40, AGC section; the number was
#: not checked against the document here). Measured here (tests/test_sensor_chain.py): it keeps
#: a 17 degC face and a -1 degC jacket in 10 degC surroundings 150+ levels apart, each beyond
#: 99 % of the background, where the 1-99 % linear stretch clips both.
DEFAULT_AGC_PLATEAU = 250.0 / (640 * 512)
#: Mean 8-bit level of the plateau AGC output when max gain limits its span ("ITT midpoint",
#: FLIR Tau 2 / Boson AGC parameters; 127 = mid grey).
DEFAULT_AGC_MIDPOINT = 127.0
EO_SPACES = ("camera", "srgb")
#: Temperatures [K] spanned by the counts when no gain/offset is authored for an IR sensor
#: (-40 degC to +100 degC, the usual "high gain" range of uncooled cores).
DEFAULT_SPAN_K = (233.15, 373.15)
#: Fraction of the full well reached by the 99.5th percentile of an EO image under auto exposure.
EO_AUTO_EXPOSURE_FILL = 0.8
EO_AUTO_EXPOSURE_PERCENTILE = 99.5
#: Longest exposure the EO auto exposure may choose [s]: one frame time of 30 frame/s video.
#: In low light the exposure stops here and the frame is as dark and noisy as its photoelectrons
#: make it (:func:`photoelectrons_per_input`), instead of being stretched to full well.
EO_MAX_EXPOSURE_S = 1.0 / 30.0
#: Quantum efficiency of the detector where its relative response peaks [electrons per photon]:
#: front/back-illuminated silicon CMOS 0.6-0.8 at 500-600 nm (Sony IMX273: ~0.7 at 525 nm,
#: EMVA 1288 data of machine-vision cameras using it), 0.65 taken.
QUANTUM_EFFICIENCY = 0.65
#: The same for the reflective infrared bands: silicon at 0.75-1.0 um 0.2-0.5 (falling to the
#: 1.1 um band gap; NIR-enhanced CMOS data sheets), 0.35 taken; InGaAs 0.7-0.85 over 1.0-1.6 um
#: (Hamamatsu G12242, Sensors Unlimited GA1280J data sheets), 0.75 taken.
QUANTUM_EFFICIENCY_BY_BAND = {"EO": QUANTUM_EFFICIENCY, "NIR": 0.35, "SWIR": 0.75}
#: Largest digital gain of the EO display: the AGC's white level is at least full scale / this
#: (24 dB, the usual upper limit of a camera's automatic gain), so that a frame of read noise is
#: shown dark, not stretched to full brightness.
EO_MAX_DISPLAY_GAIN = 16.0
#: Encircled energy the truncated PSF kernel keeps before renormalisation.
PSF_ENERGY = 0.99
PSF_MAX_RADIUS_PX = 48


def photoelectrons_per_input(model: SensorModel, exposure_s: float) -> float:
    r"""Photoelectrons per pixel per unit of the chain's EO input in an exposure [e per unit].

    The EO input is linear RGB in the render's unit, the CIE-Y-normalised mean spectral radiance
    [W m-2 sr-1 nm-1] (:mod:`humv_usd.render.eo`), so a channel value v stands for the band
    radiance :math:`v\,\Delta\lambda` with :math:`\Delta\lambda` = 106.857 nm (the integral of
    the CIE y-bar). The camera equation for an on-axis pixel (Holst, *Electro-Optical Imaging
    System Performance*, 5th ed., 2008, eq. 12.6; unit optics transmittance, obliquity ignored):

    .. math:: N_e = \frac{\pi L}{4 N^2}\,p^2\,t\,\eta\,\frac{\lambda}{h c}

    with N the f-number, p the pixel pitch, t the exposure, :math:`\eta` =
    :data:`QUANTUM_EFFICIENCY` and the photon energy at 0.555 um (the peak of y-bar). For NIR and
    SWIR the input is the band radiance L itself (the render's response-weighted radiance),
    :math:`\eta` from :data:`QUANTUM_EFFICIENCY_BY_BAND` and the photon energy at the band's
    centre.
    """
    if model.band == "EO":
        band_per_unit = 106.856895  # [nm]: v [W m-2 sr-1 nm-1] -> v * 106.857 [W m-2 sr-1]
        wavelength_m = 0.555e-6
    else:  # NIR, SWIR: the input is the response-weighted band radiance [W m-2 sr-1]
        band_per_unit = 1.0
        wavelength_m = 0.5e-6 * (model.wavelength_range_um[0] + model.wavelength_range_um[1])
    focal_irradiance = math.pi / (4.0 * float(model.f_number) ** 2) * band_per_unit
    photons_per_joule = wavelength_m / (PLANCK_CONSTANT * SPEED_OF_LIGHT)
    return (
        focal_irradiance
        * float(model.pixel_pitch_m) ** 2
        * float(exposure_s)
        * QUANTUM_EFFICIENCY_BY_BAND.get(model.band, QUANTUM_EFFICIENCY)
        * photons_per_joule
    )


def field_of_view_deg(extent_m, focal_length_m):
    r"""Full field of view of a pinhole (distortion-free) camera [deg].

    Parameters
    ----------
    extent_m : numeric
        Width of the image on the detector [m]: pixels x pitch (or a USD camera's aperture in
        the same unit as the focal length).
    focal_length_m : numeric
        Focal length [m] (same unit as ``extent_m``).

    Notes
    -----
    :math:`\mathrm{FOV} = 2\arctan\left(\frac{n\,p}{2 f}\right)` (rectilinear projection;
    e.g. Holst, Electro-Optical Imaging System Performance, 5th ed., 2008, ch. 2). The one
    field-of-view formula of the code base: presets, the sensor model, the camera reader and the
    editor's plan all call it.
    """
    out = np.degrees(2.0 * np.arctan(0.5 * np.asarray(extent_m, dtype=float) / focal_length_m))
    return float(out) if out.ndim == 0 else out


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
        Where the NETD comes from (given, a preset, a preset scaled to another f-number, a
        default), as recorded at the scenario load and read back from the ``humv:netdOrigin``
        customData of ``humv:sensor:netd`` (:func:`humv_usd.usd.sensor.netd_origin`); else "".
    path : str
        The camera prim's path ("" for a model not read from a stage).
    subbands : int or None
        ``humv:sensor:subbands`` when authored (IR), else None (the render's default).
    skip_reason : str or None
        Why the render skips this camera (e.g. not a perspective projection); None: rendered.
    response_authored : bool
        Whether the stage gives a spectral response (else the flat band is assumed).
    agc_plateau : float
        Plateau AGC: most pixels one histogram bin (1 count) may contribute, as a fraction of the
        frame's pixels [0-1] (:func:`plateau_equalisation`).
    agc_max_gain : float
        Plateau AGC: largest slope of the count -> 8-bit map [levels per count]; 0 = unlimited.
    agc_midpoint : float
        Plateau AGC: mean output level when max gain limits the span (ITT midpoint) [0-255].
    fpn_gain_sigma : float
        IR: standard deviation of the residual per-pixel gain error after the non-uniformity
        correction [fraction] (:func:`fixed_pattern`); 0 = off.
    fpn_offset_sigma_k : float
        IR: standard deviation of the residual per-pixel offset just after a flat-field
        correction, as an equivalent scene temperature [K]; 0 = off.
    fpn_drift_k_per_s : float
        IR: standard deviation of the per-pixel offset drift rate since the last flat-field
        correction [K/s]; 0 = off.
    ffc_interval_s : float
        IR: time between flat-field corrections [s] (one at t = 0 and every interval); 0 = only
        the one at t = 0.
    fpn_seed : int
        Seed of the fixed pattern (the same pattern in every frame of this sensor).
    vignetting : str
        "none" or "cos4" (relative illumination cos^4 of the field angle; :func:`vignetting`).
    time_constant_s : float
        IR: bolometer thermal time constant [s] (:func:`bolometer_lag`); 0 = off.
    jpeg_quality : int
        JPEG quality of the 8-bit image, 1-100 (Pillow/libjpeg scale); 0 = no compression.
    motion_blur : str
        "none" or "camera": the camera's motion during the integration window
        (:func:`motion_blur`: EO exposure, IR bolometer time constant), given the image velocity.
    rolling_shutter_s : float
        EO: readout time of a rolling shutter, first to last row [s] (:func:`rolling_shutter`);
        0 = global shutter.
    turbulence_cn2 : float
        Refractive-index structure constant of a horizontal path [m^-2/3]
        (:func:`apply_turbulence`); 0 = off.
    turbulence_path_m : float
        Length of that path [m] (e.g. the range to the people).
    h264_crf : int
        H.264 constant rate factor of the 8-bit clip, 1-51 (:class:`H264Stream`); 0 = off.
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
    agc_plateau: float = DEFAULT_AGC_PLATEAU
    agc_max_gain: float = 0.0
    agc_midpoint: float = DEFAULT_AGC_MIDPOINT
    fpn_gain_sigma: float = 0.0
    fpn_offset_sigma_k: float = 0.0
    fpn_drift_k_per_s: float = 0.0
    ffc_interval_s: float = 0.0
    fpn_seed: int = 0
    vignetting: str = "none"
    time_constant_s: float = 0.0
    jpeg_quality: int = 0
    motion_blur: str = "none"
    rolling_shutter_s: float = 0.0
    turbulence_cn2: float = 0.0
    turbulence_path_m: float = 0.0
    h264_crf: int = 0

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
        if self.vignetting not in VIGNETTING_MODES:
            raise ValueError(
                f"vignetting = {self.vignetting!r}: allowed values: {', '.join(VIGNETTING_MODES)}"
            )
        ranges = {
            "agc_plateau": (0.0, 1.0),
            "agc_max_gain": (0.0, math.inf),
            "agc_midpoint": (0.0, 255.0),
            "fpn_gain_sigma": (0.0, 1.0),
            "fpn_offset_sigma_k": (0.0, 100.0),
            "fpn_drift_k_per_s": (0.0, 10.0),
            "ffc_interval_s": (0.0, math.inf),
            "time_constant_s": (0.0, 10.0),
            "rolling_shutter_s": (0.0, 1.0),
            "turbulence_cn2": (0.0, 1.0e-10),
            "turbulence_path_m": (0.0, 1.0e6),
        }
        if self.motion_blur not in MOTION_BLUR_MODES:
            raise ValueError(
                f"motion_blur = {self.motion_blur!r}: allowed values: {', '.join(MOTION_BLUR_MODES)}"
            )
        for key, (a, b) in ranges.items():
            v = float(getattr(self, key))
            if not (math.isfinite(v) or b == math.inf) or not a <= v <= b:
                raise ValueError(f"{key} = {getattr(self, key)!r}: allowed range {a:g}..{b:g}")
        if not 0 <= int(self.h264_crf) <= 51:
            raise ValueError(f"h264_crf = {self.h264_crf!r}: allowed range 0..51 (0 = off)")
        if not 0 <= int(self.jpeg_quality) <= 100:
            raise ValueError(f"jpeg_quality = {self.jpeg_quality!r}: allowed range 0..100 (0 = off)")

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
        return (
            field_of_view_deg(w * self.pixel_pitch_m, self.focal_length_m),
            field_of_view_deg(h * self.pixel_pitch_m, self.focal_length_m),
        )

    @property
    def ifov_rad(self) -> float:
        """Instantaneous field of view of one pixel, pitch / focal length [rad]."""
        return self.pixel_pitch_m / self.focal_length_m

    @property
    def kind(self) -> str:
        """ "EO" (spectral render in the visible, band "EO") or "IR" (sub-band render: MWIR,
        LWIR and the reflective NIR and SWIR). A band's range is checked against the band where
        the sensor is read (:func:`humv_usd.usd.sensor.read_sensor`), never reinterpreted."""
        return "EO" if self.band == "EO" else "IR"

    @property
    def is_reflective(self) -> bool:
        """NIR or SWIR: a sub-band render whose output is radiance and photoelectrons."""
        return self.band in REFLECTIVE_BANDS

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
    out = np.stack([trapezoid(spec * rc, wl, axis=-1) for rc in r], axis=-1)
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


def plateau_equalisation(
    counts,
    bit_depth: int = 14,
    plateau: float = DEFAULT_AGC_PLATEAU,
    max_gain: float = 0.0,
    midpoint: float = DEFAULT_AGC_MIDPOINT,
):
    r"""Plateau equalisation: the AGC of FLIR thermal cores (Tau 2, Boson, Lepton "HEQ").

    Parameters
    ----------
    counts : integer ndarray
        Raw counts, 0 .. 2^bit_depth - 1.
    bit_depth : int
        Bits of the counts (the histogram has one bin per count).
    plateau : float
        Largest number of pixels one bin may contribute, as a fraction of the frame's pixels
        [0-1] (at least one pixel). 1 gives histogram equalisation; a tiny value gives each
        occupied count the same share of the output (a "occupied-level" equalisation).
    max_gain : float
        Largest slope of the map [8-bit levels per count]: the output span is
        min(255, max_gain x (highest - lowest occupied count)); 0 = unlimited.
    midpoint : float
        Mean output level of a span narrower than 255 (FLIR's "ITT midpoint") [0-255].

    Returns
    -------
    image8 : uint8 ndarray
    info : dict

    Notes
    -----
    With :math:`h_k` the histogram of the counts and :math:`P` the plateau in pixels,

    .. math::

        h'_k = \min(h_k, P), \qquad
        C_k = \sum_{j \le k} h'_j, \qquad
        y_k = y_0 + S\,\frac{C_k - C_{k_{min}}}{C_{k_{max}} - C_{k_{min}}}

    (Vickers 1996): bins holding more than :math:`P` pixels (the large uniform background) are
    clipped, so a small warm or cool object keeps output levels in proportion to the counts it
    occupies instead of its share of the pixels. :math:`S = 255` unless max gain limits it;
    :math:`y_0 = \mathrm{clip}(m - S/2, 0, 255 - S)` centres a narrower span on the midpoint m.

    References
    ----------
    .. [1] V. E. Vickers, "Plateau equalization algorithm for real-time display of high-quality
       infrared imagery", Optical Engineering 35(7), 1921-1926, 1996.
    .. [2] FLIR Tau 2 product specification (102-PS242-40) and Boson datasheet / software IDD
       (102-2013-42): AGC modes plateau equalisation, linear; parameters plateau value, ITT
       midpoint, max gain.
    """
    c = np.asarray(counts)
    flat = c.ravel().astype(np.int64)
    hist = np.bincount(flat, minlength=(1 << int(bit_depth)))
    cap = max(float(plateau) * flat.size, 1.0)
    clipped = np.minimum(hist.astype(float), cap)
    cdf = np.cumsum(clipped)
    occupied = np.nonzero(hist)[0]
    k_lo, k_hi = (int(occupied[0]), int(occupied[-1])) if occupied.size else (0, 0)
    c_lo = cdf[k_lo]
    denom = cdf[k_hi] - c_lo
    span = 255.0 if max_gain <= 0 else min(255.0, float(max_gain) * (k_hi - k_lo))
    y0 = min(max(float(midpoint) - span / 2.0, 0.0), 255.0 - span)
    if denom > 0:
        level = np.clip((cdf - c_lo) / denom, 0.0, 1.0)
    else:  # one occupied count: mid-grey
        level = np.full(cdf.shape, 0.5)
        y0, span = float(midpoint), 0.0
    lut = np.clip(np.rint(y0 + span * level), 0, 255).astype(np.uint8)
    info = {
        "mode": "plateau",
        "plateau_fraction": float(plateau),
        "plateau_pixels": cap,
        "clipped_bins": int(np.count_nonzero(hist > cap)),
        "max_gain": float(max_gain),
        "midpoint": float(midpoint),
        "span_levels": span,
        "levels": int(occupied.size),
    }
    return lut[flat].reshape(c.shape), info


def agc(
    counts,
    mode: str = "linear",
    percentiles=(1.0, 99.0),
    bit_depth: int = 14,
    *,
    plateau: float = DEFAULT_AGC_PLATEAU,
    max_gain: float = 0.0,
    midpoint: float = DEFAULT_AGC_MIDPOINT,
):
    """Automatic gain control: raw counts -> 8-bit display values.

    Modes
    -----
    none
        Fixed: the top 8 of ``bit_depth`` bits (counts x 255 / (2^bits - 1)).
    linear
        Linear stretch between the low and high percentiles of the frame (clipped), the usual
        "linear AGC" of thermal cores. A person under the low/high percentile's share of the
        pixels saturates (a 17 degC face and the hottest background noise both 255).
    histogram
        Histogram equalisation: each count maps to 255 x its cumulative frequency
        (Gonzalez & Woods, Digital Image Processing, 4th ed., §3.3.1).
    plateau
        Plateau equalisation (:func:`plateau_equalisation`, Vickers 1996; FLIR cores' default):
        histogram equalisation with each bin clipped at ``plateau`` x pixels, so that small
        warm or cool regions (people) keep distinct grey levels.

    Returns
    -------
    image8 : uint8 ndarray
    levels : dict
        What was used (mode, black/white level), for the manifest.
    """
    c = np.asarray(counts)
    if mode == "plateau":
        return plateau_equalisation(c, bit_depth, plateau, max_gain, midpoint)
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


# ============================================================================ artefacts
def vignetting(resolution, pixel_pitch_m: float, focal_length_m: float) -> np.ndarray:
    r"""Relative illumination of each pixel, :math:`\cos^4\theta` of its field angle, (H, W).

    Notes
    -----
    :math:`\tan\theta = r / f` with :math:`r = p\sqrt{(i - c_x)^2 + (j - c_y)^2}` the pixel
    centre's distance from the optical axis (the array centre, :math:`c = (n - 1)/2`). The
    irradiance an aberration-free lens puts on the focal plane from a uniform (Lambertian)
    scene falls as :math:`\cos^4\theta` (one cosine for the obliquity of the pupil, one for that
    of the detector, two for the inverse square of the longer path; Slater 1980, Remote Sensing:
    Optics and Optical Systems, §7.3; Smith 2008, Modern Optical Engineering, 4th ed., §9.10).
    Real lenses deviate (pupil aberration, mechanical vignetting); radiometric thermal cores
    largely remove it in their factory non-uniformity gain table, hence off by default.
    """
    w, h = int(resolution[0]), int(resolution[1])
    x = (np.arange(w) - 0.5 * (w - 1)) * pixel_pitch_m
    y = (np.arange(h) - 0.5 * (h - 1)) * pixel_pitch_m
    r2 = x[None, :] ** 2 + y[:, None] ** 2
    cos2 = focal_length_m**2 / (focal_length_m**2 + r2)
    return cos2 * cos2


def bolometer_lag(signal, previous_signal, previous_output, dt_s: float, time_constant_s: float):
    r"""Output of a first-order (bolometer) detector after ``dt_s``, exact for an input that varies
    linearly between two frames.

    Parameters
    ----------
    signal, previous_signal : ndarray
        Input (scene radiance at the detector) at this frame and the previous one.
    previous_output : ndarray
        Detector output at the previous frame.
    dt_s : float
        Time between the frames [s] (> 0).
    time_constant_s : float
        Thermal time constant :math:`\tau = C/G` [s] (> 0).

    Notes
    -----
    :math:`\tau\,\dot y = x - y` (a microbolometer's thermal response; Kruse & Skatrud 1997,
    Uncooled Infrared Imaging Arrays and Systems, ch. 2; Vollmer & Möllmann 2017 §2.5: 7-14 ms for
    VOx cores). With :math:`x` linear over the step (slope :math:`s = (x_n - x_{n-1})/\Delta t`)
    and :math:`a = e^{-\Delta t/\tau}`:

    .. math::

        y_n = x_n - s\tau + (y_{n-1} - x_{n-1} + s\tau)\,a

    A render draws one instant per frame, so the lag acts only across frames (a target moving
    during one frame's exposure is not smeared within it).
    """
    a = math.exp(-float(dt_s) / float(time_constant_s))
    x = np.asarray(signal, dtype=float)
    slope_tau = (x - np.asarray(previous_signal, dtype=float)) * (float(time_constant_s) / float(dt_s))
    return (
        x
        - slope_tau
        + (np.asarray(previous_output, dtype=float) - np.asarray(previous_signal) + slope_tau) * a
    )


def fixed_pattern(shape, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Three standard-normal per-pixel patterns (gain, offset, drift rate), the same for a given
    seed and shape (a camera's fixed pattern: it does not change from frame to frame)."""
    rng = np.random.default_rng([int(seed), 0x46504E])  # "FPN": apart from the temporal noise streams
    z = rng.standard_normal((3, *shape))
    return z[0], z[1], z[2]


def time_since_ffc(time_s: float, ffc_interval_s: float) -> float:
    """Time since the last flat-field correction [s]: one at t = 0 and every ``ffc_interval_s``
    (0: only the one at t = 0)."""
    t = max(float(time_s), 0.0)
    return math.fmod(t, ffc_interval_s) if ffc_interval_s > 0 else t


def apply_fixed_pattern(
    radiance,
    gain_z,
    offset_z,
    drift_z,
    *,
    reference_radiance: float,
    radiance_per_k: float,
    gain_sigma: float,
    offset_sigma_k: float,
    drift_k_per_s: float,
    t_since_ffc_s: float,
):
    r"""Residual fixed-pattern noise of a microbolometer after non-uniformity correction.

    Notes
    -----
    .. math::

        L'_i = L_i + \sigma_g z^g_i\,(L_i - L_{ref})
              + \frac{dL}{dT}\left(\sigma_o z^o_i + \sigma_r z^r_i\,t\right)

    with :math:`z` the seeded standard-normal patterns (:func:`fixed_pattern`), :math:`L_{ref}`
    the radiance of the flat-field shutter (taken at the sensor's reference temperature), so the
    gain error vanishes on a scene at the shutter's temperature (a two-point correction's
    residual grows away from its calibration points; Mooney et al. 1989, "Characterizing IR
    FPA nonuniformity and IR camera spatial noise", Opt. Eng. 28(11); Scribner et al. 1991,
    "Nonuniformity correction for staring IR focal plane arrays using scene-based techniques",
    Proc. SPIE 1308), and the offset residual grows linearly with the time t since the last
    flat-field correction as the focal-plane temperature drifts (Budzier & Gerlach 2011,
    Thermal Infrared Sensors, §8.3: offset drift between shutter corrections; the Boson and Tau 2
    correct it with an automatic FFC every few minutes or after an FPA temperature change).
    """
    x = np.asarray(radiance, dtype=float)
    out = x + float(gain_sigma) * gain_z * (x - float(reference_radiance))
    k = float(offset_sigma_k) * offset_z + float(drift_k_per_s) * drift_z * float(t_since_ffc_s)
    return out + float(radiance_per_k) * k


# ---------------------------------------------------------------------------- motion, turbulence
#: sub-frame samples of :func:`motion_blur`: at least this many, and two per pixel of the
#: longest streak (box: v T; exponential: v 3 tau), at most MOTION_BLUR_MAX_SAMPLES
MOTION_BLUR_SAMPLES = 16
MOTION_BLUR_MAX_SAMPLES = 256


def motion_blur_samples(max_speed_px_s: float, window_s: float, kind: str = "box") -> int:
    """Sub-frame samples of :func:`motion_blur` for the fastest pixel (see :data:`MOTION_BLUR_SAMPLES`)."""
    streak = float(max_speed_px_s) * float(window_s) * (1.0 if kind == "box" else 3.0)
    return int(min(MOTION_BLUR_MAX_SAMPLES, max(MOTION_BLUR_SAMPLES, math.ceil(2.0 * streak))))


def _sample_shifted(image, coords_u, coords_v):
    """Bilinear samples of (H, W) or (H, W, C) ``image`` at continuous pixel-centre coordinates
    (column u, row v; pixel centres at integers), edges clamped."""
    img = np.asarray(image, dtype=float)
    coords = np.stack([coords_v, coords_u])
    if img.ndim == 2:
        return ndimage.map_coordinates(img, coords, order=1, mode="nearest")
    return np.stack(
        [ndimage.map_coordinates(img[..., c], coords, order=1, mode="nearest") for c in range(img.shape[2])],
        axis=-1,
    )


def motion_blur(image, velocity_px_s, window_s: float, kind: str = "box", samples: int | None = None):
    r"""The image a detector integrates while the scene moves across it.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, C)
        The scene at the end of the integration (the render's instant).
    velocity_px_s : ndarray (H, W, 2)
        Image velocity of the content at each pixel, (du/dt, dv/dt) [px/s] (columns right, rows
        down): content at pixel p was at p - v s a time s earlier.
    window_s : float
        Exposure [s] (``kind="box"``) or the bolometer's time constant [s] (``"exponential"``).
    kind : {"box", "exponential"}
    samples : int, optional
        Sub-frame samples (default :func:`motion_blur_samples` of the fastest pixel: no gaps
        between the copies of a long streak).

    Notes
    -----
    With the scene static in the world and the motion the camera's, the pixel p saw at time
    t - s what it sees at p + v s now, so the integrated signal is

    .. math:: y(p) = \int_0^\infty w(s)\, x(p + v(p)\,s)\, ds

    with :math:`w = 1/T` on [0, T] (an exposure, box) or :math:`w = e^{-s/	au}/	au` (a
    microbolometer's first-order response, the impulse response of :func:`bolometer_lag`). The
    integral is taken at ``samples`` equal-weight nodes: the midpoints of [0, T] (box) or the
    quantiles :math:`s_k = -	au \ln(1 - (k + 1/2)/n)` (exponential); each sample is bilinear.
    The velocity is the one of the current pixel along the whole window (first order in the
    motion); subject motion (a person walking) is not included.
    """
    if kind not in ("box", "exponential"):
        raise ValueError(f"invalid kind {kind!r}: box or exponential")
    img = np.asarray(image, dtype=float)
    vel = np.asarray(velocity_px_s, dtype=float)
    h, w = img.shape[:2]
    if vel.shape != (h, w, 2):
        raise ValueError(f"velocity_px_s shape {vel.shape}: expected {(h, w, 2)}")
    if window_s <= 0 or not np.any(vel):
        return img.copy()
    if samples is None:
        samples = motion_blur_samples(float(np.hypot(vel[..., 0], vel[..., 1]).max()), window_s, kind)
    u_k = (np.arange(samples) + 0.5) / samples
    s_k = u_k * window_s if kind == "box" else -window_s * np.log1p(-u_k)
    rows, cols = np.mgrid[0:h, 0:w].astype(float)
    out = np.zeros_like(img)
    for s in s_k:
        out += _sample_shifted(img, cols + vel[..., 0] * s, rows + vel[..., 1] * s)
    return out / samples


def rolling_shutter(image, velocity_px_s, readout_s: float):
    r"""A rolling-shutter image from the global-shutter ``image`` (the last row's instant).

    Row r of H is read :math:`\Delta_r = (H - 1 - r)/(H - 1)\, t_{readout}` before the last row,
    so it shows what is now at :math:`p + v\,\Delta_r` (``velocity_px_s`` (H, W, 2) [px/s] as in
    :func:`motion_blur`): a pan skews vertical edges by :math:`v_u t_{readout}` pixels over the
    frame (Liang, Chang & Chen 2008, IEEE TIP 17(8), "Analysis and compensation of rolling
    shutter effect"). Bilinear sampling, edges clamped."""
    img = np.asarray(image, dtype=float)
    vel = np.asarray(velocity_px_s, dtype=float)
    h, w = img.shape[:2]
    if readout_s <= 0 or h < 2 or not np.any(vel):
        return img.copy()
    rows, cols = np.mgrid[0:h, 0:w].astype(float)
    delta = (h - 1 - rows) / (h - 1) * readout_s
    return _sample_shifted(img, cols + vel[..., 0] * delta, rows + vel[..., 1] * delta)


def fried_parameter(wavelength_m, cn2_m23: float, path_m: float, wave: str = "spherical"):
    r"""Fried's coherence diameter :math:`r_0` [m] of a horizontal path of uniform
    :math:`C_n^2` [m^-2/3] and length ``path_m`` at ``wavelength_m``.

    .. math:: r_0 = \left(0.423\, k^2 C_n^2 L\, \gamma\right)^{-3/5},\quad k = 2\pi/\lambda

    with :math:`\gamma = 1` for a plane wave and 3/8 for a spherical wave (a point source seen
    by the camera: the usual case for imaging along the ground). Fried 1966, J. Opt. Soc. Am.
    56(10):1372; Andrews & Phillips 2005, Laser Beam Propagation through Random Media, 2nd ed.,
    SPIE, ch. 6. Valid for weak to moderate turbulence (Rytov variance below about 1) and
    inner/outer scales outside the imaged band. Typical :math:`C_n^2` near the ground:
    1e-15 (night, weak) to 1e-13 (sunny afternoon over hot ground, strong)."""
    gamma = {"spherical": 3.0 / 8.0, "plane": 1.0}[wave]
    k = 2.0 * np.pi / np.asarray(wavelength_m, dtype=float)
    return (0.423 * k**2 * float(cn2_m23) * float(path_m) * gamma) ** (-3.0 / 5.0)


def turbulence_mtf(frequency_cyc_per_rad, wavelength_m: float, r0_m: float):
    r"""Long-exposure atmospheric MTF (Fried 1966):
    :math:`\exp[-3.44\, (\lambda f / r_0)^{5/3}]` at angular frequency f [cycles/rad]."""
    f = np.abs(np.asarray(frequency_cyc_per_rad, dtype=float))
    return np.exp(-3.44 * (float(wavelength_m) * f / float(r0_m)) ** (5.0 / 3.0))


def apply_turbulence(image, model: SensorModel, cn2_m23: float, path_m: float):
    """``image`` (H, W) or (H, W, C) blurred by the long-exposure turbulence MTF of the path at
    the band centre (:func:`fried_parameter`, spherical wave; :func:`turbulence_mtf`), pixel
    frequencies turned into angle by the IFOV (pitch / focal length), FFT with reflected edges.
    Returns (image, r0 [m], seeing FWHM [px] ~ 0.98 lambda / r0 / IFOV). The band centre is close
    enough: lambda / r0 varies as lambda^(-1/5)."""
    img = np.asarray(image, dtype=float)
    lam = 0.5e-6 * (model.wavelength_range_um[0] + model.wavelength_range_um[1])
    r0 = float(fried_parameter(lam, cn2_m23, path_m))
    ifov = model.pixel_pitch_m / model.focal_length_m
    h, w = img.shape[:2]
    pad = np.pad(img, [(h // 2, h // 2), (w // 2, w // 2)] + [(0, 0)] * (img.ndim - 2), mode="reflect")
    fy = np.fft.fftfreq(pad.shape[0])[:, None] / ifov
    fx = np.fft.fftfreq(pad.shape[1])[None, :] / ifov
    mtf = turbulence_mtf(np.hypot(fx, fy), lam, r0)
    if pad.ndim == 3:
        mtf = mtf[..., None]
    out = np.real(np.fft.ifft2(np.fft.fft2(pad, axes=(0, 1)) * mtf, axes=(0, 1)))
    return out[h // 2 : h // 2 + h, w // 2 : w // 2 + w], r0, 0.98 * lam / r0 / ifov


def jpeg_roundtrip(image8, quality: int) -> np.ndarray:
    """Encode an 8-bit image (H, W) or (H, W, 3) as baseline JPEG at ``quality`` (1-100, the
    libjpeg / IJG scale) with Pillow and decode it again (what a dataset stored as JPEG holds;
    ITU-T T.81 / ISO 10918-1: 8 x 8 DCT, quantisation table scaled by quality, 4:2:0 chroma)."""
    import io

    from PIL import Image

    img = np.ascontiguousarray(np.asarray(image8, dtype=np.uint8))
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG", quality=int(quality))
    buf.seek(0)
    with Image.open(buf) as decoded:
        return np.asarray(decoded.convert("L" if img.ndim == 2 else "RGB"), dtype=np.uint8)


@dataclass
class ChainState:
    """What the chain keeps from one frame of a sensor to the next (the bolometer's state):
    the time [s], the input and the output of the lag stage at the last frame."""

    time_s: float | None = None
    signal: np.ndarray | None = None
    output: np.ndarray | None = None
    video: Any = None  # the H.264 encoder and decoder of the sensor's clip (:class:`H264Stream`)


class H264Stream:
    r"""An H.264 encoder and decoder (libx264 and FFmpeg's decoder through PyAV, the optional
    ``video`` extra) kept over a sensor's frames: each 8-bit frame is encoded at constant rate
    factor ``crf`` (x264's scale, 0-51: 0 lossless, 23 the default, 51 the worst), without
    B-frames and with zero-latency tuning, and decoded at once, so frame n after the first is a
    P-frame predicted from frame n-1 (ITU-T H.264 / ISO 14496-10; what a recorded clip's frames
    hold). Frames are padded to even sizes (4:2:0 chroma) and cropped back; RGB goes through
    YUV 4:2:0, grey as the luma plane."""

    def __init__(self, crf: int, shape):
        import av  # noqa: PLC0415  (optional: pip install humv-usd[video])

        self.crf, self.shape = int(crf), tuple(shape)
        h, w = shape[:2]
        self.size = (w + w % 2, h + h % 2)
        self.enc = av.CodecContext.create("libx264", "w")
        self.enc.width, self.enc.height = self.size
        self.enc.pix_fmt = "yuv420p"
        self.enc.options = {"crf": str(self.crf), "tune": "zerolatency", "preset": "veryfast", "bf": "0"}
        self.dec = av.CodecContext.create("h264", "r")
        self.frames = 0
        self.bytes: list[int] = []
        self._av = av

    def roundtrip(self, image8) -> np.ndarray:
        img = np.asarray(image8, dtype=np.uint8)
        h, w = img.shape[:2]
        pad = [(0, self.size[1] - h), (0, self.size[0] - w)] + [(0, 0)] * (img.ndim - 2)
        padded = np.ascontiguousarray(np.pad(img, pad, mode="edge"))
        fmt = "gray" if img.ndim == 2 else "rgb24"
        frame = self._av.VideoFrame.from_ndarray(padded, format=fmt).reformat(format="yuv420p")
        frame.pts = self.frames
        self.frames += 1
        out = None
        for packet in self.enc.encode(frame):
            self.bytes.append(packet.size)
            for decoded in self.dec.decode(packet):
                out = decoded.to_ndarray(format=fmt)
        if out is None:  # not expected with zero latency; keep the frame rather than drop it
            return img.copy()
        return np.ascontiguousarray(out[:h, :w])


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
def eo_exposure_s(model: SensorModel, x) -> float:
    """The exposure [s] of an EO frame: the auto exposure's (the 99.5th percentile of the
    brightest channel at 80 % of full well, at most :data:`EO_MAX_EXPOSURE_S`) or the one an
    authored gain implies (full scale at full well)."""
    if model.gain is None:
        level = (
            float(np.percentile(np.asarray(x).max(axis=-1), EO_AUTO_EXPOSURE_PERCENTILE))
            if np.size(x)
            else 0.0
        )
        l_floor = model.full_well_e / photoelectrons_per_input(model, EO_MAX_EXPOSURE_S)
        l_sat = max(level / EO_AUTO_EXPOSURE_FILL, l_floor)
    else:
        l_sat = (model.max_count - model.offset) / model.gain
    return float(model.full_well_e / (l_sat * photoelectrons_per_input(model, 1.0)))


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
    time_s: float | None = None,
    state: ChainState | None = None,
    velocity_px_s=None,
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
    time_s : float, optional
        Time of the frame [s] (scenario time codes / fps): the fixed-pattern drift grows with the
        time since the last flat-field correction; None = just after one.
    state : ChainState, optional
        This sensor's state from its previous frame (updated in place): the bolometer lag needs
        it; without it (or after a step back in time) the detector starts settled (y = x).
    velocity_px_s : ndarray (H, W, 2), optional
        Image velocity of the scene from the camera's motion [px/s]
        (:func:`humv_usd.geometry.camera.image_velocity`): the motion blur (``motion_blur =
        "camera"``) and the EO rolling shutter need it; without it they are off.

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
       (percentile of the brightest channel, or full scale for "none"; "histogram" and
       "plateau" equalise the luminance and scale RGB with it), then the colour matrix and the
       sRGB encoding.

    Artefact stages (each off unless its setting is authored; values in the manifest): after
    the PSF :func:`vignetting` (``vignetting="cos4"``); IR: :func:`bolometer_lag`
    (``time_constant_s`` > 0, across frames through ``state``), :func:`apply_fixed_pattern`
    (``fpn_*``, drift since the last FFC from ``time_s``) before the temporal noise; after the
    AGC :func:`jpeg_roundtrip` of the 8-bit image (``jpeg_quality`` > 0). The counts hold
    everything up to the ADC; the JPEG changes only ``image8``.
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

    # 0. the camera's motion during the integration window (IR: replaces the lag across frames)
    settings["motion_blur"] = None
    settings["rolling_shutter"] = None
    blurred_in_frame = False
    if velocity_px_s is not None and model.motion_blur == "camera":
        tau = float(model.time_constant_s)
        if model.is_infrared and tau > 0:
            x = motion_blur(x, velocity_px_s, tau, "exponential")
            settings["motion_blur"] = {"kind": "exponential (bolometer)", "window_s": tau}
            blurred_in_frame = True
        elif not model.is_infrared:
            t_exp = eo_exposure_s(model, x)
            x = motion_blur(x, velocity_px_s, t_exp, "box")
            settings["motion_blur"] = {"kind": "box (exposure)", "window_s": t_exp}
        if settings["motion_blur"] is not None:
            speed = np.hypot(velocity_px_s[..., 0], velocity_px_s[..., 1])
            kind = "box" if settings["motion_blur"]["kind"].startswith("box") else "exponential"
            settings["motion_blur"].update(
                samples=motion_blur_samples(float(speed.max()), settings["motion_blur"]["window_s"], kind),
                max_speed_px_s=float(speed.max()),
                max_streak_px=float(speed.max() * settings["motion_blur"]["window_s"]),
            )
    if velocity_px_s is not None and not model.is_infrared and model.rolling_shutter_s > 0:
        x = rolling_shutter(x, velocity_px_s, float(model.rolling_shutter_s))
        settings["rolling_shutter"] = {"readout_s": float(model.rolling_shutter_s), "instant": "last row"}

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

    # optics: relative illumination
    if model.vignetting == "cos4":
        falloff = vignetting((x.shape[1], x.shape[0]), model.pixel_pitch_m, model.focal_length_m)
        x = x * (falloff if x.ndim == 2 else falloff[..., None])
        settings["vignetting"] = {"model": "cos^4 of the field angle", "corner": float(falloff[0, 0])}
    else:
        settings["vignetting"] = None

    # atmosphere: turbulence blur of a long horizontal path
    settings["turbulence"] = None
    if model.turbulence_cn2 > 0 and model.turbulence_path_m > 0:
        x, r0, seeing_px = apply_turbulence(x, model, model.turbulence_cn2, model.turbulence_path_m)
        settings["turbulence"] = {
            "model": "long-exposure MTF, spherical-wave Fried parameter (Fried 1966)",
            "cn2_m-2/3": float(model.turbulence_cn2),
            "path_m": float(model.turbulence_path_m),
            "r0_m": r0,
            "seeing_fwhm_px": seeing_px,
        }

    # detector: bolometer lag across frames, residual fixed pattern (IR)
    if model.is_infrared:
        if blurred_in_frame:  # the exponential window of the motion blur is the lag
            settings["lag"] = {
                "time_constant_s": float(model.time_constant_s),
                "applied": False,
                "why": "in the motion blur's exponential window",
            }
        else:
            settings["lag"] = _lag_stage(model, x, time_s, state)
        if settings["lag"] and settings["lag"].get("applied"):
            x = state.output.copy()
        x, settings["fixed_pattern"] = _fixed_pattern_stage(model, x, time_s)

    # 2-3. noise, gain/offset, counts
    if reference_temperature_k is None:
        reference_temperature_k = float(model.reference_temperature_k)
    if model.is_reflective:  # NIR, SWIR: photoelectrons of a capped auto exposure
        x, gain, offset, gain_source, noise_sigma, settings["noise"] = _photon_stage(model, x, rng, noise)
    elif model.is_infrared:
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
            # the exposure cannot exceed EO_MAX_EXPOSURE_S: the input that fills the well then
            l_floor = model.full_well_e / photoelectrons_per_input(model, EO_MAX_EXPOSURE_S)
            l_sat = max(level / EO_AUTO_EXPOSURE_FILL, l_floor)
            gain_source = (
                f"auto exposure: {EO_AUTO_EXPOSURE_PERCENTILE:g}th percentile at "
                f"{EO_AUTO_EXPOSURE_FILL:.0%} of full well"
                + (f", exposure capped at {EO_MAX_EXPOSURE_S:.4g} s (low light)" if l_sat == l_floor else "")
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
    if model.is_reflective and model.agc in ("none", "linear"):
        image8, info = _reflective_display(counts, model, offset)
    elif model.is_infrared:
        image8, info = agc(
            counts,
            model.agc,
            model.agc_percentiles,
            model.bit_depth,
            plateau=model.agc_plateau,
            max_gain=model.agc_max_gain,
            midpoint=model.agc_midpoint,
        )
    else:
        image8, info = _eo_display(counts, model, offset, eo_space)
    settings["agc"] = info

    # 5. compression of the 8-bit image
    if model.jpeg_quality > 0:
        before = image8
        image8 = jpeg_roundtrip(image8, model.jpeg_quality)
        err = image8.astype(float) - before
        settings["compression"] = {
            "model": "JPEG baseline (Pillow/libjpeg)",
            "quality": int(model.jpeg_quality),
            "rms_error_levels": float(np.sqrt(np.mean(err * err))) if err.size else 0.0,
        }
    else:
        settings["compression"] = None
    if model.h264_crf > 0:
        if state is None:
            state = ChainState()
        if state.video is None or state.video.shape != image8.shape or state.video.crf != model.h264_crf:
            state.video = H264Stream(model.h264_crf, image8.shape)
        before = image8
        image8 = state.video.roundtrip(image8)
        err = image8.astype(float) - before
        settings["compression"] = {
            "model": "H.264 (libx264 via PyAV), no B-frames, zero latency"
            + (" after JPEG" if settings["compression"] else ""),
            "crf": int(model.h264_crf),
            "frame_in_stream": state.video.frames - 1,
            "frame_bytes": state.video.bytes[-1] if state.video.bytes else None,
            "rms_error_levels": float(np.sqrt(np.mean(err * err))) if err.size else 0.0,
        }
    return ChainOutput(
        counts=counts, image8=image8, radiance=x, noise_sigma=float(noise_sigma), settings=settings
    )


def _photon_stage(model: SensorModel, x, rng, noise: bool):
    """Reflective infrared (NIR, SWIR) detector: auto exposure (the 99.5th percentile at 80 % of
    the full well, exposure at most :data:`EO_MAX_EXPOSURE_S`) or the authored gain, Poisson
    shot noise on the photoelectrons :func:`photoelectrons_per_input` plus Gaussian read noise
    (EMVA 1288), as the EO chain on one channel. Returns (radiance with noise, gain [counts per
    W m-2 sr-1], offset, gain source, noise sigma at half full well [W m-2 sr-1], settings)."""
    if model.gain is None:
        level = float(np.percentile(x, EO_AUTO_EXPOSURE_PERCENTILE)) if x.size else 0.0
        l_floor = model.full_well_e / photoelectrons_per_input(model, EO_MAX_EXPOSURE_S)
        l_sat = max(level / EO_AUTO_EXPOSURE_FILL, l_floor)
        source = (
            f"auto exposure: {EO_AUTO_EXPOSURE_PERCENTILE:g}th percentile at {EO_AUTO_EXPOSURE_FILL:.0%} "
            "of full well"
            + (f", exposure capped at {EO_MAX_EXPOSURE_S:.4g} s (low light)" if l_sat == l_floor else "")
        )
        offset = model.offset
        gain = (model.max_count - offset) / l_sat
    else:
        gain, offset, source = model.gain, model.offset, "authored"
        l_sat = (model.max_count - offset) / gain
    e_per_unit = model.full_well_e / l_sat
    if noise:
        electrons = rng.poisson(np.clip(x, 0.0, None) * e_per_unit).astype(float)
        x = (electrons + rng.normal(0.0, model.read_noise_e, size=x.shape)) / e_per_unit
    sigma = math.sqrt(0.5 * model.full_well_e + model.read_noise_e**2) / e_per_unit if noise else 0.0
    exposure_s = model.full_well_e / (l_sat * photoelectrons_per_input(model, 1.0))
    return (
        x,
        gain,
        offset,
        source,
        sigma,
        {
            "model": "shot (Poisson) + read (Gaussian), EMVA 1288",
            "full_well_e": model.full_well_e,
            "read_noise_e": model.read_noise_e,
            "quantum_efficiency": QUANTUM_EFFICIENCY_BY_BAND[model.band],
            "exposure_s": exposure_s,
            "saturation_input": l_sat,
        },
    )


def _lag_stage(model: SensorModel, x, time_s, state) -> dict | None:
    """Bolometer lag: update ``state`` with this frame; the settings record (None when off)."""
    tau = float(model.time_constant_s)
    if tau <= 0:
        return None
    if state is None or time_s is None:
        return {"time_constant_s": tau, "applied": False, "why": "no previous frame (state/time)"}
    dt = None if state.time_s is None else float(time_s) - state.time_s
    usable = dt is not None and dt > 0 and state.signal is not None and state.signal.shape == x.shape
    out = bolometer_lag(x, state.signal, state.output, dt, tau) if usable else x.copy()
    state.time_s, state.signal, state.output = float(time_s), x.copy(), out
    record = {"time_constant_s": tau, "applied": bool(usable)}
    if usable:
        record.update(dt_s=dt, carry_over=math.exp(-dt / tau))
    else:
        record["why"] = "first frame or a step back in time: detector settled"
    return record


def _fixed_pattern_stage(model: SensorModel, x, time_s):
    """Residual FPN and its drift (IR): the new radiance and the settings record (None when off)."""
    sg, so, sr = float(model.fpn_gain_sigma), float(model.fpn_offset_sigma_k), float(model.fpn_drift_k_per_s)
    if sg == 0 and so == 0 and sr == 0:
        return x, None
    t_ffc = time_since_ffc(0.0 if time_s is None else time_s, model.ffc_interval_s)
    t_ref = float(model.reference_temperature_k)
    l_ref = planck.band_radiance(t_ref, model.wavelength_range_um, model.response_pair)
    per_k = planck.band_radiance_derivative(t_ref, model.wavelength_range_um, model.response_pair)
    zg, zo, zr = fixed_pattern(x.shape, model.fpn_seed)
    out = apply_fixed_pattern(
        x,
        zg,
        zo,
        zr,
        reference_radiance=float(l_ref),
        radiance_per_k=float(per_k),
        gain_sigma=sg,
        offset_sigma_k=so,
        drift_k_per_s=sr,
        t_since_ffc_s=t_ffc,
    )
    return out, {
        "model": "residual gain/offset after NUC + linear offset drift since the last FFC",
        "gain_sigma": sg,
        "offset_sigma_k": so,
        "drift_k_per_s": sr,
        "ffc_interval_s": float(model.ffc_interval_s),
        "time_since_ffc_s": t_ffc,
        "seed": int(model.fpn_seed),
    }


def _reflective_display(counts, model: SensorModel, black: float):
    """NIR/SWIR 8-bit image: black at the offset, white at the AGC's high percentile of the
    counts above it (full scale for "none"), at most :data:`EO_MAX_DISPLAY_GAIN` of display gain
    (as the EO display), linear grey: a frame of read noise stays dark."""
    lin = np.clip(counts.astype(float) - black, 0.0, None)
    full = model.max_count - black
    white = full
    if model.agc == "linear":
        top = float(np.percentile(lin, model.agc_percentiles[1])) if lin.size else 0.0
        white = max(top, full / EO_MAX_DISPLAY_GAIN) if top > 0 else full
    image8 = np.clip(np.rint(lin / white * 255.0), 0, 255).astype(np.uint8)
    return image8, {"mode": model.agc, "black_count": float(black), "white_count": float(white + black)}


def _eo_display(counts, model: SensorModel, black: float, eo_space: str):
    lin = np.clip(counts.astype(float) - black, 0.0, None)
    full = model.max_count - black
    if model.agc == "none":
        white = full
        info = {"mode": "none", "white_count": float(full + black)}
    else:
        white = float(np.percentile(lin.max(axis=-1), model.agc_percentiles[1]))
        # at most EO_MAX_DISPLAY_GAIN: a frame of read noise stays dark
        white = max(white, full / EO_MAX_DISPLAY_GAIN) if white > 0 else full
        info = {"mode": model.agc, "white_count": white + black, "percentile": model.agc_percentiles[1]}
    m = colour_correction_matrix(model) if eo_space == "camera" else np.eye(3)
    if model.agc not in ("histogram", "plateau") and np.array_equal(m, np.eye(3)):
        # per-channel map of the integer counts: a lookup table gives the very same values
        levels = np.clip(np.arange(model.max_count + 1, dtype=float) - black, 0.0, None) / white
        lut = np.clip(np.rint(srgb_encode(levels) * 255.0), 0, 255).astype(np.uint8)
        info["colour_matrix"] = np.round(m, 6).tolist()
        return lut[np.minimum(counts, model.max_count)], info
    rgb = lin / white
    rgb = rgb @ m.T
    if model.agc in ("histogram", "plateau"):
        lum = np.clip(rgb @ np.array([0.2126, 0.7152, 0.0722]), 0.0, None)
        q = np.clip(np.rint(lum / max(lum.max(), 1e-12) * 4095), 0, 4095).astype(np.uint16)
        eq, _ = agc(
            q,
            model.agc,
            bit_depth=12,
            plateau=model.agc_plateau,
            max_gain=model.agc_max_gain,
            midpoint=model.agc_midpoint,
        )
        target = eq.astype(float) / 255.0
        scale = np.where(lum > 0, target / np.where(lum > 0, lum, 1.0), 0.0)
        rgb = rgb * scale[..., None]
    info["colour_matrix"] = np.round(m, 6).tolist()
    image8 = np.clip(np.rint(srgb_encode(rgb) * 255.0), 0, 255).astype(np.uint8)
    return image8, info
