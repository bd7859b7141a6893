"""Build a pose bank (COCO-17, metres) from a motion-capture folder, for `rmpl train`.

Reads CMU ASF/AMC (and BVH) files below MOTION_DIR, runs forward kinematics, retargets the
joints to COCO-17 and keeps frames at --fps. Training reads the bank in a second instead of
parsing the motion files again.

Example: rmpl poses ../shared/data/cmu_mocap --out cmu_poses.npz
"""

from __future__ import annotations

import argparse
import logging

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("motion", help="motion-capture folder (ASF/AMC or BVH, searched below)")
    parser.add_argument("--out", required=True, help="pose bank to write (.npz)")
    parser.add_argument(
        "--fps",
        type=float,
        default=None,
        help="frames kept per second (default 10; with --sequences 60, or 30 with --body anny)",
    )
    parser.add_argument(
        "--sequences",
        action="store_true",
        help="keep whole clean stretches of motion in time (a sequence bank, for training the "
        "temporal model) instead of de-duplicated poses",
    )
    parser.add_argument(
        "--body",
        choices=("mocap", "anny"),
        default="mocap",
        help="mocap: COCO-17 from the mocap's own skeleton; anny: each pose retargeted onto "
        "a random anny body and its HALPE-26 joints taken from the mesh (COCO-17 + head top, "
        "neck, mid-hip and feet; needs rmpl[synth] and anny's cache, ANNY_CACHE_DIR)",
    )
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rmpl.errors import InputError
    from rmpl.synth.motion import load_motion_dir, save_pose_set

    if not str(args.out).endswith(".npz"):
        raise InputError(args.out, None, "an output path ending in .npz")
    seq_fps = 30.0 if args.body == "anny" else 60.0
    fps = args.fps if args.fps is not None else (seq_fps if args.sequences else 10.0)
    if not fps > 0:
        raise InputError(None, "--fps", "a frame rate > 0", fps)
    if not Path(args.motion).is_dir():
        raise InputError(args.motion, None, "a folder of motion-capture files")
    if args.sequences and args.body == "mocap":
        from rmpl.data.sequences import SequenceBank

        seq = SequenceBank.from_motion_dir(args.motion, fps=fps)
        seq.save(args.out)
        minutes = len(seq.poses) / fps / 60
        log.info("wrote %s: %d segments, %.1f minutes at %g frames/s", args.out, len(seq),
                 minutes, fps)  # fmt: skip
        return 0
    args.fps = fps
    if args.sequences:  # on anny bodies
        from rmpl.data.sequences import anny_sequence_bank
        from rmpl.synth.body import BodyModel

        seq = anny_sequence_bank(args.motion, BodyModel(joints="halpe26"), fps=fps, progress=True)
        seq.save(args.out)
        minutes = len(seq.poses) / fps / 60
        log.info("wrote %s: %d segments on anny bodies (HALPE-26), %.1f minutes at %g frames/s",
                 args.out, len(seq), minutes, fps)  # fmt: skip
        return 0
    if args.body == "anny":
        from rmpl.synth.body import BodyModel
        from rmpl.synth.retarget import anny_pose_set, build_pose_bank

        body = BodyModel(joints="halpe26")
        bank = anny_pose_set(build_pose_bank(args.motion, fps=fps), body, progress=True)
        save_pose_set(args.out, bank, fps=float(fps), body="anny", skeleton="halpe26")
        log.info("wrote %s: %d HALPE-26 poses on anny bodies", args.out, len(bank))
        return 0
    bank = load_motion_dir(args.motion, fps=args.fps)
    save_pose_set(args.out, bank, fps=float(args.fps))
    counts = ", ".join(f"{k}: {v}" for k, v in sorted(bank.counts().items()))
    log.info("wrote %s: %d poses (%s)", args.out, len(bank), counts)
    return 0
