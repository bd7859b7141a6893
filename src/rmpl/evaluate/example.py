"""The embedded example (``rmpl example``): every method with all 4 cameras and with 2.

The example is a 60-frame walk of a held-out motion-capture subject on an anny body,
rendered from 4 cameras and seen by MediaPipe BlazePose (``rmpl/examples/walk``). Each method
runs ``rmpl run``'s chain (:func:`rmpl.pipeline.runner.run_with_floor`) on all 4 cameras and
on every pair of them; errors are scored on COCO-17 against the example's ground truth.
:func:`verdict` says which method wins where, from whatever the numbers are.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rmpl.geometry.camera import Rig

__all__ = ["EXAMPLE", "METHODS", "Score", "example_inputs", "score_methods", "verdict"]

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "walk"
#: The methods compared: ``--method`` of ``rmpl run`` -> its label.
METHODS = {"rmpl": "RMPL", "robust": "robust triangulation", "triangulate": "triangulation (DLT)"}


@dataclass(frozen=True)
class Score:
    """One method on one camera set (a mean over subsets for "2 cameras").

    Attributes:
        mpjpe, kp_star: mm, over the joints the method estimated (COCO-17; KP*: the 12 limb
            joints). coverage: % of the ground truth's joints it estimated.
    """

    mpjpe: float
    kp_star: float
    coverage: float


def example_inputs():
    """The example's inputs (:class:`rmpl.pipeline.inputs.Inputs`) and ground truth
    (T, 17, 3) metres."""
    from rmpl.pipeline.inputs import InputSpec, load_inputs

    spec = InputSpec(calib=str(EXAMPLE / "calibration.toml"),
                     keypoints=[str(EXAMPLE / "keypoints.json")])  # fmt: skip
    inputs = load_inputs(spec)
    gt = np.load(EXAMPLE / "ground_truth.npz")["points"][:, 0, :17]  # (T, 17, 3)
    return inputs, gt


def _views(inputs, views: tuple[int, ...]):
    """The inputs of a subset of the cameras."""
    v = list(views)
    rig = Rig(tuple(inputs.rig[i] for i in v))
    return replace(inputs, rig=rig, keypoints=inputs.keypoints[:, v], scores=inputs.scores[:, v])


def _score(points: np.ndarray, gt: np.ndarray) -> Score:
    from rmpl.metrics import mpjpe
    from rmpl.skeleton import KP_STAR

    cov = 100 * np.isfinite(points).all(-1).mean()
    return Score(1000 * mpjpe(points, gt), 1000 * mpjpe(points, gt, KP_STAR), cov)


def _run(inputs, method: str, model: str):
    from rmpl.pipeline.runner import RunConfig, run_with_floor

    cfg = RunConfig(method=method, model=model)
    return run_with_floor(
        inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, cfg,
        joints=inputs.skeleton, progress=False,
    )  # fmt: skip


def score_methods(inputs, gt: np.ndarray, model: str, keep=None) -> dict[str, dict[str, Score]]:
    """Every method of :data:`METHODS` with all the cameras and, averaged, with every pair.

    Args:
        model: RMPL's ``--model``.
        keep: ``fn(poses, floor)`` given RMPL's answer with all the cameras (to write it).

    Returns:
        ``{"4 cameras": {method: Score}, "2 cameras": {method: Score}}`` (the first key
        names the example's camera count).
    """
    V = len(inputs.rig)
    out: dict[str, dict[str, Score]] = {f"{V} cameras": {}, "2 cameras": {}}
    pairs = list(itertools.combinations(range(V), 2))
    for method in METHODS:
        poses, floor = _run(inputs, method, model)
        if method == "rmpl" and keep is not None:
            keep(poses, floor)
        out[f"{V} cameras"][method] = _score(poses.points[:, 0, :17], gt)
        scores = [_score(_run(_views(inputs, p), method, model)[0].points[:, 0, :17], gt)
                  for p in pairs]  # fmt: skip
        out["2 cameras"][method] = Score(*np.mean([list(vars(s).values()) for s in scores], 0))
    return out


def verdict(scores: dict[str, dict[str, Score]]) -> str:
    """One line: which method has the lowest MPJPE with each camera set, and its coverage
    when it estimates fewer joints than another method."""
    parts = []
    for setting, by_method in scores.items():
        best = min(by_method, key=lambda m: by_method[m].mpjpe)
        s = by_method[best]
        most = max(v.coverage for v in by_method.values())
        note = (
            f", but it estimates {s.coverage:.0f}% of the joints" if s.coverage < most - 0.5 else ""
        )
        parts.append(f"with {setting} {METHODS[best]} ({s.mpjpe:.1f} mm{note})")
    return "lowest error: " + "; ".join(parts)
