"""One frame of a composed stage as the render needs it: :class:`FrameState` (visible meshes,
their world points, per-face temperatures, cameras, the sky temperature; filled by
:class:`humv_usd.render.export.StageExport`), the frames of a stage and a sensor's path table at
a frame:

- :func:`stage_frames`: the integer frames of the stage's time range;
- :func:`path_table`: a sensor's slant-path table at a frame
  (:func:`humv_usd.usd.atmosphere.path_table`) as a :class:`humv_usd.render.radiometry.PathTable`;
- :func:`exr_metadata`: the EXR header of a sensor's frame, for every pass.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd

from humv_usd.geometry.camera import CAMERA_FILE, Camera, CameraPose
from humv_usd.physics.sensor import SensorModel
from humv_usd.render.radiometry import PathTable
from humv_usd.render.scene_export import MeshInfo
from humv_usd.usd import atmosphere as usd_atmosphere


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


def path_table(stage: Usd.Stage, sensor: SensorModel, time) -> PathTable | None:
    """The sensor's slant-path table at ``time``, or None when the stage has none
    (:func:`humv_usd.usd.atmosphere.path_table`)."""
    t = usd_atmosphere.path_table(stage, sensor.path, sensor.name, time)
    if t is None:
        return None
    return PathTable(t.prim, t.ranges_m, t.wavelengths_um, t.transmittance, t.radiance)


def exr_metadata(sensor: SensorModel, frame: int, spp: int, camera: Camera, **extra) -> dict[str, str]:
    """The EXR header of one sensor's frame, the same for every pass: ``humv:sensor`` (prim
    path), ``humv:frame``, ``humv:spp`` (the samples per pixel spent), ``humv:<key>`` for each
    of ``extra`` (as text), ``humv:camera`` (the sensor's camera file) and the camera's
    intrinsics and pose (:meth:`humv_usd.geometry.camera.Camera.exr_header`)."""
    return {
        "humv:sensor": sensor.path,
        "humv:frame": str(frame),
        "humv:spp": str(spp),
        **{f"humv:{key}": str(value) for key, value in extra.items()},
        "humv:camera": os.path.join(sensor.name, CAMERA_FILE),
        **camera.exr_header(),
    }
