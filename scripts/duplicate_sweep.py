"""Sweep AssociationConfig.duplicate_tolerance on a scene set (scene_eval's chain, method rmpl).

Associates every k-subset once with the rule off, lifts every person once, then applies
rmpl.pipeline.association.duplicate_people at each tolerance (the rule only removes people,
and each person's per-frame lift does not depend on the others).
The rule that chose the shipped default (stated before any Shelf or demo run): the value of
the grid with the fewest missed (2+ views detect them, not found) + spurious people, ties to
the smaller value.

Usage: python scripts/duplicate_sweep.py SCENES_DIR [K]
"""

import itertools
import sys
from dataclasses import replace

import numpy as np

sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
import scene_eval as se  # noqa: E402

from rmpl.io.keypoints import drop_far_keypoints  # noqa: E402
from rmpl.pipeline.association import AssociationConfig, duplicate_people  # noqa: E402
from rmpl.pipeline.runner import associate_frames  # noqa: E402

GRID = (None, 0.1, 0.2, 0.3, 0.4, 0.5)
d = se.load_scenes(sys.argv[1])
k = int(sys.argv[2]) if len(sys.argv) > 2 else 4
fn = se.make_methods(["rmpl"], "default")["rmpl"]
off = AssociationConfig(duplicate_tolerance=None)
tot = {t: np.zeros(4, int) for t in GRID}  # found (det>=2), n det>=2, spurious, subsets
V = d["keypoints"].shape[1]
for m in range(len(d["joints3d"])):
    for views in itertools.combinations(range(V), k):
        v = list(views)
        rig = se.scene_rig(d, m, views)
        bodies = np.flatnonzero(d["present"][m])
        gt = d["joints3d"][m, bodies].astype(float)
        kp, sc, _ = drop_far_keypoints(
            d["keypoints"][m, v].astype(float), d["scores"][m, v].astype(float), rig.sizes, -4
        )
        det = se.seen_by_detector(d["match"][m, v], d["present"].shape[1])[:, bodies].sum(0)
        a = associate_frames(kp[None], sc[None], rig, off)[0]
        pred = se._estimate(fn, a, rig)
        for t in GRID:
            keep = np.ones(len(pred), bool)
            if t is not None and len(pred) > 1:
                keep = duplicate_people(a, rig, replace(off, duplicate_tolerance=t))
            idx, _ = se.person_errors(pred[keep], gt)
            tot[t] += [
                ((idx >= 0) & (det >= 2)).sum(),
                (det >= 2).sum(),
                keep.sum() - (idx >= 0).sum(),
                1,
            ]
print("| tolerance | found, 2+ views detect | missed | spurious (total, per subset) | sum |")
print("|---|---|---|---|---|")
for t, (f, n, s, p) in tot.items():
    name = "off" if t is None else t
    print(f"| {name} | {100 * f / n:.2f}% of {n} | {n - f} | {s}, {s / p:.3f} | {n - f + s} |")
