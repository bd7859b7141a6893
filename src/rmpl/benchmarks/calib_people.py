"""Calibration from people against a reference calibration (Shelf, the Pose2Sim demo).

The reference's extrinsics are withheld: only its intrinsics go in (its poses never reach
:func:`rmpl.calibration.people.calibrate_from_people`). The cameras found are aligned to
the reference by a similarity on the centres (Umeyama), then each camera's rotation error
(degrees) and centre error (mm) are reported, with the similarity's scale (1 = metric
scale right) and the report's reprojection RMS. Targets (issue 26): every camera within
0.75 degree and 50 mm, scale within 5%.

Example::

    python -m rmpl.benchmarks.calib_people --shelf ../shared/data/shelf_dev
    python -m rmpl.benchmarks.calib_people --calib CALIB --keypoints POSE_DIR
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def compare(found, truth) -> dict:
    """Per-camera errors of ``found`` against ``truth`` after a similarity alignment."""
    from rmpl.calibration.people import similarity

    s, R, t = similarity(found.centers, truth.centers)
    rows = []
    for f, g in zip(found, truth, strict=True):
        Ra = f.R @ R.T
        ang = np.degrees(np.arccos(np.clip((np.trace(Ra @ g.R.T) - 1) / 2, -1, 1)))
        d = np.linalg.norm(s * R @ f.center + t - g.center)
        rows.append({"camera": g.name, "rotation_deg": round(float(ang), 3),
                     "centre_mm": round(1000 * float(d), 1)})  # fmt: skip
    ok = all(r["rotation_deg"] <= 0.75 and r["centre_mm"] <= 50 for r in rows)
    return {"cameras": rows, "scale": round(1.0 / s, 4), "cameras_within_target": ok,
            "scale_within_target": abs(1.0 / s - 1) <= 0.05}  # fmt: skip


def _inputs(args):
    from rmpl.io.calibration import load_rig

    if args.shelf:
        from rmpl.pipeline.inputs import _shelf4d_keypoints

        root = Path(args.shelf)
        kp = _shelf4d_keypoints(root)
        return kp.keypoints, kp.scores, load_rig(root / "calibration.json")
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    inp = load_inputs(InputSpec(args.calib, args.keypoints))
    return inp.keypoints, inp.scores, inp.rig


def main(argv: list[str] | None = None) -> int:
    from rmpl.calibration.people import calibrate_from_people

    p = argparse.ArgumentParser(prog="python -m rmpl.benchmarks.calib_people",
                                description=__doc__.splitlines()[0])  # fmt: skip
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--shelf", help="a Shelf folder (4D-association layout)")
    src.add_argument("--calib", help="the reference calibration (with --keypoints)")
    p.add_argument("--keypoints", nargs="+")
    p.add_argument("--max-frames", type=int, default=200)
    p.add_argument("--json", help="write the figures here")
    args = p.parse_args(argv)
    keypoints, scores, truth = _inputs(args)
    t0 = time.time()
    cal = calibrate_from_people(keypoints, scores, truth, max_frames=args.max_frames)
    out = compare(cal.rig, truth)
    out |= {"rms_px": [round(float(r), 2) for r in cal.rms], "scale_source": cal.scale_source,
            "scale_sd": round(cal.scale_sd, 4), "people": len(cal.people),
            "frames": len(cal.frames_used), "seconds": round(time.time() - t0)}  # fmt: skip
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
