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
from humv_usd.scenario.spec import DEFAULT_SUBBANDS

log = logging.getLogger(__name__)

#: compose: layer text per frame and clothed person [bytes] (avatar motion + garment points).
#: Measured (issue 29, ``python -m humv_usd.bench.crowd``, 2026-11-27): 10 walkers in a
#: T-shirt, leggings and shoes wrote 62 MB of layers at 16 frames and 142 MB at 46 frames,
#: 265 kB per person and frame (clothing 257 kB, avatar 8 kB); at 3,601 frames (s7) 180 kB
#: (clothing 176 kB, avatar 3.6 kB) and, while compose runs, 57 kB of held scratch files
#: (``compose.hold_layer``): 237 kB.
PERSON_FRAME_BYTES = 270e3
#: compose: per-face temperature text per frame and person of a thermal model that solves per
#: frame (jos3, twoNode; "fixed" writes no per-frame samples). Measured (``python -m
#: humv_usd.bench.crowd``, 2026-11-27, s5): 2 walkers, 31 frames, jos3 25.1 MB of layers against
#: 14.4 MB with "fixed": 173 kB per person and frame (16.5 k body and garment faces)
THERMAL_PERSON_FRAME_BYTES = 180e3
#: compose: layer text per frame for the rest (sun, weather samples)
SCENE_FRAME_BYTES = 2e3
#: What compose holds (issue 29.5). Every layer's text goes to disk by USD's streaming writer as
#: soon as the layer is built (``compose.stage_layer``; before s5 the text was one string, then
#: encoded: ~2 x the text on top), and a layer is dropped once the last layer reading it is
#: built. The thermal tool spills each mesh's per-frame temperatures to disk as soon as they are
#: solved (``usd.spill``), so its layer and the people's results are no longer held (before: all
#: people's float64 results + the float32 layer + 2 x its text). What still grows per frame: the
#: avatar/clothing layers the thermal tool reads (every person's, ``HELD``), the working set of
#: the one clothing layer being built (``BUILD``) and, for a per-frame thermal model, the one
#: person's physiology and garment balance over the whole clip (``THERMAL_SOLVE``: (frames, faces)
#: float64 arrays of the coupled solve, :func:`humv_usd.thermal.human.human_temperatures`).
#: Measured peak RSS (``python -m humv_usd.bench.crowd OUT --people 2 --fps 10 --durations 3 6
#: 12 24``, each layer build's own peak, 2026-11-27 s5, under load; /work/notes/s5/crowds.md):
#: 2 walkers, "fixed", 440 / 444 / 489 / 508 MB at 31 / 61 / 121 / 241 frames (the clothing build
#: over the avatar phase: +29 / +34 / +43 / +65 MB, ~0.15 MB per frame); 10 walkers for 2 min at
#: 1 fps (121 frames, ``--people 10 --fps 1 --duration 120``): 556 MB, the clothing phases
#: growing from 502 (first person) to 556 MB (tenth): 50 kB per person and frame held.
#: Since s7 compose holds those layers as scratch crate files read back on demand
#: (``compose.hold_layer``): file pages, not compose's memory (a clothing layer of 3,601 frames,
#: T-shirt, leggings and shoes: 199 MB of usdc, 202 MB when held in memory), so ``HELD`` is 0.
#: The build: 10 walkers x 3,601 frames (2 min at 30 fps, ``--people 10 --fps 30 --duration
#: 120``, s7, under load): the first clothing build peaked at 1,047 MB over 431 MB before it
#: (0.17 MB per frame), the second at 1,011 MB. 0.5 MB
#: per frame covers every measured point (the s3 ones held the layers' texts).
COMPOSE_BUILD_FRAME_BYTES = 0.5e6
COMPOSE_HELD_PERSON_FRAME_BYTES = 0.0
#: per-frame thermal model: the one person's solve, fixed part and per frame. Measured (2 walkers,
#: jos3, ``--durations 3 6`` at 10 fps): peak 840 MB at 31 frames (the thermal build over 421 MB
#: held), 882 MB at 61: 1.37 MB per frame for the solve and both people's held layers (the code
#: before the spill: 850 and 934 MB, 2.78 MB per frame). Rounded up.
COMPOSE_THERMAL_SOLVE_BYTES = 450e6
COMPOSE_THERMAL_SOLVE_FRAME_BYTES = 1.5e6
#: compose: seconds per frame and person (skinning, garments, thermal) and per frame (measured
#: 2026-11-27 s5, bench above, "fixed": 14.6 / 24.9 / 46.4 CPU-s at 31 / 61 / 121 frames of 2
#: walkers, 0.18 s per person and frame)
COMPOSE_PERSON_FRAME_S = 0.2
#: compose: seconds per frame and person of a per-frame thermal model (jos3: 79 / 178 CPU-s at
#: 31 / 61 frames of 2 walkers, 1.65 s per person and frame; under load, so rounded up)
COMPOSE_THERMAL_PERSON_FRAME_S = 1.7
#: render: bytes written per pixel of an image (EXR with labels, previews, masks)
IMAGE_DISK_PER_PIXEL = 40.0
#: render: bytes of arrays per pixel of the image being rendered and labelled
IMAGE_MEMORY_PER_PIXEL = 400.0
#: render, fast estimator: bytes per lane (one camera sample of one pixel; all pixels x spp lanes
#: of a batch live at once) and per lane and infrared sub-band. Measured peak RSS (``/usr/bin/time
#: -f %M humv-usd render STAGE -o R --spp N --subbands K --yes``, one LWIR camera of walk.toml,
#: usd-core 26.11, 2026-11-27) minus the run at spp 1: 64x48 px at spp 256: 384 B/lane (K 1), 494
#: (K 4), 787 (K 16); spp 512, 1024: 753, 751 (K 16); 256x192 px at spp 64, 128: 742, 749 (K 16).
#: Linear in pixels x spp (3.1 M lanes: 2.70 GB at 64x48 x 1024, 2.72 GB at 256x192 x 64; 6.3 M
#: lanes: 5.04 GB), so 1024x768 at spp 32 (25 M lanes) needs about 19 GB; the path
#: estimator stayed at 0.35-0.40 GB from spp 1 to 1024 (flat). Rounded up: 400 + 28 K.
FAST_LANE_BYTES = 400.0
FAST_LANE_BYTES_PER_SUBBAND = 28.0
#: the EO fast estimator (12 visible sub-bands) per lane, measured as above on the same camera
#: as EO: 314 B/lane at spp 256, 232 at spp 1024
EO_FAST_LANE_BYTES = 320.0
EO_SUBBANDS = 12
#: fast estimator: lanes x sub-bands per second (the runs above: 3.1 M lanes x 16 sub-bands in
#: 15-16 s on two shared cores)
FAST_SUBBAND_LANES_PER_S = 3.2e6
#: render: Monte Carlo samples per second (two cores) and fixed seconds per image
SAMPLES_PER_S = 4e6
IMAGE_OVERHEAD_S = 0.5
#: render / compose: the base memory of the process (Python, USD, Mitsuba) [bytes]
BASE_MEMORY = 600e6
#: most frames one render may take (``--frames`` or the stage's whole range), checked before a
#: list of them is built (``--frames 0:99999999999`` once ended in MemoryError)
MAX_FRAMES_PER_CALL = 1_000_000
#: most samples per pixel ``humv-usd render --spp`` and the editor's spp field accept (the
#: memory estimate then decides what fits this machine)
MAX_SPP = 1 << 20
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
    """The estimate of a compose (see the constants above): disk = the layer texts and, while
    the thermal layer is written, its spilled samples once more; memory = the base + per frame
    the one clothing build's working set (the layers later builds read are held on disk) + for
    a per-frame thermal model one person's solve (its layer goes to disk as it is made)."""
    frames = scenario.frame_count
    people = len(scenario["human"])
    per_frame_thermal = (scenario.get("thermal") or {}).get("model", "fixed") != "fixed"
    thermal_text = frames * people * THERMAL_PERSON_FRAME_BYTES if per_frame_thermal else 0.0
    text = frames * (people * PERSON_FRAME_BYTES + SCENE_FRAME_BYTES) + thermal_text
    solve = (
        COMPOSE_THERMAL_SOLVE_BYTES + frames * COMPOSE_THERMAL_SOLVE_FRAME_BYTES
        if per_frame_thermal and people
        else 0.0
    )
    memory = (
        BASE_MEMORY
        + frames * (COMPOSE_BUILD_FRAME_BYTES * min(people, 1) + people * COMPOSE_HELD_PERSON_FRAME_BYTES)
        + solve
    )
    return Budget(
        "compose",
        memory,
        text + thermal_text,
        frames
        * (people * (COMPOSE_PERSON_FRAME_S + COMPOSE_THERMAL_PERSON_FRAME_S * per_frame_thermal) + 0.01)
        + 2.0,
        f"{frames:,} frame(s) x {people} person(s)",
        "general.duration_s or general.fps",
    )


