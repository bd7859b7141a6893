"""Sweep AssociationConfig.duplicate_tolerance on a scene set (scene_eval's chain, method rmpl).

Associates every k-subset once with the rule off, lifts every person once, then applies
rmpl.pipeline.association.duplicate_people at each tolerance (the rule only removes people,
and each person's per-frame lift does not depend on the others).
The rule that chose the shipped default (stated before any Shelf or demo run): the value of
the grid with the fewest missed (2+ views detect them, not found) + spurious people, ties to
the smaller value.

    python -m rmpl.benchmarks.duplicate_sweep SCENES_DIR [K]
"""

from __future__ import annotations

import argparse
import itertools
from dataclasses import replace

import numpy as np

from rmpl.benchmarks import scene_eval as se
from rmpl.benchmarks._common import run_main
from rmpl.io.keypoints import drop_far_keypoints
from rmpl.pipeline.association import AssociationConfig, duplicate_people
from rmpl.pipeline.runner import associate_frames

GRID = (None, 0.1, 0.2, 0.3, 0.4, 0.5)


def sweep(d: dict[str, np.ndarray], k: int) -> dict[float | None, np.ndarray]:
    """Per tolerance of :data:`GRID`: found (2+ views detect), persons 2+ views detect,
    spurious people and subsets, summed over every scene and k-subset of its views."""
    fn = se.make_methods(["rmpl"], "default")["rmpl"]
    off = AssociationConfig(duplicate_tolerance=None)
    tot = {t: np.zeros(4, int) for t in GRID}
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
    return tot


def table(tot: dict[float | None, np.ndarray]) -> str:
    """The sweep as a Markdown table (found, missed, spurious, their sum)."""
    lines = [
        "| tolerance | found, 2+ views detect | missed | spurious (total, per subset) | sum |",
        "|---|---|---|---|---|",
    ]
    for t, (f, n, s, p) in tot.items():
        name = "off" if t is None else t
        lines.append(
            f"| {name} | {100 * f / n:.2f}% of {n} | {n - f} | {s}, {s / p:.3f} | {n - f + s} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", help="a scene set of rmpl generate (people = [2, 4])")
    ap.add_argument("k", nargs="?", type=int, default=4, help="views per subset")
    a = ap.parse_args(argv)
    print(table(sweep(se.load_scenes(a.scenes), a.k)))
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
