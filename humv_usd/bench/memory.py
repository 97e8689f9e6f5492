"""Resident memory of a long render, sampled while it runs (``humv-usd bench memory``).

The render is expected to keep nothing per frame (issue 15: per-frame results are streamed to
record files and the aggregates rebuilt from them at the end), so its resident set size (RSS)
after frame 300 should be within a few per cent of that after frame 30.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def rss_mb() -> float:
    """Resident set size of this process [MB] (Linux /proc; 0 where it is not available)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            return int(fh.read().split()[1]) * _PAGE / 1e6
    except (OSError, ValueError, IndexError):
        return 0.0


class FrameRSS:
    """Samples RSS every ``period_s`` while a render writes ``folder`` (one image per frame:
    ``*.exr`` files counted) and keeps the RSS at the moment each checkpoint frame's image
    appeared (frame n done = n + 1 images), plus the peak."""

    def __init__(self, folder, checkpoints=(30, 300), period_s: float = 0.05):
        self.folder = Path(folder)
        self.checkpoints = sorted(int(c) for c in checkpoints)
        self.period_s = period_s
        self.at: dict[int, float] = {}
        self.peak = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _images(self) -> int:
        if not self.folder.is_dir():
            return 0
        return sum(1 for p in self.folder.iterdir() if p.suffix == ".exr" and not p.name.startswith("."))

    def _run(self) -> None:
        while not self._stop.is_set():
            rss = rss_mb()
            self.peak = max(self.peak, rss)
            done = self._images()
            for c in self.checkpoints:
                if c not in self.at and done >= c + 1:
                    self.at[c] = rss
            self._stop.wait(self.period_s)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        return False

    def growth(self) -> float | None:
        """RSS at the last checkpoint relative to the first, minus 1 (0.05 = 5 % more)."""
        first, last = self.checkpoints[0], self.checkpoints[-1]
        if first in self.at and last in self.at and self.at[first] > 0:
            return self.at[last] / self.at[first] - 1.0
        return None


def small_sensors(raw: dict, width: int, height: int) -> dict:
    """The scenario document with every sensor at ``width`` x ``height`` pixels and the same
    field of view (focal length scaled with the width; else the pixel pitch)."""
    out = dict(raw)
    sensors = []
    for s in raw.get("sensor", []):
        s = dict(s)
        old_w = (s.get("resolution") or [width, height])[0]
        s["resolution"] = [int(width), int(height)]
        if "focal_length_mm" in s:
            s["focal_length_mm"] = max(0.5, float(s["focal_length_mm"]) * width / old_w)
        else:
            s["pixel_pitch_um"] = min(100.0, float(s.get("pixel_pitch_um", 17.0)) * old_w / width)
        sensors.append(s)
    out["sensor"] = sensors
    return out


def timed(fn, *args, **kwargs):
    t = time.perf_counter()
    result = fn(*args, **kwargs)
    return result, time.perf_counter() - t
