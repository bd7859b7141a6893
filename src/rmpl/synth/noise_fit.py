"""Detector statistics of MHP shards, and the parametric noise model fitted to them.

``rmpl generate --stats DIR`` compares the detector's keypoints in the shards of ``DIR``
with the mesh's COCO-17 joints projected into the same views, and reports the per-joint
pixel error, the miss rate and how confidence tracks error. It then fits the parameters of
:class:`rmpl.synth.noise.NoiseConfig` (the fast source's detector model) to the same
statistics, so the fast source reproduces the real detector's noise. Every fitted value is
a simple robust statistic:

- ``joint_sigma[j]``: median over unoccluded joints ``j`` of |error| / person height,
  divided by 1.1774 (the median of a 2D Gaussian's radius is 1.1774 sigma);
- ``occluded_sigma``: the same median on self-occluded joints (capsule test of
  :func:`rmpl.synth.noise.occlusion_mask`) over the unoccluded one;
- ``sigma_spread``: standard deviation of the log of each view's median normalised error,
  minus (in quadrature) what the sampling of ~17 joints alone gives;
- ``outlier_rate``: joints further than 15% of the person height from their true place
  and not explained by a left/right swap;
- ``swap_rate`` / ``flip_rate``: left/right pairs whose detections fit the swapped truth
  better; a view with at least 6 of 8 limb and hip/shoulder pairs swapped is a flip;
- ``miss_view_rate``: views with no detection at all; ``occluded_drop``: occluded joints
  with score 0 in detected views; ``truncate_rate``: detected views with some in-image
  joint at score 0;
- ``conf_visible``, ``conf_occluded``, ``conf_slope``, ``conf_jitter``: least squares fit
  of score = base(occluded) - slope * error / (0.05 height) and its residual spread.

Not fitted (kept at their defaults): ``conf_gamma``, ``limb_radius``, ``torso_radius``.

Shape glossary: ``M`` meshes, ``V`` views, ``J`` joints (17).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17

__all__ = ["DetectorStats", "detector_stats", "fit_noise", "write_noise", "load_shards"]

log = logging.getLogger(__name__)

_RAYLEIGH_MEDIAN = float(np.sqrt(2 * np.log(2)))  # median radius of a unit 2D Gaussian
_OUTLIER = 0.15  # fraction of the person height
_SWAP_PAIRS = [
    (COCO17.index("left_" + n), COCO17.index("right_" + n))
    for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle", "eye", "ear")
]


def load_shards(root: str | Path, keys: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """Concatenate the arrays of every finished shard of an MHP directory.

    Raises:
        InputError: no shards in ``root``.
    """
    from rmpl.synth.shards import list_shards

    paths = list_shards(root)
    if not paths:
        raise InputError(root, None, "an MHP directory with shard_*.npz files", "none")
    parts: dict[str, list] = {}
    for p in paths:
        with np.load(p, allow_pickle=False) as z:
            for k in keys or [k for k in z.files if k != "stats"]:
                if k not in z.files:
                    raise InputError(p, k, "the array", "missing")
                parts.setdefault(k, []).append(z[k])
    return {k: np.concatenate(v) for k, v in parts.items()}


@dataclass
class DetectorStats:
    """What ``--stats`` measured (see the module docstring) and the fitted noise."""

    root: str
    meshes: int
    views: int
    height_px: float
    view_miss_rate: float
    joint_table: list[dict]
    calibration: list[dict]
    overall: dict
    by_height: list[dict] = field(default_factory=list)
    noise: dict = field(default_factory=dict)

    def markdown(self) -> str:
        lines = [
            f"MHP detector statistics: {self.root} ({self.meshes} meshes, {self.views} views; "
            f"median person height {self.height_px:.0f} px; views with no detection "
            f"{100 * self.view_miss_rate:.1f}%)",
            "",
            "| joint | mean px | median px | p90 px | miss % | mean score |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for r in self.joint_table:
            lines.append(
                f"| {r['joint']} | {r['mean_px']:.1f} | {r['median_px']:.1f} | "
                f"{r['p90_px']:.1f} | {r['miss_pct']:.1f} | {r['mean_score']:.2f} |"
            )
        o = self.overall
        lines.append(
            f"| **all** | **{o['mean_px']:.1f}** | **{o['median_px']:.1f}** | "
            f"**{o['p90_px']:.1f}** | **{o['miss_pct']:.1f}** | **{o['mean_score']:.2f}** |"
        )
        lines += [
            "",
            "Confidence vs error (detected joints inside the image):",
            "",
            "| score | joints | median px | mean px | median error / height |",
            "| --- | --- | --- | --- | --- |",
        ]
        for r in self.calibration:
            lines.append(
                f"| {r['bin']} | {r['count']} | {r['median_px']:.1f} | {r['mean_px']:.1f} | "
                f"{r['median_rel']:.3f} |"
            )
        lines += [
            "",
            "Views with no detection by person height (extent of the projected joints):",
            "",
            "| height px | views | no detection % |",
            "| --- | --- | --- |",
        ]
        for r in self.by_height:
            lines.append(f"| {r['bin']} | {r['views']} | {r['miss_pct']:.1f} |")
        lines += ["", "Fitted NoiseConfig:", "", "| parameter | value |", "| --- | --- |"]
        for k, v in self.noise.items():
            text = ", ".join(f"{x:.4f}" for x in v) if isinstance(v, list) else f"{v:.4f}"
            lines.append(f"| {k} | {text} |")
        return "\n".join(lines)


@dataclass(frozen=True, eq=False)
class _Detections:
    """The detector's keypoints beside the projected truth, M meshes x V views x J joints.

    err and rel are pixel and person-relative errors; valid marks joints that are detected,
    inside the image and not under a pasted occluder (comparable with the truth).
    """

    det: np.ndarray  # (M, V, J, 2) detected pixels
    proj: np.ndarray  # (M, V, J, 2) projected true joints, pixels
    scores: np.ndarray  # (M, V, J)
    inside: np.ndarray  # (M, V, J) the true joint lies in the image
    pasted: np.ndarray  # (M, V, J) under a pasted black square
    occ: np.ndarray  # (M, V, J) occluded by the body itself
    seen: np.ndarray  # (M, V) the detector found the person
    height: np.ndarray  # (M, V) person size, pixels
    err: np.ndarray  # (M, V, J) pixels, NaN where missed
    rel: np.ndarray  # (M, V, J) err / height
    valid: np.ndarray  # (M, V, J)


def detector_stats(root: str | Path) -> DetectorStats:
    """Error, misses and calibration of the detector in the shards of ``root``, plus the
    fitted :class:`~rmpl.synth.noise.NoiseConfig` values (``.noise``)."""
    d = _load_detections(root)
    M, V, _ = d.scores.shape
    noise = _fit_noise(d)
    return DetectorStats(
        root=str(root),
        by_height=_miss_by_height(d),
        meshes=M,
        views=M * V,
        height_px=float(np.median(d.height)),
        view_miss_rate=float(1 - d.seen.mean()),
        joint_table=_joint_table(d),
        calibration=_score_calibration(d),
        overall=_overall(d),
        noise=noise,
    )


def _load_detections(root: str | Path) -> _Detections:
    from rmpl.synth.noise import NoiseConfig, occlusion_mask

    keys = ("joints3d", "keypoints", "scores", "projected", "R", "t", "size", "occluded")
    d = load_shards(root, keys)
    det, scores, proj = d["keypoints"].astype(float), d["scores"], d["projected"].astype(float)
    size = d["size"][..., None, :].astype(float)  # (M, V, 1, 2)
    inside = np.all((proj >= -0.5) & (proj < size - 0.5), axis=-1)  # (M, V, J) true joint
    lo, hi = proj.min(axis=2), proj.max(axis=2)
    height = np.max(hi - lo, axis=-1)  # (M, V) person size in pixels
    seen = scores.max(axis=-1) > 0  # (M, V) the detector found the person
    err = np.linalg.norm(det - proj, axis=-1)  # (M, V, J), NaN where missed
    centers = -np.einsum("mvji,mvj->mvi", d["R"], d["t"])
    cfg0 = NoiseConfig()
    occ = occlusion_mask(d["joints3d"].astype(float), centers, cfg0.limb_radius, cfg0.torso_radius)
    pasted = d["occluded"]  # black squares: not part of the detector's own noise
    valid = inside & seen[..., None] & (scores > 0) & ~pasted  # detected, comparable
    return _Detections(
        det, proj, scores, inside, pasted, occ, seen, height, err, err / height[..., None], valid
    )


def _swaps(d: _Detections) -> tuple[np.ndarray, float, float]:
    """Joints caught in a left/right swap (M, V, J), the pair swap rate and the whole-body
    flip rate."""
    M, V, _ = d.scores.shape
    swapped = np.zeros((M, V, len(_SWAP_PAIRS)), bool)
    for k, (a, b) in enumerate(_SWAP_PAIRS):
        straight = d.err[..., a] + d.err[..., b]
        cross = np.linalg.norm(d.det[..., a, :] - d.proj[..., b, :], axis=-1) + np.linalg.norm(
            d.det[..., b, :] - d.proj[..., a, :], axis=-1
        )
        apart = np.linalg.norm(d.proj[..., a, :] - d.proj[..., b, :], axis=-1) > 0.05 * d.height
        ok = d.valid[..., a] & d.valid[..., b] & apart
        swapped[..., k] = ok & (cross < 0.5 * straight)
    pair_ok = np.stack([d.valid[..., a] & d.valid[..., b] for a, b in _SWAP_PAIRS], -1)
    flip = swapped.sum(-1) >= 6  # (M, V)
    n_pair = pair_ok[~flip].sum()
    swap_rate = float(swapped[~flip].sum() / max(n_pair, 1))
    flip_rate = float(flip[d.seen].mean()) if d.seen.any() else 0.0
    in_swap = np.zeros_like(d.valid)
    for k, (a, b) in enumerate(_SWAP_PAIRS):
        in_swap[..., a] |= swapped[..., k] | flip
        in_swap[..., b] |= swapped[..., k] | flip
    return in_swap, swap_rate, flip_rate


def _fit_noise(d: _Detections) -> dict:
    """The NoiseConfig values that reproduce the detector's errors, misses and scores."""
    from rmpl.synth.noise import NoiseConfig

    cfg0 = NoiseConfig()
    in_swap, swap_rate, flip_rate = _swaps(d)
    clean = d.valid & ~in_swap
    outlier = clean & (d.rel > _OUTLIER)
    inlier = clean & ~outlier
    sigma, occ_ratio, spread = _error_scales(d, inlier, cfg0)
    conf_visible, conf_occluded, slope, resid = _fit_confidence(d, inlier, cfg0)
    in_seen = d.inside & d.seen[..., None] & ~d.pasted
    truncated = (in_seen & (d.scores == 0)).any(-1) & d.seen
    occ_seen = in_seen & d.occ
    any_inside = d.inside.any(-1)
    occluded_drop = float((d.scores[occ_seen] == 0).mean()) if occ_seen.any() else 0.0
    noise = {
        "joint_sigma": [round(float(s), 5) for s in sigma],
        "sigma_spread": round(spread, 4),
        "occluded_sigma": round(max(occ_ratio, 1.0), 4),
        "occluded_drop": round(occluded_drop, 4),
        "conf_visible": round(float(np.clip(conf_visible, 0, 1)), 4),
        "conf_occluded": round(float(np.clip(conf_occluded, 0, 1)), 4),
        "conf_slope": round(max(slope, 0.0), 4),
        "conf_jitter": round(resid, 4),
        "outlier_rate": round(float(outlier.sum() / max(clean.sum(), 1)), 4),
        "swap_rate": round(swap_rate, 4),
        "flip_rate": round(flip_rate, 4),
        "miss_view_rate": round(float((~d.seen & any_inside).sum() / max(any_inside.sum(), 1)), 4),
        "truncate_rate": round(float(truncated.sum() / max(d.seen.sum(), 1)), 4),
    }
    NoiseConfig.from_dict(noise)  # the trainer must accept it
    return noise


