"""Benchmark ``rmpl calibrate`` on rendered board sets against the cameras they were
rendered through, side by side with OpenCV alone and aniposelib, with the time each took.

A set: ``--cameras`` cameras (1280x720, distortion, random focal and principal point)
around a capture volume, ``--intrinsics-views`` close-up views per camera and
``--extrinsics-views`` shared views (the first on the floor at the world origin), blur 0.6
px and noise 1.5 grey levels (``rmpl.calibration.render``). Every method gets the same
corners (``rmpl.calibration.detect``):

- ``rmpl``: :func:`rmpl.calibration.calibrate.calibrate_boards`;
- ``opencv``: one ``cv2.calibrateCamera`` per camera on its close-ups, one ``cv2.solvePnP``
  per camera on the floor view (a camera that misses it is not placed);
- ``aniposelib`` (ChArUco only, when installed): ``CameraGroup.calibrate_rows`` on the
  same corners (close-ups and shared views).

Per method, the worst camera's focal error (%), principal point error (px), reprojection
RMS (px), and, after a similarity alignment of the camera centres to the truth, rotation
(degrees) and centre (mm) errors, and the scale error (%).

    python -m rmpl.benchmarks.calib_boards --out bench/calib_boards [--board charuco]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from rmpl.calibration.boards import Board, parse_board
from rmpl.calibration.calibrate import calibrate_boards
from rmpl.calibration.render import make_scene, write_scene
from rmpl.geometry.camera import Camera, Rig

BOARDS = {"charuco": "charuco:8x6:0.1:0.075:DICT_4X4_50", "checkerboard": "checkerboard:9x6:0.1"}


def similarity(a: np.ndarray, b: np.ndarray):
    """Scale, rotation and shift mapping points a (N, 3) best onto b (Umeyama)."""
    ma, mb = a.mean(0), b.mean(0)
    U, S, Vt = np.linalg.svd((b - mb).T @ (a - ma))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / ((a - ma) ** 2).sum())
    return s, R, mb - s * R @ ma


def _angle(Ra, Rb) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1))))


def score(found: list[Camera | None], truth: Rig, rms: list[float], seconds: float) -> dict:
    """The worst camera's errors (see the module)."""
    ok = [i for i, c in enumerate(found) if c is not None]
    out = {"seconds": round(seconds, 1), "cameras_placed": len(ok), "rms_px": float(np.nanmax(rms))}
    out["focal_pct"] = max(abs(found[i].K[0, 0] / truth[i].K[0, 0] - 1) * 100 for i in ok)
    out["pp_px"] = max(float(np.linalg.norm(found[i].K[:2, 2] - truth[i].K[:2, 2])) for i in ok)
    if len(ok) >= 3:
        a = np.array([found[i].center for i in ok])
        s, R, t = similarity(a, truth.centers[ok])
        out["scale_pct"] = abs(s - 1) * 100
        out["centre_mm"] = max(
            float(np.linalg.norm(s * R @ found[i].center + t - truth[i].center)) * 1000 for i in ok
        )
        out["rotation_deg"] = max(_angle(found[i].R @ R.T, truth[i].R) for i in ok)
    return {k: round(v, 4) if isinstance(v, float) else v for k, v in out.items()}


def _views(folder: Path, board: Board, names: list[str]):
    from rmpl.calibration.frames import read_views

    intr = [read_views(folder / "intrinsics" / n, board, n, progress=False) for n in names]
    ext = [read_views(folder / "extrinsics" / n, board, n, progress=False) for n in names]
    return intr, ext


def opencv_alone(board: Board, intr, ext, size) -> tuple[list, list, float]:
    import cv2

    start = time.perf_counter()
    cams, rms = [], []
    for ci, ce in zip(intr, ext, strict=True):
        obj = [board.points[d.ids].astype(np.float32) for d in ci.views.values()]
        img = [d.corners.astype(np.float32) for d in ci.views.values()]
        err, K, dist, _, _ = cv2.calibrateCamera(obj, img, size, None, None)
        rms.append(err)
        floor = ce.views.get(0)
        if floor is None:
            cams.append(None)
            continue
        _, rv, tv = cv2.solvePnP(board.points[floor.ids], floor.corners, K, dist)
        R_cb = cv2.Rodrigues(rv)[0]
        # the floor board: board -> world is diag(1, -1, -1), so world -> board is the same
        G = np.diag([1.0, -1.0, -1.0])
        cams.append(Camera(K, R_cb @ G, tv.ravel(), np.ravel(dist)[:5], size, ce.name))
    return cams, rms, time.perf_counter() - start


