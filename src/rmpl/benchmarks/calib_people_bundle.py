"""The bundle adjustment of calibration from people on its own: its seconds and the cameras
it finds, with the analytic Jacobian or SciPy's finite differences, and with more solver
evaluations per round.

The whole of :func:`rmpl.calibration.people.calibrate_from_people` runs on the recording
(Shelf, or a reference calibration with its keypoints, as in
:mod:`rmpl.benchmarks.calib_people`) with its adjustment
(:func:`rmpl.calibration.people_bundle.adjust`) run with the options given. The figures are
those of :mod:`rmpl.benchmarks.calib_people` (per camera the rotation and centre errors
after a similarity alignment, the scale, the reprojection RMS), plus the adjustment's own
seconds and, per round, its observations, evaluations, SciPy status (0: the evaluations ran
out; 1-4: converged) and cost.

Example::

    python -m rmpl.benchmarks.calib_people_bundle --shelf ../shared/data/shelf_dev
    python -m rmpl.benchmarks.calib_people_bundle --shelf ../shared/data/shelf_dev \\
        --jacobian finite-differences
    python -m rmpl.benchmarks.calib_people_bundle --shelf ../shared/data/shelf_dev --max-nfev 200
"""

from __future__ import annotations

import argparse
import inspect
import json
import logging
import sys
import time
from pathlib import Path
from unittest import mock


class _Rounds(logging.Handler):
    """Collects the adjustment's per-round lines."""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.lines: list[str] = []

    def emit(self, record):
        self.lines.append(record.getMessage())


def _run(args) -> dict:
    from rmpl.benchmarks.calib_people import _inputs, compare
    from rmpl.calibration import people_bundle
    from rmpl.calibration.people import calibrate_from_people

    keypoints, scores, truth = _inputs(args)
    spent = []
    default = inspect.signature(people_bundle.adjust).parameters["max_nfev"].default
    nfev = args.max_nfev or default

    def adjust(prob, R, t, points, lengths, fixed, gauge_cam, rounds=people_bundle.ROUNDS):
        t0 = time.perf_counter()
        analytic = args.jacobian == "analytic"
        out = people_bundle._adjust(
            prob, R, t, points, lengths, (fixed, gauge_cam), rounds, nfev, analytic
        )
        spent.append(time.perf_counter() - t0)
        return out

    rounds = _Rounds()
    logger = logging.getLogger(people_bundle.__name__)
    logger.addHandler(rounds)
    logger.setLevel(logging.DEBUG)
    t0 = time.perf_counter()
    with mock.patch.object(people_bundle, "adjust", adjust):
        cal = calibrate_from_people(keypoints, scores, truth, max_frames=args.max_frames)
    out = compare(cal.rig, truth)
    out |= {"rms_px": [round(float(r), 2) for r in cal.rms], "people": len(cal.people),
            "frames": len(cal.frames_used), "jacobian": args.jacobian,
            "max_nfev": nfev, "rounds": rounds.lines,
            "adjust_seconds": round(sum(spent), 1),
            "seconds": round(time.perf_counter() - t0, 1)}  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m rmpl.benchmarks.calib_people_bundle",
                                description=__doc__.splitlines()[0])  # fmt: skip
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--shelf", help="a Shelf folder (4D-association layout)")
    src.add_argument("--calib", help="the reference calibration (with --keypoints)")
    p.add_argument("--keypoints", nargs="+")
    p.add_argument("--max-frames", type=int, default=200)
    p.add_argument("--jacobian", choices=("analytic", "finite-differences"), default="analytic")
    p.add_argument("--max-nfev", type=int, help="evaluations per round (default: adjust's)")
    p.add_argument("--json", help="write the figures here")
    args = p.parse_args(argv)
    text = json.dumps(_run(args), indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
