"""The calibration-from-people benchmark's comparison: a rig moved, turned and scaled as a
whole compares as exact, and `aligned` puts it back onto the truth."""

from __future__ import annotations

import numpy as np

from rmpl.benchmarks.calib_people import aligned, compare
from rmpl.calibration.people_synth import ring_rig
from rmpl.geometry.camera import Camera, Rig, rodrigues


def _moved(rig: Rig, s: float, R: np.ndarray, t: np.ndarray) -> Rig:
    """The same rig in a world x' = s R x + t (centres mapped, orientations turned)."""
    cams = []
    for c in rig:
        Rn = c.R @ R.T
        cams.append(Camera(c.K, Rn, -Rn @ (s * R @ c.center + t), c.dist, c.size, c.name))
    return Rig(tuple(cams))


def test_a_similar_rig_is_exact_and_aligned_back():
    truth = ring_rig(4, rng=3)
    found = _moved(truth, 0.5, rodrigues(np.array([[0.3, -0.2, 1.0]]))[0], np.array([1, 2, 3.0]))
    out = compare(found, truth)
    assert out["cameras_within_target"] and abs(out["scale"] - 0.5) < 1e-6
    assert max(r["rotation_deg"] for r in out["cameras"]) < 1e-3
    back = aligned(found, truth)
    assert np.allclose(back.centers, truth.centers, atol=1e-9)
    assert np.allclose(back.R, truth.R, atol=1e-9)


def test_a_turned_camera_is_reported():
    truth = ring_rig(4, rng=3)
    cams = list(truth)
    c = cams[2]
    R = rodrigues(np.array([[0.0, np.radians(2.0), 0.0]]))[0] @ c.R
    cams[2] = Camera(c.K, R, -R @ c.center, c.dist, c.size, c.name)
    out = compare(Rig(tuple(cams)), truth)
    assert not out["cameras_within_target"]
    assert abs(out["cameras"][2]["rotation_deg"] - 2.0) < 0.05
