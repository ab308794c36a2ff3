"""Shared fixtures: the real motion-capture corpus in ../shared/data."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import simenv  # noqa: F401  (chooses MUJOCO_GL before any test module imports mujoco)

REPO = Path(__file__).resolve().parent.parent
SHARED_DATA = Path(os.environ.get("SIMENV_SHARED_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Root of the real mocap corpus; skips the test when it is absent."""
    if not (SHARED_DATA / "SOURCES.md").is_file():
        pytest.skip(
            f"real mocap corpus not found at {SHARED_DATA} "
            "(set SIMENV_SHARED_DATA to the shared/data folder)"
        )
    return SHARED_DATA
