"""Visible (EO) rendering: reflectance spectra, sun and sky, to CIE XYZ and sRGB.

Two estimators of the same model: the default, :mod:`humv_usd.render.eo_fast` (the infrared
estimator on visible sub-bands, X, Y, Z as its weighted channels; automatic quality: batches
until the mean error of Y away from edges is <= 1 % of the mean Y there), and the reference,
Mitsuba's spectral path tracer on the 5-nm grid below (:class:`EOScene`, ``estimator="path"``,
also used when the variant is not vectorised or ``max_depth`` is bounded).

Radiometry (opaque Lambertian surfaces, no emission in the visible)
-----------------------------------------------------------------
Each part (but calm water, a Fresnel mirror in the fast estimator: :mod:`humv_usd.render.estimator`)
reflects diffusely with its material's spectral reflectance
``humv:material:reflectance`` on ``humv:material:wavelengths`` (linear, held beyond the ends),
sampled every :data:`EO_STEP_NM` nm over 360-830 nm as a Mitsuba ``regular`` spectrum. Illumination:

- the sun: a ``directional`` emitter along ``humv:environment:sunDirection`` with the direct
  beam spectral irradiance at the ground ``humv:atmosphere:solarSpectralIrradiance``
  (beam-normal, W m-2 um-1 -> W m-2 nm-1); without that table (or one not covering
  0.40-0.70 um), a 5772 K blackbody spectrum scaled to the broadband
  ``humv:environment:directNormalIrradiance``
  (:func:`humv_usd.render.radiometry.blackbody_sun`, an approximation: no spectral
  atmospheric extinction); none when the sun is below the horizon;
- the sky: a ``constant`` environment with, per wavelength, the cosine-weighted hemispherical
  mean of ``humv:atmosphere:skySpectralRadiance`` against zenith (the uniform sky that gives the
  same irradiance on a horizontal surface; its angular structure is not kept in the visible);
- lamps and lit windows (:mod:`humv_usd.render.lights`): Mitsuba point, spot and area emitters
  in the path tracer; next-event estimation per bin in the fast estimator.

Atmospheric path: per pixel by range as in the infrared, on the film's X, Y, Z channels,
:math:`XYZ_{sensor} = \\tau_{xyz}(r)\\,XYZ + P_{xyz}(r)` with the sensor's spectral path table
``/World/Atmosphere/Paths/<sensor>_path`` reduced to the channels with the CIE colour-matching
functions (:func:`humv_usd.render.radiometry.reduce_xyz`: the transmittance weighted for a
spectrally flat surface radiance, an approximation); r is the range of the pixel centre's first
hit; sky pixels get no path term. Skipped (and listed) when there is no table or it does not
cover 0.40-0.70 um. The table's path radiance is thermal only (≈ 0 in the visible), so
:math:`P_{xyz}` also carries Koschmieder's airlight :math:`L_h (1 - \\tau(r))`, the horizon sky
radiance :math:`L_h` (the sky table's rows at zenith 85-90°, else its cosine-weighted mean;
:func:`humv_usd.render.radiometry.horizon_sky`) scattered into the line of sight, with the path
transmittance standing in for the scattering transmittance (Koschmieder 1924; Middleton 1952;
:func:`humv_usd.render.radiometry.reduce_xyz`): distant objects fade toward the horizon sky,
their contrast falling as :math:`C(r) = C_0\\,\\tau(r)`. No airlight (and noted) without a sky
table covering 0.40-0.70 um.

Colour: the film integrates the spectrum against the CIE 1931 2° colour-matching functions and
gives CIE XYZ normalised so that a constant spectral radiance :math:`L` [W m-2 sr-1 nm-1] has
:math:`Y = L` (Mitsuba divides by :math:`\\int\\bar y\\,d\\lambda` = 106.857 nm): the luminance is
:math:`683\\,\\mathrm{lm\\,W^{-1}} \\times 106.857\\,\\mathrm{nm} \\times Y` [cd m-2]. XYZ goes to
linear sRGB (D65) with colour-science's sRGB matrix (``colour.XYZ_to_sRGB``; CIE 1931 and
IEC 61966-2-1), frozen in :mod:`humv_usd.render.cie` so that a render does not import
colour-science.

Closed-form check: a white Lambertian plate (:math:`\\rho = 1`) under a beam of spectral
irradiance :math:`E` at incidence :math:`\\theta` has radiance :math:`E\\rho\\cos\\theta/\\pi`
(tests/test_render_eo.py).
"""

from __future__ import annotations

import os

import numpy as np

from humv_usd import images as writers
from humv_usd import mode
from humv_usd.fileio import write_json
from humv_usd.geometry.camera import CAMERA_FILE, Camera, camera_file
from humv_usd.physics.sensor import srgb_encode
from humv_usd.render import elements as el
from humv_usd.render import eo_fast, lights, nightlight, radiometry
from humv_usd.render import estimator as E
from humv_usd.render import quality as Q
from humv_usd.render.cie import XYZ_TO_SRGB
from humv_usd.render.frame import exr_metadata, path_table
from humv_usd.render.ir import IRScene, SensorSetup, monte_carlo_stderr
from humv_usd.render.light import FrameLight, read_frame_light
from humv_usd.render.radiometry import hemisphere_mean
from humv_usd.render.renderer import choose_estimator
from humv_usd.usd import environment as usd_environment
from humv_usd.usd import lights as usd_lights
from humv_usd.usd.atmosphere import atmosphere_spectra

