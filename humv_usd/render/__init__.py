"""Rendering of composed stages: infrared band radiance with Mitsuba 3, plus labels.

``render_stage`` is the entry point; ``mode`` is the one place that imports Mitsuba.
"""
from humv_usd.render.run import render_stage

__all__ = ["render_stage"]
