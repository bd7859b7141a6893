"""Shared fixtures. Real data from ../shared/data is found through RMPL_SHARED_DATA or the
sibling folder of the checkout; tests that need it skip with a reason when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

_DEFAULT = Path(__file__).resolve().parents[2] / "shared" / "data"


def shared_data_root() -> Path | None:
    root = Path(os.environ.get("RMPL_SHARED_DATA", _DEFAULT))
    return root if root.is_dir() else None


@pytest.fixture
def shared_data() -> Path:
    """Path to ../shared/data; skips the test when it is absent."""
    root = shared_data_root()
    if root is None:
        pytest.skip(f"shared data not found at {_DEFAULT} (set RMPL_SHARED_DATA)")
    return root


def pytest_configure(config):
    """One torch thread: the test models are tiny, and two spinning OpenMP threads on a
    shared 2-core machine slow them down tenfold."""
    import torch

    torch.set_num_threads(1)