#: Wavelength grid of the Mitsuba spectra [nm] (Mitsuba's spectral variants sample 360-830 nm).
EO_STEP_NM = 5.0
EO_WAVELENGTHS_NM = np.arange(360.0, 830.0 + 0.5 * EO_STEP_NM, EO_STEP_NM)
#: The visible range an EO render needs covered by the illumination tables [um] (within 0.01 um);
#: beyond it, up to Mitsuba's 360-830 nm, the tables are held at their end values (the CIE
#: colour-matching functions carry ~1 % of their weight there).
EO_RANGE_UM = (0.40, 0.70)
#: Mitsuba's normalisation of Y: the integral of the CIE 1931 y-bar over 360-830 nm [nm].
CIE_Y_INTEGRAL_NM = 106.856895
#: Maximum luminous efficacy [lm W-1].
KM_LM_PER_W = 683.0
#: Spectra are never exactly zero in Mitsuba (its spectrum sampling needs probability mass);
#: "off" emitters get this value and a sampling weight of 0.
TINY = el.SPECTRUM_FLOOR
#: PNG preview exposure (without the sensor chain): this percentile of Y maps to PREVIEW_WHITE.
PREVIEW_PERCENTILE = 99.0
PREVIEW_WHITE = 0.9


def _spectrum(values_nm_grid) -> dict:
    """A Mitsuba ``regular`` spectrum on :data:`EO_WAVELENGTHS_NM` (never collapsed to a uniform
    one, so its values stay updatable per frame)."""
    return el.regular_spectrum(EO_WAVELENGTHS_NM, values_nm_grid)


def reflectance_spectrum(material) -> np.ndarray:
    """A material's reflectance on :data:`EO_WAVELENGTHS_NM` (linear, held beyond the table)."""
    wl = np.asarray(material.wavelengths_um, dtype=float)
    rho = np.asarray(material.reflectance, dtype=float)
    if wl.size == 1:
        return np.full(EO_WAVELENGTHS_NM.size, float(rho[0]))
    return np.clip(np.interp(EO_WAVELENGTHS_NM / 1000.0, wl, rho), 0.0, 1.0)


def _covers_visible(wl) -> bool:
    return (
        wl is not None and wl.size > 1 and wl[0] <= EO_RANGE_UM[0] + 0.01 and wl[-1] >= EO_RANGE_UM[1] - 0.01
    )


def illumination(
    spectra, sun_direction, dni_w_m2: float | None = None
) -> tuple[np.ndarray | None, np.ndarray | None, dict]:
    """Sun irradiance and uniform-sky radiance on :data:`EO_WAVELENGTHS_NM`, per nm, and notes.

    The sun comes from the solar spectral table when it covers 0.40-0.70 um, else from the
    broadband ``dni_w_m2`` with a blackbody shape (:func:`humv_usd.render.radiometry.blackbody_sun`).
    Returns (sun [W m-2 nm-1] or None, sky [W m-2 sr-1 nm-1] or None, ran).
    """
    ran: dict = {}
    wl = None if spectra is None else spectra.wavelengths_um
    covered = _covers_visible(wl)
    x = EO_WAVELENGTHS_NM / 1000.0
    sun = sky = None
    table = covered and spectra.solar_irradiance is not None
    if sun_direction is None:
        ran["sun"] = "skipped: no humv:environment:sunDirection"
    elif not table and not dni_w_m2:
        ran["sun"] = (
            "skipped: no humv:atmosphere:solarSpectralIrradiance covering 0.40-0.70 um "
            "(and no humv:environment:directNormalIrradiance)"
        )
    elif sun_direction[2] <= 0:
        ran["sun"] = "skipped: sun below the horizon (night)"
    elif table:
        sun = np.interp(x, wl, spectra.solar_irradiance) / 1000.0
        ran["sun"] = "directional, spectral irradiance from humv:atmosphere:solarSpectralIrradiance"
    else:
        sun = radiometry.blackbody_sun(x, dni_w_m2) / 1000.0
        ran["sun"] = (
            f"directional, no humv:atmosphere:solarSpectralIrradiance covering 0.40-0.70 um: "
            f"DNI {float(dni_w_m2):.4g} W m-2 with a {radiometry.SUN_FALLBACK_NOTE}"
        )
    if not covered:
        ran["sky"] = "skipped: no atmosphere spectra covering 0.40-0.70 um"
    elif spectra.sky_radiance is None:
        ran["sky"] = "skipped: no humv:atmosphere:skySpectralRadiance"
    else:
        per_wl = np.array(
            [hemisphere_mean(spectra.sky_zenith_deg, spectra.sky_radiance[:, j]) for j in range(wl.size)]
        )
        sky = np.interp(x, wl, per_wl) / 1000.0
        ran["sky"] = "uniform, cosine-weighted hemispherical mean of humv:atmosphere:skySpectralRadiance"
    return sun, sky, ran


