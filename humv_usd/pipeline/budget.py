"""Before a long run: estimates of memory, disk and time, and a refusal of what cannot fit.

The estimates are rough (factor ~2) linear models of what compose and render hold and write,
fitted on this repository's examples (a clothed walking person writes about 160 kB of layer
text per frame, an image about 40 bytes per pixel of EXR + PNG files and needs about 400 bytes
per pixel of arrays while it is rendered and labelled; the path tracer does about 4 M samples
per second on two cores, see the shared recipes). Their job is to stop a run that would exhaust
this machine (86,400,001 frames from ``duration_s = 86400, fps = 1000``; a 16384 x 16384
sensor) with one line naming the estimate, the key to change and ``--yes`` to go ahead anyway.
"""

from __future__ import annotations

import logging
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from humv_usd.errors import InputError

log = logging.getLogger(__name__)

#: compose: layer text per frame and clothed person [bytes] (avatar motion + garment points)
PERSON_FRAME_BYTES = 160e3
#: compose: layer text per frame for the rest (sun, weather samples, per-face temperatures)
SCENE_FRAME_BYTES = 2e3
#: compose: memory held per byte of layer text (USD layers, Python arrays, the text itself)
COMPOSE_MEMORY_PER_BYTE = 8.0
#: compose: seconds per frame and person (skinning, garments, thermal) and per frame
COMPOSE_PERSON_FRAME_S = 0.2
#: render: bytes written per pixel of an image (EXR with labels, previews, masks)
IMAGE_DISK_PER_PIXEL = 40.0
#: render: bytes of arrays per pixel of the image being rendered and labelled
IMAGE_MEMORY_PER_PIXEL = 400.0
#: render: Monte Carlo samples per second (two cores) and fixed seconds per image
SAMPLES_PER_S = 4e6
IMAGE_OVERHEAD_S = 0.5
#: render / compose: the base memory of the process (Python, USD, Mitsuba) [bytes]
BASE_MEMORY = 600e6
#: share of the available memory a run may plan to use
MEMORY_SHARE = 0.8


@dataclass(frozen=True)
class Budget:
    """An estimate of one run."""

    what: str  # "compose" or "render"
    memory_bytes: float
    disk_bytes: float
    seconds: float
    basis: str  # what the estimate is made of, in the user's words
    keys: str  # the keys or options that change it

    def text(self) -> str:
        return (
            f"{self.what} of {self.basis}: about {size_text(self.memory_bytes)} of memory, "
            f"{size_text(self.disk_bytes)} on disk, {_duration(self.seconds)}"
        )


def size_text(n: float) -> str:
    """A byte count in kB, MB, GB or TB, 3 significant digits."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"


def _duration(s: float) -> str:
    for unit, scale in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s:.2g} s"


def compose_budget(scenario) -> Budget:
    frames = scenario.frame_count
    people = len(scenario["human"])
    text = frames * (people * PERSON_FRAME_BYTES + SCENE_FRAME_BYTES)
    return Budget(
        "compose",
        BASE_MEMORY + COMPOSE_MEMORY_PER_BYTE * text,
        text,
        frames * (people * COMPOSE_PERSON_FRAME_S + 0.01) + 2.0,
        f"{frames:,} frame(s) x {people} person(s)",
        "general.duration_s or general.fps",
    )


def render_budget(resolutions, frames: int, spp: int) -> Budget:
    """``resolutions``: (width, height) of every sensor rendered; ``frames`` to render."""
    pixels = [int(w) * int(h) for w, h in resolutions]
    images = frames * len(pixels)
    return Budget(
        "render",
        BASE_MEMORY + IMAGE_MEMORY_PER_PIXEL * max(pixels, default=0),
        IMAGE_DISK_PER_PIXEL * frames * sum(pixels),
        frames * sum(p * spp / SAMPLES_PER_S + IMAGE_OVERHEAD_S for p in pixels),
        f"{images:,} image(s) ({frames:,} frame(s) x {len(pixels)} sensor(s), up to "
        f"{max(pixels, default=0):,} pixels, {spp} spp)",
        "sensor.resolution in the scenario, or --frames",
    )


def available_memory() -> float:
    """MemAvailable of /proc/meminfo [bytes] (inf where it is not known)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return float("inf")


def free_disk(folder) -> float:
    path = Path(folder).absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    try:
        return float(shutil.disk_usage(path).free)
    except OSError:
        return float("inf")


def require_fits(budget: Budget, folder, yes: bool = False) -> None:
    """Log the estimate; raise InputError (one line: estimate, what this machine has, the keys to
    change, ``--yes``) when it needs more memory or disk than there is, unless ``yes``."""
    log.info("%s", budget.text())
    memory, disk = available_memory() * MEMORY_SHARE, free_disk(folder)
    short = []
    if budget.memory_bytes > memory:
        short.append(f"{size_text(memory / MEMORY_SHARE)} of memory available")
    if budget.disk_bytes > disk:
        short.append(f"{size_text(disk)} free on disk at {os.fspath(folder)}")
    if short and not yes:
        raise InputError(
            f"{budget.text()}; this machine has {' and '.join(short)}: change {budget.keys}, "
            "or pass --yes to go ahead anyway"
        )
