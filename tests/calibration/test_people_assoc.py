"""Calibration from people, who is who: the people of each frame associated across views
through the cameras and linked over time (:mod:`rmpl.calibration.people_assoc`), and a
detector whose joints scatter by several pixels."""

from __future__ import annotations

import numpy as np

from rmpl.calibration.people import _normalised, calibrate_from_people, triangulate_normalised
from rmpl.calibration.people_assoc import reassociate
from rmpl.calibration.people_synth import moving_people, observe, ring_rig


def test_persons_are_pure_and_cover_the_people():
    rig = ring_rig(4, rng=5)
    X = moving_people(np.arange(50) / 20, (1.8, 1.6, 1.7), rng=6)  # (T, 3, J, 3)
    kp, sc = observe(X, rig, noise=1.0, rng=5)  # people shuffled in every frame and view
    obs, ids, persons = reassociate(kp, sc, rig, 0.15, 0.3, _normalised)
    T, G = obs.shape[:2]
    assert G >= 3 and len(persons) == G
    P3 = triangulate_normalised(np.moveaxis(obs, 2, 3), rig.R, rig.t, np.ones(len(rig), bool))
    covered = np.zeros((T, 3), bool)
    for g in range(G):
        frames = np.flatnonzero(np.isfinite(P3[:, g]).all(-1).any(-1))
        d = np.nanmean(np.linalg.norm(P3[frames, g][:, None] - X[frames], axis=-1), -1)  # (n, 3)
        who = d.argmin(-1)
        assert (who == who[0]).all()  # one true person throughout
        assert d[np.arange(len(frames)), who].max() < 0.05
        covered[frames, who[0]] = True
    assert covered.mean() > 0.95
    seen = ids >= 0
    assert (np.isfinite(obs).all(-1).any(-1) == seen).all()


def test_a_detector_that_scatters_by_sixteen_pixels_still_calibrates():
    rig = ring_rig(4, rng=11, distortion=True)
    X = moving_people(np.arange(80) / 20, (1.75,), rng=12)
    kp, sc = observe(X, rig, noise=16.0, rng=11)
    cal = calibrate_from_people(kp, sc, rig, max_frames=60)
    assert len(cal.rig) == 4 and np.isfinite(cal.rig.centers).all()
    from rmpl.calibration.people import similarity

    s, R, t = similarity(cal.rig.centers, rig.centers)
    d = np.linalg.norm(s * cal.rig.centers @ R.T + t - rig.centers, axis=-1)
    assert d.max() < 0.15