def after_sunset(light, sun_direction, sun_nm, sky_nm, ran: dict):
    """With the sun below the horizon: the twilight, moonlit and natural night sky added to the
    sky, and the moon in place of the sun (:func:`humv_usd.render.nightlight.frame_night_light`
    of the frame's ``light``), on :data:`EO_WAVELENGTHS_NM` per nm. Returns (direction of the
    directional light or None, its irradiance or None, sky); ``ran`` gets ``night``. Unchanged
    while the sun is up."""
    night = nightlight.frame_night_light(light, EO_WAVELENGTHS_NM / 1000.0)
    if night is None:
        return sun_direction, sun_nm, sky_nm
    sky_nm = night.sky / 1000.0 + (0.0 if sky_nm is None else sky_nm)
    ran["night"] = night.ran
    ran["sky"] = f"{ran.get('sky')}; plus the night sky (night.twilight, night.night_sky, night.moon)"
    if night.moon_direction is None:
        return sun_direction, None, sky_nm
    ran["sun"] = f"{ran.get('sun')}; the moon takes the directional light (night.moon)"
    return night.moon_direction, night.moon_irradiance / 1000.0, sky_nm


class EOScene(IRScene):
    """The Mitsuba scene of the EO sensors (spectral variant), built once per mesh topology.

    Shares vertex and camera updates and the label ray cast (:meth:`IRScene.hits`) with
    :class:`~humv_usd.render.ir.IRScene`; surfaces only reflect.

    Parameters
    ----------
    parts : list of (Part, vertices, flip)
        Every material must carry a reflectance (``Material.reflectance``).
    sensors : list of SensorSetup
    spp, max_depth : int
    workdir : path-like
    sky, sun : bool
        Include the uniform sky / the sun.
    """

    spectral = True

    def __init__(
        self,
        parts,
        sensors: list[SensorSetup],
        spp: int,
        max_depth: int,
        workdir,
        sky: bool = True,
        sun: bool = True,
        lamps=(),
    ):
        mi = mode.mitsuba(spectral=True)
        self.mi = mi
        self.scalar = not mode.is_vectorized()
        self.parts = [p for p, _, _ in parts]
        self.sensors = {s.id: s for s in sensors}
        self.sky_map = False
        self.has_sun = bool(sun)
        self.has_sky = bool(sky)
        elements = []
        if self.has_sky:
            elements.append(el.constant_sky(_spectrum(np.full(EO_WAVELENGTHS_NM.size, TINY)), "values"))
        if self.has_sun:
            elements.append(el.directional_sun(_spectrum(np.full(EO_WAVELENGTHS_NM.size, TINY)), "values"))
        elements += [el.perspective_sensor(mi, s, spp, "xyz") for s in sensors]
        elements += lights.lamp_elements(mi, list(lamps), EO_WAVELENGTHS_NM)  # street lamps, windows
        for part, vertices, flip in parts:
            bsdf = {"type": "diffuse", "reflectance": _spectrum(reflectance_spectrum(part.material))}
            elements.append(el.mesh(part, vertices, flip, workdir, bsdf=bsdf, prefix="eo_"))
        #: the scene's elements (Mitsuba dicts and the parameter keys each updates per frame)
        self.elements = elements
        scene = el.scene_dict(max_depth, elements)
        self.scene = mi.load_dict(scene, optimize=False)
        self.params = mi.traverse(self.scene)
        self._sensor_objects = {s.id(): s for s in self.scene.sensors()}
        channels = ["X", "Y", "Z"] + list(self.scene.integrator().aov_names())
        self._m1 = [channels.index(f"nested.{c}") for c in "XYZ"]
        self._m2 = channels.index("m2_nested.Y")
        self._positions = {p.key: np.asarray(v, dtype=np.float32) for p, v, _ in parts}
        self._flips = {p.key: bool(f) for p, _, f in parts}
        self.geometry_version = 0  # as IRScene: the smooth-shading blend is cached against it

    def _mi(self):
        self.mi = mode.mitsuba(spectral=True)
        return self.mi

    def set_illumination(self, sun_direction, sun_nm, sky_nm) -> None:
        """Sun (toward-sun unit vector, irradiance per nm on the grid or None = off) and sky
        (radiance per nm or None = off)."""
        self._mi()
        if self.has_sun:
            on = sun_nm is not None and sun_direction is not None
            vals = np.maximum(
                np.asarray(sun_nm if on else np.zeros(EO_WAVELENGTHS_NM.size), dtype=float), TINY
            )
            self._set_array("sun.irradiance.values", vals)
            # next-event estimation picks sun or sky in proportion to the irradiance each can
            # deliver (beam-normal sun, pi x mean sky radiance): far less noise than 1:1
            self.params["sun.sampling_weight"] = float(np.sum(vals)) if on else 0.0
            if on:
                d = -np.asarray(sun_direction, dtype=float)
                helper = [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0]
                cls = self.mi.ScalarTransform4f if self.scalar else self.mi.Transform4f
                self.params["sun.to_world"] = cls().look_at(
                    origin=[0.0, 0.0, 0.0], target=[float(v) for v in d], up=helper
                )
        if self.has_sky:
            on = sky_nm is not None
            vals = np.maximum(
                np.asarray(sky_nm if on else np.zeros(EO_WAVELENGTHS_NM.size), dtype=float), TINY
            )
            self._set_array("sky.radiance.values", vals)
            self.params["sky.sampling_weight"] = float(np.pi * np.sum(vals)) if on else 0.0

    def set_camera(self, sensor_id, pose) -> None:
        self._mi()
        super().set_camera(sensor_id, pose)

    def update(self) -> None:
        self._mi()
        self.params.update()

    def render_xyz(self, sensor_id: str, spp: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """CIE XYZ (H, W, 3) [W m-2 sr-1 nm-1, see module notes] and the standard error of Y."""
        mi = self._mi()
        img = mi.render(
            self.scene, sensor=self.mitsuba_sensor(sensor_id), spp=int(spp), seed=int(seed) % 2**32
        )
        a = np.asarray(img, dtype=np.float64)
        xyz = a[..., self._m1]
        return xyz, monte_carlo_stderr(xyz[..., 1], a[..., self._m2], spp)


def xyz_to_linear_srgb(xyz) -> np.ndarray:
    """Linear sRGB (D65) from CIE XYZ: colour-science's ``XYZ_to_sRGB`` without the transfer
    function, i.e. its sRGB matrix (:data:`humv_usd.render.cie.XYZ_TO_SRGB`)."""

    return np.asarray(xyz, dtype=float) @ XYZ_TO_SRGB.T


def srgb_preview(xyz) -> tuple[np.ndarray, float]:
    """8-bit sRGB (H, W, 3) of an XYZ image exposed so that the :data:`PREVIEW_PERCENTILE` of Y
    maps to :data:`PREVIEW_WHITE`, and that exposure (a scale on XYZ); colour-science's
    XYZ -> sRGB matrix (:func:`xyz_to_linear_srgb`) and the IEC 61966-2-1 encoding
    (:func:`humv_usd.physics.sensor.srgb_encode`), as ``colour.XYZ_to_sRGB``."""

    xyz = np.asarray(xyz, dtype=float)
    y = xyz[..., 1][np.isfinite(xyz[..., 1])]
    top = float(np.percentile(y, PREVIEW_PERCENTILE)) if y.size else 0.0
    exposure = PREVIEW_WHITE / top if top > 0 else 1.0
    rgb = srgb_encode(xyz_to_linear_srgb(np.nan_to_num(xyz) * exposure))
    return np.rint(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8), exposure


#: EXR channels of an EO frame (float32), with units.
EO_EXR_CHANNELS = {
    "X": "CIE 1931 XYZ, W m-2 sr-1 nm-1 (y-bar weighted mean spectral radiance; luminance = 683 * 106.857 * Y cd m-2)",
    "Y": "as X",
    "Z": "as X",
    "R": "linear sRGB (D65) from XYZ via colour.XYZ_to_sRGB, same scale as XYZ",
    "G": "as R",
    "B": "as R",
    "Y_stderr": "Monte Carlo standard error of Y",
    "depth": "m (distance along the optical axis; inf for sky)",
    "instance_id": "1 (integer, stored as uint32; 0 = sky/background)",
}


class EORender:
    """Renders the EO sensors of a stage frame by frame (called from ``render_stage``).

    Skips (with the reason in :attr:`skipped`) when the stage has no visible illumination data,
    or a rendered material has no ``humv:material:reflectance``.
    """

    def __init__(
        self,
        stage,
        sensors,
        spp: int,
        max_depth: int,
        seed: int,
        out_dir,
        truth=None,
        estimator: str = "fast",
        spp_auto: bool = False,
    ):
        from pxr import Usd

        self.stage = stage
        self.truth = truth  # humv_usd.groundtruth.GroundTruth: the same labels as the IR sensors
        self.spp, self.max_depth, self.seed, self.out_dir = int(spp), int(max_depth), int(seed), out_dir
        self.estimator, self.estimator_note = _eo_estimator(estimator, max_depth)
        # artificial lights (UsdLux lamps with a HumV spectrum): emitters of the spectral path
        # tracer's scene, next-event estimation in the fast estimator (render.lights.lamp_table)
        self.has_lamps = bool(usd_lights.read_lamps(stage, Usd.TimeCode(stage.GetStartTimeCode())))
        self.lamps_key = None
        # automatic quality (fast estimator, no spp given): batches of DEFAULT_EO_SPP
        self.spp_auto = bool(spp_auto) and self.estimator == "fast"
        if self.spp_auto:
            self.spp = eo_fast.DEFAULT_EO_SPP
        self.sensors = list(sensors)
        self.skipped: list[dict] = []
        self.scene: EOScene | None = None
        self.key = None
        self.records = {
            s.name: {"frames": [], "cameras": [], "timings_s": {"render": 0.0, "labels": 0.0, "write": 0.0}}
            for s in self.sensors
        }
        self.bins = eo_fast.visible_bins(eo_fast.DEFAULT_EO_BINS) if self.estimator == "fast" else None
        self.ids = {s.name: f"eo_{i}" for i, s in enumerate(self.sensors)}
        if not self.sensors:
            return
        frames = [int(round(stage.GetStartTimeCode()))]
        t0 = Usd.TimeCode(frames[0])
        spectra = atmosphere_spectra(stage, t0)
        covered = _covers_visible(spectra.wavelengths_um)
        self.has_sun = usd_environment.sun_direction(stage, t0) is not None and (
            (covered and spectra.solar_irradiance is not None)
            or usd_environment.direct_normal_irradiance(stage, t0) is not None
        )
        self.has_sky = covered and spectra.sky_radiance is not None
        self._paths: dict = {}  # sensor name -> (PathTable identity, XYZPath)
        if not (self.has_sun or self.has_sky or self.has_lamps):
            self._skip_all(
                "no visible illumination in the stage: humv:atmosphere:solarSpectralIrradiance / "
                "skySpectralRadiance covering 0.40-0.70 um (atmosphere layer) and "
                "humv:environment:directNormalIrradiance are absent"
            )

    @property
    def shares_scene(self) -> bool:
        """Whether the EO sensors render from the frame's one scene (the fast estimator traces
        geometry only, in the same Mitsuba variant as the infrared); the spectral path tracer
        needs a scene of its own (spectral variant, reflectance spectra)."""
        return self.estimator == "fast" and bool(self.sensors)

    def _skip_all(self, reason: str) -> None:
        self.skipped += [
            {"name": s.name, "prim": s.path, "band": s.band, "reason": reason} for s in self.sensors
        ]
        self.sensors = []

    def path(self, sensor, time_code, spectra=None) -> tuple[radiometry.XYZPath | None, str]:
        """The sensor's path table reduced to X, Y, Z with the Koschmieder airlight of the horizon
        sky of ``spectra`` (:func:`radiometry.reduce_xyz`, :func:`radiometry.horizon_sky`), or
        None, and what ran."""
        table = path_table(self.stage, sensor, time_code)
        if table is None:
            return (
                None,
                "skipped: no path table under /World/Atmosphere/Paths (no transmittance or path radiance)",
            )
        if not _covers_visible(table.wavelengths_um):
            return None, f"skipped: path table {table.prim} does not cover 0.40-0.70 um"
        horizon, rule = None, None
        if (
            spectra is not None
            and _covers_visible(spectra.wavelengths_um)
            and spectra.sky_radiance is not None
        ):
            l_h, rule = radiometry.horizon_sky(spectra.sky_zenith_deg, spectra.sky_radiance)
            horizon = (spectra.wavelengths_um, l_h)
        key = (
            table.ranges_m.tobytes(),
            table.wavelengths_um.tobytes(),
            table.transmittance.tobytes(),
            table.radiance.tobytes(),
            None if horizon is None else (horizon[0].tobytes(), horizon[1].tobytes()),
        )
        cached = self._paths.get(sensor.name)
        if cached is None or cached[0] != key:
            cached = self._paths[sensor.name] = (key, radiometry.reduce_xyz(table, horizon))
        path = cached[1]
        if path.horizon_xyz is None:
            air = (
                "no airlight: no humv:atmosphere:skySpectralRadiance covering 0.40-0.70 um "
                "(thermal path radiance only, no fading toward the horizon sky)"
            )
        else:
            air = (
                f"Koschmieder airlight L_h (1 - tau(r)) added (path tau for the scattering tau), "
                f"L_h = {rule}, Y_h = {path.horizon_xyz[1]:.6g} W m-2 sr-1 nm-1"
            )
        return path, (
            f"per pixel by range from {table.prim} reduced to CIE X, Y, Z (colour-matching "
            f"functions, flat-spectrum transmittance weighting; {table.ranges_m.size} ranges "
            f"{table.ranges_m[0]:g}-{table.ranges_m[-1]:g} m); {air}"
        )

    def frame(
        self, state, frame: int, chains, write=None, light: FrameLight | None = None, shared=None
    ) -> None:
        """Render, label and write every EO sensor at ``frame``; ``write(what, fn, *args,
        **kwargs)`` runs the file writes (the pipeline's background writer: this frame's files are
        written while the next one renders; default: now). ``light``: the frame's light
        (:func:`humv_usd.render.light.read_frame_light`; default: read here). ``shared``: the
        frame's scene shared with the infrared sensors (:attr:`shares_scene`: built with these
        sensors under :attr:`ids`, vertices and cameras set); default: this object builds its own."""
        write = write or (lambda _what, fn, *args, **kwargs: fn(*args, **kwargs))
        import tempfile
        import time

        from pxr import Usd

        if not self.sensors:
            return
        parts = [
            (part, state.points[m.path][part.vertex_ids], state.flip[m.path])
            for m in state.meshes
            for part in m.parts
        ]
        time_code = Usd.TimeCode(frame)
        light = light or read_frame_light(self.stage, time_code)  # the render reads it once per frame
        lamps = list(light.lamps) if self.has_lamps else []
        # the path tracer's scene holds the lamps as emitters: rebuilt when they change
        lamps_key = (
            repr([(a.path, a.to_world.tobytes(), a.luminous_flux_lm, a.luminance) for a in lamps])
            if self.estimator != "fast"
            else None
        )
        if self.scene is None or state.topology_key != self.key or lamps_key != self.lamps_key:
            self.lamps_key = lamps_key
            bare = sorted({p.material.path for p, _, _ in parts if p.material.reflectance is None})
            if bare:
                self._skip_all(
                    f"material {bare[0]} (and {len(bare) - 1} more) has no humv:material:reflectance"
                    if len(bare) > 1
                    else f"material {bare[0]} has no humv:material:reflectance"
                )
                return
            if shared is None:
                setups = [
                    SensorSetup(self.ids[s.name], s.resolution[0], s.resolution[1], state.cameras[s.name])
                    for s in self.sensors
                ]
                with tempfile.TemporaryDirectory(prefix="humv_eo_") as tmp:
                    if self.estimator == "fast":  # geometry only: the estimator lights it itself
                        self.scene = IRScene(parts, setups, self.spp, self.max_depth, tmp)
                    else:
                        self.scene = EOScene(
                            parts,
                            setups,
                            self.spp,
                            self.max_depth,
                            tmp,
                            sky=self.has_sky,
                            sun=self.has_sun,
                            lamps=lamps,
                        )
            self.key = state.topology_key
        elif shared is None:
            for part, vertices, _ in parts:
                self.scene.set_vertices(part, vertices)
        if shared is not None:  # the frame's one scene: vertices and cameras set by the render
            self.scene = shared
        else:
            for s in self.sensors:
                self.scene.set_camera(self.ids[s.name], state.cameras[s.name])
        scene = self.scene
        spectra, sun_direction = light.spectra, light.sun_direction
        sun, sky, ran = illumination(spectra, sun_direction, light.dni_w_m2)
        sun_direction, sun, sky = after_sunset(light, sun_direction, sun, sky, ran)
        if self.has_lamps:
            ran["lamps"] = lights.describe(lamps)
        sun_up = light.sun_direction is not None and light.sun_direction[2] > 0  # (not the moon)
        cloud = light.clouds if sun is not None and sun_up else None
        if cloud is not None:
            ran["cloud_shadows"] = cloud.describe() + (
                "" if self.estimator == "fast" else " (not rendered: the path tracer's sun is uniform)"
            )
        if self.estimator == "fast":
            light = eo_fast.bin_illumination(self.bins, sun, sky, sun_direction)
            light.clouds = cloud
            light.lamps = lights.lamp_table(lamps, eo_fast.GRID_NM, self.bins.channel_preserving_mean)
            weight = eo_fast.horizontal_irradiance(sun, sky, sun_direction, lamps)
            rho = {}

            def reflectance_of(material):
                if material.path not in rho:
                    rho[material.path] = self.bins.mean(reflectance_spectrum(material), weight)
                return rho[material.path]
        else:
            scene.set_illumination(sun_direction, sun, sky)
        scene.update()
        for s in self.sensors:
            rec = self.records[s.name]
            t, cpu0 = time.perf_counter(), time.process_time()
            before = dict(rec["timings_s"])
            sid = self.ids[s.name]
            if self.estimator == "fast":
                xyz, y_err, noise = self._render_fast(scene, sid, state, reflectance_of, light, frame)
            else:
                xyz, y_err = scene.render_xyz(sid, self.spp, self.seed + frame)
                noise = Q.relative_noise(xyz[..., 1], y_err, E.geometric_edges(scene.hits(sid)))
                noise.update(spp_used=self.spp, spp_rule=f"path tracer: {self.spp} spp")
            rec["timings_s"]["render"] += time.perf_counter() - t
            t = time.perf_counter()
            rel = os.path.join(s.name, f"{frame:04d}")
            if self.truth is not None:  # emissivity is a thermal-band quantity: NaN for EO
                hits = self.truth.annotate(
                    scene,
                    self.ids[s.name],
                    s,
                    state,
                    lambda part: float("nan"),
                    self.out_dir,
                    rel,
                    write=write,
                )
                extra = hits.channels
            else:
                hits, extra = scene.hits(self.ids[s.name]), {}
            rec["timings_s"]["labels"] += time.perf_counter() - t
            t = time.perf_counter()
            path, path_ran = self.path(s, time_code, spectra)
            if path is not None:  # atmosphere per pixel by range of the pixel centre's first hit
                h = scene.hits(self.ids[s.name])
                origin = np.asarray(state.cameras[s.name].origin, dtype=np.float64)
                hit = np.isfinite(h.depth)
                range_m = np.where(
                    hit, np.linalg.norm(np.where(hit[..., None], h.position, 0.0) - origin, axis=-1), np.inf
                )
                xyz, tau = radiometry.apply_xyz_path(xyz, range_m, path)
                y_err = y_err * tau[..., 1]
            rgb = xyz_to_linear_srgb(xyz)
            rec["timings_s"]["render"] += time.perf_counter() - t
            t = time.perf_counter()
            # sensor chain: the single call site for EO (depth and instances: the motion blur's velocity)
            movers = chains.movers(extra.get("class_id"), hits.instance)
            chained = chains.apply(s, rgb, frame, eo_space="srgb", depth=hits.depth, instance=movers)
            camera = Camera.from_pose(state.cameras[s.name], xyz.shape[1], xyz.shape[0])
            rec["cameras"].append((frame, camera))
            channels = {
                "X": xyz[..., 0],
                "Y": xyz[..., 1],
                "Z": xyz[..., 2],
                "R": rgb[..., 0],
                "G": rgb[..., 1],
                "B": rgb[..., 2],
                "Y_stderr": y_err,
                "depth": hits.depth,
                "instance_id": hits.instance.astype(np.float32),
                **extra,
            }
            if chained is not None:
                channels.update(
                    {f"counts_{c}": chained.counts[..., i].astype(np.float32) for i, c in enumerate("RGB")}
                )
            write(
                rel + ".exr",
                writers.write_exr,
                os.path.join(self.out_dir, rel + ".exr"),
                channels,
                metadata=exr_metadata(
                    s,
                    frame,
                    noise["spp_used"],
                    camera,
                    estimator=self.estimator,
                    colour="CIE 1931 XYZ (CIE.X, CIE.Y, CIE.Z) and linear sRGB (D65) (R, G, B)",
                ),
            )
            if self.truth is not None:
                self.truth.image_written(rel, channels)
            png, exposure = srgb_preview(xyz)
            write(rel + ".png", writers.write_png, os.path.join(self.out_dir, rel + ".png"), png)
            chain_record = chains.write(chained, self.out_dir, rel, write=write)
            rec["timings_s"]["write"] += time.perf_counter() - t
            y = xyz[..., 1]
            rec["frames"].append(
                {
                    "frame": frame,
                    "exr": rel + ".exr",
                    "png": rel + ".png",
                    "preview_exposure": exposure,
                    "Y_mean": float(np.mean(y)),
                    "luminance_mean_cd_m2": float(KM_LM_PER_W * CIE_Y_INTEGRAL_NM * np.mean(y)),
                    "Y_stderr_mean": float(np.nanmean(y_err)) if np.isfinite(y_err).any() else None,
                    "monte_carlo_error_relative": noise,
                    # the automatic quality's verdict on the image and every region (None: the
                    # path tracer or a given spp)
                    "quality": noise.pop("quality", None),
                    "illumination": ran,
                    "atmosphere": path_ran,
                    "sensor_chain": chain_record,
                    "timings_s": {
                        **{k: rec["timings_s"][k] - before[k] for k in rec["timings_s"]},
                        "cpu": time.process_time() - cpu0,
                    },
                }
            )

    def _render_fast(self, scene, sid, state, reflectance_of, light, frame):
        """X, Y, Z, the standard error of Y and its summary with the fast estimator: the given
        spp, or (automatic quality) batches of :data:`eo_fast.DEFAULT_EO_SPP`, at least
        :data:`humv_usd.render.quality.MIN_BATCHES` (each pixel's error from >= 4 replicas; one
        batch's 2 replicas gave night frames whose pixels differed between seeds where both stated
        no error), more until the error of Y relative to the mean Y away from edges is <=
        :data:`eo_fast.EO_TARGET_RELATIVE` on average and its 99th percentile <= 10 % (the
        infrared rule with :data:`humv_usd.render.quality.RELATIVE_NETD`) on the image
        and on every labelled region class (people first; as NIR/SWIR), at most
        :data:`eo_fast.EO_MAX_SPP`. ``noise`` carries the frame's ``quality`` record."""
        hits = scene.hits(sid)
        edges = E.geometric_edges(hits)
        regions, names = Q.region_map(hits.part, [p.label_class for p in scene.parts])
        pooled = Q.Batches()
        replicas = E.replica_count(self.spp)
        while True:
            seed = (self.seed + frame + eo_fast.SEED_STRIDE * pooled.count) % 2**32
            batch = eo_fast.render_xyz_fast(
                scene, sid, state, self.bins, reflectance_of, light, self.spp, seed
            )
            pooled.add(batch[0], batch[1], replicas)
            xyz = pooled.mean()
            # one batch: its estimator's error as it stands; more: replicas and batches pooled
            y_err = (batch[1] if pooled.count == 1 else pooled.stderr())[..., 1]
            noise = Q.relative_noise(xyz[..., 1], y_err, edges)
            relative = y_err / noise["mean_y"] if noise["mean_y"] > 0 else np.full(y_err.shape, np.nan)
            per_region = Q.region_stats(relative, edges, regions, names)
            image = E.noise_stats(relative, edges)
            judged = Q.verdict(image, per_region, Q.RELATIVE_NETD if self.spp_auto else None)
            if not (self.spp_auto and Q.needs_more(True, judged, pooled.count, self.spp)):
                break
        for name, rec in per_region.items():
            rec["met"] = judged["regions"].get(name)
        noise.update(spp_used=self.spp * pooled.count, spp_rule=self.spp_rule)
        noise["quality"] = {
            "met": judged["met"],
            "image_met": judged["regions"].get("image"),
            "targets_k": Q.targets(Q.RELATIVE_NETD) if self.spp_auto else None,
            "unit": "relative to the mean Y away from edges",
            "regions": per_region,
            "batches": pooled.count,
            "replicas_per_pixel": pooled.count * replicas,
            "error_dof": pooled.dof,
        }
        return xyz, y_err, noise

    @property
    def spp_rule(self) -> str:
        if not self.spp_auto:
            return f"given: {self.spp} spp"
        return (
            f"automatic: at least {Q.MIN_BATCHES} batches of {self.spp} spp, more until the error of Y "
            f"away from edges is <= {eo_fast.EO_TARGET_RELATIVE:.0%} of the mean Y there on average and "
            f"its 99th percentile <= {Q.targets(Q.RELATIVE_NETD)['p99_k']:.0%}, "
            f"on the image and every region, or {eo_fast.EO_MAX_SPP} spp"
        )

    @property
    def settings_key(self) -> tuple[str, str]:
        """(estimator with its parameters, spp mode) for the images' record settings."""
        if self.estimator != "fast":
            return "path (spectral)", "fixed"
        key = (
            f"fast EO (bins {eo_fast.DEFAULT_EO_BINS}, splits {eo_fast.DEFAULT_EO_SPLITS}, replicas "
            f"{E.DEFAULT_REPLICAS}, filter radius {E.DEFAULT_FILTER_RADIUS} px)"
        )
        return key, (self.spp_rule if self.spp_auto else "fixed")

    def write_cameras(self) -> None:
        """``<sensor>/camera.json`` of every EO sensor rendered (intrinsics, per-frame pose)."""
        for s in self.sensors:
            cams = self.records[s.name]["cameras"]
            if cams:
                write_json(os.path.join(self.out_dir, s.name, CAMERA_FILE), camera_file(s.name, cams))

    def manifest(self, frames_of: dict | None = None) -> list[dict]:
        """The manifest entries of the EO sensors; ``frames_of``: their frame entries (default
        the ones this object kept)."""
        frames_of = frames_of or {s.name: self.records[s.name]["frames"] for s in self.sensors}
        return [
            {
                "name": s.name,
                "prim": s.path,
                "band": s.band,
                "resolution": list(s.resolution),
                "variant": mode.variant()
                if self.estimator == "fast"
                else mode.SPECTRAL_VARIANTS[mode.variant()],
                "estimator": self.estimator,
                "estimator_note": self.estimator_note,
                "spectral_bins_nm": None if self.bins is None else [float(v) for v in self.bins.edges_nm],
                "spp": self.spp,
                "spp_auto": self.spp_auto,
                "channels": {k: writers.channel_info(k, v) for k, v in EO_EXR_CHANNELS.items()},
                "camera": os.path.join(s.name, CAMERA_FILE) if frames_of.get(s.name) else None,
                "preview": f"PNG 8-bit sRGB; the {PREVIEW_PERCENTILE:g}th percentile of Y exposed to {PREVIEW_WHITE:g}",
                "frames": frames_of.get(s.name, []),
                "timings_s": {
                    **self.records[s.name]["timings_s"],
                    "total": sum(self.records[s.name]["timings_s"].values()),
                },
                "monte_carlo_error_relative": Q.relative_summary(
                    [f.get("monte_carlo_error_relative") or {} for f in frames_of.get(s.name, [])]
                ),
                "quality": Q.quality_summary(frames_of.get(s.name, []), EO_QUALITY_DEFINITION),
            }
            for s in self.sensors
        ]


#: What an EO sensor's ``quality`` summary judges (:meth:`EORender.manifest`).
EO_QUALITY_DEFINITION = (
    "automatic quality (humv_usd.render.quality): the error of Y relative to the mean Y away from "
    "edges, mean <= 1 % and p99 <= 10 %, on the image and on every region class (label class of the "
    "pixel-centre hit) with enough pixels, at least 2 batches; per frame in frames[].quality"
)


def _eo_estimator(requested: str, max_depth: int) -> tuple[str, str]:
    """The EO estimator that runs and why: the fast one needs a vectorised variant and unbounded
    paths (as in the infrared)."""
    if requested != "fast":
        return "path", f"requested: {requested} (Mitsuba's spectral path tracer)"
    est, why = choose_estimator(requested, max_depth)  # the infrared's rule
    return est, why or "requested: fast (humv_usd.render.eo_fast)"
