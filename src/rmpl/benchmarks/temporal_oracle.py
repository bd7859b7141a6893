"""Design measurements for the temporal lifter on Shelf, with oracle identity.

The 2D is associated per view subset as `rmpl evaluate` does; each associated person is put
on its ground-truth actor by Hungarian matching of a per-frame DLT (oracle identity: an upper
bound on what a tracker gives), then each actor's sequence goes through every method.

Usage: python -m rmpl.benchmarks.temporal_oracle SHELF_DEV [MODEL ...] [--fps 25] [--views 2,5]
Prints, per view count (mean over subsets): MPJPE on the joints every method estimated, on
the joints neither triangulation estimated ("hard"), on the part of those the DLT + median
fills ("hard, filled"), PCK@150 over KP* (missing = wrong), and the share of all scored
joints' errors inside the temporal model's predicted 50% / 90% radii.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from rmpl.benchmarks._common import run_main
from rmpl.evaluate.evalset import gt_coco, load_eval_set
from rmpl.evaluate.harness import _per_person_input
from rmpl.geometry import triangulate, triangulate_robust
from rmpl.inference import Lifter
from rmpl.inference_temporal import TemporalLifter
from rmpl.pipeline.association import AssociationConfig, match_poses
from rmpl.skeleton import KP_STAR


def _median_filter(x: np.ndarray, k: int = 7) -> np.ndarray:
    """Centred NaN-aware median over k frames (T, J, 3)."""
    T = len(x)
    out = np.full_like(x, np.nan)
    h = k // 2
    for t in range(T):
        win = x[max(0, t - h) : t + h + 1]
        if np.isfinite(win).any():
            out[t] = np.nanmedian(win, axis=0)
    return out


def actor_tracks(part, views, assoc):
    """Per actor: keypoints (T, k, 17, 2), scores (T, k, 17) from the associated 2D."""
    kp, sc, frame, _ = _per_person_input(part, views, "associate", assoc)
    rig = part.rig[list(views)]
    gt = gt_coco(part)  # (T, P, 17, 3)
    T, P = gt.shape[:2]
    tri = triangulate(kp, sc, rig).points if len(kp) else np.zeros((0, 17, 3))
    K = len(views)
    tk = np.full((P, T, K, 17, 2), np.nan)
    ts = np.zeros((P, T, K, 17))
    for t in np.unique(frame):
        rows = np.flatnonzero(frame == t)
        m = match_poses(tri[rows], gt[t], 0.5, list(KP_STAR))
        for p in range(P):
            if m[p] >= 0:
                tk[p, t], ts[p, t] = kp[rows[m[p]]], sc[rows[m[p]]]
    return tk, ts, rig, gt


def run(root, models, fps, view_counts):
    evset = load_eval_set("shelf", root)
    part = evset.parts[0]
    assoc = AssociationConfig()
    frame_lifter = Lifter.from_pretrained()
    temporal = {m: TemporalLifter.from_pretrained(m) for m in models}
    results = {}
    for k in view_counts:
        agg = {}
        for views in itertools.combinations(range(part.num_views), k):
            tk, ts, rig, gt = actor_tracks(part, views, assoc)
            per = {name: [] for name in ["dlt", "robust", "rmpl", "dlt+f", "rmpl+f", *temporal]}
            sig = {m: [] for m in temporal}
            gts = []
            for p in range(tk.shape[0]):
                has = np.isfinite(gt[:, p, list(KP_STAR)]).all((-1, -2))
                if not has.any():
                    continue
                kp, sc = tk[p], ts[p]
                dlt = triangulate(kp, sc, rig).points
                rob = triangulate_robust(kp, sc, rig).points
                seen = (sc > 0).any((1, 2))
                fr = np.full((len(kp), 17, 3), np.nan)
                if seen.any():
                    fr[seen] = frame_lifter.lift(kp[seen], sc[seen], rig).points
                per["dlt"].append(dlt)
                per["robust"].append(rob)
                per["rmpl"].append(fr)
                per["dlt+f"].append(_median_filter(dlt))
                per["rmpl+f"].append(_median_filter(fr))
                for m, lifter in temporal.items():
                    r = lifter.lift_track(kp, sc, rig, fps=fps)
                    pts = r.points.copy()
                    per[m].append(pts)
                    sig[m].append(np.stack([r.radius(0.5), r.radius(0.9)], -1))
                gts.append(np.where(has[:, None, None], gt[:, p], np.nan))
            cat = {n: np.concatenate(v)[:, list(KP_STAR)] for n, v in per.items()}
            g = np.concatenate(gts)[:, list(KP_STAR)]
            err = {n: np.linalg.norm(v - g, axis=-1) for n, v in cat.items()}
            scored = np.isfinite(g).all(-1)
            common = scored & np.all([np.isfinite(e) for e in err.values()], 0)
            hard = scored & ~np.isfinite(err["dlt"]) & ~np.isfinite(err["robust"])
            filled = hard & np.isfinite(err["dlt+f"])
            row = {}
            for n, e in err.items():
                row[f"{n} common"] = np.mean(e[common]) * 1000
                row[f"{n} hard"] = np.nanmean(e[hard]) * 1000 if hard.any() else np.nan
                row[f"{n} hard, filled"] = np.mean(e[filled]) * 1000 if filled.any() else np.nan
                row[f"{n} pck150"] = np.mean(np.nan_to_num(e[scored], nan=9) < 0.15) * 100
            for m in temporal:
                s = np.concatenate(sig[m])[:, list(KP_STAR)]  # (T, 12, 2) the 50% / 90% radii
                e = err[m]
                ok = scored & np.isfinite(e) & np.isfinite(s).all(-1)
                row[f"{m} cover50"] = np.mean(e[ok] < s[ok][:, 0]) * 100
                row[f"{m} cover90"] = np.mean(e[ok] < s[ok][:, 1]) * 100
            row["n hard"] = int(hard.sum())
            row["n hard, filled"] = int(filled.sum())
            for key, v in row.items():
                agg.setdefault(key, []).append(v)
        results[k] = {key: float(np.nanmean(v)) for key, v in agg.items()}
        print(f"== {k} views")
        for key, v in results[k].items():
            print(f"  {key:28s} {v:8.1f}")
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root")
    ap.add_argument("models", nargs="*", default=["temporal"])
    ap.add_argument("--fps", type=float, default=25.0)
    ap.add_argument("--views", default="2,5")
    a = ap.parse_args(argv)
    run(a.root, a.models, a.fps, [int(v) for v in a.views.split(",")])
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
