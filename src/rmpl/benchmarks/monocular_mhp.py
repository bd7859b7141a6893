"""One camera on held-out MHP sequences (rendered, real detector): `rmpl run`'s one-camera path.

    python -m rmpl.benchmarks.monocular_mhp DIR [--model default] [--floor z=0] \
        [--cues floor,size,time]

``--cues`` defaults to what ``rmpl run`` uses with the model
(:meth:`rmpl.pipeline.monocular.MonocularConfig.for_model`).

DIR is an MHP sequence set (``rmpl generate`` with ``sequence_frames``, e.g.
``configs/mhp_seq_heldout.toml``: CMU subject 03, 48 frames, 5 views, one body per sequence,
the floor at z = 0). Each (sequence, view) is one track lifted as ``rmpl run`` does with one
camera (:func:`rmpl.pipeline.monocular.lift_single_view`: the per-frame lifter, then depth
from the floor, a body-size prior and time), at the sequence's frame rate (the filters'
cut-off min(6 Hz, 0.45 fps), as rmpl.benchmarks.temporal_mhp). The estimate with
the most frames is the person (one body per sequence). Scored on the COCO-17 limb joints
(KP*) in the frames where it exists: MPJPE, PA-MPJPE, the root (mid-hip) error, the ratio of
estimated to true height (ankles to the eyes' midpoint, per frame, median) and coverage
(frames with an estimate among those where the view detects the person), and how often a
joint's error is within the 50% radius the run writes (``Poses3D.uncertainty``; 50% when
calibrated). Issue 16's target: MPJPE at most 150 mm. ``--model`` may be a temporal model
that reads the floor (``rmpl run``'s one-camera path with it: whole tracks).
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from rmpl.benchmarks._common import run_main
from rmpl.data.mhp import load_mhp_sequences
from rmpl.geometry.camera import Camera, Rig
from rmpl.geometry.floor import parse_floor
from rmpl.metrics import procrustes_align
from rmpl.pipeline.monocular import MonocularConfig, lift_single_view
from rmpl.pipeline.runner import RunConfig
from rmpl.skeleton import KP_STAR

_HIPS, _ANKLES, _EYES = (11, 12), (15, 16), (1, 2)


def _height(x: np.ndarray) -> np.ndarray:
    """Eyes' midpoint above the ankles' midpoint, (T,) metres, z up."""
    return x[:, list(_EYES), 2].mean(1) - x[:, list(_ANKLES), 2].mean(1)


def track(d: dict, s: int, v: int, cfg: RunConfig, floor, mono: MonocularConfig):
    """One (sequence, view): errors per frame (T, 12) mm, PA-MPJPE per frame (T,) mm, root
    error (T,) mm, height ratio (T,), which frames the view detects the person in, and
    whether each error is within its 50% radius (T, 12) (NaN: no radius)."""
    c = Camera(d["K"][s, v], d["R"][s, v], d["t"][s, v], size=tuple(map(int, d["size"][s, v])))
    kp = d["keypoints"][s][:, v][:, None, None].astype(float)  # (T, 1, 1, J, 2)
    sc = d["scores"][s][:, v][:, None, None].astype(float)
    seen = (sc > 0).any((1, 2, 3))
    T = len(kp)
    nan = np.full(T, np.nan)
    none = np.full((T, len(KP_STAR)), np.nan)
    if seen.sum() < 2:
        return none, nan, nan, nan, seen, none
    fps = float(d["fps"][s])
    cfg = replace(cfg, cutoff=min(cfg.cutoff, 0.45 * fps))  # below Nyquist at 10-60 fps
    poses = lift_single_view(kp, sc, Rig((c,)), np.arange(T), fps, floor, cfg, mono)
    x = poses.points[..., :17, :]  # (T, P, 17, 3)
    if x.shape[1] == 0:
        return none, nan, nan, nan, seen, none
    p = int(np.isfinite(x).all(-1).any(-1).sum(0).argmax())  # the longest track
    x, gt = x[:, p], d["joints3d"][s][:, :17].astype(float)
    e = np.linalg.norm(x - gt, axis=-1)[:, list(KP_STAR)] * 1000
    ok = np.isfinite(x[:, list(KP_STAR)]).all((-1, -2))
    pa = np.full(T, np.nan)
    if ok.any():
        xk, gk = x[ok][:, list(KP_STAR)], gt[ok][:, list(KP_STAR)]
        pa[ok] = np.linalg.norm(procrustes_align(xk, gk) - gk, axis=-1).mean(-1) * 1000
    root = np.linalg.norm(x[:, list(_HIPS)].mean(1) - gt[:, list(_HIPS)].mean(1), axis=-1)
    root = root * 1000
    inside = none
    if poses.uncertainty is not None:
        u = poses.uncertainty[:, p][:, list(KP_STAR)] * 1000
        inside = np.where(np.isfinite(u) & np.isfinite(e), e < u, np.nan)
    return e, pa, root, _height(x) / _height(gt), seen, inside


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root")
    ap.add_argument("--model", default="default", help="the per-frame model (one camera)")
    ap.add_argument("--floor", default="z=0", help="the floor ('none': the size prior only)")
    ap.add_argument(
        "--cues", default=None,
        help="comma-separated cues or 'none' (default: what rmpl run uses with the model)",
    )  # fmt: skip
    a = ap.parse_args(argv)
    d = load_mhp_sequences(a.root)
    floor = None if a.floor == "none" else parse_floor(a.floor)
    cfg = RunConfig(method="rmpl", model=a.model)
    mono = MonocularConfig.for_model(a.model, floor_known=floor is not None)
    if a.cues is not None:
        mono = MonocularConfig.from_cues(a.cues.replace(",", "+"), lifter_sd=mono.lifter_sd)
    a.cues = ",".join(mono.cues) or "none"
    S, V = d["scores"].shape[0], d["scores"].shape[2]
    parts = [track(d, s, v, cfg, floor, mono) for s in range(S) for v in range(V)]
    e = np.concatenate([p[0] for p in parts])
    pa, root, ratio = (np.concatenate([p[i] for p in parts]) for i in (1, 2, 3))
    seen = np.concatenate([p[4] for p in parts])
    inside = np.concatenate([p[5] for p in parts])
    est = np.isfinite(e).all(-1)
    print(f"{a.root}: {S} sequences x {V} views, model {a.model}, floor {a.floor}, cues {a.cues}")
    print("| MPJPE (mm) | median | PA-MPJPE (mm) | root error (mm) | height ratio (median) "
          "| coverage | within the 50% radius |")  # fmt: skip
    print("|---:|---:|---:|---:|---:|---:|---:|")
    cover = 100 * (est & seen).sum() / seen.sum()
    print(f"| {np.nanmean(e[est]):.1f} | {np.nanmedian(e[est].mean(-1)):.1f} | "
          f"{np.nanmean(pa[est]):.1f} | {np.nanmean(root[est]):.1f} | "
          f"{np.nanmedian(ratio[est]):.3f} | {cover:.1f}% | "
          f"{100 * np.nanmean(inside[est]):.1f}% |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
