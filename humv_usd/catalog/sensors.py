"""Sensor presets: the four imagers of the seed's HUMVVEX experiment (EO colour, MWIR, 2 x LWIR)
and common thermal cores and cameras (FLIR Boson 320 / 640, Tau 2 640 as on the FLIR ADAS car,
Lepton 3.5, the DJI Zenmuse H20T's thermal camera).

A ``[[sensor]]`` table with ``preset = "<name>"`` takes every value below unless the table gives
it. Each preset names its sources; values marked *typical* are representative of the class of
camera, not a data-sheet number of one product. The counts calibration (gain/offset) of the IR
presets maps blackbody scenes over ``span_k`` onto the full count range
(:func:`humv_usd.physics.sensor.default_gain_offset`): 233.15-373.15 K (-40 to +100 degC, the
usual high-gain range of uncooled cores) for LWIR, 253.15-328.15 K for the cooled MWIR camera.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from humv_usd.physics.sensor import SensorModel, default_gain_offset, field_of_view_deg

PLATFORMS = ("tripod", "mast", "aerial", "vehicle", "drone", "handheld")


@dataclass(frozen=True)
class SensorPreset:
    name: str
    description: str
    band: str
    wavelength_um: tuple[float, float]
    response_wavelengths_um: tuple[float, ...]
    response: tuple[float, ...]  # peak 1
    resolution: tuple[int, int]  # (width, height) [px]
    pixel_pitch_um: float
    focal_length_mm: float
    f_number: float
    netd_k: float  # [K] (EO: 0, not used)
    bit_depth: int
    agc: str
    source: str
    agc_percentiles: tuple[float, float] = (1.0, 99.0)
    channel_response: tuple[tuple[float, ...], ...] | None = None  # EO (R, G, B)
    full_well_e: float = 10500.0
    read_noise_e: float = 2.5
    gain: float | None = None  # None: IR calibration span / EO auto exposure
    offset: float | None = None
    span_k: tuple[float, float] = (233.15, 373.15)  # IR: blackbody range mapped to 0..full scale [K]
    #: The field of view the source states [deg] and along which axis ("horizontal" or
    #: "diagonal"); None where the lens is typical rather than a data-sheet one.
    stated_fov_deg: float | None = None
    stated_fov_axis: str = "horizontal"
    frame_rate_hz: float | None = None  # the core's full frame rate (informative)

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Full horizontal and vertical field of view [deg] = 2 atan(n p / 2 f)
        (:func:`humv_usd.physics.sensor.field_of_view_deg`)."""
        w, h = self.resolution
        p, f = self.pixel_pitch_um * 1e-6, self.focal_length_mm * 1e-3
        return (field_of_view_deg(w * p, f), field_of_view_deg(h * p, f))

    @property
    def diagonal_fov_deg(self) -> float:
        """Full diagonal field of view [deg]."""
        w, h = self.resolution
        return field_of_view_deg(math.hypot(w, h) * self.pixel_pitch_um * 1e-6, self.focal_length_mm * 1e-3)


def _gauss_channel(wl, peak_um, sigma_um, cut_um=0.650, cut_width_um=0.010):
    """Gaussian colour-filter band times a logistic IR-cut edge (50 % at cut_um)."""
    g = np.exp(-0.5 * ((wl - peak_um) / sigma_um) ** 2)
    return g / (1.0 + np.exp((wl - cut_um) / cut_width_um))


def _rgb_curves():
    wl = np.round(np.arange(0.40, 0.7001, 0.01), 3)
    # typical Sony Pregius colour response (B/G/R peaks near 455/535/600 nm) behind an IR-cut filter
    r = _gauss_channel(wl, 0.600, 0.030)
    g = _gauss_channel(wl, 0.535, 0.040)
    b = _gauss_channel(wl, 0.455, 0.030)
    peak = max(r.max(), g.max(), b.max())
    r, g, b = r / peak, g / peak, b / peak
    envelope = np.maximum(np.maximum(r, g), b)
    envelope = envelope / envelope.max()
    rnd = lambda a: tuple(round(float(v), 4) for v in a)  # noqa: E731
    return tuple(wl.tolist()), rnd(envelope), (rnd(r), rnd(g), rnd(b))


