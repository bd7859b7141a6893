"""Whole projects in one command: Pose2Sim's demo trials as one project, run by ``rmpl batch``.

Builds a project in Pose2Sim's batch layout out of symbolic links (nothing is copied): one
``calibration/`` at the top, and one trial folder per demo trial with its ``videos/`` and its
``Config.toml``. From Pose2Sim's video demos (``--videos``: ``Demo_SinglePerson`` and
``Demo_MultiPerson``, 4 cameras, 100 frames each; their two calibrations are the same file)
or, faster, from the OpenPose JSON of its older single-trial demo (``--keypoints``: the
trial ``S01_Demo_SingleTrial`` twice, ``Trial_2`` with ``method = "robust"`` in its
``rmpl.toml``). Then:

1. ``rmpl batch PROJECT --out OUT`` on a local Ray: every trial done, exit status 0;
2. the same again: every trial unchanged (skipped), exit status 0;
3. a copy of the project with one camera's video (or 2D folder) of the last trial replaced by
   damaged bytes, to a fresh output folder: the other trials done, that one failed, exit 1;
4. with ``--address``, run 1 again on that Ray cluster (``ray start --head --num-cpus 2``) to
   a fresh folder, and each trial's poses compared with run 1's (largest difference, metres).

Each step prints its wall time, the trials' statuses and the exit status, then a markdown
table. ``rmpl run`` options after ``--`` go to every trial (``-- --no-overlay``).

Examples:
  python -m rmpl.benchmarks.project --videos ../shared/data/pose2sim_videos --work /tmp/pj
  python -m rmpl.benchmarks.project --keypoints ../shared/data/pose2sim_demo --work /tmp/pk \\
      --address 127.0.0.1:6379
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["build_project", "main"]

_VIDEO_TRIALS = ("Demo_SinglePerson", "Demo_MultiPerson")
_KEYPOINT_TRIAL = Path("Pose2Sim") / "S01_Demo_SingleTrial"


def _link(target: Path, link: Path) -> None:
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(target.resolve(), target_is_directory=target.is_dir())


def build_project(root: Path, videos: Path | None, keypoints: Path | None) -> list[str]:
    """The project of symbolic links at ``root`` (replaced); returns its trial names."""
    if root.exists():
        shutil.rmtree(root)
    if videos is not None:
        first = videos / _VIDEO_TRIALS[0]
        _link(first / "calibration" / "Calib.qca.txt", root / "calibration" / "Calib.qca.txt")
        for name in _VIDEO_TRIALS:
            _link(videos / name / "videos", root / name / "videos")
            _link(videos / name / "Config.toml", root / name / "Config.toml")
        return list(_VIDEO_TRIALS)
    src = keypoints / _KEYPOINT_TRIAL
    _link(src / "calibration" / "Calib.qca.txt", root / "calibration" / "Calib.qca.txt")
    for name in ("Trial_1", "Trial_2"):
        _link(src / "pose", root / name / "pose")
        _link(src / "Config.toml", root / name / "Config.toml")
    (root / "Trial_2" / "rmpl.toml").write_text('method = "robust"\n')
    return ["Trial_1", "Trial_2"]


def _damage(project: Path, copy: Path, trial: str) -> str:
    """A copy of the project (links) with one camera of ``trial`` replaced by bad bytes."""
    if copy.exists():
        shutil.rmtree(copy)
    shutil.copytree(project, copy, symlinks=True)
    for kind in ("videos", "pose"):
        link = copy / trial / kind
        if link.is_symlink():
            target = link.resolve()
            link.unlink()
            link.mkdir()
            items = sorted(target.iterdir())
            for item in items[1:]:
                _link(item, link / item.name)
            bad = link / items[0].name
            if items[0].is_dir():
                bad.mkdir()
                bad = bad / f"{items[0].name}.0000.json"
            bad.write_bytes(np.random.default_rng(0).bytes(4096))
            return f"{trial}/{kind}/{items[0].name}"
    raise ValueError(f"{copy / trial} has no videos/ or pose/")


def _batch(project: Path, out: Path, extra: list[str]) -> dict:
    from rmpl.cli import main

    start = time.perf_counter()
    code = main(["batch", str(project), "--out", str(out), *extra])
    seconds = time.perf_counter() - start
    summary = (
        json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    )
    rows = {r["trial"]: r for r in summary.get("trials", [])}
    return {"exit": code, "seconds": seconds, "trials": rows}


def _largest_difference(a: Path, b: Path) -> float:
    x, y = np.load(a / "poses.npz")["points"], np.load(b / "poses.npz")["points"]
    if x.shape != y.shape or not np.array_equal(np.isnan(x), np.isnan(y)):
        return float("inf")
    return float(np.nanmax(np.abs(x - y))) if np.isfinite(x).any() else 0.0


def _line(step: str, r: dict) -> str:
    statuses = "; ".join(f"{n}: {t['status']}" for n, t in r["trials"].items())
    return f"| {step} | {r['seconds']:.1f} | {r['exit']} | {statuses} |"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m rmpl.benchmarks.project",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    data = parser.add_mutually_exclusive_group(required=True)
    data.add_argument("--videos", type=Path, help="Pose2Sim's video demos (Demo_SinglePerson, ...)")
    data.add_argument("--keypoints", type=Path, help="Pose2Sim's older demo with OpenPose JSON")
    parser.add_argument("--work", type=Path, required=True, help="folder for the projects/outputs")
    parser.add_argument("--address", default=None, help="a Ray cluster for step 4")
    parser.add_argument(
        "run_options", nargs="*", help="rmpl run options for every trial (after --)"
    )
    args = parser.parse_args(argv)
    work, extra = args.work, list(args.run_options)
    for name in ("out", "out-damaged", "out-cluster"):  # every step starts from nothing
        shutil.rmtree(work / name, ignore_errors=True)
    project = work / "project"
    trials = build_project(project, args.videos, args.keypoints)
    rows = ["| step | wall s | exit | trials |", "|---|---|---|---|"]
    first = _batch(project, work / "out", extra)
    rows.append(_line("1. first run (local Ray)", first))
    rows.append(_line("2. second run", _batch(project, work / "out", extra)))
    damaged = _damage(project, work / "damaged", trials[-1])
    rows.append(
        _line(f"3. damaged {damaged}", _batch(work / "damaged", work / "out-damaged", extra))
    )
    if args.address:
        cluster = _batch(project, work / "out-cluster", [*extra, "--address", args.address])
        rows.append(_line(f"4. Ray cluster {args.address}", cluster))
        for name in trials:
            diff = _largest_difference(work / "out" / name, work / "out-cluster" / name)
            rows.append(f"| 4. {name}: largest difference from run 1 | | | {diff:.3g} m |")
    print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
