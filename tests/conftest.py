"""Shared fixtures: the real datasets (../shared/data or $RGBD_DATA)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rgbd_rs.data import data_root


@pytest.fixture(scope="session")
def shared_data() -> Path:
    root = data_root()
    if root is None:
        pytest.skip("shared datasets not found: set RGBD_DATA or place ../shared/data")
    return root