_RGB_WL, _RGB_ENVELOPE, _RGB_CHANNELS = _rgb_curves()
#: Relative response of FLIR's 7.5-13.5 um VOx cores (germanium window + absorber; typical shape)
_BOSON_WL = (7.5, 8.0, 8.5, 9.0, 12.0, 12.5, 13.0, 13.5)
_BOSON_RESPONSE = (0.5, 0.85, 0.97, 1.0, 1.0, 0.95, 0.8, 0.5)
#: The band of FLIR's VOx cores with that response
_FLIR_VOX_BAND = {
    "wavelength_um": (7.5, 13.5),
    "response_wavelengths_um": _BOSON_WL,
    "response": _BOSON_RESPONSE,
}
#: The Boson 640 with its 18 mm lens (Teledyne FLIR Boson datasheet; the lwir640_12um and boson640
#: presets)
_BOSON640_CORE = {
    "resolution": (640, 512),
    "pixel_pitch_um": 12.0,
    "focal_length_mm": 18.0,
    "stated_fov_deg": 24.0,
    "frame_rate_hz": 60.0,
}
#: An 8-14 um microbolometer band: germanium optics + absorber, flat 9-12.5 um, falling past 13 um
#: (typical shape, not one product's data)
_LWIR_8_14_BAND = {
    "wavelength_um": (8.0, 14.0),
    "response_wavelengths_um": (8.0, 8.5, 9.0, 11.0, 12.5, 13.0, 13.5, 14.0),
    "response": (0.85, 0.97, 1.0, 1.0, 0.97, 0.9, 0.75, 0.55),
}


def _uncooled_lwir(**values) -> SensorPreset:
    """An uncooled microbolometer LWIR preset: 14-bit, plateau-equalisation AGC and NETD 50 mK at
    f/1.0 (the data-sheet values of every uncooled core here, each preset's ``source`` says
    where) unless ``values`` give others."""
    return SensorPreset(
        **{"band": "LWIR", "f_number": 1.0, "netd_k": 0.05, "bit_depth": 14, "agc": "plateau", **values}
    )


def _reflective(**values) -> SensorPreset:
    """A reflected-light (EO, NIR, SWIR) preset: no NETD (photon noise instead), a linear stretch
    and offset 0 unless ``values`` give others."""
    return SensorPreset(**{"netd_k": 0.0, "agc": "linear", "offset": 0.0, **values})


