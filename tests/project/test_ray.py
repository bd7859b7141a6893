"""A two-trial project through a local Ray: the same results as in this process."""

from __future__ import annotations

import numpy as np
import pytest

from rmpl.project import run_project


def test_two_trials_on_local_ray(walk_project, tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        on_ray = run_project(walk_project, tmp_path / "ray", [], workers=2, progress=False)
    finally:
        ray.shutdown()
    inline = run_project(walk_project, tmp_path / "inline", [], ray=False, progress=False)
    assert [r.status for r in inline] == ["done", "done"]
    assert [r.status for r in on_ray] == ["done", "done"]
    for trial in ("t1", "t2"):
        a = np.load(tmp_path / "ray" / trial / "poses.npz")
        b = np.load(tmp_path / "inline" / trial / "poses.npz")
        assert np.array_equal(a["points"], b["points"], equal_nan=True)
    assert (tmp_path / "ray" / "logs" / "t1.log").read_text().strip()
