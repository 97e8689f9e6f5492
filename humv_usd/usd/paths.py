"""Prim paths of the composed stage: where each tool's prims live, so that every tool can find
another tool's prims without importing that tool."""

from __future__ import annotations

from pxr import Sdf

from humv_usd.usd.layers import SCOPES

#: the ground mesh of the scene layer
GROUND = SCOPES["scene"].AppendChild("Ground")


def human_path(human_id: str) -> Sdf.Path:
    """SkelRoot of a person (avatar layer)."""
    return SCOPES["humans"].AppendChild(human_id)


def body_path(human_id: str) -> Sdf.Path:
    """Skinned body mesh of a person (avatar layer)."""
    return human_path(human_id).AppendChild("Body")


def skeleton_path(human_id: str) -> Sdf.Path:
    """UsdSkel.Skeleton of a person (avatar layer)."""
    return human_path(human_id).AppendChild("Skeleton")


def motion_path(human_id: str) -> Sdf.Path:
    """UsdSkel.Animation of a person (avatar layer)."""
    return human_path(human_id).AppendChild("Motion")


def clothing_path(human_id: str) -> Sdf.Path:
    """Scope of a person's garments (clothing layer)."""
    return human_path(human_id).AppendChild("Clothing")


def props_path(human_id: str) -> Sdf.Path:
    """Scope of a person's carried props (clothing layer)."""
    return human_path(human_id).AppendChild("Props")


def material_path(name: str) -> Sdf.Path:
    """A library material (materials layer)."""
    return SCOPES["materials"].AppendChild(name)


def object_path(object_id: str) -> Sdf.Path:
    """A scene object (scene layer)."""
    return SCOPES["scene"].AppendChild(object_id)


def sensor_path(sensor_id: str) -> Sdf.Path:
    """A sensor's camera (sensors layer)."""
    return SCOPES["sensors"].AppendChild(sensor_id)
