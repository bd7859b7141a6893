"""Compare 3D methods on identical 2D input: triangulation, robust triangulation, RMPL.

A method maps per-person multi-view keypoints ``(N, V, J, 2)`` + scores ``(N, V, J)`` and a
rig to joints ``(N, J, 3)``. Every method of one run sees the same associated 2D people.

Shelf protocol (multi-person, real OpenPose detections): per view, candidates are grouped
into people with their part affinities; people are associated across the views in use by
ray distance, re-run for every view subset; estimates are matched to the ground-truth
actors by Hungarian assignment on the mean limb-joint distance (0.5 m gate). An unmatched
actor counts as missing: every PCP part wrong, and outside the MPJPE coverage.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rmpl.geometry import Rig, triangulate, triangulate_robust
from rmpl.metrics import mpjpe, pcp_parts
from rmpl.skeleton import COCO17, SHELF14, SHELF_LIMB_JOINTS, convert

__all__ = ["METHODS", "make_method", "ShelfEvaluation", "evaluate_shelf", "shelf_markdown"]

log = logging.getLogger(__name__)

Method = Callable[[np.ndarray, np.ndarray, Rig], np.ndarray]

MATCH_GATE = 0.5  # metres, mean limb-joint distance
ACTORS = (0, 1, 2)  # gt ids 0..2 = the customary actors 1-3
MID_HIP = SHELF14.num_joints  # index of the mid-hip appended after the Shelf-14 joints
#: The customary ten Shelf PCP parts: head, arms, legs (Shelf-14 bones) and the torso.
PCP_PARTS = SHELF14.bones[:9] + ((SHELF14.index("neck"), MID_HIP),)


def _rmpl(spec: str) -> Method:
    from rmpl.inference import Lifter

    lifter = Lifter.from_pretrained(spec or "default")
    return lambda kp, sc, rig: lifter.lift(kp, sc, rig).points


METHODS: dict[str, Callable[[str], Method]] = {
    "triangulate": lambda _: lambda kp, sc, rig: triangulate(kp, sc, rig).points,
    "robust": lambda _: (
        lambda kp, sc, rig: triangulate_robust(kp, sc, rig, swap_pairs=COCO17.flip_pairs).points
    ),
    "rmpl": _rmpl,
}


def make_method(spec: str) -> Method:
    """A method from ``name`` or ``name:argument`` (e.g. ``rmpl:runs/x``)."""
    name, _, arg = spec.partition(":")
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose from {', '.join(METHODS)}")
    return METHODS[name](arg)


def shelf15(coco: np.ndarray) -> np.ndarray:
    """COCO-17 joints (*, 17, 3) to Shelf-14 plus the mid-hip: shape (*, 15, 3)."""
    shelf = convert(coco, "coco17", "shelf14")
    hips = shelf[..., [SHELF14.index("right_hip"), SHELF14.index("left_hip")], :]
    return np.concatenate([shelf, hips.mean(-2, keepdims=True)], axis=-2)


@dataclass
class ShelfEvaluation:
    """Results keyed by (view setting, method): metric name -> value."""

    results: dict[tuple[str, str], dict[str, float]] = field(default_factory=dict)
    frames: tuple[int, int] = (0, 0)
    present_actors: tuple[int, ...] = ()


def _scores(pred: np.ndarray, gt: np.ndarray, common: np.ndarray) -> dict[str, float]:
    limbs = list(SHELF_LIMB_JOINTS)
    present = np.isfinite(gt[..., limbs, :]).all(-1)
    covered = present & np.isfinite(pred[..., limbs, :]).all(-1)
    e = np.linalg.norm(pred[..., limbs, :] - gt[..., limbs, :], axis=-1)
    out = {
        "mpjpe": 1000 * mpjpe(pred, gt, joints=limbs),
        "coverage": 100 * covered.sum() / max(present.sum(), 1),
        "mpjpe_common": 1000 * float(np.mean(e[common])) if common.any() else float("nan"),
    }
    for a in ACTORS:
        frames = np.isfinite(gt[:, a]).all((-1, -2))
        parts = pcp_parts(pred[frames, a], gt[frames, a], PCP_PARTS)
        out[f"pcp{a}"] = 100 * parts.mean() if frames.any() else float("nan")
    return out


def evaluate_shelf(
    data, methods: dict[str, Method], view_sets: dict[str, list[tuple[int, ...]]], progress=True
) -> ShelfEvaluation:
    """Run every method on every view subset of a :class:`rmpl.data.shelf.ShelfData`.

    ``mpjpe_common`` is measured on the limb joints that *every* method estimated for the
    same subset, so methods are compared on identical joints.
    """
    from tqdm import tqdm

    from rmpl.association import (
        AssociationConfig,
        GroupingConfig,
        associate,
        group_people,
        match_poses,
    )

    grouping, assoc = GroupingConfig(), AssociationConfig()
    people = [
        [group_people(c, grouping) for c in frame]
        for frame in tqdm(data.detections, desc="grouping", disable=not progress)
    ]
    total = len(data) * sum(len(s) for s in view_sets.values())
    ev = ShelfEvaluation(frames=(int(data.frames[0]), int(data.frames[-1])))
    ev.present_actors = tuple(a for a in ACTORS if np.isfinite(data.gt[:, a]).all((-1, -2)).any())
    limbs = list(SHELF_LIMB_JOINTS)
    with tqdm(total=total, desc="evaluate", disable=not progress) as bar:
        for label, subsets in view_sets.items():
            per_method: dict[str, list[dict]] = {m: [] for m in methods}
            for views in subsets:
                rig = data.rig[list(views)]
                preds = {m: np.full(data.gt.shape, np.nan) for m in methods}
                for t, frame in enumerate(people):
                    found = associate(
                        [frame[v][0] for v in views], [frame[v][1] for v in views], rig, assoc
                    )
                    bar.update()
                    if len(found) == 0:
                        continue
                    for name, method in methods.items():
                        pred = shelf15(method(found.keypoints, found.scores, rig))
                        match = match_poses(pred, data.gt[t], MATCH_GATE, SHELF_LIMB_JOINTS)
                        preds[name][t, match >= 0] = pred[match[match >= 0]]
                gt_ok = np.isfinite(data.gt[..., limbs, :]).all(-1)
                common = gt_ok & np.logical_and.reduce(
                    [np.isfinite(p[..., limbs, :]).all(-1) for p in preds.values()]
                )
                for name in methods:
                    per_method[name].append(_scores(preds[name], data.gt, common))
            for name, rows in per_method.items():
                ev.results[(label, name)] = {k: _mean([r[k] for r in rows]) for k in rows[0]}
    return ev


def _mean(values: list[float]) -> float:
    """Mean of the finite values; NaN when there are none (e.g. an actor absent)."""
    v = np.asarray(values, float)
    return float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else float("nan")


def view_subsets(num_views: int, spec: str) -> dict[str, list[tuple[int, ...]]]:
    """View subsets from a spec like ``all,pairs`` or ``1,2,3,4,5`` (k = every k-subset)."""
    out = {}
    for item in spec.split(","):
        item = item.strip()
        if item == "all":
            out[f"{num_views} views"] = [tuple(range(num_views))]
        elif item == "pairs":
            item = "2"
        if item.isdigit():
            k = int(item)
            if not 1 <= k <= num_views:
                raise ValueError(f"--views: {k} views requested but the dataset has {num_views}")
            subs = list(itertools.combinations(range(num_views), k))
            out[f"{k} views" + (f" (mean of {len(subs)})" if len(subs) > 1 else "")] = subs
        elif item != "all":
            raise ValueError(f"--views: expected 'all', 'pairs' or view counts, got {item!r}")
    return out


def _fmt(x: float) -> str:
    return "—" if not np.isfinite(x) else f"{x:.1f}"


def shelf_markdown(ev: ShelfEvaluation) -> str:
    """Results as a Markdown table."""
    lines = [
        "| views | method | MPJPE (mm) | coverage (%) | MPJPE common joints (mm) "
        "| PCP actor 1 | PCP actor 2 | PCP actor 3 | PCP mean |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for (label, method), r in ev.results.items():
        pcps = [r[f"pcp{a}"] for a in ACTORS]
        mean = np.mean([r[f"pcp{a}"] for a in ev.present_actors]) if ev.present_actors else np.nan
        cells = [
            _fmt(r["mpjpe"]),
            _fmt(r["coverage"]),
            _fmt(r["mpjpe_common"]),
            *map(_fmt, pcps),
            _fmt(mean),
        ]
        lines.append(f"| {label} | {method} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