PRESETS: dict[str, SensorPreset] = {
    p.name: p
    for p in (
        _uncooled_lwir(
            name="atom1024_lwir",
            description="Uncooled LWIR microbolometer core, 1024x768, 17 um (Lynred ATOM 1024-like), "
            "25 mm f/1.0 lens",
            **_LWIR_8_14_BAND,
            resolution=(1024, 768),
            pixel_pitch_um=17.0,
            focal_length_mm=25.0,
            source="1024x768, 17 um pitch, 8-14 um, NETD < 50 mK at f/1: Lynred (ULIS) ATOM 1024 "
            "thermal camera core product brief (2018); 14-bit output, 25 mm f/1.0 lens "
            "(HFOV 38.4 deg) and the response shape (germanium optics + microbolometer "
            "absorber, flat 9-12.5 um, falling past 13 um) are typical values of uncooled "
            "cores, not ATOM data",
        ),
        _uncooled_lwir(
            name="lwir640_12um",
            description="Uncooled VOx LWIR core, 640x512, 12 um (FLIR Boson 640-like), 18 mm f/1.0",
            **_FLIR_VOX_BAND,
            **_BOSON640_CORE,
            source="640x512, 12 um VOx, 7.5-13.5 um, NETD < 50 mK (industrial grade < 40 mK), "
            "18 mm f/1.0 lens HFOV 24 deg, 14-bit pre-AGC video and plateau-equalisation AGC: "
            "Teledyne FLIR Boson product datasheet (2019); response shape typical, not "
            "measured",
        ),
        SensorPreset(
            name="mwir_insb640",
            description="Cooled InSb MWIR camera, 640x512, 15 um, 3-5 um cold filter, 50 mm f/2.5",
            band="MWIR",
            wavelength_um=(3.0, 5.0),
            response_wavelengths_um=(3.0, 3.1, 3.5, 4.0, 4.5, 4.9, 4.95, 5.0),
            response=(0.5, 0.62, 0.71, 0.81, 0.91, 0.99, 1.0, 0.5),
            resolution=(640, 512),
            pixel_pitch_um=15.0,
            focal_length_mm=50.0,
            f_number=2.5,
            netd_k=0.02,
            bit_depth=14,
            agc="plateau",
            span_k=(253.15, 328.15),
            stated_fov_deg=11.0,
            source="InSb 640x512, 15 um pitch, 3-5 um, NETD < 20 mK, 14-bit, f/2.5 cold stop, "
            "lowest calibrated range -20 to +55 degC (the counts span here): "
            "Teledyne FLIR X6900sc / A6750sc MWIR data sheets (typical of cooled InSb "
            "science cameras); response = photon detector with flat quantum efficiency, "
            "relative per-watt response proportional to wavelength (Dereniak & Boreman 1996, "
            "Infrared Detectors and Systems, §4), band-limited by the cold filter (edges "
            "typical); 50 mm lens: 11 x 8.8 deg field of view in the A6750sc lens table",
        ),
        _uncooled_lwir(
            name="boson320",
            description="FLIR Boson 320: uncooled VOx LWIR core, 320x256, 12 um, 6.3 mm lens (34 deg HFOV)",
            **_FLIR_VOX_BAND,
            resolution=(320, 256),
            pixel_pitch_um=12.0,
            focal_length_mm=6.3,
            stated_fov_deg=34.0,
            frame_rate_hz=60.0,
            source="320x256, 12 um uncooled VOx, 7.5-13.5 um, NETD < 50 mK (as low as < 40 mK) at "
            "f/1.0, 60 Hz (8.6 Hz export), 14-bit pre-AGC video, plateau AGC, 6.3 mm lens "
            "with 34 deg HFOV: Teledyne FLIR Boson datasheet 102-2013-40 (2021), lens table; "
            "f/1.0 and the response shape typical",
        ),
        _uncooled_lwir(
            name="boson640",
            description="FLIR Boson 640: uncooled VOx LWIR core, 640x512, 12 um, 18 mm lens (24 deg HFOV)",
            **_FLIR_VOX_BAND,
            **_BOSON640_CORE,
            source="640x512, 12 um uncooled VOx, 7.5-13.5 um, NETD < 50 mK at f/1.0, 60 Hz "
            "(8.6 Hz export), 14-bit pre-AGC video, plateau AGC, 18 mm lens with 24 deg "
            "HFOV: Teledyne FLIR Boson datasheet 102-2013-40 (2021), lens table; response "
            "shape typical",
        ),
        _uncooled_lwir(
            name="tau2_640",
            description="FLIR Tau 2 640: uncooled VOx LWIR core, 640x512, 17 um, 13 mm f/1.0 lens "
            "(45 x 37 deg; the FLIR ADAS dataset's camera)",
            **_FLIR_VOX_BAND,
            resolution=(640, 512),
            pixel_pitch_um=17.0,
            focal_length_mm=13.0,
            stated_fov_deg=45.0,
            frame_rate_hz=30.0,
            source="640x512, 17 um uncooled VOx, 7.5-13.5 um, NETD < 50 mK at f/1.0, 30 Hz "
            "(9 Hz export), 14-bit, plateau-equalisation AGC: FLIR Tau 2 product "
            "specification 102-PS242-40; 13 mm f/1.0 lens, HFOV 45 deg x VFOV 37 deg: FLIR "
            "ADAS thermal dataset description (Teledyne FLIR, 2018/2022); response shape "
            "typical",
        ),
        _uncooled_lwir(
            name="lepton35",
            description="FLIR Lepton 3.5: radiometric uncooled LWIR module, 160x120, 12 um, 57 deg HFOV",
            **_LWIR_8_14_BAND,
            resolution=(160, 120),
            pixel_pitch_um=12.0,
            focal_length_mm=1.77,
            f_number=1.1,
            stated_fov_deg=57.0,
            frame_rate_hz=8.7,
            source="160x120, 12 um, 8-14 um, NETD < 50 mK, 57 deg HFOV, f/1.1 silicon doublet, "
            "< 9 Hz, 14-bit (Raw14), histogram-equalisation AGC with clip limit: FLIR Lepton "
            "Engineering Datasheet 500-0659-00-09; the data sheet states no focal length: "
            "1.77 mm is the pinhole focal length giving 57 deg over 160 x 12 um (the real "
            "lens has barrel distortion); response shape typical",
        ),
        _uncooled_lwir(
            name="h20t_thermal",
            description="DJI Zenmuse H20T thermal camera: uncooled VOx, 640x512, 12 um, 13.5 mm f/1.0 "
            "(40.6 deg diagonal)",
            **_LWIR_8_14_BAND,
            resolution=(640, 512),
            pixel_pitch_um=12.0,
            focal_length_mm=13.5,
            stated_fov_deg=40.6,
            stated_fov_axis="diagonal",
            frame_rate_hz=30.0,
            source="Uncooled VOx microbolometer 640x512, 12 um pitch, 8-14 um, NETD <= 50 mK at "
            "f/1.0, 13.5 mm lens, DFOV 40.6 deg, 30 Hz: DJI Zenmuse H20 series specifications "
            "(dji.com/zenmuse-h20-series/specs, 2020); 14-bit counts and the response shape "
            "typical",
        ),
        _reflective(
            name="rgb_imx273",
            description="Global-shutter colour CMOS, 1440x1080, 3.45 um (Sony IMX273, e.g. FLIR "
            "Blackfly S BFS-U3-16S2C), 12 mm f/2.8",
            band="EO",
            wavelength_um=(0.4, 0.7),
            response_wavelengths_um=_RGB_WL,
            response=_RGB_ENVELOPE,
            channel_response=_RGB_CHANNELS,
            resolution=(1440, 1080),
            pixel_pitch_um=3.45,
            focal_length_mm=12.0,
            f_number=2.8,
            bit_depth=12,
            agc_percentiles=(0.0, 99.5),
            full_well_e=10500.0,
            read_noise_e=2.4,
            source="Sony IMX273 1440x1080, 3.45 um pixels, 12-bit ADC (8-bit mode too): Sony "
            "IMX273LQR product brief; saturation capacity ~10.5 ke- and temporal dark noise "
            "~2.4 e- of 3.45 um Pregius sensors: FLIR Blackfly S EMVA 1288 imaging "
            "performance reports (typical); channel responses are Gaussian approximations "
            "(B 455 nm / G 535 nm / R 600 nm peaks, IR-cut 50 % at 650 nm) of the relative "
            "response plot of Sony colour Pregius data sheets, typical not measured; 12 mm "
            "f/2.8 lens (HFOV 23.3 deg) typical",
        ),
        _reflective(
            name="swir_ingaas640",
            description="InGaAs SWIR camera, 640x512, 15 um, 0.9-1.7 um, 25 mm f/1.4",
            band="SWIR",
            wavelength_um=(0.9, 1.7),
            response_wavelengths_um=(0.9, 0.95, 1.0, 1.1, 1.3, 1.5, 1.6, 1.65, 1.7),
            response=(0.25, 0.65, 0.82, 0.92, 1.0, 1.0, 0.93, 0.65, 0.15),
            resolution=(640, 512),
            pixel_pitch_um=15.0,
            focal_length_mm=25.0,
            f_number=1.4,
            bit_depth=14,
            agc_percentiles=(0.5, 99.5),
            full_well_e=170000.0,
            read_noise_e=50.0,
            source="640x512 InGaAs focal plane, 15 um pitch, 0.9-1.7 um, 14-bit: typical of "
            "uncooled/TE-stabilised SWIR cameras (e.g. Collins Aerospace / Sensors Unlimited "
            "GA640, Xenics Bobcat-640); response: InGaAs quantum efficiency, cut on by the InP "
            "substrate near 0.9 um, flat 1.1-1.6 um, cut off by the In0.53Ga0.47As band gap at "
            "1.7 um (Rogalski, Infrared Detectors, 2nd ed., 2011, ch. 15; shape typical); full "
            "well 170 ke- and read noise 50 e- typical of the high-gain CTIA mode of such "
            "read-out circuits, not one product's data; 25 mm f/1.4 SWIR lens typical",
        ),
        _reflective(
            name="nir_imx273",
            description="Monochrome global-shutter CMOS (Sony IMX273) behind a 750 nm long-pass "
            "filter: NIR 0.75-1.0 um, 1440x1080, 3.45 um, 12 mm f/2.8",
            band="NIR",
            wavelength_um=(0.75, 1.0),
            response_wavelengths_um=(0.75, 0.8, 0.85, 0.9, 0.95, 1.0),
            response=(1.0, 0.82, 0.62, 0.42, 0.24, 0.1),
            resolution=(1440, 1080),
            pixel_pitch_um=3.45,
            focal_length_mm=12.0,
            f_number=2.8,
            bit_depth=12,
            agc_percentiles=(0.0, 99.5),
            full_well_e=10500.0,
            read_noise_e=2.4,
            source="Sony IMX273 (mono) 1440x1080, 3.45 um, 12-bit, saturation ~10.5 ke-, dark "
            "noise ~2.4 e-: as rgb_imx273 (FLIR Blackfly S EMVA 1288 reports); response: "
            "silicon quantum efficiency falling from 750 nm to the 1.1 um band gap (relative "
            "values read from the Pregius mono QE curve, typical) behind a 750 nm long-pass "
            "filter; 12 mm f/2.8 lens typical",
        ),
    )
}


