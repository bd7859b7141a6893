"""Scores of 3D estimates against ground truth: MPJPE, KP*, PA-MPJPE, PCK, coverage, PCP.

Every function takes predictions and ground truth as COCO-17 arrays ``(n, 17, 3)`` in
metres (NaN: not estimated / not annotated) and returns millimetres or percent.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from rmpl.metrics import pcp_parts, procrustes_align
from rmpl.skeleton import COCO17, KP_STAR, SHELF14, convert

if TYPE_CHECKING:
    from rmpl.evaluate.harness import Evaluation

__all__ = [
    "PCP_ACTORS",
    "PCP_PARTS",
    "common_mask",
    "condition_label",
    "joint_errors_mm",
    "mean_finite",
    "pcp_actors",
    "pcp_by_actor",
    "pose_metrics",
    "shelf15",
]

MID_HIP = SHELF14.num_joints  # index of the mid-hip appended after the Shelf-14 joints
#: The customary ten Shelf/Campus PCP parts: head, arms, legs (Shelf-14 bones) and torso.
PCP_PARTS = SHELF14.bones[:9] + ((SHELF14.index("neck"), MID_HIP),)
#: PCP is reported for the customary actors 1-3 (Shelf's actor 4 is left out).
PCP_ACTORS = 3


def shelf15(coco: np.ndarray) -> np.ndarray:
    """COCO-17 joints (*, 17, 3) to Shelf-14 plus the mid-hip: shape (*, 15, 3)."""
    shelf = convert(coco, "coco17", "shelf14")
    return _with_mid_hip(shelf)


def _with_mid_hip(shelf: np.ndarray) -> np.ndarray:
    """Shelf-14 joints (*, 14, 3) plus the mid-hip (mean of the hips): (*, 15, 3)."""
    hips = shelf[..., [SHELF14.index("right_hip"), SHELF14.index("left_hip")], :]
    return np.concatenate([shelf, hips.mean(-2, keepdims=True)], axis=-2)


def pose_metrics(
    pred: np.ndarray,
    gt: np.ndarray,
    joints: Sequence[int],
    pck_threshold: float = 0.150,
) -> dict[str, float]:
    """MPJPE, KP* MPJPE, PA-MPJPE (mm), PCK and coverage (%) of poses.

    Args:
        pred: (n, 17, 3) COCO-17, metres; NaN = not estimated.
        gt: (n, 17, 3), metres; NaN = not annotated (not scored).
        joints: COCO-17 indices to score.
        pck_threshold: metres.

    Returns:
        ``mpjpe``, ``kpstar`` (the :data:`~rmpl.skeleton.KP_STAR` joints among ``joints``),
        ``pa_mpjpe`` (per-pose similarity alignment on the estimated joints, poses with at
        least 4), ``pck`` (a missing estimate counts as wrong), ``coverage`` (estimated
        share of annotated joints). MPJPE and PA-MPJPE leave missing estimates out.
    """
    joints = list(joints)
    p, g = pred[:, joints], gt[:, joints]
    present = np.isfinite(g).all(-1)
    e = np.linalg.norm(p - g, axis=-1)
    ok = present & np.isfinite(e)
    star = np.isin(joints, KP_STAR)
    out = {
        "mpjpe": 1000 * float(e[ok].mean()) if ok.any() else np.nan,
        "kpstar": 1000 * float(e[:, star][ok[:, star]].mean()) if ok[:, star].any() else np.nan,
        "pa_mpjpe": np.nan,
        "pck": 100
        * float((ok & (np.nan_to_num(e, nan=np.inf) <= pck_threshold)).sum())
        / max(int(present.sum()), 1)
        if present.any()
        else np.nan,
        "coverage": 100 * float(ok.sum()) / max(int(present.sum()), 1) if present.any() else np.nan,
    }
    enough = ok.sum(-1) >= 4
    if enough.any():
        pp = np.where(ok[enough, :, None], p[enough], np.nan)
        aligned = procrustes_align(pp, g[enough])
        ea = np.linalg.norm(aligned - g[enough], axis=-1)
        out["pa_mpjpe"] = 1000 * float(ea[ok[enough]].mean())
    return out


def pcp_by_actor(pred: np.ndarray, native: np.ndarray, person: np.ndarray) -> dict[str, float]:
    """PCP (%) per actor label over poses, Shelf-14 parts + torso (to the mid-hip).

    Args:
        pred: (n, 17, 3) COCO-17 estimates, metres.
        native: (n, 14, 3) Shelf-14 ground truth, metres.
        person: (n,) actor label per pose.
    """
    parts = pcp_parts(shelf15(pred), _with_mid_hip(native), PCP_PARTS)  # (n, 10)
    out = {}
    for a in np.unique(person):
        sel = person == a
        out[str(a)] = 100 * float(parts[sel].mean()) if sel.any() else np.nan
    return out


def mean_finite(values: Iterable[float]) -> float:
    """Mean of the finite values; NaN when there are none."""
    v = np.asarray(list(values), float)
    return float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else float("nan")


def condition_label(p: float, calib: tuple[float, float] | None) -> tuple[float, str]:
    """The (dropout, calib_noise) cells of a row: p and "none" or "DEG deg, MM mm"."""
    c = "none" if calib is None else f"{calib[0]:g} deg, {1000 * calib[1]:g} mm"
    return p, c


def pcp_actors(ev: Evaluation) -> list[str]:
    """Actor labels PCP is reported for (actors 1-3 that appear)."""
    labels = [f"actor {i}" for i in range(1, PCP_ACTORS + 1)]
    return [a for a in labels if (ev.person == a).any()]


def common_mask(ev: Evaluation, label: str, ci: int, k: int) -> np.ndarray:
    """Joints every method estimated in entry ``k``, shape (n, 17)."""
    ok = np.isfinite(ev.gt).all(-1)
    for m in ev.methods:
        ok &= np.isfinite(ev.preds[label, ci, m][k]).all(-1)
    return ok


def joint_errors_mm(ev: Evaluation, label: str, ci: int, method: str) -> dict[str, np.ndarray]:
    """Every finite per-joint error (mm) of a view setting, condition and method, by joint."""
    out = {}
    for j in ev.joints:
        e = [np.linalg.norm(x[:, j] - ev.gt[:, j], axis=-1) for x in ev.preds[label, ci, method]]
        e = np.concatenate(e) * 1000 if e else np.zeros(0)
        out[COCO17.joints[j]] = e[np.isfinite(e)]
    return out
