"""What the render refuses before it opens the stage: the root layer's stage metadata that
``humv-usd check`` reports as errors, and frame ranges that cannot be rendered.

Stage metadata (upAxis, metersPerUnit, start/endTimeCode) lives in the root layer only (USD
reads no stage metadata from sublayers), so reading that one layer is enough and cheap.
``humv-usd check`` flags upAxis other than Z and metersPerUnit other than 1 (``humv:upAxis``,
``humv:metersPerUnit``; unauthored values are USD's fallbacks, Y and 0.01); the render went ahead
and drew a Y-up centimetre stage lying on its side at 1/100 scale (issue 26). An endTimeCode
before startTimeCode passed both and rendered one frame; a range of 10^11 frames built a list
of every frame before any check.
"""

from __future__ import annotations

import math

from pxr import UsdGeom

from humv_usd.errors import InputError, bad_value
from humv_usd.pipeline.budget import MAX_FRAMES_PER_CALL
from humv_usd.usd.layers import open_root_layer


def stage_problems(stage_path) -> list[str]:
    """One line per reason the render must not go ahead with the stage at ``stage_path``
    (empty when none). A root file that is missing or not USD raises InputError."""
    root = open_root_layer(stage_path)
    info = root.pseudoRoot
    where = str(stage_path)
    out = []
    up = info.GetInfo(UsdGeom.Tokens.upAxis) if info.HasInfo(UsdGeom.Tokens.upAxis) else None
    up_used = up if up is not None else UsdGeom.GetFallbackUpAxis()
    if up_used != UsdGeom.Tokens.z:
        out.append(
            f"{where}: "
            + bad_value("upAxis", str(up_used), "expected Z (humv-usd check: humv:upAxis)")
            + ("" if up is not None else " (not authored: USD's fallback)")
        )
    mpu = info.GetInfo(UsdGeom.Tokens.metersPerUnit) if info.HasInfo(UsdGeom.Tokens.metersPerUnit) else None
    mpu_used = float(mpu) if mpu is not None else UsdGeom.LinearUnits.centimeters
    if not math.isclose(mpu_used, 1.0):
        out.append(
            f"{where}: "
            + bad_value("metersPerUnit", mpu_used, "expected 1 (humv-usd check: humv:metersPerUnit)")
            + ("" if mpu is not None else " (not authored: USD's fallback)")
        )
    for name in ("timeCodesPerSecond", "framesPerSecond"):  # 0 divides frame times by zero
        value = float(getattr(root, name))
        if not (math.isfinite(value) and value > 0):
            out.append(f"{where}: " + bad_value(name, value, "expected > 0 (humv-usd check: humv:timeCodes)"))
    if root.HasStartTimeCode() and root.HasEndTimeCode():
        start, end = float(root.startTimeCode), float(root.endTimeCode)
        if not (math.isfinite(start) and math.isfinite(end)):
            out.append(
                f"{where}: " + bad_value("startTimeCode..endTimeCode", [start, end], "expected finite")
            )
        elif end < start:
            out.append(
                f"{where}: "
                + bad_value("endTimeCode", end, f"expected >= startTimeCode ({start:g}): no frame to render")
            )
        elif math.floor(end) - math.ceil(start) + 1 > MAX_FRAMES_PER_CALL:
            out.append(
                f"{where}: "
                + bad_value(
                    "startTimeCode..endTimeCode",
                    [start, end],
                    f"{math.floor(end) - math.ceil(start) + 1:,} frames; at most "
                    f"{MAX_FRAMES_PER_CALL:,} per render (use --frames)",
                )
            )
    return out


def check_stage_for_render(stage_path, frames_given: bool = False) -> None:
    """Raise InputError (one line per problem) when :func:`stage_problems` finds any; a frame
    range too long to render whole is fine when ``frames_given`` (the render takes those)."""
    problems = stage_problems(stage_path)
    if frames_given:
        problems = [p for p in problems if "startTimeCode..endTimeCode" not in p]
    if problems:
        raise InputError(problems[0], problems)
