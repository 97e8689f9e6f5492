"""The renderer interface: one implementation per estimator of a sensor's band radiance.

Kubric's pattern (STYLE.md): the render pass talks to a small interface, and each estimator is
one implementation behind it:

- ``"fast"``: :func:`humv_usd.render.estimator.render_band_fast` (sub-bands on one path, emission
  evaluated, sky control variate, stratified, error from independent replicas);
- ``"path"``: Mitsuba's path tracer per sub-band, :func:`humv_usd.render.ir.render_band` (the
  reference, and what a scalar variant or a bounded ``max_depth`` runs).

Both take a scene built from the frame's meshes (:class:`humv_usd.render.ir.IRScene`), a sensor
id in it, the frame state, the sensor's sub-bands and the frame's radiometry, and return the
at-sensor radiance and its standard error per pixel. :func:`choose_estimator` is the one rule
that decides which runs (infrared and visible alike).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from humv_usd import mode
from humv_usd.render.estimator import render_band_fast
from humv_usd.render.ir import render_band

#: The estimators, in the order the CLI offers them.
ESTIMATORS = ("fast", "path")


def choose_estimator(requested: str, max_depth: int) -> tuple[str, str | None]:
    """The estimator that runs for ``requested`` and why it differs (None when it does not).

    The fast estimator needs a vectorised Mitsuba variant (:func:`humv_usd.mode.is_vectorized`)
    and unbounded paths (Russian roulette); otherwise the path tracer runs, which honours both.
    """
    if requested != "fast":
        return requested, None
    if not mode.is_vectorized():
        return "path", f"fast estimator needs a vectorised variant; {mode.variant()} runs the path tracer"
    if int(max_depth) != -1:
        return "path", f"max_depth {max_depth} asks for a truncated path: the path tracer honours it"
    return "fast", None


@dataclass(frozen=True)
class BandRenderer:
    """One estimator behind the interface the render pass calls:
    ``render(scene, sensor_id, state, sub, emissivity_of, radiometry, spp=, seed=,
    transmittance_of=None, **options) -> (radiance, stderr)``, each (H, W) [W m-2 sr-1]
    (the parameters of :func:`humv_usd.render.ir.render_band`; ``options`` only for the fast
    estimator: ``info``, ``direct_target`` and its other keywords)."""

    name: str
    #: True when ``spp`` is the camera samples per pixel shared by all sub-bands (False: split
    #: over them, :func:`humv_usd.render.ir.subband_spp`).
    shares_samples: bool
    render: Callable


#: The implementations: the fast estimator and Mitsuba's path tracer per sub-band (the reference).
RENDERERS: dict[str, BandRenderer] = {
    "fast": BandRenderer("fast", True, render_band_fast),
    "path": BandRenderer("path", False, render_band),
}


def band_renderer(estimator: str) -> BandRenderer:
    """The implementation of ``estimator`` (one of :data:`ESTIMATORS`)."""
    return RENDERERS[estimator]
