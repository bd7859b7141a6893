"""Render the MHP training, validation and occlusion sets the per-frame models use.

The validation set (held-out CMU subject 03, seed 101), the training set (every other
subject), the validation set again with black 50 px squares over joints before detection
(thesis 6.11.1: rates 0.2 and 0.4, the same meshes and cameras), and a larger second
training set (more meshes, 10 views each, seed 7, two workers). Runs at nice 10; resumable.
Needs ``rmpl[synth]`` and ``ANNY_CACHE_DIR`` pointing at anny's cache.

    python -m rmpl.benchmarks.mhp_sets [MOTION_DIR] [OUT_ROOT] [--train 600] [--val 100]
        [--train2 3000] [--dry-run]

Writes ``OUT_ROOT/mhp_val``, ``mhp_train``, ``mhp_val_occ0.2``, ``mhp_val_occ0.4`` and
``mhp_train2``. The shipped model's sets: ``../shared/data/cmu_mocap data --train 500``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from rmpl.benchmarks._common import run_commands, run_main, toml_string

HELD_OUT = ['subjects=["03"]', "exclude_subjects=[]"]


def _generate(out: Path, motion: Path, *overrides: str, workers: int = 1) -> list[str]:
    sets = [f"poses={toml_string(motion)}", *overrides]
    head = ["generate", "configs/mhp.toml", "--out", str(out), "--no-progress"]
    head += ["--workers", str(workers)] if workers > 1 else []
    return head + [x for s in sets for x in ("--set", s)]


def commands(motion: Path, root: Path, train: int, val: int, train2: int) -> list[list[str]]:
    """Every ``rmpl generate`` command, in order."""
    held = [*HELD_OUT, f"num_meshes={val}", "seed=101"]
    out = [
        _generate(root / "mhp_val", motion, *held),
        _generate(root / "mhp_train", motion, 'exclude_subjects=["03"]', f"num_meshes={train}"),
    ]
    for p in ("0.2", "0.4"):
        out.append(_generate(root / f"mhp_val_occ{p}", motion, *held, f"occlusion_rate={p}"))
    more = ['exclude_subjects=["03"]', f"num_meshes={train2}", "views=10", "seed=7"]
    out.append(_generate(root / "mhp_train2", motion, *more, workers=2))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("motion", type=Path, nargs="?", default=Path("../shared/data/cmu_mocap"))
    ap.add_argument("root", type=Path, nargs="?", default=Path("data"))
    ap.add_argument("--train", type=int, default=600, help="meshes of mhp_train")
    ap.add_argument("--val", type=int, default=100, help="meshes of mhp_val")
    ap.add_argument("--train2", type=int, default=3000, help="meshes of mhp_train2")
    ap.add_argument("--dry-run", action="store_true", help="print the commands only")
    a = ap.parse_args(argv)
    if not a.dry_run:
        os.nice(10)
    return run_commands(commands(a.motion, a.root, a.train, a.val, a.train2), a.dry_run)


if __name__ == "__main__":
    raise SystemExit(run_main(main))
