"""The sensor chain of a render: the render's sensor model applied after the render."""

from __future__ import annotations

import os

import numpy as np
from pxr import Usd, UsdGeom

from humv_usd import images as writers
from humv_usd.geometry.camera import Camera, image_velocity
from humv_usd.groundtruth.labels import CLASS_ID
from humv_usd.physics import sensor as chain
from humv_usd.physics.sensor import SensorModel
from humv_usd.usd.sensor import read_camera_pose

#: half-width [frames] of the central difference of the camera's pose that gives the image
#: velocity of the motion blur and rolling shutter (USD interpolates the transform between frames)
VELOCITY_STEP_FRAMES = 0.1
#: label classes whose objects move on their own (their image motion is their mask's, not the
#: static scene's)
MOVING_CLASSES = ("person", "vehicle", "animal")


class SensorChains:
    """The sensor chain (:mod:`humv_usd.physics.sensor`): optics, noise, counts, AGC per sensor
    and frame, after the render. The model is the render's one checked read of the sensor prim
    (:func:`humv_usd.usd.sensor.read_sensor`, carried here; not read again); the noise generator is seeded from
    (seed, sensor index in the stage, frame), so outputs are reproducible."""

    def __init__(self, stage, seed: int, sensor_paths: list[str]):
        self.stage = stage
        self.seed = int(seed)
        self.index = {p: i for i, p in enumerate(sensor_paths)}
        self.ran: dict[str, str] = {}
        self.reason = None
        self.chain = chain
        self.states: dict = {}
        self.objects: dict = {}  # sensor path -> (frame, {instance id: mask centroid (u, v) [px]})

    def apply(
        self,
        sensor: SensorModel,
        radiance,
        frame: int,
        eo_space: str | None = None,
        depth=None,
        instance=None,
    ):
        """ChainOutput for one frame, or None when the chain is unavailable. ``depth`` (the
        labels' depth image) makes the motion blur's image velocity exact for the static scene;
        ``instance`` (instance ids, 0 elsewhere) gives those objects their own motion: pass the
        moving objects' only (:meth:`movers`)."""
        if self.chain is None:
            return None
        rng = np.random.default_rng([self.seed, self.index.get(sensor.path, 0), int(frame)])
        extra = {} if eo_space is None else {"eo_space": eo_space}
        # frame time and the sensor's state from its last frame (FPN drift since FFC, bolometer lag)
        extra["time_s"] = int(frame) / (self.stage.GetTimeCodesPerSecond() or 1.0)
        extra["state"] = self.states.setdefault(sensor.path, self.chain.ChainState())
        if sensor.motion_blur == "camera" or (sensor.kind == "EO" and sensor.rolling_shutter_s > 0):
            extra["velocity_px_s"] = self.velocity(sensor, frame, depth, instance)
        out = self.chain.apply_chain(radiance, sensor, rng, **extra)  # the render's checked read
        self.ran[sensor.name] = "ran"
        return out

    @staticmethod
    def movers(class_id, instance) -> np.ndarray | None:
        """``instance`` where the labels' ``class_id`` image is a :data:`MOVING_CLASSES` class, 0
        elsewhere (what :meth:`apply` takes as ``instance``); None without both images."""
        if class_id is None or instance is None:
            return None
        moving = np.isin(np.asarray(class_id).astype(int), [CLASS_ID[c] for c in MOVING_CLASSES])
        return np.where(moving, np.asarray(instance), 0)

    def velocity(self, sensor: SensorModel, frame: int, depth=None, instance=None) -> np.ndarray | None:
        """(H, W, 2) image velocity [px/s] at ``frame``: the static scene's from the camera's own
        motion (:func:`humv_usd.geometry.camera.image_velocity` with ``depth``, else flat ground
        at z = 0; central difference of the pose over +-:data:`VELOCITY_STEP_FRAMES`), and, with
        ``instance``, each labelled object's own: the motion of its mask's centroid since the
        previous frame (a person a camera tracks stays sharp; zero on an object's first frame).
        None when nothing moves."""
        prim = self.stage.GetPrimAtPath(sensor.path)
        xf = UsdGeom.Xformable(prim)
        samples = xf.GetTimeSamples() if xf.TransformMightBeTimeVarying() else []
        w, h = (int(v) for v in sensor.resolution)
        fps = self.stage.GetTimeCodesPerSecond() or 1.0
        vel = np.zeros((h, w, 2))
        lo = max(frame - VELOCITY_STEP_FRAMES, samples[0]) if len(samples) > 1 else frame
        hi = min(frame + VELOCITY_STEP_FRAMES, samples[-1]) if len(samples) > 1 else frame
        if hi > lo:
            before = Camera.from_pose(read_camera_pose(prim, Usd.TimeCode(lo)), w, h)
            after = Camera.from_pose(read_camera_pose(prim, Usd.TimeCode(hi)), w, h)
            z = None if depth is None else np.where(np.isfinite(depth) & (depth > 0), depth, np.inf)
            vel = image_velocity(after, before, (hi - lo) / fps, depth=z)
        if instance is not None and np.shape(instance) == (h, w):
            self._object_velocity(sensor.path, frame, vel, np.asarray(instance), fps)
        return vel if np.any(vel) else None

    def _object_velocity(self, path: str, frame: int, vel, instance, fps: float) -> None:
        """Overwrite ``vel`` on each labelled object's pixels with its mask centroid's image
        velocity since the previous frame of this sensor (zero without one)."""
        ids = [int(i) for i in np.unique(instance) if i > 0]
        rows, cols = np.nonzero(instance > 0)
        labels = instance[rows, cols]
        cents = {i: np.array([cols[labels == i].mean() + 0.5, rows[labels == i].mean() + 0.5]) for i in ids}
        prev_frame, prev = self.objects.get(path, (None, {}))
        self.objects[path] = (frame, cents)
        for i in ids:
            mask = instance == i
            if prev_frame == frame - 1 and i in prev:
                vel[mask] = (cents[i] - prev[i]) * fps
            else:
                vel[mask] = 0.0

    def write(self, out, out_dir, rel, write=None) -> dict | None:
        """Write ``<rel>_counts.png`` (16-bit raw counts) and ``<rel>_image8.png`` (8-bit AGC);
        ``write(what, fn, *args)`` runs the writes (default: now)."""
        if out is None:
            return None
        write = write or (lambda _what, fn, *args: fn(*args))
        write(
            rel + "_counts.png", writers.write_png16, os.path.join(out_dir, rel + "_counts.png"), out.counts
        )
        write(rel + "_image8.png", writers.write_png, os.path.join(out_dir, rel + "_image8.png"), out.image8)
        return {
            "counts_png": rel + "_counts.png",
            "image8_png": rel + "_image8.png",
            "noise_sigma": float(out.noise_sigma),
            "settings": out.settings,
        }

    def status(self) -> str:
        return self.reason or "ran: counts (16-bit PNG, EXR channel counts) and image8 (PNG) per frame"
