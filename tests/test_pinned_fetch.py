"""The set-up fetch tools' shared helper (tools/pinned_fetch.py): the destination folder is replaced
only by a complete, stamped fetch; a failed one leaves it as it was and no staging folder behind."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import pinned_fetch as P  # noqa: E402


def test_staged_replaces_the_folder_only_when_the_body_finishes(tmp_path):
    dest = tmp_path / "data"
    dest.mkdir()
    (dest / "old.txt").write_text("old")
    with pytest.raises(P.FetchError), P.staged(dest, "pin-2", ".x-") as staging:
        (staging / "half.txt").write_text("half")
        raise P.FetchError("archive lacks a file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]  # no staging folder left
    assert (dest / "old.txt").is_file() and not P.is_current(dest, "pin-2")

    with P.staged(dest, "pin-2", ".x-") as staging:
        (staging / "new.txt").write_text("new")
    assert sorted(p.name for p in dest.iterdir()) == [P.STAMP, "new.txt"]
    assert P.is_current(dest, "pin-2") and not P.is_current(dest, "pin-1")


def test_file_sha256_reads_in_blocks(tmp_path):
    path = tmp_path / "blob"
    data = bytes(range(256)) * 9000  # 2.2 MiB: three blocks
    path.write_bytes(data)
    assert P.file_sha256(path) == hashlib.sha256(data).hexdigest()
