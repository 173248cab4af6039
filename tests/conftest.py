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


@pytest.fixture(scope="session")
def office_log(tmp_path_factory) -> Path:
    """A 30 s simulated office walk (seed 3), recorded once per test session."""
    from smokyslam.config import load_config
    from smokyslam.sim.simulate import simulate

    path = tmp_path_factory.mktemp("logs") / "office30.mcap"
    simulate("office", 30.0, 3, path, load_config())
    return path