def _error_scales(d: _Detections, inlier: np.ndarray, cfg0) -> tuple[np.ndarray, float, float]:
    """Per-joint sigma (J,), the occluded/visible error ratio and the per-view spread."""
    J = d.scores.shape[-1]
    occ = d.occ
    # Per-joint sigma from unoccluded inliers (the outliers are their own parameter).
    sigma = np.zeros(J)
    for j in range(J):
        r = d.rel[..., j][inlier[..., j] & ~occ[..., j]]
        sigma[j] = np.median(r) / _RAYLEIGH_MEDIAN if r.size else cfg0.joint_sigma[j]
    norm = d.rel / sigma  # error in units of the joint's sigma
    occ_ratio = (
        float(np.median(norm[inlier & occ]) / np.median(norm[inlier & ~occ]))
        if (inlier & occ).any() and (inlier & ~occ).any()
        else cfg0.occluded_sigma
    )
    # Per-view quality spread, minus what sampling ~n Rayleigh draws gives alone.
    view_med, counts = [], []
    for m, v in zip(*np.nonzero(d.seen), strict=True):
        sel = inlier[m, v] & ~occ[m, v]
        if sel.sum() >= 5:
            view_med.append(np.median(norm[m, v][sel]))
            counts.append(int(sel.sum()))
    spread = cfg0.sigma_spread
    if len(view_med) >= 10:
        observed = np.var(np.log(view_med))
        rng = np.random.default_rng(0)
        sim = [np.median(np.hypot(*rng.standard_normal((2, c)))) for c in counts]
        spread = float(np.sqrt(max(observed - np.var(np.log(sim)), 0.0)))
    return sigma, occ_ratio, spread


