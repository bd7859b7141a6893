"""Benchmark ``rmpl calibrate`` on real board footage against the calibrations beside it.

- ``pose2sim``: Pose2Sim's 28 checkerboard photos (``Demo_SinglePerson/calibration/
  intrinsics``, 4 x 7 inner corners, 60 mm) against the Qualisys calibration beside them
  (``Calib.qca.txt``): per camera the focal length error (%) and the principal point's
  distance (px), for rmpl and for one ``cv2.calibrateCamera`` on every photo.
- ``caliscope``: the 4 webcam videos of ``caliscope_charuco`` (an inverted ChArUco board)
  alone, lenses and poses, against caliscope's ``camera_array.toml`` (world -> camera
  ``rotation``, ``translation`` in metres): per camera the reprojection RMS beside
  caliscope's ``error``, and after a similarity alignment of the camera centres each
  camera's centre (mm) and rotation (degrees) difference, and the scale.

    python -m rmpl.benchmarks.calib_real --root ../shared/data [--which pose2sim caliscope]
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
from pathlib import Path

import numpy as np

from rmpl.benchmarks.calib_boards import _angle, similarity
from rmpl.calibration.boards import parse_board
from rmpl.calibration.calibrate import calibrate_boards
from rmpl.calibration.frames import read_views
from rmpl.io.calibration import load_rig


def pose2sim(root: Path) -> dict:
    import cv2

    base = root / "pose2sim_videos" / "Demo_SinglePerson" / "calibration"
    board = parse_board("checkerboard:4x7:0.06")
    truth = load_rig(base / "Calib.qca.txt")
    folders = sorted(p for p in (base / "intrinsics").iterdir() if p.is_dir())
    opencv = []
    for folder in folders:  # OpenCV alone first, on every photo with the board
        views = read_views(folder, board, folder.name, progress=False)
        obj = [board.points[d.ids].astype(np.float32) for d in views.views.values()]
        img = [d.corners.astype(np.float32) for d in views.views.values()]
        opencv.append((cv2.calibrateCamera(obj, img, views.size, None, None)[1], len(obj)))
    start = time.perf_counter()
    cal = calibrate_boards(board, folders, [], progress=False)
    seconds = time.perf_counter() - start
    out = {"seconds": round(seconds, 1), "cameras": {}}
    for v, (K_cv, n_images) in enumerate(opencv):
        true = truth[v]
        row = {}
        for name, K in (("rmpl", cal.rig[v].K), ("opencv", K_cv)):
            row[name] = {
                "focal_pct": round(float((K[0, 0] / true.K[0, 0] - 1) * 100), 3),
                "pp_px": round(float(np.linalg.norm(K[:2, 2] - true.K[:2, 2])), 1),
            }
        row["images"] = n_images
        row["dropped"] = cal.lenses[v].dropped
        row["rms_px"] = round(cal.lenses[v].rms, 3)
        out["cameras"][true.name] = row
    return out


def caliscope(root: Path) -> dict:
    base = root / "caliscope_charuco"
    board = parse_board(str(base / "charuco.toml"))
    ref = tomllib.loads((base / "camera_array.toml").read_text())["cameras"]
    keys = sorted(ref, key=int)
    videos = [base / "calibration" / "extrinsic" / f"cam_{k}.mp4" for k in keys]
    start = time.perf_counter()
    cal = calibrate_boards(board, [], videos, progress=False)
    seconds = time.perf_counter() - start
    R_ref = [np.array(ref[k]["rotation"], float) for k in keys]
    C_ref = np.array(
        [-R.T @ np.array(ref[k]["translation"], float) for R, k in zip(R_ref, keys, strict=True)]
    )
    s, R, t = similarity(cal.rig.centers, C_ref)
    out = {"seconds": round(seconds, 1), "scale": round(s, 4), "cameras": {}}
    for v, (cam, k) in enumerate(zip(cal.rig, keys, strict=True)):
        K_ref = np.array(ref[k]["matrix"], float)
        out["cameras"][cam.name] = {
            "rms_px": round(cal.rms[v], 3),
            "lens_rms_px": round(cal.lenses[v].rms, 3),
            "caliscope_error_px": ref[k]["error"],
            "centre_mm": round(float(np.linalg.norm(s * R @ cam.center + t - C_ref[v])) * 1000, 1),
            "rotation_deg": round(_angle(cam.R @ R.T, R_ref[v]), 2),
            "focal_pct": round(float((cam.K[0, 0] / K_ref[0, 0] - 1) * 100), 2),
            "pp_px": round(float(np.linalg.norm(cam.K[:2, 2] - K_ref[:2, 2])), 1),
            "dropped": cal.views_dropped[v],
        }
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--root", type=Path, required=True, help="the shared data folder")
    p.add_argument("--which", nargs="+", choices=["pose2sim", "caliscope"],
                   default=["pose2sim", "caliscope"])  # fmt: skip
    p.add_argument("--out", type=Path, help="write the results as JSON here")
    args = p.parse_args(argv)
    results = {}
    for name in args.which:
        results[name] = {"pose2sim": pose2sim, "caliscope": caliscope}[name](args.root)
        print(json.dumps({name: results[name]}, indent=1))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
