"""One camera on synthetic sequences: the dev set of rmpl.pipeline.monocular's smoother.

Usage: python -m rmpl.benchmarks.monocular_synthetic SEQBANK [--windows 40]

Windows of 100 frames of the CMU subjects filmed on a flat floor (02, 07, 08, 13, 14; seed
[5, 1]), one random camera each, the floor at z = 0; the shipped per-frame lifter, then
:func:`rmpl.pipeline.monocular.lift_stretch` with the cue sets below. Prints MPJPE /
PA-MPJPE / PCK (rmpl.evaluate.scoring.pose_metrics) over all 17 joints per cue set.
"""

from __future__ import annotations

import argparse

import numpy as np

from rmpl.benchmarks._common import run_main
from rmpl.data.sequences import SequenceBank, SequenceSource
from rmpl.evaluate.scoring import pose_metrics
from rmpl.geometry.camera import Camera, Rig
from rmpl.geometry.floor import Floor
from rmpl.inference import Lifter
from rmpl.pipeline.monocular import MonocularConfig, lift_stretch

FLAT_FLOOR_SUBJECTS = ["02", "07", "08", "13", "14"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank")
    ap.add_argument("--windows", type=int, default=40)
    ap.add_argument("--cues", default="floor,floor+time,floor+size+time")
    a = ap.parse_args(argv)
    _, held = SequenceBank.load(a.bank).split(FLAT_FLOOR_SUBJECTS)
    T = 100
    b = SequenceSource(held, seed=[5, 1]).batch(a.windows, T, 1, train=False)
    fps = 1 / np.diff(b.times, axis=1).mean(1)
    lifter = Lifter.from_pretrained("default")
    up = np.array([0, 0, 1.0])

    def lift(k, s, r):
        x = lifter.lift(k, s, r, up=up)
        return x.points, x.num_views

    for cues in a.cues.split(","):
        preds, truth = [], []
        for i in range(a.windows):
            rig = Rig((Camera(b.K[i, 0], b.R[i, 0], b.t[i, 0], name="0"),))
            kp, sc = b.keypoints[i], b.scores[i].astype(float)
            seen = (sc > 0).any((-1, -2))
            pred, at = lift_stretch(
                kp[seen], sc[seen], np.flatnonzero(seen), T, rig, float(fps[i]),
                Floor((0, 0, 1.0), 0.0), MonocularConfig.from_cues(cues), lift=lift,
            )  # fmt: skip
            out = np.full((T, 17, 3), np.nan)
            out[at] = pred
            preds.append(out)
            truth.append(b.target[i])
        m = pose_metrics(np.concatenate(preds), np.concatenate(truth).astype(float), range(17))
        print(cues, m)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
