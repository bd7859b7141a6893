"""Score a chain run on a simulation against its truth: the files in, one document out.

:func:`score_all` reads ``truth/`` and ``chain/`` and calls :mod:`rmpl.simulate.score`
stage by stage. 3D through the found cameras is moved into the true world first by the
similarity that maps the found cameras onto the true ones (a calibration has its own
origin, orientation and scale; the scale is reported with the calibration). Runs are
scored over the truth's frames: a frame or joint the run lacks counts against its
coverage. Joints are scored on the joint set both have (HALPE-26, or the first 17:
COCO-17).

It also keeps, per method, each true person's hips on the floor and their error in every
frame (``chain/errors_<method>_<cameras>.npz``), for the report's map of the room.
"""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np

from rmpl.simulate import score

__all__ = ["score_all", "load_truth_2d"]

log = logging.getLogger(__name__)


def load_truth_2d(sim: Path, names: list[str], T: int):
    """The true pixels (T, V, P, 26, 2) and visibility (T, V, P, 26) of every camera's
    frames, padded with NaN / False to T frames."""
    uv, vis = [], []
    for name in names:
        with np.load(sim / "truth" / "projections" / f"{name}.npz") as z:
            u, hidden = z["uv"].astype(float), z["hidden"]
        pad = max(T - len(u), 0)
        u = np.concatenate([u, np.full((pad, *u.shape[1:]), np.nan)])[:T]
        v = (
            np.isfinite(u).all(-1)
            & ~np.concatenate([hidden, np.ones((pad, *hidden.shape[1:]), bool)])[:T]
        )
        uv.append(u)
        vis.append(v)
    return np.stack(uv, axis=1), np.stack(vis, axis=1)


def _detection(sim: Path, chain: Path, names: list[str]) -> dict:
    from rmpl.io.keypoints import load_keypoints

    kp = load_keypoints(chain / "keypoints2d.npz")
    order = [list(kp.views).index(n) for n in names]
    keypoints, scores_ = kp.keypoints[:, order], kp.scores[:, order]
    truth_2d, visible = load_truth_2d(sim, names, keypoints.shape[0])
    return score.detection_scores(keypoints, scores_, truth_2d, visible, views=names)


def _on_truth_frames(poses, truth) -> np.ndarray:
    """The run's points on the truth's frames (T, Q, J, 3), NaN where the run has none."""
    ia, ib = score.frames_on_common_clock(np.asarray(poses.frames), np.asarray(truth.frames))
    out = np.full((len(truth.frames), *poses.points.shape[1:]), np.nan)
    out[ib] = poses.points[ia]
    return out


def _same_joints(pred: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    if pred.shape[2] == true.shape[2]:
        return pred, true, "halpe26" if true.shape[2] == 26 else "coco17"
    return pred[:, :, :17], true[:, :, :17], "coco17"


def _errors_map(paired: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per frame and true person: the hips on the floor (T, P, 2) and the MPJPE (T, P) m."""
    err = np.linalg.norm(paired - true, axis=-1)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        e = np.nanmean(err, axis=-1)
    hips = true[:, :, 11:13, :2].mean(axis=2)
    return hips, e


def _score_run(path: Path, truth, transform, chain: Path, key: str) -> dict:
    from rmpl.io.poses import load_poses

    if not path.exists():
        return {"note": "the run refused or did not finish"}
    poses = load_poses(path)
    pred = _on_truth_frames(poses, truth)
    if transform is not None:
        s, R, t = transform
        pred = s * pred @ R.T + t
    pred, true, joints = _same_joints(pred, truth.points.astype(float))
    res = score.pose_scores(pred, true)
    res["joints"] = joints
    res["body"] = score.pose_scores(pred[:, :, :17], true[:, :, :17])["overall"]
    paired = np.full_like(true, np.nan)
    for p, q in enumerate(res["identity"]["assignment"]):
        if q is not None:
            paired[:, p] = pred[:, q]
    if joints == "halpe26":
        res["angles"] = score.angle_errors(paired, true)
    hips, err = _errors_map(paired, true)
    np.savez_compressed(chain / f"errors_{key}.npz", hips=hips, error=err)
    return res


def score_all(
    sim: Path,
    chain: Path,
    doc: dict,
    found: Path | None,
    sync: Path | None,
    runs: dict,
    record: dict,
) -> dict:
    """Every stage's scores (see the module docstring); JSON-ready."""
    from rmpl.calibration.sync import read_sync
    from rmpl.io.calibration import load_rig
    from rmpl.io.poses import load_poses

    truth_rig = load_rig(sim / "truth" / "calibration.toml")
    people = (sim / "truth" / "poses.npz").exists()
    truth_poses = load_poses(sim / "truth" / "poses.npz") if people else None
    out: dict = {"settings": doc["settings"], "rig": doc["rig"], "steps": record}
    transform = None
    if found is not None:
        found_rig = load_rig(found)
        out["calibration"] = score.calibration_errors(found_rig, truth_rig)
        names = [n for n in truth_rig.names if n in found_rig.names]
        if len(names) >= 2:
            transform = score._world_similarity(
                [found_rig[found_rig.names.index(n)] for n in names],
                [truth_rig[truth_rig.names.index(n)] for n in names],
            )
    else:
        out["calibration"] = {"note": "refused; the later steps used the true cameras"}
    out["calibration"]["method"] = "board" if doc["settings"].get("board") else "people"
    if not people:
        return _jsonable(out)
    if len(truth_rig) > 1:
        out["sync"] = score.sync_errors(
            read_sync(sync) if sync else None, read_sync(sim / "truth" / "sync.json")
        )
    out["detection"] = _detection(sim, chain, list(truth_rig.names))
    out["3d"] = {}
    for (method, which), path in runs.items():
        key = f"{method}_{which}"
        use = transform if which == "found" else None
        out["3d"][f"{method} ({which} cameras)"] = _score_run(path, truth_poses, use, chain, key)
    return _jsonable(out)


def _jsonable(x):
    """Numbers as plain floats, NaN as None, tuples as lists."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x
