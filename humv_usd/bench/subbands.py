"""Spectral (not Monte Carlo) error of the sub-band model against sub-band count
(``humv-usd bench render`` prints it before the estimators' error curves)."""

from __future__ import annotations

import numpy as np
from pxr import Usd

from humv_usd.physics import planck
from humv_usd.render import radiometry
from humv_usd.render.export import StageExport
from humv_usd.render.frame import path_table as read_path_table
from humv_usd.render.frame import stage_frames
from humv_usd.usd import environment as usd_environment
from humv_usd.usd.atmosphere import AtmosphereSpectra, atmosphere_spectra
from humv_usd.usd.layers import open_stage

#: Ranges [m] at which the bench evaluates the path term when the stage has a path table.
BENCH_RANGES_M = (5.0, 15.0, 30.0, 60.0)


def spectra_from_atmosphere(atm, time_s: float = 0.0, sun_direction=None):
    """(AtmosphereSpectra, PathTable) from a :class:`humv_usd.atmosphere.model.Atmosphere`, for a
    bench on a stage whose atmosphere layer has no spectral tables."""

    wl = np.asarray(atm.wavelengths_um, dtype=float)
    spectra = AtmosphereSpectra(
        model=atm.source,
        wavelengths_um=wl,
        sky_zenith_deg=np.asarray(atm.sky_zenith_deg, dtype=float),
        sky_radiance=atm.sky_spectral_radiance(atm.sky_zenith_deg, time_s),
        solar_irradiance=atm.solar_spectral_irradiance([time_s])[0],
    )
    tau, rad = atm.path()
    table = radiometry.PathTable(
        f"atmosphere_for ({atm.source})",
        np.asarray(atm.path_ranges_m, dtype=float),
        wl,
        np.asarray(tau, dtype=float),
        np.asarray(rad, dtype=float),
    )
    return spectra, table


def subband_error_table(
    stage_path, counts=(1, 2, 3, 4, 6, 8, 16), frame=None, spectra=None, path_table=None, sun_direction=None
) -> dict:
    """Spectral (not Monte Carlo) error of the sub-band model against sub-band count.

    For every IR sensor of the stage, every material bound to a rendered mesh and the face
    temperatures of the frame (1st, 50th and 99th percentile over all faces), the at-sensor
    brightness temperature of a horizontal opaque Lambertian facet under the stage's sky (its
    spectral table, cosine-weighted over the hemisphere, else the blackbody at skyTemperature),
    the stage's sun (if up) and the sensor's path table at :data:`BENCH_RANGES_M` (if any) is
    computed with n sub-bands and on a fine spectral grid
    (:func:`humv_usd.render.radiometry.subband_error`). Returns, per sensor and n, the largest
    and the RMS error [K] over materials, temperatures and ranges. ``spectra``, ``path_table``
    and ``sun_direction`` replace what the stage has (see :func:`spectra_from_atmosphere`).
    """
    stage = open_stage(stage_path)
    exporter = StageExport(stage)
    frames = stage_frames(stage)
    frame = frames[0] if frame is None else int(frame)
    ir = [s for s in exporter.sensors if s.rendered and s.kind != "EO"]
    state = exporter.frame_state(frame, ir)
    time_code = Usd.TimeCode(frame)
    spectra = atmosphere_spectra(stage, time_code) if spectra is None else spectra
    sun_dir = (
        usd_environment.sun_direction(stage, time_code)
        if sun_direction is None
        else np.asarray(sun_direction, float)
    )
    temps = (
        np.concatenate([state.temperatures[m.path] for m in state.meshes])
        if state.meshes
        else np.array([300.0])
    )
    temps = np.percentile(temps, [1.0, 50.0, 99.0])
    materials = {part.material.path: part.material for m in state.meshes for part in m.parts}
    out: dict = {
        "frame": frame,
        "temperatures_k": temps.tolist(),
        "materials": sorted(materials),
        "reference": f"trapezoid on {radiometry.REFERENCE_NODES}+ nodes per band",
        "sensors": {},
    }
    for s in ir:
        band, resp = s.wavelength_range_um, s.band_response
        wl = spectra.wavelengths_um
        notes = {}
        if spectra.sky_radiance is not None and radiometry.covers(wl, band):
            sky_l = np.array(
                [
                    radiometry.hemisphere_mean(spectra.sky_zenith_deg, spectra.sky_radiance[:, j])
                    for j in range(wl.size)
                ]
            )
            sky = (wl, sky_l)
            notes["sky"] = "spectral table"
        else:
            x = np.linspace(band[0], band[1], 512)
            sky = (x, planck.spectral_radiance(x, state.sky_temperature_k))
            notes["sky"] = f"blackbody {state.sky_temperature_k:.1f} K"
        sun = None
        if (
            sun_dir is not None
            and sun_dir[2] > 0
            and spectra.solar_irradiance is not None
            and radiometry.covers(wl, band)
        ):
            sun = (wl, spectra.solar_irradiance, float(sun_dir[2]))
            notes["sun"] = f"cos(zenith) {sun_dir[2]:.3f}"
        table = read_path_table(stage, s, time_code) if path_table is None else path_table
        paths = [None]
        if table is not None and radiometry.covers(table.wavelengths_um, band):
            paths = []
            for r in BENCH_RANGES_M:
                tau = np.array(
                    [np.interp(r, table.ranges_m, table.transmittance[:, j]) for j in range(wl.size)]
                )
                lp = np.array([np.interp(r, table.ranges_m, table.radiance[:, j]) for j in range(wl.size)])
                paths.append((table.wavelengths_um, tau, lp))
            notes["path"] = f"table {table.prim} at {list(BENCH_RANGES_M)} m"
        rows = {}
        for n in counts:
            errs = []
            sub = radiometry.SubBands(band, resp, n)
            for mat in materials.values():
                for path in paths:
                    errs.append(
                        radiometry.subband_error(
                            band,
                            resp,
                            mat.wavelengths_um,
                            mat.emissivity,
                            temps,
                            n,
                            sky=sky,
                            sun=sun,
                            path=path,
                            subbands=sub,
                        )
                    )
            e = np.abs(np.concatenate(errs))
            rows[int(n)] = {"max_k": float(e.max()), "rms_k": float(np.sqrt(np.mean(e**2)))}
        out["sensors"][s.name] = {"band_um": list(band), "inputs": notes, "error_by_subbands": rows}
    return out
