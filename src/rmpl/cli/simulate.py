"""Simulate a capture before recording it: videos of a rig with known cameras, sync and 3D.

A digital twin of a recording: anny bodies of varied shapes move with real motion capture
(walking, running, turning, bending) in a room, filmed by your rig (a calibration file,
lenses included, or a preset) at each camera's frame rate and start offset, through its
lens, compressed as a phone would. The truth is written beside the videos in rmpl's own
formats, so every stage of the chain can be checked against it. With --run the chain runs
on the videos as you would run it (calibration from the board sweep or from the people,
rmpl sync, rmpl run through the found and the true cameras) and report.md answers: what
error to expect, where in the room, and what limits the rig.

Examples:
  rmpl simulate --cameras 4 --radius 4 --height 2 --people 2 --seconds 10 --out sim/ --run
  rmpl simulate --rig calib.toml --bystander --fps 30,30,25,60 --offsets 0,3,-5,11 --out s2/
  rmpl simulate --rig arc --cameras 3 --board charuco:5x7:0.1:0.075 --out sim/ --run

Outputs: videos/<camera>.mp4, board/<camera>.mp4 (--board), truth/ (calibration.toml,
sync.json, poses.npz, people.json, projections/), simulate.json; with --run, chain/ and
report.md, report.png. Run the same command again to resume.
"""

from __future__ import annotations

import argparse
import logging

from rmpl.cli._common import at_least_one, count, positive

log = logging.getLogger(__name__)


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}") from None
    return w, h


def _floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas, got {text!r}"
        ) from None


def register(parser: argparse.ArgumentParser) -> None:
    _rig_options(parser.add_argument_group("the rig"))
    _people_options(parser.add_argument_group("the people and the recording"))
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument(
        "--run",
        action="store_true",
        dest="run_chain",
        help="then run the chain on the videos and score every stage",
    )
    parser.add_argument(
        "--methods",
        default="rmpl,robust",
        help="--run: rmpl run --method values to score (default rmpl,robust)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.set_defaults(run=run)


def _rig_options(rig) -> None:
    rig.add_argument(
        "--rig",
        default="ring",
        help="a calibration file (any format rmpl reads), or a preset: ring "
        "(default), arc, corners",
    )
    rig.add_argument("--cameras", type=at_least_one, default=4, help="cameras of a preset")
    rig.add_argument("--radius", type=positive, default=4.0, help="preset: metres from the centre")
    rig.add_argument("--height", type=positive, default=1.8, help="preset: camera height, m")
    lens = rig.add_mutually_exclusive_group()
    lens.add_argument(
        "--fov",
        type=positive,
        default=None,
        help="preset: horizontal field of view, degrees (default 65)",
    )
    lens.add_argument("--focal", type=positive, default=None, help="preset: focal length, px")
    rig.add_argument(
        "--resolution",
        type=_size,
        default=(1920, 1080),
        help="preset: WIDTHxHEIGHT (default 1920x1080)",
    )
    rig.add_argument(
        "--distortion",
        type=_floats,
        default=(-0.06, 0.02),
        help="preset: radial k1,k2 (default -0.06,0.02)",
    )


def _people_options(who) -> None:
    who.add_argument("--people", type=count, default=2, help="moving people (default 2)")
    who.add_argument("--bystander", action="store_true", help="one more person, standing still")
    who.add_argument(
        "--motion",
        default="walk",
        help="what they do, person i the i-th (cycled): walk, run, turn, bend; "
        "e.g. walk,run (default walk)",
    )
    who.add_argument("--seconds", type=positive, default=10.0, help="recording length (10)")
    who.add_argument(
        "--fps",
        type=_floats,
        default=(30.0,),
        help="frames per second, one or one per camera: 30 or 30,30,25,60",
    )
    who.add_argument(
        "--offsets",
        default="0",
        help="each camera's start offset in its own frames (0,3,-5,11: camera 2 "
        "started 3 frames before camera 1), or random:N (default 0)",
    )
    who.add_argument(
        "--area",
        type=positive,
        default=None,
        help="radius of the walking area, m (default: 45%% of the nearest "
        "camera's distance, 0.8-3 m)",
    )
    who.add_argument(
        "--board",
        default=None,
        help="also film a board carried through the volume (board/<camera>.mp4): "
        "a spec as rmpl calibrate --board takes, e.g. charuco:5x7:0.1:0.075",
    )
    who.add_argument("--board-seconds", type=positive, default=20.0, help="the sweep's length")
    who.add_argument("--seed", type=count, default=0, help="random seed (default 0)")


def run(args: argparse.Namespace) -> int:
    from rmpl.errors import InputError
    from rmpl.simulate.capture import SimulateConfig, simulate

    cfg = SimulateConfig.from_args(args)
    methods = tuple(m.strip() for m in args.methods.split(",") if m.strip())
    bad = [m for m in methods if m not in ("rmpl", "triangulate", "robust")]
    if bad:
        raise InputError(None, "--methods", "rmpl, triangulate or robust", bad)
    if args.run_chain and cfg.board is None:
        from rmpl.simulate.rig import build_rig

        if len(build_rig(cfg.rig)) < 2:
            raise InputError(
                args.rig,
                "--run",
                "two or more cameras to calibrate from people, or a --board sweep",
                "one camera",
            )
    doc = simulate(cfg, args.out, progress=not args.no_progress)
    log.info(
        "wrote %s: %d cameras, %s frames",
        args.out,
        len(doc["rig"]["cameras"]),
        doc["rig"]["frames"],
    )
    if not args.run_chain:
        return 0
    from rmpl.simulate.chain import run_chain
    from rmpl.simulate.report import write_report

    scores = run_chain(args.out, methods)
    path = write_report(args.out, scores)
    log.info("wrote %s", path)
    return 0