def aniposelib_rows(board: Board, intr, ext, names, size) -> tuple[list, list, float] | None:
    try:
        from aniposelib.boards import CharucoBoard
        from aniposelib.cameras import CameraGroup
    except ImportError:
        return None
    if board.kind != "charuco":
        return None
    bits, number = int(board.dictionary[5]), int(board.dictionary.rsplit("_", 1)[1])
    ab = CharucoBoard(board.cols, board.rows, board.square, board.marker, bits, number)
    start = time.perf_counter()
    rows = []
    for v, (ci, ce) in enumerate(zip(intr, ext, strict=True)):
        r = [_row(("x", f, 0), d) for f, d in ce.views.items()]
        r += [_row(("i", v, k), d) for k, d in ci.views.items()]
        rows.append(ab.fill_points_rows(r))
    group = CameraGroup.from_names(names)
    for cam in group.cameras:
        cam.set_size(size)
    error = group.calibrate_rows(rows, ab, verbose=False)
    cams = []
    for cam, name in zip(group.cameras, names, strict=True):
        import cv2

        R = cv2.Rodrigues(np.asarray(cam.get_rotation(), float))[0]
        d = np.pad(np.ravel(cam.get_distortions()), (0, 5))[:5]
        cams.append(Camera(cam.get_camera_matrix(), R, cam.get_translation(), d, size, name))
    return cams, [float(error)] * len(names), time.perf_counter() - start


def _row(key, det) -> dict:
    corners = det.corners.reshape(-1, 1, 2).astype(np.float32)
    return {"framenum": key, "corners": corners, "ids": det.ids.reshape(-1, 1).astype(np.int32)}


def run_set(kind: str, folder: Path, args) -> dict:
    board = parse_board(BOARDS[kind])
    scene = make_scene(
        board, cameras=args.cameras, intrinsics_views=args.intrinsics_views,
        extrinsics_views=args.extrinsics_views, seed=args.seed,
    )  # fmt: skip
    if not (folder / "truth.toml").is_file():
        write_scene(scene, folder, blur=0.6, noise=1.5, seed=args.seed)
    names, size = scene.rig.names, scene.rig[0].size
    start = time.perf_counter()
    cal = calibrate_boards(
        board, [folder / "intrinsics" / n for n in names],
        [folder / "extrinsics" / n for n in names], progress=False,
    )  # fmt: skip
    out = {"rmpl": score(list(cal.rig), scene.rig, cal.rms, time.perf_counter() - start)}
    intr, ext = _views(folder, board, names)
    cams, rms, sec = opencv_alone(board, intr, ext, size)
    out["opencv"] = score(cams, scene.rig, rms, sec)
    try:
        ani = aniposelib_rows(board, intr, ext, names, size)
    except Exception as e:  # report its failure, keep the others' figures
        out["aniposelib"] = {"failed": f"{type(e).__name__}: {e}"[:200]}
        ani = None
    if ani is not None:
        out["aniposelib"] = score(ani[0], scene.rig, ani[1], ani[2])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="folder for the sets and results")
    p.add_argument("--board", choices=sorted(BOARDS), nargs="+", default=sorted(BOARDS))
    p.add_argument("--cameras", type=int, default=4)
    p.add_argument("--intrinsics-views", type=int, default=15)
    p.add_argument("--extrinsics-views", type=int, default=30)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    results = {
        kind: run_set(kind, args.out / f"{kind}_seed{args.seed}", args) for kind in args.board
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"results_seed{args.seed}.json").write_text(json.dumps(results, indent=1))
    for kind, methods in results.items():
        print(f"## {kind}")
        for method, r in methods.items():
            print(f"{method:11s} " + " ".join(f"{k}={v}" for k, v in r.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
