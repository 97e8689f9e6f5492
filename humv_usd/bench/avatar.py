"""``humv-usd bench avatar``: body fit errors over a grid, ground contact of walk and run on flat
and 5-degree ground, and the time to author a 10 s, 30 fps walk (the ``humv-usd avatar`` command
in a new process)."""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from humv_usd.human.body import build_body
from humv_usd.human.motion import make_motion
from humv_usd.human.skeleton import skeleton_for


def body_fit_errors(age: int = 30) -> dict[str, tuple[float, float]]:
    """Per sex, the largest |error| [%] of the built body's stature and mesh mass over statures
    1.5-2.0 m x masses 50-110 kg (average build)."""
    out = {}
    for sex in ("female", "male"):
        worst_h = worst_m = 0.0
        for stature in (1.5, 1.75, 2.0):
            for mass in (50.0, 80.0, 110.0):
                b = build_body(sex, age, stature, mass)
                worst_h = max(worst_h, abs(b.stature_m / stature - 1) * 100)
                worst_m = max(worst_m, abs(b.mass_kg / mass - 1) * 100)
        out[sex] = (worst_h, worst_m)
    return out


def contact_figures() -> list[dict]:
    """Ground contact of 10 s at 30 fps, male 1.78 m / 80 kg, walk (1.4 m/s) and run (3.5 m/s)
    on flat and 5-degree ground: the largest gap, penetration and stance slip of the sole
    vertices [m]."""
    body = build_body("male", 30, 1.78, 80.0)
    skel = skeleton_for(body.points, body.groups)
    slope = math.tan(math.radians(5.0))
    rows = []
    for activity, speed in (("walk", 1.4), ("run", 3.5)):
        for name, ground in (("flat", None), ("5 deg", lambda x, y: -slope * y)):
            m = make_motion(
                activity,
                skel,
                30.0,
                300,
                speed_m_s=speed,
                mass_kg=80.0,
                body_points=body.points,
                ground=ground,
            )
            c = m.contact
            rows.append(
                {
                    "activity": activity,
                    "speed_m_s": speed,
                    "ground": name,
                    "max_gap_m": c["max_gap_m"],
                    "max_penetration_m": c["max_penetration_m"],
                    "max_slip_m": c["max_slip_m"],
                }
            )
    return rows


def author_times(repeat: int) -> list[float]:
    """Wall times [s] of ``humv-usd avatar --activity walk --duration 10 --fps 30`` in a new
    process, ``repeat`` runs."""
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            t = time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "humv_usd.cli.main", "avatar", "--activity", "walk", "--duration", "10",
                 "--fps", "30", "-o", str(Path(tmp) / f"a{i}.usda")],
                check=True,
                capture_output=True,
            )  # fmt: skip
            times.append(time.perf_counter() - t)
    return times
