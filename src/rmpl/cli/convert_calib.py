"""Convert a camera calibration file from one format to another.

Reads IN in any format rmpl knows (rmpl TOML/JSON, anipose/Pose2Sim TOML, CMU Panoptic,
Shelf/Campus 4D-association and VoxelPose JSON, EasyMocap YAML, Human3.6M JSON/pickle,
Qualisys .qca.txt), detected from the extension and content unless --from is given, and
writes OUT atomically, in the format named by --to or implied by OUT's extension
(.toml rmpl TOML, .json rmpl JSON, .yml or a folder EasyMocap).

Example: rmpl convert-calib Calib.qca.txt Calib.toml --to anipose
"""

from __future__ import annotations

import argparse
import logging

from rmpl.io.calibration import CAMERA_TYPES, FORMATS, UNITS, load_rig, save_rig

__all__ = ["register", "run"]

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    """Add the command's arguments to ``parser`` and set ``run`` as its action."""
    writable = sorted(name for name, (_, writer) in FORMATS.items() if writer is not None)
    parser.add_argument("input", metavar="IN", help="calibration file (or EasyMocap folder)")
    parser.add_argument("output", metavar="OUT", help="file (or EasyMocap folder) to write")
    parser.add_argument("--from", dest="input_format", choices=sorted(FORMATS), help="format of IN")
    parser.add_argument("--to", dest="output_format", choices=writable, help="format of OUT")
    parser.add_argument(
        "--in-units",
        choices=sorted(UNITS),
        help="length unit of IN's translations (default: the format's own, e.g. Panoptic cm)",
    )
    parser.add_argument(
        "--out-units", choices=sorted(UNITS), help="length unit to write (default: the format's)"
    )
    parser.add_argument(
        "--camera-type",
        choices=CAMERA_TYPES,
        default="hd",
        help="Panoptic: camera type to read and write (default: hd)",
    )
    parser.add_argument("--subject", default="S1", help="Human3.6M subject (default: S1)")
    parser.add_argument(
        "--binning-factor", type=int, default=1, help="Qualisys pixel binning (default: 1)"
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Load IN, save OUT; returns 0. Bad input raises :class:`rmpl.errors.InputError`."""
    rig = load_rig(
        args.input,
        args.input_format,
        units=args.in_units,
        camera_type=args.camera_type,
        subject=args.subject,
        binning_factor=args.binning_factor,
    )
    save_rig(
        rig, args.output, args.output_format, units=args.out_units, camera_type=args.camera_type
    )
    log.info("wrote %d cameras (%s) to %s", len(rig), ", ".join(rig.names), args.output)
    return 0
