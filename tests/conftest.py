"""Shared fixtures."""

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def real_data_dir() -> Path:
    """``../shared/data/real`` beside the checkout (real recordings, never committed)."""
    path = Path(__file__).resolve().parents[1].parent / "shared/data/real"
    if not path.is_dir():
        pytest.skip(f"real recordings not found at {path}")
    return path
