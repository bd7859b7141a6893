"""Find each camera's time offset from the motion of the people in view; writes sync.json.

With --calib, the offsets are those at which the views' people agree best through the
cameras, every camera solved jointly against every other over every whole-frame lag up to
--max-offset seconds, then to a fraction of a frame; without, from the cross-correlation of
the views' 2D motion speeds (whole frames). A recording whose motion does not decide (an
offset not better than the others by three standard errors) is refused in one line. The
first view is the reference (offset 0).

Example: rmpl sync --calib calib.toml --keypoints pose/ --out sync.json
         rmpl run --calib calib.toml --keypoints pose/ --sync sync.json --out run/
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from rmpl.cli._common import positive

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--keypoints", nargs="+", help="2D keypoint files or folders, one per view")
    src.add_argument("--videos", nargs="+", help="one video per camera (needs rmpl[detect])")
    parser.add_argument("--calib", default=None, help="calibration (for the 3D agreement)")
    parser.add_argument("--out", default="sync.json", help="output file (default sync.json)")
    parser.add_argument(
        "--fps",
        type=positive,
        nargs="+",
        default=None,
        help="frame rate: one value, or one per view (cameras at different rates); default: "
        "each video's own, or the 2D file's",
    )
    parser.add_argument(
        "--max-offset", type=positive, default=3.0, help="largest offset searched, seconds"
    )
    parser.add_argument("--coarse", action="store_true", help="whole frames only")
    parser.add_argument("--skeleton", default=None, help="the 2D files' joint set if ambiguous")
    parser.add_argument("--detector", default=None, help="2D detector for --videos")
    parser.set_defaults(run=run)


def _load(args: argparse.Namespace):
    """(keypoints2d, rig or None) in the rig's view order."""
    from rmpl.io.keypoints import Keypoints2D, load_keypoints
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    if args.calib is None:
        if args.videos:
            from rmpl.errors import InputError

            raise InputError(None, "--calib", "a calibration with --videos (to read them)")
        return load_keypoints(args.keypoints, skeleton=args.skeleton), None
    spec = InputSpec(args.calib, args.keypoints, args.videos, skeleton=args.skeleton,
                     detector=args.detector, sync="find")  # fmt: skip
    cache = Path(args.out).with_suffix(".keypoints2d.npz") if args.videos else None
    inp = load_inputs(spec, cache)
    kp = Keypoints2D(inp.keypoints, inp.scores, inp.skeleton, inp.rig.names, inp.frames, inp.fps)
    return kp, inp.rig


def _fps(args: argparse.Namespace, kp) -> list[float]:
    """--fps, else each video's own frame rate, else the 2D file's."""
    from rmpl.errors import InputError

    if not args.fps and args.videos:
        from rmpl.pipeline.detect2d import probe_video, view_names

        rates = {n: probe_video(v).fps for n, v in zip(view_names(args.videos), args.videos,
                                                      strict=True)}  # fmt: skip
        if set(kp.views) <= set(rates):
            return [rates[n] for n in kp.views]
        return [probe_video(v).fps for v in args.videos]  # matched by order
    fps = args.fps or ([kp.fps] if kp.fps else None)
    if not fps:
        raise InputError(None, "--fps", "the frame rate (the 2D input states none)")
    if len(fps) not in (1, kp.num_views):
        raise InputError(None, "--fps", f"one value or {kp.num_views} (one per view)", fps)
    return list(fps) * (kp.num_views if len(fps) == 1 else 1)


def run(args: argparse.Namespace) -> int:
    from rmpl.calibration.sync import find_sync, write_sync

    kp, rig = _load(args)
    source = ", ".join(args.keypoints or args.videos)
    sync = find_sync(kp.keypoints, _fps(args, kp), kp.views, rig, args.max_offset, source,
                     fine=not args.coarse)  # fmt: skip
    path = write_sync(sync, args.out)
    for name, cam in sync.to_dict()["cameras"].items():
        err = cam["uncertainty_frames"]
        log.info("%s: %s frames (%.3f s), confidence %.2f%s", name, cam["offset_frames"],
                 cam["offset_seconds"], cam["confidence"],
                 "" if err is None else f", +/- {err:.2f} frames")  # fmt: skip
        if err is not None and err >= 0.5:
            log.warning("%s: the whole frame is uncertain (standard error %.2f frames): "
                        "a longer stretch with more motion decides it", name, err)  # fmt: skip
    log.info("wrote %s (%s)", path, sync.method)
    return 0
