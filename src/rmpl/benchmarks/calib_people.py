"""Calibration from people against a reference calibration (Shelf, the Pose2Sim demo).

The reference's extrinsics are withheld: only its intrinsics go in (its poses never reach
:func:`rmpl.calibration.people.calibrate_from_people`). The cameras found are aligned to
the reference by a similarity on the centres (Umeyama), then each camera's rotation error
(degrees) and centre error (mm) are reported, with the similarity's scale (1 = metric
scale right) and the report's reprojection RMS. Targets: every camera within 0.75 degree
and 50 mm, scale within 5%.

``--run OUT`` (Shelf) then runs ``rmpl run`` (RMPL, the per-frame model ``default``) through
the true cameras and through the found ones, put into the true cameras' frame by that
similarity (so the scale found does not count), and scores both against the ground truth
with ``rmpl evaluate``: target, the found cameras' MPJPE within 1.1x of the true ones'.

Example::

    python -m rmpl.benchmarks.calib_people --shelf ../shared/data/shelf_dev --run OUT
    python -m rmpl.benchmarks.calib_people --calib CALIB --keypoints POSE_DIR
"""

from __future__ import annotations

import argparse
import csv
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


def aligned(found, truth):
    """``found`` moved into ``truth``'s frame and scale by the similarity of the centres."""
    from rmpl.calibration.people import similarity
    from rmpl.geometry.camera import Camera, Rig

    s, R, t = similarity(found.centers, truth.centers)
    cams = []
    for c in found:
        Rn = c.R @ R.T
        cams.append(Camera(c.K, Rn, -Rn @ (s * R @ c.center + t), c.dist, c.size, c.name))
    return Rig(tuple(cams))


def run_through(found, truth, root: Path, out: Path) -> dict:
    """MPJPE and PCP of ``rmpl run`` through the true and the found cameras (Shelf)."""
    from rmpl.cli import main
    from rmpl.io.calibration import save_rig

    out.mkdir(parents=True, exist_ok=True)
    save_rig(aligned(found, truth), out / "found.json")
    calibs = {"true": root / "calibration.json", "found": out / "found.json"}
    for name, calib in calibs.items():
        code = main(["run", "--calib", str(calib), "--keypoints", str(root), "--method", "rmpl",
                     "--model", "default", "--no-pictures", "--formats", "npz", "--pose2sim",
                     "off", "--out", str(out / name)])  # fmt: skip
        if code not in (0, 3):
            raise SystemExit(code)
    poses = [f"{n}={out / n / 'poses.npz'}" for n in calibs]
    code = main(["evaluate", "--dataset", "shelf", "--root", str(root), "--poses", *poses,
                 "--no-plots", "--out", str(out / "eval")])  # fmt: skip
    if code != 0:
        raise SystemExit(code)
    with open(out / "eval" / "results.csv", encoding="utf-8") as f:
        rows = {r["method"]: r for r in csv.DictReader(f)}
    got = {n: {"mpjpe_mm": round(float(rows[n]["mpjpe"]), 1),
               "pa_mpjpe_mm": round(float(rows[n]["pa_mpjpe"]), 1),
               "pcp_mean": round(float(rows[n]["pcp_mean"]), 1)} for n in calibs}  # fmt: skip
    ratio = got["found"]["mpjpe_mm"] / got["true"]["mpjpe_mm"]
    return got | {"mpjpe_ratio": round(ratio, 3), "ratio_within_target": ratio <= 1.1}


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
    from rmpl.benchmarks._common import emit_json
    from rmpl.calibration.people import calibrate_from_people

    p = argparse.ArgumentParser(prog="python -m rmpl.benchmarks.calib_people",
                                description=__doc__.splitlines()[0])  # fmt: skip
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--shelf", help="a Shelf folder (4D-association layout)")
    src.add_argument("--calib", help="the reference calibration (with --keypoints)")
    p.add_argument("--keypoints", nargs="+")
    p.add_argument("--max-frames", type=int, default=200)
    p.add_argument("--json", help="write the figures here")
    p.add_argument("--run", help="Shelf: rmpl run through both rigs here, and score them")
    args = p.parse_args(argv)
    keypoints, scores, truth = _inputs(args)
    t0 = time.time()
    cal = calibrate_from_people(keypoints, scores, truth, max_frames=args.max_frames)
    out = compare(cal.rig, truth)
    out |= {"rms_px": [round(float(r), 2) for r in cal.rms], "scale_source": cal.scale_source,
            "scale_sd": round(cal.scale_sd, 4), "people": len(cal.people),
            "frames": len(cal.frames_used), "seconds": round(time.time() - t0),
            "centre_sd_of_distance": [round(float(r), 4) for r in cal.centre_sd_relative],
            "warnings": cal.warnings}  # fmt: skip
    if args.run and args.shelf:
        out["run"] = run_through(cal.rig, truth, Path(args.shelf), Path(args.run))
    emit_json(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
