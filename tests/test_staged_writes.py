"""Streaming writes (issue 29.5): a text staged to a temp file as soon as it is made is
committed with the others as one change (humv_usd.fileio.stage_text / commit_files)."""

from __future__ import annotations

import os

from humv_usd.fileio import commit_files, discard_staged, remove_stale_temps, stage_text


def test_staged_text_commits_with_the_others(tmp_path):
    a, b = tmp_path / "layers" / "a.usda", tmp_path / "b.txt"
    staged = stage_text(a, "#usda 1.0\n" + "x" * 1000)
    assert staged.tmp.parent == a.parent and not a.exists()  # nothing final before the commit
    written = commit_files(tmp_path, {a: staged, b: "plain"})
    assert set(written) == {a, b}
    assert a.read_text() == "#usda 1.0\n" + "x" * 1000 and b.read_text() == "plain"
    assert not staged.tmp.exists()
    assert sorted(p.name for p in tmp_path.rglob(".*")) == []


def test_an_unchanged_staged_text_is_not_rewritten(tmp_path):
    a = tmp_path / "a.usda"
    a.write_text("same")
    os.utime(a, (1_000_000, 1_000_000))
    staged = stage_text(a, "same")
    assert commit_files(tmp_path, {a: staged}) == []
    assert a.stat().st_mtime == 1_000_000 and not staged.tmp.exists()


def test_a_failed_change_leaves_no_staged_file(tmp_path):
    a = tmp_path / "a.usda"
    staged = [stage_text(a, "one"), stage_text(tmp_path / "b.usda", "two")]
    discard_staged(staged + ["a plain text is ignored"])
    assert not any(s.tmp.exists() for s in staged) and not a.exists()
    # a staged file a kill left behind is a temp file compose's start-up removes
    left = stage_text(a, "three")
    assert remove_stale_temps(tmp_path) == [left.tmp]
