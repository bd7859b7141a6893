"""Scores of 3D estimates against ground truth: MPJPE, KP*, PA-MPJPE, PCK, coverage, PCP.

Every function takes predictions and ground truth as COCO-17 arrays ``(n, 17, 3)`` in
metres (NaN: not estimated / not annotated) and returns millimetres or percent; PCP with
the "own" conversion takes HALPE-26 predictions ``(n, 26, 3)``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from rmpl.metrics import pcp_parts, procrustes_align
from rmpl.skeleton import COCO17, HALPE26, KP_STAR, SHELF14, convert

if TYPE_CHECKING:
    from rmpl.evaluate.harness import Evaluation

__all__ = [
    "PCP_ACTORS",
    "PCP_CONVERSIONS",
    "PCP_PARTS",
    "PCP_PART_NAMES",
    "PCP_UP",
    "common_mask",
    "condition_label",
    "joint_errors_mm",
    "mean_finite",
    "pcp_actors",
    "pcp_by_actor",
    "pcp_parts_by_actor",
    "pose_metrics",
    "root_metrics",
    "shelf14_published",
    "shelf15",
    "shelf15_own",
    "shelf15_published",
]

MID_HIP = SHELF14.num_joints  # index of the mid-hip appended after the Shelf-14 joints
#: The customary ten Shelf/Campus PCP parts: head, arms, legs (Shelf-14 bones) and torso.
PCP_PARTS = SHELF14.bones[:9] + ((SHELF14.index("neck"), MID_HIP),)
#: Names of the :data:`PCP_PARTS`, in their order.
PCP_PART_NAMES = (
    "head",
    "right_upper_arm",
    "right_lower_arm",
    "left_upper_arm",
    "left_lower_arm",
    "right_upper_leg",
    "right_lower_leg",
    "left_upper_leg",
    "left_lower_leg",
    "torso",
)
#: PCP is reported for the customary actors 1-3 (Shelf's actor 4 is left out).
PCP_ACTORS = 3
#: World up direction of Shelf and Campus, the datasets PCP is reported on (z up).
PCP_UP = (0.0, 0.0, 1.0)
#: COCO-17 indices of the Shelf-14 limb joints (Shelf 0-11), by name.
_COCO_LIMBS = [COCO17.index(name) for name in SHELF14.joints[:12]]


def shelf15(coco: np.ndarray) -> np.ndarray:
    """COCO-17 joints (*, 17, 3) to Shelf-14 plus the mid-hip: shape (*, 15, 3)."""
    shelf = convert(coco, "coco17", "shelf14")
    return _with_mid_hip(shelf)


def shelf14_published(
    coco: np.ndarray, up: Sequence[float] = PCP_UP, ears: bool = True
) -> np.ndarray:
    """COCO-17 joints to Shelf-14 with the conversion of the published evaluations.

    This is ``coco2shelf3D`` of the mvpose and VoxelPose evaluation code, which the Shelf
    and Campus PCP figures of the literature use. The limbs are copied by name. With
    ``ms`` the shoulder midpoint, ``n`` the nose and ``d = n - ms``, mvpose puts the head
    top at ``ms + 0.75 d`` plus another ``0.75 d`` along the up axis (``d * [0.75, 0.75,
    1.5]`` when z is up) and the neck (bottom of the head) at ``ms + 0.5 d``. VoxelPose
    (``ears=True``) then blends each with an ear-based point: with ``ec`` the ear midpoint,
    ``hb = (ms + ec) / 2`` and ``ht = 2 ec - hb``, the head top becomes ``0.75 top + 0.25
    ht`` and the neck ``0.75 neck + 0.25 hb``.

    Args:
        coco: COCO-17 joints, shape (*, 17, 3), metres; NaN = missing (a derived joint
            is NaN when one of its sources is).
        up: the world up direction, a 3-vector (Shelf and Campus: z up).
        ears: blend with the ear-based points (VoxelPose); False gives mvpose's points.

    Returns:
        Shelf-14 joints, shape (*, 14, 3).

    >>> import numpy as np
    >>> x = np.zeros((17, 3))
    >>> x[[5, 6]] = [[0.2, 0.0, 1.4], [-0.2, 0.0, 1.4]]  # shoulders
    >>> x[0] = [0.0, 0.1, 1.6]  # nose
    >>> x[[3, 4]] = [[0.08, 0.0, 1.6], [-0.08, 0.0, 1.6]]  # ears
    >>> shelf14_published(x)[-2:].round(5).tolist()  # neck, head top
    [[0.0, 0.0375, 1.5], [0.0, 0.05625, 1.7]]
    """
    coco = np.asarray(coco, float)
    if coco.shape[-2:] != (COCO17.num_joints, 3):
        raise ValueError(f"coco must have shape (*, 17, 3), got {coco.shape}")
    u = np.asarray(up, float)
    if u.shape != (3,) or not np.linalg.norm(u) > 0:
        raise ValueError(f"up must be a non-zero 3-vector, got {u.tolist()}")
    u = u / np.linalg.norm(u)
    ms = coco[..., [COCO17.index("left_shoulder"), COCO17.index("right_shoulder")], :].mean(-2)
    d = coco[..., COCO17.index("nose"), :] - ms  # (*, 3)
    vertical = (d @ u)[..., None] * u  # (*, 3) the up component of d
    top = ms + 0.75 * d + 0.75 * vertical  # horizontal x 0.75, vertical x 1.5
    bottom = ms + 0.5 * d
    if ears:
        ec = coco[..., [COCO17.index("left_ear"), COCO17.index("right_ear")], :].mean(-2)
        hb = (ms + ec) / 2
        top = 0.75 * top + 0.25 * (2 * ec - hb)
        bottom = 0.75 * bottom + 0.25 * hb
    # (*, 12, 3) limbs + neck + head top, in Shelf-14 order
    return np.concatenate([coco[..., _COCO_LIMBS, :], bottom[..., None, :], top[..., None, :]], -2)


def shelf15_published(coco: np.ndarray) -> np.ndarray:
    """COCO-17 joints (*, 17, 3) to Shelf-14 (published conversion, z up) + mid-hip: (*, 15, 3)."""
    return _with_mid_hip(shelf14_published(coco))


def shelf15_own(halpe: np.ndarray) -> np.ndarray:
    """HALPE-26 joints (*, 26, 3) to Shelf-14 + mid-hip (*, 15, 3) with the model's own
    neck and head top (:func:`rmpl.skeleton.convert`, halpe26 -> shelf14); the mid-hip is
    the mean of the hips, as for the ground truth.

    >>> x = np.zeros((26, 3))
    >>> x[HALPE26.index("head_top")], x[HALPE26.index("neck")] = [0, 0, 1.8], [0, 0, 1.5]
    >>> shelf15_own(x)[[12, 13], 2].tolist()  # neck, head top
    [1.5, 1.8]
    """
    halpe = np.asarray(halpe, float)
    if halpe.shape[-2:] != (HALPE26.num_joints, 3):
        raise ValueError(f"halpe must have shape (*, 26, 3), got {halpe.shape}")
    return _with_mid_hip(convert(halpe, HALPE26, SHELF14))


#: How the predicted joints become Shelf-14 + mid-hip for PCP: from COCO-17, "derived" (the
#: neck and head top of :func:`rmpl.skeleton.convert`) or "published" (the literature's);
#: from HALPE-26, "own" (the model's own neck and head top).
PCP_CONVERSIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "derived": shelf15,
    "published": shelf15_published,
    "own": shelf15_own,
}


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


def root_metrics(pred: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """Where a pose stands and how big it is: the questions one view leaves open.

    Args:
        pred: (n, 17, 3) COCO-17, metres; NaN = not estimated.
        gt: (n, 17, 3), metres; NaN = not annotated.

    Returns:
        ``root``: mean distance (mm) between the estimated and true pelvis (the midpoint of
        the hips) over poses where both hips are estimated and annotated; ``height_ratio``:
        the median over poses of estimated / true stature proxy
        (:func:`rmpl.pipeline.monocular.stature_proxy`: (shin + thigh + trunk) / 0.779,
        bone lengths, so posture does not change it), over poses where both are finite.
        NaN when no pose qualifies.

    >>> g = np.zeros((1, 17, 3))
    >>> g[0, [15, 16], 2], g[0, [13, 14], 2], g[0, [11, 12], 2], g[0, [5, 6], 2] = 0, .4, .8, 1.3
    >>> p = g * 1.1 + [0.3, 0.0, 0.0]  # 10% taller: the pelvis also rises 0.08 m
    >>> {k: round(v, 3) for k, v in root_metrics(p, g).items()}  # root: hypot(0.3, 0.08)
    {'root': 310.483, 'height_ratio': 1.1}
    """
    from rmpl.pipeline.monocular import stature_proxy

    hips = [COCO17.index("left_hip"), COCO17.index("right_hip")]
    with np.errstate(invalid="ignore"):
        e = np.linalg.norm(pred[:, hips].mean(1) - gt[:, hips].mean(1), axis=-1)
        ratio = stature_proxy(pred) / stature_proxy(gt)
    e, ratio = e[np.isfinite(e)], ratio[np.isfinite(ratio)]
    return {
        "root": 1000 * float(e.mean()) if e.size else np.nan,
        "height_ratio": float(np.median(ratio)) if ratio.size else np.nan,
    }


def pcp_by_actor(
    pred: np.ndarray, native: np.ndarray, person: np.ndarray, conversion: str = "derived"
) -> dict[str, float]:
    """PCP (%) per actor label over poses, Shelf-14 parts + torso (to the mid-hip).

    Args:
        pred: (n, 17, 3) COCO-17 estimates, metres; (n, 26, 3) HALPE-26 for "own".
        native: (n, 14, 3) Shelf-14 ground truth, metres.
        person: (n,) actor label per pose.
        conversion: a key of :data:`PCP_CONVERSIONS` (the predicted neck and head top).
    """
    convert_pred = PCP_CONVERSIONS[conversion]
    parts = pcp_parts(convert_pred(pred), _with_mid_hip(native), PCP_PARTS)  # (n, 10)
    out = {}
    for a in np.unique(person):
        sel = person == a
        out[str(a)] = 100 * float(parts[sel].mean()) if sel.any() else np.nan
    return out


def pcp_parts_by_actor(
    pred: np.ndarray, native: np.ndarray, person: np.ndarray, conversion: str = "derived"
) -> dict[str, dict[str, float]]:
    """PCP (%) of each part per actor label: actor -> {part name: %} (:data:`PCP_PART_NAMES`).

    Args: as :func:`pcp_by_actor`.
    """
    convert_pred = PCP_CONVERSIONS[conversion]
    parts = pcp_parts(convert_pred(pred), _with_mid_hip(native), PCP_PARTS)  # (n, 10)
    out = {}
    for a in np.unique(person):
        share = 100 * parts[person == a].mean(0)  # (10,)
        out[str(a)] = dict(zip(PCP_PART_NAMES, share.tolist(), strict=True))
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
