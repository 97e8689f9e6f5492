"""Sensor tool: cameras with HumvSensorAPI → layers/sensors.usda.

One UsdGeom.Camera per ``[[sensor]]`` with the radiometric model (HumvSensorAPI) from the table
and its preset (:mod:`humv_usd.catalog.sensors`). Tripod and mast cameras have one transform;
an aerial camera's transform is time-sampled at every frame (orbit looking at its centre), so
all sensors share the frame times (synchronised, multi-view).
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

from humv_usd.catalog.sensors import PRESETS, netd_for_f_number, orbit_positions, preset
from humv_usd.scenario import Scenario, validate
from humv_usd.scenario.inputs import FRAMES
from humv_usd.usd.layers import SCOPES, finish, library_layer_main, look_at_matrix, new_layer_stage
from humv_usd.usd.paths import sensor_path
from humv_usd.usd.sensor import CHAIN_ATTRIBUTES, write_sensor

NAME = "sensors"
READS = (*FRAMES, "sensor")
UPSTREAM = ()
VERSION = "3"  # 3: focusDistance at the look-at point

# UsdGeom lens and filmback values are in tenths of a scene unit: on a metre stage 1 mm = 0.01.
_MM_TO_TENTHS_OF_M = 0.01


def camera_positions(s: dict, fps: float, frame_count: int) -> np.ndarray:
    """Camera position [m] per frame, (frame_count, 3): constant unless the platform is aerial."""
    if s["platform"] != "aerial":
        return np.tile(np.asarray(s["position_m"], dtype=float), (max(frame_count, 1), 1))
    times = np.arange(max(frame_count, 1)) / fps
    return orbit_positions(
        s["look_at_m"],
        s["altitude_m"],
        s["orbit_radius_m"],
        s["orbit_speed_m_s"],
        times,
        start_deg=s["orbit_start_deg"],
        clockwise=s["orbit_clockwise"] == "yes",
    )


def _response(s: dict):
    """Response curve and EO channel responses authored for the sensor: the preset's when the
    band is the preset's, clipped to the sensor's band edges; none (flat) otherwise."""
    if not s.get("preset"):
        return None, None, None
    p = preset(s["preset"])
    if p.band != s["band"]:
        return None, None, None
    wl = np.asarray(p.response_wavelengths_um, dtype=float)
    lo, hi = s["wavelength_um"]
    if not np.any((wl >= lo) & (wl <= hi)):
        return None, None, None
    channels = None if p.channel_response is None else np.asarray(p.channel_response, dtype=float)
    return wl, np.asarray(p.response, dtype=float), channels


def netd_of(s: dict) -> tuple[float, str | None]:
    """The NETD [K] to author for a sensor table, and a note when it was derived.

    An infrared sensor with a preset whose ``f_number`` differs from the preset's and whose
    table does not give ``netd_k`` gets, at scenario load (``_fill_sensor``), the preset's NETD
    scaled to the new f-number with the detector-limited law
    :func:`humv_usd.catalog.sensors.netd_for_f_number`; this says so in a note. A given
    ``netd_k`` is used as is (None note).
    """
    netd = float(s["netd_k"])
    if s["band"] == "EO" or not s.get("preset"):
        return netd, None
    p = preset(s["preset"])
    if p.band != s["band"] or float(s["f_number"]) == float(p.f_number):
        return netd, None
    scaled = netd_for_f_number(p.netd_k, p.f_number, s["f_number"])
    if netd != scaled:
        return netd, None
    note = (
        f"scaled from preset {p.name} NETD {p.netd_k:g} K at f/{p.f_number:g} to f/{float(s['f_number']):g}: "
        f"x (4N^2+1)/(4N0^2+1) (detector-limited; humv_usd.catalog.sensors.netd_for_f_number)"
    )
    return scaled, note


def build(scenario: Scenario, upstream=None) -> Sdf.Layer:
    g = scenario["general"]
    frames = scenario.frame_count
    stage = new_layer_stage(g["fps"], frames, "HumV-USD sensors layer")
    UsdGeom.Scope.Define(stage, SCOPES["sensors"])
    for s in scenario["sensor"]:
        cam = UsdGeom.Camera.Define(stage, sensor_path(s["id"]))
        op = cam.AddTransformOp()
        positions = camera_positions(s, g["fps"], frames)
        # focused where it looks (HumV renders a pinhole; a viewer honouring fStop without a
        # focusDistance focuses at 0 m: Blender rendered a uniform blur)
        focus = cam.CreateFocusDistanceAttr()
        target = np.asarray(s["look_at_m"], dtype=float)
        if s["platform"] == "aerial":
            for frame, pos in enumerate(positions):
                op.Set(look_at_matrix(pos.tolist(), s["look_at_m"]), Usd.TimeCode(frame))
                focus.Set(float(np.linalg.norm(target - pos)), Usd.TimeCode(frame))
        else:
            op.Set(look_at_matrix(s["position_m"], s["look_at_m"]))
            focus.Set(float(np.linalg.norm(target - np.asarray(s["position_m"], dtype=float))))
        width, height = s["resolution"]
        pitch_mm = s["pixel_pitch_um"] * 1e-3
        cam.CreateProjectionAttr(UsdGeom.Tokens.perspective)
        cam.CreateFocalLengthAttr(s["focal_length_mm"] * _MM_TO_TENTHS_OF_M)
        cam.CreateHorizontalApertureAttr(width * pitch_mm * _MM_TO_TENTHS_OF_M)
        cam.CreateVerticalApertureAttr(height * pitch_mm * _MM_TO_TENTHS_OF_M)
        cam.CreateFStopAttr(s["f_number"])
        cam.CreateClippingRangeAttr(Gf.Vec2f(0.05, 1.0e5))
        netd, netd_note = netd_of(s)
        wl, response, channels = _response(s)
        eo = s["band"] == "EO"
        write_sensor(
            cam.GetPrim(),
            band=s["band"],
            wavelength_range_um=s["wavelength_um"],
            resolution=(width, height),
            pixel_pitch_m=s["pixel_pitch_um"] * 1e-6,
            f_number=s["f_number"],
            netd_k=netd,
            netd_note=netd_note,
            bit_depth=s["bit_depth"],
            offset=s["offset"],
            preset=s.get("preset") or "",
            platform=s["platform"],
            agc=s["agc"],
            agc_percentiles=s["agc_percentiles"],
            gain=s["gain"],  # EO presets: no gain = auto exposure
            subbands=None if eo else s["subbands"],  # the render's sub-band count (--subbands overrides)
            full_well_e=s["full_well_e"] if eo else None,
            read_noise_e=s["read_noise_e"] if eo else None,
            response_wavelengths_um=wl,
            response=response,
            channel_response=channels,
            chain_settings={k: s.get(k) for k in CHAIN_ATTRIBUTES},
        )
    return finish(stage)


# ---------------------------------------------------------------------------- presets file
PRESETS_FILE = Path(__file__).resolve().parents[2] / "layers" / "sensors.usda"


def build_presets() -> Sdf.Layer:
    """Every sensor preset as a camera /World/Sensors/<preset> (the reusable layers/sensors.usda):
    on a tripod 1.6 m above the origin's south, 15 m away, looking north (as in humvvex)."""
    raw = {
        "general": {
            "name": "sensor_presets",
            "start": _dt.datetime(2018, 10, 24, 14, 5),
            "utc_offset_h": 0.0,
            "latitude_deg": 0.0,
            "longitude_deg": 0.0,
            "fps": 1.0,
        },
        "sensor": [
            {"id": name, "preset": name, "position_m": [0.0, -15.0, 1.6], "look_at_m": [0.0, 0.0, 1.6]}
            for name in PRESETS
        ],
    }
    layer = build(validate(raw))
    layer.documentation = (
        "HumV-USD sensor presets (humv_usd.catalog.sensors), one camera each. "
        "Generated: python -m humv_usd.sensors.layer"
    )
    return layer


def main(argv=None) -> int:
    """Write layers/sensors.usda (``--check``: exit 1 if it is out of date)."""
    return library_layer_main(PRESETS_FILE, build_presets, main.__doc__, argv)


if __name__ == "__main__":
    raise SystemExit(main())