def render_budget(
    resolutions,
    frames: int,
    spp: int,
    *,
    estimator: str = "fast",
    subbands: int = DEFAULT_SUBBANDS,
    eo_resolutions=(),
    eo_spp: int | None = None,
) -> Budget:
    """The estimate of a render.

    Parameters
    ----------
    resolutions : list of (int, int)
        (width, height) of every infrared sensor rendered.
    frames : int
        Frames to render.
    spp : int
        Samples per pixel of a batch (the fast estimator traces pixels x spp paths at once).
    estimator : str
        ``"fast"`` (memory grows with pixels x spp x sub-bands) or ``"path"`` (flat in spp).
    subbands : int
        Most sub-bands of an infrared sensor.
    eo_resolutions : list of (int, int)
        (width, height) of every EO sensor rendered.
    eo_spp : int, optional
        Samples per pixel of the EO sensors (default ``spp``).

    Notes
    -----
    Sensors render one after another, so memory is the base plus the largest sensor's
    :data:`IMAGE_MEMORY_PER_PIXEL` x pixels plus, for the fast estimator, pixels x spp lanes of
    :data:`FAST_LANE_BYTES` + :data:`FAST_LANE_BYTES_PER_SUBBAND` x sub-bands each (EO:
    :data:`EO_FAST_LANE_BYTES`); frames add disk and time, not memory (the render's memory is
    flat over frames).
    """
    eo_spp = spp if eo_spp is None else eo_spp
    fast = estimator == "fast"
    ir = [(int(w) * int(h), "ir") for w, h in resolutions]
    eo = [(int(w) * int(h), "eo") for w, h in eo_resolutions]
    lane_bytes = {"ir": FAST_LANE_BYTES + FAST_LANE_BYTES_PER_SUBBAND * subbands, "eo": EO_FAST_LANE_BYTES}
    sensor_spp = {"ir": spp, "eo": eo_spp}
    memory = [
        IMAGE_MEMORY_PER_PIXEL * p + (p * sensor_spp[k] * lane_bytes[k] if fast else 0.0) for p, k in ir + eo
    ]
    seconds = [
        p * sensor_spp[k] * (subbands if k == "ir" else EO_SUBBANDS) / FAST_SUBBAND_LANES_PER_S
        if fast
        else p * sensor_spp[k] / SAMPLES_PER_S
        for p, k in ir + eo
    ]
    pixels = [p for p, _ in ir + eo]
    images = frames * len(pixels)
    return Budget(
        "render",
        BASE_MEMORY + max(memory, default=0.0),
        IMAGE_DISK_PER_PIXEL * frames * sum(pixels),
        frames * sum(t + IMAGE_OVERHEAD_S for t in seconds),
        f"{images:,} image(s) ({frames:,} frame(s) x {len(pixels)} sensor(s), up to "
        f"{max(pixels, default=0):,} pixels, {spp} spp"
        + (f" (EO {eo_spp})" if eo and eo_spp != spp else "")
        + (f", {subbands} sub-bands, {estimator} estimator)" if ir else f", {estimator} estimator)"),
        "sensor.resolution in the scenario, --spp, --subbands or --frames",
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


def scenario_render_budget(scenario, spp: int, estimator: str = "fast") -> Budget:
    """:func:`render_budget` of rendering every frame of a validated scenario's sensors at
    ``spp`` (what ``humv-usd render`` of its composed stage would estimate; the editor checks
    its spp field with it before starting a render)."""
    ir = [s for s in scenario["sensor"] if s["wavelength_um"][0] >= 3.0]
    eo = [s for s in scenario["sensor"] if s["wavelength_um"][0] < 3.0]
    return render_budget(
        [s["resolution"] for s in ir],
        scenario.frame_count,
        spp,
        estimator=estimator,
        subbands=max((s.get("subbands") or DEFAULT_SUBBANDS for s in ir), default=1),
        eo_resolutions=[s["resolution"] for s in eo],
    )
