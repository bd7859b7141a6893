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
out; 1-4: converged) and cost; and ``bones_over_rig``, the people's size beside the
cameras' (median bone length over the RMS distance of the centres from their mean) at the
start and at the end of the adjustment.

``--start truth`` is a diagnosis: the adjustment starts at the reference cameras instead
(moved by a similarity onto the start found from the people, so that the gauge and the
scale stay those of the chain) with the points triangulated through them; where it settles
tells whether the objective itself (associations, bones, loss) or the start is at fault.
``--bones metres|relative`` picks the bone term (default: the package's,
:data:`rmpl.calibration.people_bundle.BONE_TERM`; "relative" does not change with the scale).

Example::

    python -m rmpl.benchmarks.calib_people_bundle --shelf ../shared/data/shelf_dev
    python -m rmpl.benchmarks.calib_people_bundle --shelf ../shared/data/shelf_dev \\
        --jacobian finite-differences
    python -m rmpl.benchmarks.calib_people_bundle --shelf ../shared/data/shelf_dev --max-nfev 200
"""

from __future__ import annotations

import argparse
import inspect
import logging
import sys
import time
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
    spent, size = [], []
    default = inspect.signature(people_bundle.adjust).parameters["max_nfev"].default
    nfev = args.max_nfev or default

    def adjust(prob, R, t, points, lengths, fixed, gauge_cam, rounds=people_bundle.ROUNDS):
        t0 = time.perf_counter()
        if args.start == "truth":
            R, t, points = _truth_start(prob, R, t, points, truth)
        analytic = args.jacobian == "analytic"
        out = people_bundle._adjust(
            prob, R, t, points, lengths, (fixed, gauge_cam), rounds, nfev, analytic
        )
        spent.append(time.perf_counter() - t0)
        size.append(_bones_over_rig(lengths, R, t))
        size.append(_bones_over_rig(out.lengths, out.R, out.t))
        return out

    rounds = _Rounds()
    logger = logging.getLogger(people_bundle.__name__)
    logger.addHandler(rounds)
    logger.setLevel(logging.DEBUG)
    t0 = time.perf_counter()
    bones = mock.patch.object(people_bundle, "BONE_TERM", args.bones or people_bundle.BONE_TERM)
    with mock.patch.object(people_bundle, "adjust", adjust), bones:
        cal = calibrate_from_people(keypoints, scores, truth, max_frames=args.max_frames)
    out = compare(cal.rig, truth)
    out |= {"rms_px": [round(float(r), 2) for r in cal.rms], "people": len(cal.people),
            "frames": len(cal.frames_used), "jacobian": args.jacobian,
            "max_nfev": nfev, "start": args.start, "bones": args.bones, "rounds": rounds.lines,
            "bones_over_rig": [round(float(v), 4) for v in size],
            "adjust_seconds": round(sum(spent), 1),
            "seconds": round(time.perf_counter() - t0, 1)}  # fmt: skip
    return out


def _bones_over_rig(lengths, R, t) -> float:
    """The median bone length over the rig's size (RMS distance of the camera centres
    from their mean): how large the people are beside the cameras."""
    import numpy as np

    C = -np.einsum("vji,vj->vi", R, t)
    rig = np.sqrt(((C - C.mean(0)) ** 2).sum(-1).mean())
    return float(np.median(lengths[lengths > 0]) / rig)


def _truth_start(prob, R, t, points, truth):
    """The reference cameras in the frame of the start (R, t), and the points triangulated
    through them (the start's points where fewer than two views see one)."""
    import numpy as np

    from rmpl.calibration.people import similarity, triangulate_normalised

    centres = -np.einsum("vji,vj->vi", R, t)
    s, Rs, ts = similarity(centres, truth.centers)  # truth ~ s Rs start + ts
    Rt = np.stack([c.R for c in truth])
    R1 = Rt @ Rs
    t1 = (np.einsum("vij,j->vi", Rt, ts) + np.stack([c.t for c in truth])) / s
    obs = np.full((len(points), len(R), 2), np.nan)
    obs[prob.point, prob.cam] = prob.xy
    X = triangulate_normalised(obs, R1, t1, np.ones(len(R), bool))
    return R1, t1, np.where(np.isfinite(X).all(-1, keepdims=True), X, points)


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
    p.add_argument("--start", choices=("people", "truth"), default="people",
                   help="truth: start at the reference cameras (a diagnosis)")  # fmt: skip
    p.add_argument("--bones", choices=("metres", "relative"), default=None,
                   help="the bone term (default: people_bundle.BONE_TERM)")  # fmt: skip
    p.add_argument("--json", help="write the figures here")
    args = p.parse_args(argv)
    from rmpl.benchmarks._common import emit_json

    emit_json(_run(args), args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
