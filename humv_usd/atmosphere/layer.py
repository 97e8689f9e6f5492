"""Atmosphere tool: sky and sun → layers/atmosphere.usda.

Reads the upstream stage (:data:`UPSTREAM`): weather and sun from the environment layer
(:mod:`humv_usd.usd.environment`); it computes neither. Authors what
:func:`humv_usd.atmosphere.model.atmosphere_for` computed (only what the scenario needs, see
there) with the frame-0 cloud cover mixed into the thermal sky
(:func:`humv_usd.atmosphere.model.with_cloud_cover`, Crawford & Duchon 1999): on /World/Atmosphere
the model that ran, the effective broadband sky (temperature, emissivity, and the longwave
radiance against zenith that the thermal layer reads), the wavelength grid of the sensors'
bands, the sky spectral radiance against zenith and, while the sun is up, the direct solar
spectral irradiance per frame. The per-sensor slant-path tables under /World/Atmosphere/Paths
are their own layer (:mod:`humv_usd.atmosphere.paths`), so that moving a sensor leaves this layer,
and the thermal layer that reads it, as they are. What ran and what was skipped is recorded in
the layer's customLayerData ``humv:atmosphere:ran``. Everything on the prim is authored through
the typed writers of :mod:`humv_usd.usd.atmosphere` (this module names no attribute).

When the weather varies (:func:`humv_usd.atmosphere.model.weather_varies`), the thermal sky
(spectral and broadband, with each node's cloud cover) gets time samples at
the weather nodes' frames (:func:`humv_usd.atmosphere.model.weather_nodes`; USD interpolates
float arrays linearly between them) and keeps the frame-0 values as its defaults, which
readers without a time get (the thermal tool and the render read the sample of their frame,
:mod:`humv_usd.usd.atmosphere`). Constant
weather authors single default values, as before.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd

from humv_usd.atmosphere.model import atmosphere_for, lerp_nodes, with_cloud_cover
from humv_usd.atmosphere.texture import sky_texture
from humv_usd.images import write_exr
from humv_usd.scenario import Scenario
from humv_usd.scenario.inputs import CLOCK
from humv_usd.usd import atmosphere as A
from humv_usd.usd.environment import read_weather, write_sky_texture
from humv_usd.usd.layers import finish, new_layer_stage

NAME = "atmosphere"
READS = (
    *CLOCK,
    "atmosphere",  # model, profile, visibility; weather_csv: its hours are the weather nodes
    "sensor.*.wavelength_um",  # the spectral grid: the union of the sensors' bands
)
#: layers read from the upstream stage: weather and sun (environment)
UPSTREAM = ("environment",)
VERSION = "5"
#: The dome light's sky texture, written beside the layer (:func:`side_files`; compose commits it
#: with the layers) and referenced from it by this relative path.
SKY_TEXTURE = "atmosphere_sky.exr"


def build(scenario: Scenario, upstream) -> Sdf.Layer:
    """The atmosphere layer; ``upstream``: a stage with the :data:`UPSTREAM` layers."""
    g, a = scenario["general"], scenario["atmosphere"]
    full = atmosphere_for(scenario, upstream)
    nodes = None
    if full.node_times_s is None:
        atm = with_cloud_cover(full, read_weather(upstream, [0.0]).cloud_cover[0])
    else:
        nodes = [
            with_cloud_cover(full.at_node(k), full.node_cloud_cover[k]) for k in range(full.node_times_s.size)
        ]
        node_codes = [float(c) for c in np.round(full.node_times_s * float(g["fps"]), 6)]
        atm = nodes[0]
    stage = new_layer_stage(
        g["fps"], scenario.frame_count, f"HumV-USD atmosphere layer: {atm.source} sky and sun"
    )
    prim = A.define_atmosphere(stage, atm.source, atm.profile, a["visibility_km"] * 1000.0)
    A.write_broadband_sky(
        prim, atm.sky_emissivity, atm.sky_temperature_k, atm.longwave_radiance, atm.sky_zenith_deg
    )
    if nodes is not None:  # defaults = frame 0 (above) plus samples at the weather nodes
        for code, n in zip(node_codes, nodes):
            A.write_broadband_sky(prim, n.sky_emissivity, n.sky_temperature_k, n.longwave_radiance, time=code)
    # the disk cache's hit/miss stays out of the layer: an unchanged scenario must give the same text
    # the paths are the atmosphere paths layer's (humv_usd.atmosphere.paths)
    ran = {
        k: ("; ".join(v) if isinstance(v, list) else str(v))
        for k, v in atm.ran.items()
        if k not in ("cache", "paths")
    }
    ran["broadband sky"] = (
        f"emissivity {atm.sky_emissivity:.4f}, temperature {atm.sky_temperature_k:.2f} K ({atm.source})"
    )
    if nodes is not None:
        ran["broadband sky"] += (
            f" at frame 0; {len(nodes)} weather nodes: emissivity "
            + ", ".join(f"{n.sky_emissivity:.4f}" for n in nodes)
            + "; time samples at frames "
            + ", ".join(f"{c:g}" for c in node_codes)
        )
    w = atm.wavelengths_um
    if w.size:
        codes = np.round(atm.times_s * float(g["fps"]), 6)
        sampled = scenario.frame_count > 1
        A.write_spectral_grid(prim, w, atm.sky_zenith_deg)
        diffuse_varies = sampled and np.ptp(atm.diffuse_radiance, axis=0).max() > 0
        if nodes is not None:
            # thermal sky linear between the nodes, diffuse skylight at its own samples
            thermal = np.stack([n.sky_radiance for n in nodes])
            sky_codes = sorted(set(node_codes) | (set(float(c) for c in codes) if diffuse_varies else set()))
            A.write_spectral_sky(prim, atm.sky_spectral_radiance(atm.sky_zenith_deg, atm.times_s[0]))
            for code in sky_codes:
                t = code / float(g["fps"])
                A.write_spectral_sky(
                    prim, lerp_nodes(full.node_times_s, thermal, t) + atm.diffuse_at(t)[None, :], code
                )
        elif diffuse_varies:
            for code, t in zip(codes, atm.times_s):
                A.write_spectral_sky(prim, atm.sky_spectral_radiance(atm.sky_zenith_deg, t), float(code))
        else:
            A.write_spectral_sky(prim, atm.sky_spectral_radiance(atm.sky_zenith_deg, atm.times_s[0]))
        if atm.solar.any():
            if sampled:
                for code, row in zip(codes, atm.solar):
                    A.write_solar_spectrum(prim, row, float(code))
            else:
                A.write_solar_spectrum(prim, atm.solar[0])
        else:
            ran["solar spectrum"] = "skipped: sun below the horizon (or fully clouded)"
    else:
        ran["spectra"] = "skipped: no sensor"
    write_sky_texture(stage, f"./{SKY_TEXTURE}")
    ran["sky texture"] = f"{SKY_TEXTURE}: " + _texture(stage)[1]
    stage.GetRootLayer().customLayerData = {"humv:atmosphere:ran": ran}
    return finish(stage)


def _texture(stage) -> tuple[np.ndarray, str]:
    """The sky texture of the atmosphere layer's frame-0 sky table (:mod:`humv_usd.atmosphere.texture`)."""
    spectra = A.atmosphere_spectra(stage, 0.0)
    return sky_texture(spectra.sky_zenith_deg, spectra.wavelengths_um, spectra.sky_radiance)


def side_files(layer: Sdf.Layer) -> dict:
    """The files beside the layer, for compose: {:data:`SKY_TEXTURE`: a writer of the dome
    light's lat-long sky texture (OpenEXR, float R, G, B) computed from ``layer``'s sky table}."""
    pixels = _texture(Usd.Stage.Open(layer))[0]
    channels = {c: pixels[:, :, i] for i, c in enumerate("RGB")}
    return {SKY_TEXTURE: lambda path: write_exr(path, channels)}
