"""Shared fixtures. Real data sets live outside the repository (never copied into it)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """Directory of the real data sets: $AIDNAV_DATA, else ``../shared/data`` beside the repository.

    Skips the test when the directory is absent. Tests needing one set should check it exists, e.g.
    ``d = data_dir / "rtklibexplorer_drive_0708"; if not d.is_dir(): pytest.skip(...)``.
    """
    d = Path(os.environ.get("AIDNAV_DATA", REPO_ROOT.parent / "shared" / "data"))
    if not d.is_dir():
        pytest.skip(f"real data not found at {d} (set AIDNAV_DATA to the data directory)")
    return d