def preset(name: str) -> SensorPreset:
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown sensor preset {name!r}: allowed {', '.join(PRESETS)}") from None


@functools.cache
def calibration(name: str) -> tuple[float | None, float]:
    """Gain [counts per W m^-2 sr^-1] and offset [counts] of a preset.

    IR: :func:`humv_usd.physics.sensor.default_gain_offset` over the preset's response (a
    blackbody at 233.15 K gives 0 counts, at 373.15 K full scale). EO: the authored offset and
    no gain (auto exposure).
    """
    p = preset(name)
    if p.band in ("EO", "NIR", "SWIR"):  # reflected light: auto exposure (physics.sensor)
        return p.gain, p.offset or 0.0
    model = SensorModel(
        name=p.name,
        band=p.band,
        wavelength_range_um=p.wavelength_um,
        response_wavelengths_um=np.asarray(p.response_wavelengths_um),
        response=np.asarray(p.response),
        resolution=p.resolution,
        pixel_pitch_m=p.pixel_pitch_um * 1e-6,
        f_number=p.f_number,
        focal_length_m=p.focal_length_mm * 1e-3,
        netd_k=p.netd_k,
        bit_depth=p.bit_depth,
    )
    return default_gain_offset(model, p.span_k)


def netd_for_f_number(netd_k: float, preset_f_number: float, f_number: float) -> float:
    r"""NETD [K] of a detector-limited thermal imager whose lens f-number changes from
    ``preset_f_number`` (where ``netd_k`` was specified) to ``f_number``.

    .. math::

        \mathrm{NETD}(N) = \mathrm{NETD}(N_0)\,\frac{4N^2 + 1}{4N_0^2 + 1}

    The signal power on a pixel is proportional to the projected solid angle of the optics,
    :math:`\pi/(4N^2 + 1)` (exact for an aplanatic lens, :math:`\sin\theta = 1/(2N)`), and a
    detector-limited imager (noise independent of the scene and background flux: uncooled
    microbolometers) has an NETD inversely proportional to it (everything else fixed).
    Background-limited (BLIP) cooled detectors with a matched cold stop scale more slowly
    (about :math:`\sqrt{4N^2+1}`); this law is used for every infrared sensor (see
    :mod:`humv_usd.sensors.layer`).

    References
    ----------
    .. [1] E. L. Dereniak, G. D. Boreman, Infrared Detectors and Systems, Wiley, 1996, §5.8:
       :math:`\mathrm{NETD} = (4N^2 + 1)\sqrt{\Delta f} / (\pi\,\tau_o D^* \sqrt{A_d}\,\partial L/\partial T)`.
    .. [2] M. Vollmer, K.-P. Möllmann, Infrared Thermal Imaging, 2nd ed., Wiley-VCH, 2017,
       ch. 2 (NETD and the f-number of microbolometer cameras).
    .. [3] G. C. Holst, Common Sense Approach to Thermal Imaging, JCD Publishing / SPIE Press,
       2000 (NETD of detector-limited systems).
    """
    n0, n = float(preset_f_number), float(f_number)
    return float(netd_k) * (4.0 * n * n + 1.0) / (4.0 * n0 * n0 + 1.0)


