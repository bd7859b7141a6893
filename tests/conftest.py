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


_GL: list = []  # the headless-OpenGL probe, run once: [None] = works, [reason] = does not


def synth_ready(*modules: str) -> Path:
    """Skip unless the MHP stack runs here; return anny's cache directory.

    Needs the given modules (any of "anny", "moderngl", "mediapipe"), and with "moderngl"
    a headless EGL context. The cache is ``$ANNY_CACHE_DIR``, else ``~/.cache/rmpl/anny``,
    which the first test that needs it builds (about 3.5 minutes and 790 MB, once).
    """
    for mod in modules:
        pytest.importorskip(mod)
    if "moderngl" in modules:
        if not _GL:
            import moderngl

            try:
                moderngl.create_standalone_context(backend="egl").release()
                _GL.append(None)
            except Exception as e:  # no EGL driver on this machine
                _GL.append(str(e) or type(e).__name__)
        if _GL[0] is not None:
            pytest.skip(f"no headless OpenGL context: {_GL[0]}")
    cache = Path(os.environ.get("ANNY_CACHE_DIR") or Path.home() / ".cache" / "rmpl" / "anny")
    cache.mkdir(parents=True, exist_ok=True)
    os.environ["ANNY_CACHE_DIR"] = str(cache)
    return cache