def _fit_confidence(d: _Detections, inlier: np.ndarray, cfg0) -> tuple[float, ...]:
    """Fit score = base(occluded) - slope * err / (0.05 h) + jitter: (visible base,
    occluded base, slope, jitter)."""
    x = d.rel[inlier] / 0.05
    o = d.occ[inlier].astype(float)
    y = d.scores[inlier].astype(float)
    A = np.stack([1 - o, o, -x], -1)
    if len(y) < 10:
        return cfg0.conf_visible, cfg0.conf_occluded, cfg0.conf_slope, cfg0.conf_jitter
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = float(np.std(y - A @ coef))
    conf_visible, conf_occluded, slope = (float(c) for c in coef)
    return conf_visible, conf_occluded, slope, resid


def _joint_table(d: _Detections) -> list[dict]:
    table = []
    joint_in = d.inside & ~d.pasted
    for j, name in enumerate(COCO17.joints):
        e = d.err[..., j][d.valid[..., j]]
        table.append(
            {
                "joint": name,
                "mean_px": float(e.mean()) if e.size else float("nan"),
                "median_px": float(np.median(e)) if e.size else float("nan"),
                "p90_px": float(np.percentile(e, 90)) if e.size else float("nan"),
                "miss_pct": float(100 * (d.scores[..., j][joint_in[..., j]] == 0).mean()),
                "mean_score": float(d.scores[..., j][d.valid[..., j]].mean()) if e.size else 0.0,
            }
        )
    return table


