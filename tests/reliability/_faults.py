"""Fault injection for the kill -9 tests: a Python subprocess that kills itself at a chosen
point of a write (the operating system then leaves whatever a real kill -9 would)."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: Prepended to a fault script: ``die()`` is kill -9 of the process itself;
#: ``kill_at(module, name, n)`` makes the n-th call (from 1) of ``module.name`` die first.
PRELUDE = """
import os, signal, sys
def die():
    os.kill(os.getpid(), signal.SIGKILL)
def kill_at(module, name, n):
    real = getattr(module, name)
    calls = [0]
    def wrapper(*args, **kwargs):
        calls[0] += 1
        if calls[0] == n:
            die()
        return real(*args, **kwargs)
    setattr(module, name, wrapper)
"""


def run_killed(script: str, cwd: Path, expect_kill: bool = True) -> subprocess.CompletedProcess:
    """Run ``script`` in a fresh interpreter; check it died of SIGKILL (or exited 0)."""
    proc = subprocess.run(
        [sys.executable, "-c", PRELUDE + textwrap.dedent(script)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        env={"PYTHONPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin", "HOME": str(cwd)},
    )
    if expect_kill:
        assert proc.returncode == -signal.SIGKILL, proc.stderr[-2000:]
    return proc
