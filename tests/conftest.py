"""Shared fixtures. ``import humv_usd`` first: the schemas must register before any stage."""
from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

import humv_usd  # noqa: F401

ROOT = Path(__file__).resolve().parents[1]
HUMVVEX = ROOT / "examples" / "humvvex.toml"


@pytest.fixture(scope="session")
def humvvex_raw() -> dict:
    return tomllib.loads(HUMVVEX.read_text())


@pytest.fixture
def raw(humvvex_raw) -> dict:
    """A fresh, mutable copy of the humvvex scenario document."""
    return copy.deepcopy(humvvex_raw)
