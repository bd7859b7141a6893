"""Check a calibration against the people of a recording (``rmpl calibrate --check``).

For every camera, the people are triangulated from the *other* cameras
(:func:`rmpl.geometry.triangulate.triangulate_robust`) and projected into it; the median
distance to what that camera's detector saw is its held-out reprojection error. A rule
fixed in advance calls a camera "moved since calibration" when its error exceeds both
10 px and three times the median of the other cameras' errors.

People are not associated across views here: in each view and frame the most confident
person is taken, so the check is meant for recordings of one person (or one person much
closer than the others).
"""

from __future__ import annotations

import argparse
import json
import logging

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.geometry.triangulate import triangulate_robust
from rmpl.io.keypoints import Keypoints2D
from rmpl.pipeline.consistency import MOVED_PX, MOVED_RATIO

__all__ = ["check_calibration", "run_check"]

log = logging.getLogger(__name__)

MIN_SCORE = 0.3


def _most_confident(kp: Keypoints2D) -> tuple[np.ndarray, np.ndarray]:
    """(T, V, J, 2) and (T, V, J): in each view and frame the person with the best mean score."""
    best = np.argmax(kp.scores.mean(axis=-1), axis=2)  # (T, V)
    points = np.take_along_axis(kp.keypoints, best[:, :, None, None, None], axis=2)[:, :, 0]
    scores = np.take_along_axis(kp.scores, best[:, :, None, None], axis=2)[:, :, 0]
    return points, scores


def _order(kp: Keypoints2D, rig: Rig) -> list[int]:
    views = kp.views or [f"view{i}" for i in range(kp.keypoints.shape[1])]
    if set(views) <= set(rig.names):
        return [rig.names.index(v) for v in views]
    if len(views) == len(rig):
        return list(range(len(rig)))
    raise InputError(None, "--keypoints", f"views named like the cameras {rig.names}", views)


def _held_out(points, scores, rig: Rig) -> list[dict]:
    out = []
    V = len(rig)
    for v in range(V):
        others = [u for u in range(V) if u != v]
        tri = triangulate_robust(points[:, others], scores[:, others], rig[others], MIN_SCORE)
        seen = (scores[:, v] >= MIN_SCORE) & np.isfinite(tri.points[..., 0])
        err = np.linalg.norm(rig[v].project(tri.points[seen]) - points[:, v][seen], axis=-1)
        median = float(np.median(err)) if err.size else float("nan")
        out.append({"camera": rig[v].name, "median_px": median, "joints": int(err.size)})
    return out


def check_calibration(kp: Keypoints2D, rig: Rig) -> list[dict]:
    """Per camera: name, held-out median error (px), joints compared, moved (bool).

    A moved camera also spoils the others' triangulations, so the worst camera is judged
    first; when it is called moved it is left out and the rest checked again (while three
    cameras remain)."""
    rig = rig[_order(kp, rig)]
    points, scores = _most_confident(kp)
    if len(rig) < 3:
        raise InputError(None, "--check", "a calibration of at least 3 cameras", len(rig))
    rows = {r["camera"]: r | {"moved": False} for r in _held_out(points, scores, rig)}
    keep = list(range(len(rig)))
    while len(keep) >= 3:
        current = _held_out(points[:, keep], scores[:, keep], rig[keep])
        for r in current:
            rows[r["camera"]].update(median_px=r["median_px"], joints=r["joints"])
        meds = np.array([r["median_px"] for r in current])
        worst = int(np.nanargmax(meds))
        rest = float(np.nanmedian(np.delete(meds, worst)))
        if not (meds[worst] > MOVED_PX and meds[worst] > MOVED_RATIO * rest) or len(keep) == 3:
            if meds[worst] > MOVED_PX and meds[worst] > MOVED_RATIO * rest:
                rows[current[worst]["camera"]]["moved"] = True
            break
        rows[current[worst]["camera"]]["moved"] = True
        keep.pop(worst)
    return list(rows.values())


def run_check(args: argparse.Namespace) -> int:
    """``rmpl calibrate --check CALIB --keypoints ... | --videos ...``: prints the table."""
    from rmpl.io.calibration import load_rig

    rig = load_rig(args.check)
    if args.keypoints:
        from rmpl.io.keypoints import load_keypoints

        kp = load_keypoints(args.keypoints if len(args.keypoints) > 1 else args.keypoints[0])
    elif args.videos:
        from rmpl.pipeline.detect2d import detect_videos

        kp = detect_videos(args.videos, progress=not args.no_progress)
    else:
        raise InputError(None, "--check", "--keypoints PATH... or --videos PATH...", "neither")
    rows = check_calibration(kp, rig)
    for r in rows:
        flag = "  MOVED since calibration?" if r["moved"] else ""
        print(f"{r['camera']}: {r['median_px']:.1f} px held-out ({r['joints']} joints){flag}")
    if args.out:
        from rmpl.io.atomic import atomic_path

        with atomic_path(args.out) as tmp:
            tmp.write_text(json.dumps(rows, indent=1))
    return 0
