"""Shared test fixtures: the location of ../shared/data and a skip marker for tests that need it."""

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
SEED = 20261121


def shared_path(*parts: str) -> Path:
    """Path below ../shared/data; skips the calling test with a reason where it is absent."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"needs ../shared/data/{'/'.join(parts)} (absent here)")
    return path
