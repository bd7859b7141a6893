"""Accuracy without 3D ground truth: the held-out-view reprojection error.

A recording with a calibration and 2D detections but no motion capture can still rank
methods. Each camera ``h`` in turn is held out: every method estimates every associated
person from ``k`` of the other cameras, the estimate is projected into ``h`` (with its lens
distortion), and compared with ``h``'s own detection of the same joint. Nothing the method
saw came from ``h``, so the error measures the 3D estimate, up to ``h``'s detection noise
and the detector's own joint definitions (which favour methods that reproduce them, like
triangulation of the same detector's keypoints).

The error is reported in pixels of ``h`` and in millimetres across ``h``'s viewing ray
(pixels x depth / focal length), so cameras at different distances weigh alike.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from rmpl.geometry.camera import Rig

__all__ = ["HeldoutEvaluation", "heldout_view_errors", "heldout_rows"]

Method = Callable[[np.ndarray, np.ndarray, Rig], np.ndarray]


@dataclass
class HeldoutEvaluation:
    """Per view count ``k``: every scored (held-out view, joint) of every method.

    ``px[k][m]`` and ``mm[k][m]`` are flat arrays of errors on the joints where the held-out
    view's detection is confident; NaN where method ``m`` gave no estimate. Every method's
    arrays for one ``k`` are aligned (the same held-out detections, in the same order).
    """

    methods: list[str]
    px: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)
    mm: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)
    subsets: dict[int, int] = field(default_factory=dict)


def heldout_view_errors(
    keypoints: np.ndarray,
    scores: np.ndarray,
    rig: Rig,
    methods: dict[str, Method],
    sizes: Sequence[int],
    min_score: float = 0.5,
    progress: bool = False,
) -> HeldoutEvaluation:
    """Leave-one-view-out reprojection errors of each method.

    Args:
        keypoints: (N, V, J, 2) pixels of N associated people (or person-frames), NaN where
            missing.
        scores: (N, V, J) confidences, 0 where missing.
        rig: the V cameras.
        methods: name -> ``fn(keypoints, scores, rig) -> (N, J, 3)`` metres (NaN = none).
        sizes: numbers of input views k, each in 1..V-1; every k-subset of the other views
            is used for each held-out view.
        min_score: a held-out detection counts as the reference when its confidence is at
            least this, in (0, 1].
        progress: show a progress bar over (held-out view, subset) pairs.

    Returns:
        :class:`HeldoutEvaluation`.

    Raises:
        ValueError: shapes that disagree, or a k outside 1..V-1.
    """
    from tqdm import tqdm

    kp, sc = _checked(keypoints, scores, rig, sizes, min_score)
    V = sc.shape[1]
    sc = np.where(np.isfinite(kp).all(-1) & np.isfinite(sc), sc, 0.0)
    jobs = [
        (h, k, list(S))
        for k in sizes
        for h in range(V)
        for S in itertools.combinations([v for v in range(V) if v != h], k)
    ]
    ev = HeldoutEvaluation(methods=list(methods))
    acc_px: dict[int, dict[str, list]] = {k: {m: [] for m in methods} for k in sizes}
    acc_mm: dict[int, dict[str, list]] = {k: {m: [] for m in methods} for k in sizes}
    for h, k, S in tqdm(jobs, desc="held-out views", unit="subset", disable=not progress):
        ev.subsets[k] = ev.subsets.get(k, 0) + 1
        for m, (px, mm) in _subset_errors(kp, sc, rig, methods, h, S, min_score).items():
            acc_px[k][m].append(px)
            acc_mm[k][m].append(mm)
    for k in sizes:
        ev.px[k] = {m: _cat(acc_px[k][m]) for m in methods}
        ev.mm[k] = {m: _cat(acc_mm[k][m]) for m in methods}
    return ev


def _checked(keypoints, scores, rig: Rig, sizes, min_score: float):
    """keypoints (N, V, J, 2) and scores (N, V, J) as float arrays, after the checks."""
    kp = np.asarray(keypoints, float)
    sc = np.asarray(scores, float)
    if kp.ndim != 4 or kp.shape[-1] != 2 or sc.shape != kp.shape[:-1]:
        raise ValueError(
            f"keypoints must be (N, V, J, 2) and scores (N, V, J), got {kp.shape}, {sc.shape}"
        )
    N, V, J = sc.shape
    if V != len(rig):
        raise ValueError(f"{V} views of 2D but {len(rig)} cameras")
    bad = [int(k) for k in sizes if not 1 <= k <= V - 1]
    if bad:
        raise ValueError(f"view counts must be in 1..{V - 1} (one view is held out), got {bad}")
    if not 0 < min_score <= 1:
        raise ValueError(f"min_score must be in (0, 1], got {min_score}")
    return kp, sc


def _subset_errors(kp, sc, rig: Rig, methods, h: int, S: list[int], min_score: float):
    """Errors in held-out view ``h`` of every method estimating from views ``S``.

    Returns:
        name -> (pixel errors, millimetre errors), flat over the confident detections of
        ``h`` (NaN where the method gave no estimate); {} when nothing is scored.
    """
    J = min(sc.shape[-1], 17)  # scored: COCO-17 (the first 17 of HALPE-26 2D and outputs)
    ref = (sc[:, h, :J] > 0) & (sc[:, h, :J] >= min_score)  # (N, J)
    keep = ref.any(-1) & (sc[:, S] > 0).any((-1, -2))
    if not keep.any():
        return {}
    sub_kp, sub_sc, sub_rig = kp[keep][:, S], sc[keep][:, S], rig[S]
    target, ref = kp[keep, h, :J], ref[keep]
    cam = rig[h]
    focal = 0.5 * (cam.K[0, 0] + cam.K[1, 1])
    preds = {m: np.asarray(fn(sub_kp, sub_sc, sub_rig), float) for m, fn in methods.items()}
    n = int(keep.sum())
    out = {}
    for m, X in preds.items():
        if X.ndim != 3 or X.shape[0] != n or X.shape[1] < J or X.shape[2] != 3:
            raise ValueError(f"method {m} returned {X.shape}, expected {(n, J, 3)} or more joints")
        X = X[:, :J]
        ok = np.isfinite(X).all(-1)
        Xs = np.where(ok[..., None], X, 0.0)
        uv = cam.project(Xs)
        depth = Xs @ cam.R[2] + cam.t[2]
        ok &= depth > 0
        err = np.linalg.norm(uv - target, axis=-1)
        err_mm = 1000.0 * err * depth / focal
        out[m] = (np.where(ok, err, np.nan)[ref], np.where(ok, err_mm, np.nan)[ref])
    return out


def _cat(parts: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(0)


def heldout_rows(ev: HeldoutEvaluation) -> list[dict]:
    """One row per (view count, method): coverage, and errors on the joints every method
    estimated (``*_common``) so the methods are compared on the same detections."""
    rows = []
    for k in ev.px:
        px, mm = ev.px[k], ev.mm[k]
        common = np.ones(len(next(iter(px.values()))), bool)
        for m in ev.methods:
            common &= np.isfinite(px[m])
        for m in ev.methods:
            e, d = px[m], mm[m]
            rows.append(
                {
                    "views": k,
                    "method": m,
                    "subsets": ev.subsets.get(k, 0),
                    "references": len(e),
                    "coverage": 100.0 * np.isfinite(e).mean() if len(e) else float("nan"),
                    "px_common": _stat(np.mean, e[common]),
                    "px_median_common": _stat(np.median, e[common]),
                    "mm_common": _stat(np.mean, d[common]),
                    "mm_median_common": _stat(np.median, d[common]),
                    "px_all": _stat(np.mean, e[np.isfinite(e)]),
                }
            )
    return rows


def _stat(fn, x: np.ndarray) -> float:
    return float(fn(x)) if len(x) else float("nan")
