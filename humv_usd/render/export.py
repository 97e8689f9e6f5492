"""USD stage -> per-frame scene description in plain numpy (no Mitsuba here).

:class:`StageExport` is the render's read of a composed stage: its rendered meshes
(:class:`humv_usd.render.scene_export.SceneMeshes`), its sensors
(:func:`humv_usd.usd.sensor.stage_sensors` -> :class:`humv_usd.physics.sensor.SensorModel`; a
band starting below 3 um, or the token ``EO``, is an EO sensor, rendered by
:mod:`humv_usd.render.eo`) and, per frame, a :class:`humv_usd.render.frame.FrameState`: the
meshes visible at the frame with their world points and face temperatures, the sensors' camera
poses (:func:`humv_usd.usd.sensor.read_camera_pose`) and the sky temperature.

Per frame it reads: the meshes' visibility and world points (``SceneMeshes.world_points``), their
face temperatures (:func:`humv_usd.usd.thermal.read_face_temperatures`: uniform or constant
``primvars:humv:thermal:temperature``, checked by
:func:`humv_usd.usd.thermal.check_temperatures`) and the sky brightness temperature
(:func:`humv_usd.usd.atmosphere.sky_temperature`). Both temperatures are required only when an
infrared sensor is rendered.

Attributes are read by name (through :mod:`humv_usd.usd` readers and schema constants), so the
render works whether or not the Humv API schemas are applied or registered. Atmosphere and
environment data (spectral tables, sun, path tables) are read by the callers directly from
:mod:`humv_usd.usd.atmosphere` and :mod:`humv_usd.usd.environment`.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd.physics.sensor import SensorModel
from humv_usd.render.frame import FrameState
from humv_usd.render.scene_export import SceneMeshes
from humv_usd.usd.atmosphere import sky_temperature
from humv_usd.usd.sensor import read_camera_pose, stage_sensors
from humv_usd.usd.thermal import has_face_temperatures, read_face_temperatures


class StageExport:
    """A composed stage read for rendering. Construct, then call :meth:`frame_state` per frame."""

    def __init__(self, stage: Usd.Stage):
        self.stage = stage
        self.meshes = SceneMeshes(stage)
        self.sensors: list[SensorModel] = stage_sensors(stage)

    def frame_state(self, frame: int, sensors: list[SensorModel]) -> FrameState:
        """Read everything needed to render ``frame`` for ``sensors``.

        Temperatures (faces, sky) are required only when an infrared sensor is among
        ``sensors``; for EO sensors alone (a stage without a thermal or atmosphere layer) an
        unauthored face temperature is NaN (it only feeds the surface_temperature label) and the
        sky temperature is NaN.
        """
        time = Usd.TimeCode(frame)
        cache = UsdGeom.XformCache(time)
        state = FrameState(frame=frame, meshes=[])
        # emission needs temperatures; NIR/SWIR read them where the thermal layer has them
        infrared = any(s.kind != "EO" and not s.is_reflective for s in sensors)
        state.sky_temperature_k = sky_temperature(self.stage, time) if infrared else float("nan")
        for prim in self.meshes.prims:
            if UsdGeom.Imageable(prim).ComputeVisibility(time) == UsdGeom.Tokens.invisible:
                continue
            info = self.meshes.mesh_info(prim, time)
            world, flip = self.meshes.world_points(prim, info, frame, cache)
            state.meshes.append(info)
            state.points[info.path] = world
            state.flip[info.path] = flip
            if infrared or has_face_temperatures(prim):
                state.temperatures[info.path] = read_face_temperatures(prim, info.face_count, time)
            else:
                state.temperatures[info.path] = np.full(info.face_count, np.nan)
        for sensor in sensors:
            state.cameras[sensor.name] = read_camera_pose(self.stage.GetPrimAtPath(sensor.path), time)
        return state
