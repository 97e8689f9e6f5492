"""Time samples spilled to disk while a layer is built, spliced into its usda text when it is
written (issue 29.5: compose memory that does not grow with the clip's length).

A layer tool that makes one large array per frame (the thermal layer: a temperature per face of
every mesh and frame) hands each series to a :class:`SampleSpill` as soon as it has it, a few
frames at a time; the spill formats them as usda time-sample lines (USD's own text writer, on a
small layer holding only those frames) and appends them to a fragment file, so neither the
arrays nor the layer hold the clip. The layer itself gets one placeholder sample per spilled
attribute (time code ``PLACEHOLDER_TIME - index``, an empty array), and :meth:`SampleSpill.export`
writes the layer's text with each placeholder line replaced by its fragment: the same bytes as
the layer holding every sample would write (``tests/test_spill.py``).

Fragments are files named like :func:`humv_usd.fileio.remove_stale_temps` removes them
(``.<name>.spill<k>.<random>.tmp.txt``) in the folder given (compose: the layer folder, on the
disk the layers go to), deleted by :meth:`SampleSpill.close`.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Sdf, Vt

#: time code of the first placeholder sample (the k-th spilled series uses this minus k): far
#: below any frame (frames are >= 0)
PLACEHOLDER_TIME = -1.0e12
#: frames formatted at once (a chunk's text lives in memory while it is formatted: 64 frames of
#: a 30 k-face body are ~16 MB of text)
CHUNK_FRAMES = 64
#: the attribute path of the scratch layer that formats samples
_SCRATCH = Sdf.Path("/Spill.samples")


@dataclass(frozen=True)
class Spilled:
    """A series on disk: its fragment file, its placeholder time code and frame count."""

    path: Path
    time: float
    frames: int


class SampleSpill:
    """Series of per-frame arrays spilled to fragment files (see the module doc).

    ``folder``: where the fragments go (None: the system's temp folder); ``name``: their file
    name's stem (the layer's name). Use as a context manager or call :meth:`close`.
    """

    def __init__(self, folder=None, name: str = "layer"):
        self.folder = Path(folder) if folder is not None else Path(tempfile.gettempdir())
        self.name = name
        self.series: list[Spilled] = []

    def __enter__(self) -> SampleSpill:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def add(self, chunks, type_name=Sdf.ValueTypeNames.FloatArray, dtype=np.float32) -> Spilled:
        """Spill a series given as ``chunks``: an iterable of (first frame, (n, ...) array),
        frames in increasing order; each frame's value is written as ``type_name`` (its rows
        cast to ``dtype``; time code = frame). Returns the handle :meth:`bind` takes."""
        self.folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(
            prefix=f".{self.name}.spill{len(self.series)}.", suffix=".tmp.txt", dir=self.folder
        )
        frames = 0
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                for first, values in chunks:
                    values = np.asarray(values, dtype=dtype)
                    for start in range(0, len(values), CHUNK_FRAMES):
                        part = values[start : start + CHUNK_FRAMES]
                        fh.write(sample_lines(first + start, part, type_name))
                        frames += len(part)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.remove(tmp)
            raise
        spilled = Spilled(Path(tmp), PLACEHOLDER_TIME - len(self.series), frames)
        self.series.append(spilled)
        return spilled

    def add_array(self, series, type_name=Sdf.ValueTypeNames.FloatArray, dtype=np.float32) -> Spilled:
        """:meth:`add` of a whole (frames, ...) array, frame i at time code i."""
        return self.add([(0, series)], type_name, dtype)

    @staticmethod
    def bind(attr, spilled: Spilled, empty=None) -> None:
        """Author the placeholder of ``spilled`` on ``attr`` (a Usd.Attribute whose type is the
        series'): the attribute then has exactly this one sample in the layer."""
        attr.Set(Vt.FloatArray() if empty is None else empty, spilled.time)

    def export(self, layer: Sdf.Layer, path) -> str:
        """Write ``layer``'s usda text to ``path`` with its placeholders replaced by their
        series, streaming (the text is never held whole); returns its sha256 hex digest."""
        by_time = {s.time: s for s in self.series}
        path = Path(path)
        fd, skeleton = tempfile.mkstemp(prefix=f".{self.name}.skeleton.", suffix=".tmp.usda", dir=path.parent)
        os.close(fd)
        digest = hashlib.sha256()
        try:
            layer.Export(skeleton)
            with open(skeleton, encoding="utf-8") as src, open(path, "w", encoding="utf-8") as out:
                for line in src:
                    spilled = _placeholder(line, by_time)
                    if spilled is None:
                        _write(out, digest, line)
                        continue
                    indent = line[: len(line) - len(line.lstrip())]
                    with open(spilled.path, encoding="utf-8") as frag:
                        for sample in frag:
                            _write(out, digest, indent + sample)
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.remove(skeleton)
        return digest.hexdigest()

    def close(self) -> None:
        """Delete the fragment files."""
        for s in self.series:
            with contextlib.suppress(FileNotFoundError):
                os.remove(s.path)
        self.series = []


def sample_lines(first: int, values: np.ndarray, type_name=Sdf.ValueTypeNames.FloatArray) -> str:
    """The usda time-sample lines (``<time>: <value>,``, no indentation, one per row) of rows
    ``values`` at time codes ``first``, ``first + 1``, ...: written by USD's text writer on a
    scratch layer, so they are the characters the layer holding these samples would write."""
    scratch = Sdf.Layer.CreateAnonymous(".usda")
    prim = Sdf.CreatePrimInLayer(scratch, _SCRATCH.GetPrimPath())
    Sdf.AttributeSpec(prim, _SCRATCH.name, type_name)
    for i, row in enumerate(values):
        scratch.SetTimeSample(_SCRATCH, float(first + i), _vt(row, type_name))
    text = scratch.ExportToString()
    start = text.index(".timeSamples = {\n") + len(".timeSamples = {\n")
    end = text.index("\n    }\n", start)
    # one sample per line (a value's text has no newline: arrays of numbers or tuples)
    lines = [line.lstrip() for line in text[start:end].splitlines()]
    if len(lines) != len(values):
        raise ValueError(f"spill: {len(values)} samples wrote {len(lines)} lines")
    return "".join(line + "\n" for line in lines)


def _vt(row: np.ndarray, type_name):
    return type_name.type.pythonClass.FromNumpy(np.ascontiguousarray(row))


def _placeholder(line: str, by_time: dict) -> Spilled | None:
    """The series whose placeholder sample ``line`` is (``<time>: [],``), else None."""
    text = line.strip()
    if not text.endswith(": [],") or not text.startswith("-"):
        return None
    try:
        return by_time.get(float(text[: -len(": [],")]))
    except ValueError:
        return None


def _write(out, digest, text: str) -> None:
    out.write(text)
    digest.update(text.encode("utf-8"))
