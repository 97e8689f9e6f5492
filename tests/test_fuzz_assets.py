"""Issue 15 (hostile input found by a machine) for asset files (issue 12's `[[scene.asset]]`).

Corrupt OBJ, glTF/GLB, PLY, STL and USD files, made by hypothesis from the example's real assets
(truncated, bytes flipped, spliced, garbage appended) and written by trimesh, are read with
``scene.assets.read_asset``: each reads (then every mesh has finite points and faces that index
them) or fails with one InputError line naming the file, never another exception. A few go
through ``humv-usd compose``: exit 2, one line, no traceback, nothing written.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from humv_usd.cli.main import main
from humv_usd.errors import InputError
from humv_usd.scene.assets import read_asset

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "examples" / "assets"
MAX_LINE = 600

FUZZ = settings(
    max_examples=400,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    derandomize=True,  # the same cases every run
)


def _box_bytes(suffix: str) -> bytes:
    """A small box exported by trimesh in ``suffix``'s format (PLY binary, STL binary)."""
    return trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(file_type=suffix.lstrip("."))


SOURCES = {
    ".obj": (ASSETS / "bench.obj").read_bytes(),
    ".glb": (ASSETS / "vehicle.glb").read_bytes(),
    ".usda": (ASSETS / "building.usda").read_bytes(),
    ".ply": _box_bytes(".ply"),
    ".stl": _box_bytes(".stl"),
}


@st.composite
def corrupt(draw):
    """One of the real files with a corruption a disk, a network or a person makes."""
    suffix = draw(st.sampled_from(sorted(SOURCES)))
    data = bytearray(SOURCES[suffix])
    how = draw(st.sampled_from(["truncate", "flip", "splice", "append", "zero", "empty"]))
    if how == "truncate":
        data = data[: draw(st.integers(0, len(data) - 1))]
    elif how == "flip":
        for _ in range(draw(st.integers(1, 16))):
            i = draw(st.integers(0, len(data) - 1))
            data[i] = draw(st.integers(0, 255))
    elif how == "splice":
        a, b = sorted(draw(st.lists(st.integers(0, len(data)), min_size=2, max_size=2)))
        data = data[:a] + draw(st.binary(min_size=0, max_size=64)) + data[b:]
    elif how == "append":
        data += draw(st.binary(min_size=1, max_size=256))
    elif how == "zero":
        a = draw(st.integers(0, len(data) - 1))
        data[a : a + draw(st.integers(1, 512))] = bytes(min(512, len(data) - a))
    else:
        data = bytearray()
    return suffix, bytes(data), how


def _read_or_fail_cleanly(path: Path) -> None:
    try:
        asset = read_asset(str(path))
    except InputError as e:
        text = str(e)
        assert "\n" not in text and len(text) <= MAX_LINE, text[:200]
        assert str(path) in text  # names the file
        return
    for m in asset.meshes:  # what it reads is usable (USD meshes stay in their file)
        if m.points is None:
            continue
        assert np.all(np.isfinite(m.points))
        faces = np.asarray(m.face_indices)
        assert faces.size == 0 or (faces.min() >= 0 and faces.max() < len(m.points))
        assert int(np.sum(m.face_counts)) == faces.size


@FUZZ
@given(case=corrupt())
def test_corrupt_asset_files_read_or_fail_with_one_line(tmp_path, case):
    suffix, data, how = case
    path = tmp_path / f"asset_{how}{suffix}"
    path.write_bytes(data)
    _read_or_fail_cleanly(path)


@pytest.mark.slow
@pytest.mark.parametrize("suffix", sorted(SOURCES))
def test_compose_refuses_a_truncated_asset_with_one_line(tmp_path, suffix):
    """End to end: a scenario whose asset file is cut in half stops compose before it writes."""
    raw = (ROOT / "examples" / "street.toml").read_text()
    scenario = tomllib.loads(raw)
    asset = tmp_path / f"broken{suffix}"
    data = SOURCES[suffix]
    asset.write_bytes(data[: len(data) // 2])
    first = scenario["scene"]["asset"][0]["file"]
    edited = tmp_path / "street.toml"
    edited.write_text(raw.replace(f'"{first}"', f'"{asset}"', 1))
    for other in ASSETS.iterdir():  # the other assets, where the scenario looks for them
        (tmp_path / "assets").mkdir(exist_ok=True)
        (tmp_path / "assets" / other.name).write_bytes(other.read_bytes())
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["compose", str(edited), "-o", str(out)])
    if result.exit_code == 0:  # the half file still held a whole mesh (OBJ, ASCII): fine
        return
    assert result.exit_code == 2, result.output
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    assert str(asset) in lines[0]
    assert not (out / "stage.usda").exists()
