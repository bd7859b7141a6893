"""The HALPE-26 points on anny bodies and a detector's 2D of them (docs/results.md, HALPE-26).

    python -m rmpl.benchmarks.halpe26_stats BANK.npz [--mhp DIR]

BANK is a HALPE-26 pose set (``rmpl poses --body anny``): the median and 99th-percentile
distance of each extra point to a neighbour. ``--mhp DIR``: an ``rmpl generate`` set with
``joints = "halpe26"``: per joint, the share of views where the detector gives it and the
median distance (px) of its 2D to the mesh point's projection.
"""

from __future__ import annotations

import argparse

import numpy as np

from rmpl.benchmarks._common import run_main
from rmpl.data.mhp import load_mhp
from rmpl.skeleton import HALPE26
from rmpl.synth.motion import load_pose_set

PAIRS = (
    ("left_heel", "left_ankle"),
    ("left_big_toe", "left_ankle"),
    ("left_small_toe", "left_big_toe"),
    ("neck", "left_shoulder"),
    ("head_top", "nose"),
    ("mid_hip", "left_hip"),
)
DETECTED = ("left_ankle", "left_heel", "left_big_toe", "left_small_toe", "head_top", "neck")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bank")
    ap.add_argument("--mhp")
    a = ap.parse_args(argv)
    P = load_pose_set(a.bank).poses
    print(f"{a.bank}: {len(P)} poses")
    for j, k in PAIRS:
        d = np.linalg.norm(P[:, HALPE26.index(j)] - P[:, HALPE26.index(k)], axis=-1)
        print(f"  {j} - {k}: median {np.median(d):.3f} m, 99% {np.percentile(d, 99):.3f} m")
    if a.mhp:
        d = load_mhp(a.mhp, joints="halpe26")
        err = np.linalg.norm(d["keypoints"] - d["projected"], axis=-1)
        print(f"{a.mhp}: {len(err)} meshes x {err.shape[1]} views")
        for name in DETECTED:
            i = HALPE26.index(name)
            ok = d["scores"][..., i] > 0
            px = f"median {np.median(err[..., i][ok]):.1f} px" if ok.any() else "never given"
            print(f"  {name}: given in {100 * ok.mean():.0f}% of views, {px}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