def netd_scaling_origin(name: str, f_number: float) -> str:
    """Where the NETD of preset ``name`` used at ``f_number`` comes from, when it is scaled
    (:func:`netd_for_f_number`): the text the scenario load records and the manifest reports."""
    p = preset(name)
    return (
        f"scaled from preset {p.name} NETD {p.netd_k:g} K at f/{p.f_number:g} to f/{float(f_number):g}: "
        f"x (4N^2+1)/(4N0^2+1) (detector-limited; humv_usd.catalog.sensors.netd_for_f_number)"
    )


def scenario_values(name: str) -> dict:
    """The preset as [[sensor]] key values (what a table with only ``preset`` gets)."""
    p = preset(name)
    gain, offset = calibration(name)
    return {
        "band": p.band,
        "wavelength_um": list(p.wavelength_um),
        "resolution": list(p.resolution),
        "pixel_pitch_um": p.pixel_pitch_um,
        "focal_length_mm": p.focal_length_mm,
        "f_number": p.f_number,
        "netd_k": p.netd_k,
        "bit_depth": p.bit_depth,
        "gain": gain,
        "offset": offset,
        "agc": p.agc,
        "agc_percentiles": list(p.agc_percentiles),
        "full_well_e": p.full_well_e,
        "read_noise_e": p.read_noise_e,
    }


