"""Compare triangulation, robust triangulation and RMPL on a dataset with 3D ground truth.

Every method gets the same per-person 2D input; tables (results.md, results.csv), per-joint
and per-person/per-clip breakdowns and PNG plots go to --out.

Examples:
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --views 1,2,3,4,5
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --dropout 0,0.2,0.4
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --calib-noise 2,20
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --methods rmpl,rmpl+floor \\
      --views 1 --floor estimate   (one camera: depth from the floor, body size and time)
  rmpl evaluate --dataset campus --root CAMPUS --2d annotations
  rmpl evaluate --dataset panoptic --root PANOPTIC --keypoints cam00_03.json cam00_06.json ...
  rmpl evaluate --dataset h36m --root H36M --subject S9
  rmpl evaluate --dataset synthetic --root poses.npz --views 1,2,3,4,5 --out results/synth
  rmpl evaluate --dataset synthetic --root poses.npz --cameras sphere --heights 2.2,3.2,4 \\
      --angles 10,20,30,40,50,60,70,80,90,100,110,120,130,140,150,160,170,180
  rmpl evaluate --dataset synthetic --root mhp_val/ --views 2,3,5   (MHP renders, real 2D)
  rmpl evaluate --dataset shelf --root ../shared/data/shelf_dev --poses run/poses.npz \\
      other=pose2sim.trc   (score finished results: rmpl run output, a TRC)
  rmpl evaluate --dataset recording --calib Calib.qca.txt --keypoints pose/cam01_json \\
      pose/cam02_json pose/cam03_json pose/cam04_json --views 1,2,3
      (no ground truth: each camera in turn is held out and predicted from k others)
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from rmpl.cli._evaluate_arguments import (
    add_2d_options,
    add_perturbation_options,
    add_synthetic_options,
)
from rmpl.errors import InputError

log = logging.getLogger(__name__)

DATASETS = ("synthetic", "shelf", "campus", "panoptic", "h36m", "recording")


def register(parser: argparse.ArgumentParser) -> None:
    _add_dataset_options(parser)
    _add_method_options(parser)
    add_2d_options(parser)
    add_perturbation_options(parser)
    add_synthetic_options(parser)
    parser.set_defaults(run=run)


def _add_dataset_options(parser: argparse.ArgumentParser) -> None:
    """What is evaluated: the dataset, or a recording (calibration + 2D)."""
    parser.add_argument("--dataset", required=True, choices=DATASETS)
    parser.add_argument(
        "--root",
        default=None,
        help="dataset folder (synthetic: a pose bank .npz, a motion folder, or an MHP "
        "directory from rmpl generate; not used by recording)",
    )
    parser.add_argument(
        "--calib",
        default=None,
        help="recording: the calibration file or folder (any format rmpl reads)",
    )
    parser.add_argument(
        "--skeleton", default=None, help="recording: 2D joint set when ambiguous (body25, body25b)"
    )
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        help="recording: frame rate if none; sequence methods (triangulate+filter, "
        "rmpl:temporal, ...): the dataset's frame rate (Shelf and Campus state none: 25 is "
        "assumed; Panoptic 29.97, H36M 50)",
    )
    parser.add_argument(
        "--min-score",
        type=float,
        default=0.5,
        help="recording: a held-out detection is a reference when its confidence is >= this",
    )


def _add_method_options(parser: argparse.ArgumentParser) -> None:
    """What is compared, on which views, and where the tables go."""
    parser.add_argument(
        "--methods",
        default="triangulate,robust,rmpl",
        help="comma-separated: triangulate, robust, rmpl[:MODEL]; sequence methods (tracked "
        "over time): triangulate+filter, robust+filter, rmpl+filter, rmpl:temporal[:MODEL]; "
        "one view with depth from the floor, body size and time: rmpl+floor[:CUES] (CUES: "
        "floor, size, time joined by +; default all)",
    )
    parser.add_argument(
        "--views",
        default=None,
        help="'all', 'pairs' and/or view counts k (mean over every k-subset of the cameras), "
        "e.g. 1,2,3,4,5 (default: all,pairs; synthetic: 1,2,3,4,5)",
    )
    parser.add_argument(
        "--poses",
        nargs="+",
        default=None,
        metavar="[NAME=]FILE",
        help="score finished 3D results (rmpl run's poses.npz/.json, a TRC) instead of "
        "running --methods; NAME defaults to the file's folder name",
    )
    parser.add_argument(
        "--floor",
        default=None,
        metavar="FLOOR",
        help="rmpl+floor (one view): the floor plane, AXIS=H (e.g. z=0: z up, floor at "
        "z = 0) or nx,ny,nz,d (n . X = d, n up); 'estimate': from the dataset's own frames "
        "with every camera (triangulated, no ground truth); 'convention' (default): the "
        "rig's axis-aligned up and 0; 'none'",
    )
    parser.add_argument("--out", default=None, help="folder for the tables and plots")


def _command(args) -> str:
    """The command line that reproduces this run (every option not at its default)."""
    import shlex

    parser = argparse.ArgumentParser()
    register(parser)
    words = ["rmpl", "evaluate"]
    for action in parser._actions:
        if not action.option_strings or action.dest in ("help", "run"):
            continue
        value = getattr(args, action.dest, None)
        if value is None or value == action.default or value is False:
            continue
        words.append(action.option_strings[0])
        if value is not True:
            words += [str(v) for v in value] if isinstance(value, list) else [str(value)]
    return " ".join(shlex.quote(w) for w in words)


def run(args: argparse.Namespace) -> int:
    from rmpl.evaluate.command import evaluate_command

    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise InputError(args.out, None, "an output folder", "an existing file")
    report = evaluate_command(args, _command(args))
    print(report.text)
    if args.out:
        from rmpl.evaluate.tables import save_report

        save_report(Path(args.out), report, plots=not args.no_plots)
    return 0
