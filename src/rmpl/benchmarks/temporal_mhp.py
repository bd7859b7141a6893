"""Per-frame and temporal methods on held-out MHP sequences (rendered, real detector).

Usage: python -m rmpl.benchmarks.temporal_mhp DIR [--views 2,3,5] [--subsets all|N] [--seed 0]
       [--methods NAME,...] [--model default] [--temporal temporal] [--csv FILE]

DIR is an MHP sequence set, e.g. the held-out CMU subject 03 set of
``configs/mhp_seq_heldout.toml`` (``rmpl generate``, ``sequence_frames = 48``, 5 views):
every frame of a sequence rendered and detected by MediaPipe BlazePose, one body and one
rig per sequence. Identity is known (one person per sequence), so no association or
tracking runs. For each view count, every subset of the set's views (or ``--subsets N``
drawn once with ``--seed``) is scored; each (sequence, subset) is one track.

Methods (:data:`METHODS`: name -> function of one :class:`Track`; add entries there):

- ``triangulate+filter``, ``robust+filter``: weighted DLT / robust triangulation per frame
  with ``rmpl run``'s settings (RunConfig defaults), then ``rmpl run``'s Hampel, gap filling
  and Butterworth (:func:`rmpl.pipeline.runner.smooth`) at the sequence's rate, cut-off
  min(6 Hz, 0.45 fps), as ``rmpl.benchmarks.temporal_synthetic`` does;
- ``rmpl+filter``: the shipped per-frame lifter (``--model``) per frame, then the same;
- ``rmpl:temporal``: the temporal lifter (``--temporal``) over the whole track.

Printed per view count: KP* MPJPE (mm, the 12 limb joints) on the "common" joints (those
every method estimated, in frames with any 2D), on the "hard" joints (fewer than two views
see the joint in that frame; each method over those it estimated, with its coverage), and
on those of them in frames where at least two views see the person (any joint), and
on every joint it estimated (with coverage); the temporal model's ratio to
``robust+filter`` on the common joints (issue 14's target: at most 0.85 with 2 views), and
the share of its errors inside its predicted 50% / 90% radii (``TrackResult.radius``).
The learned methods are given the world's up axis (+z), which a calibrated rig states.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rmpl.benchmarks._common import run_main, set_rig
from rmpl.data.mhp import load_mhp_sequences
from rmpl.geometry.camera import Rig
from rmpl.pipeline.runner import RunConfig, _estimator, smooth
from rmpl.skeleton import KP_STAR

UP = np.array([0.0, 0.0, 1.0])  # the MHP world is z up


@dataclass
class Track:
    """One sequence seen by one view subset.

    Attributes:
        keypoints: (T, V, J, 2) pixels, NaN = missing. scores: (T, V, J), 0 = missing.
        rig: the V cameras. times: (T,) seconds. fps: frames per second.
        target: (T, J, 3) ground truth, metres.
    """

    keypoints: np.ndarray
    scores: np.ndarray
    rig: Rig
    times: np.ndarray
    fps: float
    target: np.ndarray


@dataclass
class Estimate:
    """A method's answer for one track: points (T, J, 3) metres, NaN = not estimated; for
    methods that predict it, the 50% and 90% error radii (T, J) metres."""

    points: np.ndarray
    radius50: np.ndarray | None = None
    radius90: np.ndarray | None = None


Method = Callable[[Track], Estimate]


def filtered(method: str, **run: object) -> Method:
    """A per-frame estimator of ``rmpl run`` (``method``: triangulate, robust, rmpl), then its
    Hampel / gap filling / Butterworth at the track's rate (cut-off min(6, 0.45 fps))."""
    estimate = _estimator(RunConfig(method=method, **run))

    def fn(track: Track) -> Estimate:
        points, _ = estimate(track.keypoints, track.scores, track.rig)  # (T, J, 3)
        cfg = RunConfig(method=method, cutoff=min(6.0, 0.45 * track.fps), **run)
        return Estimate(smooth(points[:, None], track.fps, cfg)[0][:, 0])

    return fn


def temporal(name: str) -> Method:
    """The temporal lifter ``name`` over the whole track, with its predicted radii."""
    from rmpl.inference_temporal import TemporalLifter

    lifter = TemporalLifter.from_pretrained(name)

    def fn(track: Track) -> Estimate:
        r = lifter.lift_track(track.keypoints, track.scores, track.rig, times=track.times, up=UP)
        return Estimate(r.points, r.radius(0.5), r.radius(0.9))

    return fn


def make_methods(model: str, temporal_model: str) -> dict[str, Method]:
    """The compared methods, in table order."""
    return {
        "triangulate+filter": filtered("triangulate"),
        "robust+filter": filtered("robust"),
        "rmpl+filter": filtered("rmpl", model=model, up=tuple(UP)),
        "rmpl:temporal": temporal(temporal_model),
    }