# ---------------------------------------------------------------------------- platforms
def orbit_positions(
    center_m,
    altitude_m: float,
    radius_m: float,
    speed_m_s: float,
    times_s,
    start_deg: float = 180.0,
    clockwise: bool = False,
) -> np.ndarray:
    r"""Camera positions [m] of an aerial platform circling ``center_m`` at constant speed.

    Parameters
    ----------
    center_m : array-like (3,)
        Orbit centre on the ground [x east, y north, z up] [m]; the camera looks at it.
    altitude_m : float
        Flight height above the ground plane z = 0 [m].
    radius_m : float
        Horizontal orbit radius [m], > 0.
    speed_m_s : float
        Ground speed along the orbit [m/s].
    times_s : array-like
        Times after frame 0 [s].
    start_deg : float, default 180
        Compass azimuth of the camera seen from the centre at t = 0 [deg] (180 = south).
    clockwise : bool, default False
        Direction seen from above.

    Returns
    -------
    ndarray (n, 3)

    Notes
    -----
    Azimuth :math:`\psi(t) = \psi_0 \pm (v/R)\,t` (compass, so east = +x at 90 deg):
    :math:`p = c + (R\sin\psi, R\cos\psi, 0)` with z = altitude.
    Counter-clockwise seen from above means decreasing compass azimuth.
    """
    c = np.asarray(center_m, dtype=float)
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    rate = speed_m_s / radius_m * (1.0 if clockwise else -1.0)
    psi = np.radians(start_deg) + rate * t
    out = np.empty((t.size, 3))
    out[:, 0] = c[0] + radius_m * np.sin(psi)
    out[:, 1] = c[1] + radius_m * np.cos(psi)
    out[:, 2] = altitude_m
    return out
