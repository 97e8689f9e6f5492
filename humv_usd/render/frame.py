"""One frame of a composed stage as the render needs it: :class:`FrameState` (visible meshes,
their world points, per-face temperatures, cameras, the sky temperature) and the temperature
readers and checks behind it.

- face temperatures: ``primvars:humv:thermal:temperature`` (HumvThermalAPI; uniform, one per
  authored face, or constant) at the frame, :func:`face_temperatures`;
- sky temperature: ``/World/Atmosphere.humv:atmosphere:skyTemperature`` at the frame
  (:func:`humv_usd.usd.atmosphere.sky_temperature`), :func:`sky_temperature`;
- both checked by :func:`check_temperatures` (finite, in :data:`TEMPERATURE_RANGE_K`);
- a sensor's slant-path table at the frame (:func:`humv_usd.usd.atmosphere.path_table`) as a
  :class:`humv_usd.render.radiometry.PathTable`, :func:`path_table`.

:class:`humv_usd.render.export.StageExport` fills a FrameState per frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.constants import TEMPERATURE_RANGE_K
from humv_usd.errors import InputError, bad_value
from humv_usd.geometry.camera import CameraPose
from humv_usd.physics.sensor import SensorModel
from humv_usd.render.radiometry import PathTable
from humv_usd.render.scene_export import MeshInfo
from humv_usd.usd import atmosphere as usd_atmosphere
from humv_usd.usd import schemas as S


@dataclass
class FrameState:
    """Everything that changes per frame, as numpy arrays keyed by mesh path / sensor name."""

    frame: int
    meshes: list[MeshInfo]  # visible meshes, in stage order
    points: dict[str, np.ndarray] = field(default_factory=dict)  # world points (P, 3) [m]
    flip: dict[str, bool] = field(default_factory=dict)  # reverse the winding (mirror or leftHanded)
    temperatures: dict[str, np.ndarray] = field(default_factory=dict)  # (F,) [K]
    cameras: dict[str, CameraPose] = field(default_factory=dict)
    sky_temperature_k: float = float("nan")

    @property
    def topology_key(self) -> tuple:
        """Changes exactly when the Mitsuba scene must be rebuilt."""
        return tuple((m.path, self.flip[m.path]) for m in self.meshes)


def stage_frames(stage: Usd.Stage) -> list[int]:
    """All integer frames from the stage's startTimeCode to endTimeCode (at least one)."""
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    first, last = math.ceil(start), math.floor(end)
    if last < first:
        return [int(round(start))]
    return list(range(int(first), int(last) + 1))


def check_temperatures(values, where: str, expected: int | None = None) -> np.ndarray:
    """Validate an array of temperatures [K] (finite, in TEMPERATURE_RANGE_K, right length)."""
    lo, hi = TEMPERATURE_RANGE_K
    a = np.asarray(values, dtype=float).ravel()
    allowed = f"expected {'' if expected is None else f'{expected} '}finite temperatures in {lo:g}-{hi:g} K"
    if expected is not None and a.size != expected:
        raise InputError(bad_value(where, f"<{a.size} values>", allowed + " (one per authored face)"))
    bad = ~np.isfinite(a) | (a < lo) | (a > hi)
    if np.any(bad):
        idx = np.flatnonzero(bad)
        raise InputError(
            bad_value(where, f"{a[idx[0]]!r} at index {idx[0]} ({idx.size} bad of {a.size})", allowed)
        )
    return a


def sky_temperature(stage: Usd.Stage, time) -> float:
    """The render's broadband sky brightness temperature [K] at ``time`` (checked)."""
    value = usd_atmosphere.sky_temperature(stage, time)
    where = f"{usd_atmosphere.ATMOSPHERE_PATH}.{S.ATMOSPHERE_SKY_TEMPERATURE}"
    return float(check_temperatures([value], where)[0])


def has_temperatures(prim: Usd.Prim) -> bool:
    """Whether the mesh has face temperatures (HumvThermalAPI) authored."""
    attr = prim.GetAttribute(S.TEMPERATURE_PRIMVAR)
    return bool(attr and attr.HasValue())


def face_temperatures(prim: Usd.Prim, info: MeshInfo, time) -> np.ndarray:
    """One temperature [K] per authored face of a mesh at ``time`` (a constant primvar is
    spread over the faces); InputError when missing, of another interpolation or out of range."""
    where = f"{info.path}.{S.TEMPERATURE_PRIMVAR}"
    attr = prim.GetAttribute(S.TEMPERATURE_PRIMVAR)
    if not attr or not attr.HasValue():
        raise InputError(
            bad_value(
                where,
                None,
                f"a rendered mesh needs one temperature per authored face "
                f"({info.face_count} faces, uniform primvar, K, HumvThermalAPI)",
            )
        )
    primvar = UsdGeom.Primvar(attr)
    interpolation = primvar.GetInterpolation() if primvar else UsdGeom.Tokens.uniform
    if interpolation not in (UsdGeom.Tokens.uniform, UsdGeom.Tokens.constant):
        raise InputError(
            bad_value(
                f"{where} interpolation",
                str(interpolation),
                "expected uniform (one value per authored face) or constant",
            )
        )
    values = primvar.ComputeFlattened(time) if primvar else attr.Get(time)
    if values is None:
        raise InputError(bad_value(where, None, f"no value at frame {time.GetValue():g}"))
    values = np.asarray(values, dtype=float).ravel()
    if primvar and primvar.GetInterpolation() == UsdGeom.Tokens.constant and values.size == 1:
        values = np.full(info.face_count, values[0])
    return check_temperatures(values, where, expected=info.face_count)


def path_table(stage: Usd.Stage, sensor: SensorModel, time) -> PathTable | None:
    """The sensor's slant-path table at ``time``, or None when the stage has none
    (:func:`humv_usd.usd.atmosphere.path_table`)."""
    t = usd_atmosphere.path_table(stage, sensor.path, sensor.name, time)
    if t is None:
        return None
    return PathTable(t.prim, t.ranges_m, t.wavelengths_um, t.transmittance, t.radiance)