def tracks(d: dict[str, np.ndarray], views: tuple[int, ...]):
    """Every sequence of ``d`` (:func:`load_mhp_sequences`) seen by the views ``views``."""
    v = list(views)
    for s in range(len(d["joints3d"])):
        yield Track(
            d["keypoints"][s][:, v].astype(float),
            d["scores"][s][:, v].astype(float),
            set_rig(d, s, v),
            d["times"][s].astype(float),
            float(d["fps"][s]),
            d["joints3d"][s].astype(float),
        )


def exact_2d(d: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``d`` with the keypoints replaced by the projected joints: score 1 inside the image,
    0 (and NaN) outside."""
    uv = d["projected"].astype(float)  # (S, T, V, J, 2)
    size = d["size"][:, None, :, None, :].astype(float)  # (S, 1, V, 1, 2)
    inside = np.all((uv >= -0.5) & (uv < size - 0.5), axis=-1)
    return {
        **d,
        "keypoints": np.where(inside[..., None], uv, np.nan).astype(np.float32),
        "scores": inside.astype(np.float32),
    }


def detector_summary(d: dict[str, np.ndarray]) -> str:
    """The 2D's error against the projected joints: one line."""
    from rmpl.skeleton import COCO17

    ok = d["scores"][..., :17] > 0  # COCO-17 joints
    uv = d["projected"][..., :17, :].astype(float)
    height = np.ptp(uv[..., 1], axis=-1)  # (S, T, V) the person's projected height, px
    err = np.linalg.norm(d["keypoints"][..., :17, :] - uv, axis=-1)
    rel = err / height[..., None]
    flip = np.asarray(COCO17.flip_permutation())
    other = np.linalg.norm(d["keypoints"][..., :17, :] - uv[..., flip, :], axis=-1) < err
    far = ok & (rel > 0.1)
    swapped = (far & other & (np.arange(17) != flip)).sum() / max(far.sum(), 1)
    seen = ok.any(-1)
    return (
        f"2D: {(~seen).mean() * 100:.1f}% of the images without a detection (median person "
        f"height {np.median(height[~seen]):.0f} px there, {np.median(height[seen]):.0f} px "
        f"where detected); detected joints {np.median(err[ok]):.1f} px median error, "
        f"{far.sum() / ok.sum() * 100:.1f}% off by more than 10% of the person's height, "
        f"{swapped * 100:.0f}% of those nearer the other side's joint (left/right)"
    )


def view_subsets(total: int, count: int, sample: int | None, rng) -> list[tuple[int, ...]]:
    """Every ``count``-view subset of ``total`` views, or ``sample`` of them drawn once."""
    subsets = list(itertools.combinations(range(total), count))
    if sample is not None and sample < len(subsets):
        pick = rng.choice(len(subsets), sample, replace=False)
        subsets = [subsets[i] for i in sorted(pick)]
    return subsets


def score(d, subsets, methods: dict[str, Method]) -> dict:
    """Errors (mm) of every method on every track, pooled over sequences and subsets."""
    kp = list(KP_STAR)
    err: dict[str, list] = {m: [] for m in methods}
    inside: dict[str, list] = {m: [] for m in methods}
    seen_all, hard_all, pinned_all, seconds = [], [], [], dict.fromkeys(methods, 0.0)
    for views in subsets:
        for track in tracks(d, views):
            ok = track.scores > 0  # (T, V, J)
            if not ok.any():  # these views never see the person: nothing to score
                continue
            seen = np.repeat(ok.any((1, 2))[:, None], len(kp), 1)  # frame has some 2D
            seen_all.append(seen)
            hard_all.append((ok.sum(1)[:, kp] < 2) & seen)
            pinned_all.append(np.repeat((ok.any(2).sum(1) >= 2)[:, None], len(kp), 1))
            for name, fn in methods.items():
                t0 = time.perf_counter()
                est = fn(track)
                seconds[name] += time.perf_counter() - t0
                e = np.linalg.norm(est.points[:, :17] - track.target[:, :17], axis=-1)
                e = e[:, kp] * 1000  # KP*, COCO-17 joints (HALPE-26's first 17)
                err[name].append(e)
                if est.radius50 is not None:
                    r = np.stack([est.radius50, est.radius90])[:, :, kp] * 1000
                    inside[name].append(e[None] < r)  # NaN errors compare False
    seen, hard = np.concatenate(seen_all), np.concatenate(hard_all)
    hard2 = hard & np.concatenate(pinned_all)  # hard joints of a person 2+ views see
    errors = {m: np.concatenate(v) for m, v in err.items()}
    common = seen & np.all([np.isfinite(e) for e in errors.values()], axis=0)
    rows = {}
    for m, e in errors.items():
        fin = np.isfinite(e)
        row = {
            "common": e[common].mean(),
            "hard": e[hard & fin].mean() if (hard & fin).any() else np.nan,
            "hard_coverage": (hard & fin).sum() / max(hard.sum(), 1),
            "hard2": e[hard2 & fin].mean() if (hard2 & fin).any() else np.nan,
            "hard2_coverage": (hard2 & fin).sum() / max(hard2.sum(), 1),
            "all": e[seen & fin].mean(),
            "coverage": (seen & fin).sum() / max(seen.sum(), 1),
            "seconds": seconds[m],
        }
        if inside[m]:
            k = np.concatenate(inside[m], axis=1)  # (2, N, J)
            row["inside50"], row["inside90"] = k[0][fin].mean(), k[1][fin].mean()
        rows[m] = row
    return {
        "rows": rows,
        "n_common": int(common.sum()),
        "n_hard": int(hard.sum()),
        "n_hard2": int(hard2.sum()),
        "n_seen": int(seen.sum()),
    }


def table(count: int, subsets, d, result: dict) -> str:
    rows, S, T = result["rows"], len(d["joints3d"]), d["joints3d"].shape[1]
    lines = [
        f"### {count} views ({len(subsets)} subsets x {S} sequences of {T} frames; "
        f"joint-frames: common {result['n_common']:,}, hard {result['n_hard']:,}, of which "
        f"{result['n_hard2']:,} with the person in 2+ views)",
        "",
        "| method | common | hard (coverage) | hard, person in 2+ views (coverage) "
        "| all estimated (coverage) | inside 50% / 90% |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for m, r in rows.items():
        cal = f"{r['inside50'] * 100:.1f}% / {r['inside90'] * 100:.1f}%" if "inside50" in r else ""
        lines.append(
            f"| {m} | {r['common']:.1f} | {r['hard']:.1f} ({r['hard_coverage'] * 100:.1f}%) | "
            f"{r['hard2']:.1f} ({r['hard2_coverage'] * 100:.1f}%) | "
            f"{r['all']:.1f} ({r['coverage'] * 100:.1f}%) | {cal} |"
        )
    if "rmpl:temporal" in rows and "robust+filter" in rows:
        ratio = rows["rmpl:temporal"]["common"] / rows["robust+filter"]["common"]
        lines += ["", f"rmpl:temporal / robust+filter on the common joints: {ratio:.3f}"]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", help="an MHP sequence set (rmpl generate, sequence_frames >= 2)")
    ap.add_argument("--views", default="2,3,5", help="view counts, comma-separated")
    ap.add_argument("--subsets", default="all", help="'all', or subsets drawn per view count")
    ap.add_argument("--seed", type=int, default=0, help="seed of the subset sample")
    ap.add_argument("--model", default="default", help="per-frame model of rmpl+filter")
    ap.add_argument("--temporal", default="temporal", help="temporal model of rmpl:temporal")
    ap.add_argument("--methods", help="only these methods (comma-separated names)")
    ap.add_argument("--csv", help="also write the rows to this CSV file")
    ap.add_argument(
        "--projected",
        action="store_true",
        help="a control: the exact projections instead of the detections (score 1 inside the "
        "image, 0 outside), so the errors left are the methods' own",
    )
    a = ap.parse_args(argv)
    import torch

    torch.set_num_threads(2)
    d = load_mhp_sequences(a.root)
    if a.projected:
        d = exact_2d(d)
    methods = make_methods(a.model, a.temporal)
    if a.methods:
        names = a.methods.split(",")
        unknown = sorted(set(names) - set(methods))
        if unknown:
            ap.error(f"unknown methods {unknown}; known: {list(methods)}")
        methods = {m: methods[m] for m in names}
    total = d["scores"].shape[2]
    sample = None if a.subsets == "all" else int(a.subsets)
    rng = np.random.default_rng(a.seed)
    fps = d["fps"]
    print(f"{a.root}: {len(fps)} sequences x {d['joints3d'].shape[1]} frames x {total} views, "
          f"{fps.min():.1f}-{fps.max():.1f} frames/s (median {np.median(fps):.1f}); "
          f"subjects {sorted(set(d['subject'].tolist()))}; KP* MPJPE in mm")  # fmt: skip
    print(detector_summary(d) + "\n")
    out = []
    for count in [int(x) for x in a.views.split(",")]:
        if not 2 <= count <= total:
            ap.error(f"view counts must be in [2, {total}], got {count}")
        subsets = view_subsets(total, count, sample, rng)
        result = score(d, subsets, methods)
        print(table(count, subsets, d, result) + "\n", flush=True)
        out += [{"views": count, "method": m, **r} for m, r in result["rows"].items()]
    if a.csv:
        keys = sorted({k for r in out for k in r}, key=lambda k: (k not in ("views", "method"), k))
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, keys)
            w.writeheader()
            w.writerows(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