def _overall(d: _Detections) -> dict:
    e = d.err[d.valid]
    return {
        "mean_px": float(e.mean()),
        "median_px": float(np.median(e)),
        "p90_px": float(np.percentile(e, 90)),
        "miss_pct": float(100 * (d.scores[d.inside & ~d.pasted] == 0).mean()),
        "mean_score": float(d.scores[d.valid].mean()),
    }


def _score_calibration(d: _Detections) -> list[dict]:
    """Error per score bin: does a higher score mean a smaller error?"""
    calibration = []
    edges = [0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 1.0001]
    valid, scores = d.valid, d.scores
    for lo_, hi_ in zip(edges[:-1], edges[1:], strict=True):
        sel = valid & (scores > lo_) & (scores <= hi_) if lo_ > 0 else valid & (scores <= hi_)
        if not sel.any():
            continue
        calibration.append(
            {
                "bin": f"{lo_:.1f}-{min(hi_, 1.0):.1f}",
                "count": int(sel.sum()),
                "median_px": float(np.median(d.err[sel])),
                "mean_px": float(d.err[sel].mean()),
                "median_rel": float(np.median(d.rel[sel])),
            }
        )
    return calibration


def _miss_by_height(d: _Detections) -> list[dict]:
    """Missed views per bin of person height in pixels."""
    by_height = []
    h_edges = [0, 100, 200, 300, 400, 600, np.inf]
    for a, b in zip(h_edges[:-1], h_edges[1:], strict=True):
        sel = (d.height >= a) & (d.height < b) & d.inside.all(-1)
        if sel.any():
            label = f"{a}-{b}" if np.isfinite(b) else f">= {a}"
            by_height.append(
                {
                    "bin": label,
                    "views": int(sel.sum()),
                    "miss_pct": float(100 * (~d.seen[sel]).mean()),
                }
            )
    return by_height


def fit_noise(root: str | Path) -> dict:
    """Only the fitted :class:`~rmpl.synth.noise.NoiseConfig` values of ``root``'s shards."""
    return detector_stats(root).noise


def write_noise(stats: DetectorStats, path: str | Path) -> Path:
    """Write the fitted noise as a TOML ``[noise]`` table (paste it into a train config) and
    beside it ``.json`` (a flat dict for ``NoiseConfig.from_dict``), atomically."""
    path = Path(path)

    def value(v) -> str:
        return "[" + ", ".join(repr(float(x)) for x in v) + "]" if isinstance(v, list) else repr(v)

    lines = [
        f"# Detector noise fitted by `rmpl generate --stats {stats.root}`",
        f"# ({stats.meshes} meshes, {stats.views} views). Use as a training config's [noise].",
        "[noise]",
        *(f"{k} = {value(v)}" for k, v in stats.noise.items()),
    ]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    with atomic_path(path.with_suffix(".json")) as tmp:
        tmp.write_text(json.dumps(stats.noise, indent=2))
    return path
