"""Calibrate cameras from checkerboard or ChArUco boards filmed or photographed by them.

Per camera a folder of images or one video; camera names come from the folder or file
names (as `rmpl run --videos` names views). --intrinsics calibrates each lens (pinhole
k1 k2 p1 p2 k3; --fisheye for fisheye lenses), --extrinsics places the cameras from board
views taken at the same instants (image i or frame i of every camera), then one bundle
adjustment refines all. Writes the calibration (rmpl TOML by default, --format or the
suffix: rmpl-toml, rmpl-json, pose2sim, anipose, easymocap) and calibration.md/.json/.png.

Examples:
  rmpl calibrate --board checkerboard:4x7:0.06 --intrinsics int/cam1 int/cam2 \
      --extrinsics ext/cam1 ext/cam2 --out Calib.toml --format pose2sim
  rmpl calibrate --board charuco.toml --extrinsics cam_0.mp4 cam_1.mp4 --out calib.toml
  rmpl calibrate --check calib.toml --keypoints run/keypoints2d.npz
"""

from __future__ import annotations

import argparse
import logging

from rmpl.errors import InputError

__all__ = ["register", "run"]

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    """Add the command's arguments to ``parser`` and set ``run`` as its action."""
    from rmpl.calibration.output import OUTPUT_FORMATS

    add = parser.add_argument
    add("--board", metavar="SPEC", help="checkerboard:COLSxROWS:SQUARE (inner corners, metres), "
        "charuco:COLSxROWS:SQUARE:MARKER[:DICT] (squares), or a board .toml")  # fmt: skip
    add(
        "--intrinsics", nargs="+", default=[], metavar="DIR_OR_VIDEO", help="lens images per camera"
    )
    add("--extrinsics", nargs="+", default=[], metavar="DIR_OR_VIDEO",
        help="per camera, board views at the same instants")  # fmt: skip
    add("--calib", metavar="CALIB", help="keep the intrinsics of this calibration")
    add("--fisheye", action="store_true", help="fisheye lenses (k1..k4); report only")
    add("--origin", default="board", metavar="board|camera:NAME",
        help="world at the first shared board view (default) or at a camera")  # fmt: skip
    add("--format", choices=sorted(OUTPUT_FORMATS), help="output format (default: from --out)")
    add("--out", metavar="PATH", help="calibration file to write (EasyMocap: a folder)")
    add("--no-progress", action="store_true", help="no progress bars")
    check = parser.add_argument_group("check a calibration against the people of a recording")
    check.add_argument("--check", metavar="CALIB", help="the calibration to check")
    check.add_argument("--keypoints", nargs="+", metavar="PATH", help="2D keypoints of the people")
    check.add_argument("--videos", nargs="+", metavar="PATH", help="or the videos (detected first)")
    people = parser.add_argument_group("calibrate from people")
    people.add_argument("--from-people", action="store_true", help="calibrate from walking people")
    people.add_argument("--refine", metavar="CALIB", help="refine this calibration from people")
    people.add_argument("--height", type=float, metavar="METRES", help="a person's height")
    people.add_argument("--camera-distance", nargs=3, metavar=("CAM_A", "CAM_B", "METRES"),
                        help="a known distance between two cameras")  # fmt: skip
    people.add_argument("--max-frames", type=int, metavar="N", help="frames to use at most")
    people.add_argument("--sync", metavar="SYNC_JSON",
                        help="cameras not started together: rmpl sync's offsets")  # fmt: skip
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Calibrate, check or hand over to calibration from people; returns the exit code."""
    if args.from_people or args.refine:
        from rmpl.calibration.people_report import run_cli

        return run_cli(args)
    if args.check:
        from rmpl.calibration.check import run_check

        return run_check(args)
    return _calibrate(args)


def _calibrate(args: argparse.Namespace) -> int:
    from rmpl.calibration.boards import parse_board
    from rmpl.calibration.calibrate import calibrate_boards
    from rmpl.calibration.output import write_calibration
    from rmpl.io.calibration import load_rig

    if not args.board:
        raise InputError(
            None, "--board", "a board spec or file (or --from-people / --check)", "none"
        )
    if not args.out:
        raise InputError(None, "--out", "a calibration file to write", "none")
    if not (args.intrinsics or args.extrinsics):
        raise InputError(
            None, "--extrinsics", "folders of images or videos, one per camera", "none"
        )
    board = parse_board(args.board)
    calib = load_rig(args.calib) if args.calib else None
    cal = calibrate_boards(
        board, args.intrinsics, args.extrinsics, calib=calib, fisheye=args.fisheye,
        origin=args.origin, progress=not args.no_progress,
    )  # fmt: skip
    written = write_calibration(cal, args.out, args.format)
    for cam, rms in zip(cal.rig, cal.rms, strict=True):
        log.info("%s: reprojection RMS %.2f px", cam.name, rms)
    log.info("wrote %s", ", ".join(str(p) for p in written))
    return 0
