"""Apply the floor model's selection rule (configs/floor26.toml) on held-out data.

    python -m rmpl.benchmarks.floor_select CANDIDATE --renders data/mhp26_test \
        --sequences data/mhp_seq_heldout26 --bank data/bank.npz

All sets are CMU subject 03, which no model trained on.

(1) One camera. The candidate, given the floor (z = 0: the renders and the sequences stand
on it), against ``rmpl run``'s one-camera path before it (the COCO-17 ``default`` model,
then depth from the floor, body size and time), KP* MPJPE on COCO-17 joints:
(a) every held-out render seen by each of its views alone, per frame (the base with the
floor and size cues, the candidate with its own depth); (b) held-out MHP sequences, each
(sequence, view) one track through ``rmpl run``'s one-camera path
(``rmpl.benchmarks.monocular_mhp``: the base with all three cues, the candidate with
:meth:`rmpl.pipeline.monocular.MonocularConfig.for_model`). It passes when lower on both.

(2) Two or more views (floor not given: the multi-view path does not pass one): the tables
of ``rmpl.benchmarks.halpe26_select`` (parametric pairs from the mocap bank BANK, and the renders)
against ``halpe26``. It passes when its mean over 2-5 views is at most 1 mm above on both.

It also prints the candidate's one-view log-depth error on the renders (the mid-hip's distance
from the camera, estimated over true): its robust standard deviation is the one-view depth
error :data:`rmpl.pipeline.monocular.FLOOR_MODEL_LIFTER_SD` that ``rmpl run`` assumes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from rmpl.benchmarks import halpe26_select, monocular_mhp
from rmpl.benchmarks._common import run_main
from rmpl.data.mhp import load_mhp, load_mhp_sequences
from rmpl.evaluate.methods import MonocularMethod
from rmpl.geometry.camera import Camera, Rig
from rmpl.geometry.floor import Floor
from rmpl.inference import Lifter
from rmpl.pipeline.monocular import MonocularConfig
from rmpl.pipeline.runner import RunConfig
from rmpl.skeleton import KP_STAR

FLOOR = Floor((0.0, 0.0, 1.0), 0.0, source="z=0 (where the renders stand)")
MARGIN_MM = 1.0


def one_view_renders(
    root: Path, methods: dict[str, MonocularMethod], log_depth: dict | None = None
) -> dict[str, float]:
    """KP* MPJPE (mm) of each method on every (render, view), one view at a time; with
    ``log_depth`` (a dict), each method's log(estimated / true distance of the mid-hip from
    the camera) per (render, view) is appended to ``log_depth[name]``."""
    d = load_mhp(root, joints="halpe26")
    M, V = d["scores"].shape[:2]
    errors: dict[str, list[float]] = {name: [] for name in methods}
    for m in range(M):
        target = d["joints3d"][m, :17].astype(float)
        for v in range(V):
            size = tuple(int(s) for s in d["size"][m, v])
            rig = Rig((Camera(d["K"][m, v], d["R"][m, v], d["t"][m, v], size=size),))
            kp = d["keypoints"][m, v][None, None].astype(float)  # (1, 1, 26, 2)
            sc = d["scores"][m, v][None, None].astype(float)
            if not (sc > 0).any():
                continue
            for name, method in methods.items():
                x = method(kp, sc, rig)[0, :17]
                e = np.linalg.norm(x - target, axis=-1)[list(KP_STAR)]
                errors[name].append(float(e.mean() * 1000))
                if log_depth is not None:
                    C = rig.centers[0]
                    r = [np.linalg.norm(p[11:13].mean(0) - C) for p in (x, target)]
                    log_depth.setdefault(name, []).append(float(np.log(r[0] / r[1])))
    return {name: float(np.nanmean(e)) for name, e in errors.items()}


def one_view_sequences(root: Path, models: dict[str, str]) -> dict[str, float]:
    """KP* MPJPE (mm) of ``rmpl run``'s one-camera path per model on held-out sequences."""
    d = load_mhp_sequences(root)
    S, V = d["scores"].shape[0], d["scores"].shape[2]
    out = {}
    for name, model in models.items():
        cfg = RunConfig(method="rmpl", model=model)
        mono = MonocularConfig.for_model(model)
        parts = [monocular_mhp.track(d, s, v, cfg, FLOOR, mono) for s in range(S) for v in range(V)]
        e = np.concatenate([p[0] for p in parts])
        out[name] = float(np.nanmean(e[np.isfinite(e).all(-1)]))
    return out


def multi_view_rule(a: argparse.Namespace) -> bool:
    """Rule (2): with two to five views and no floor, the candidate within MARGIN_MM of the
    multi-view model before it, on parametric pairs and on the renders; prints the table."""
    print("(2) two to five views, no floor (KP* MPJPE, mm; before / candidate)\n")
    models = {"base": a.multi_base, "candidate": a.candidate}
    lifters = {k: Lifter.from_pretrained(v, backend="torch") for k, v in models.items()}
    head = " | ".join(f"{v} views" for v in halpe26_select.VIEWS)
    print(f"| set | {head} | mean | difference | rule |")
    print("|---|" + "---:|" * (len(halpe26_select.VIEWS) + 3))
    ok_multi = True
    tables = {
        "parametric, subject 03": halpe26_select.parametric(a.bank, lifters, a.samples),
        f"renders {a.renders}": halpe26_select.renders(a.renders, models),
    }
    for label, table in tables.items():
        views = sorted(table["base"])
        mb = np.mean([table["base"][v] for v in views])
        mc = np.mean([table["candidate"][v] for v in views])
        ok = mc <= mb + MARGIN_MM
        ok_multi &= ok
        cells = " | ".join(f"{table['base'][v]:.1f} / {table['candidate'][v]:.1f}" for v in views)
        print(f"| {label} | {cells} | {mb:.1f} / {mc:.1f} | {mc - mb:+.1f} | "
              f"{'pass' if ok else 'fail'} |")  # fmt: skip
    return ok_multi


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("candidate", help="the floor-reading checkpoint")
    ap.add_argument("--renders", type=Path, required=True, help="held-out HALPE-26 renders")
    ap.add_argument("--sequences", type=Path, required=True, help="held-out MHP sequences")
    ap.add_argument("--bank", type=Path, required=True, help="the mocap pose bank (COCO-17)")
    ap.add_argument("--base", default="default", help="the one-camera model before")
    ap.add_argument("--multi-base", default="halpe26", help="the multi-view model before")
    ap.add_argument("--samples", type=int, default=512, help="parametric pairs per view count")
    a = ap.parse_args(argv)
    torch.set_num_threads(2)

    base = MonocularMethod("floor+size", model=a.base)
    cand = MonocularMethod(f"none@{a.candidate}")
    for method in (base, cand):
        method.floor = FLOOR
    log_depth: dict[str, list[float]] = {}
    renders = one_view_renders(a.renders, {"base": base, "cand": cand}, log_depth)
    one = {
        "renders, one view, per frame": renders,
        "sequences, one view, rmpl run": one_view_sequences(
            a.sequences, {"base": a.base, "cand": a.candidate}
        ),
    }
    print("(1) one camera, floor given (KP* MPJPE, mm)\n")
    print("| set | before | candidate | rule |")
    print("|---|---:|---:|---|")
    ok_one = True
    for label, r in one.items():
        ok = r["cand"] < r["base"]
        ok_one &= ok
        print(f"| {label} | {r['base']:.1f} | {r['cand']:.1f} | {'pass' if ok else 'fail'} |")
    print("\n(1) " + ("passes: the candidate lifts one camera" if ok_one else "fails") + "\n")
    ld = np.asarray(log_depth["cand"])
    ld = ld[np.isfinite(ld)]
    mad = 1.4826 * np.median(np.abs(ld - np.median(ld)))
    print(f"the candidate's one-view log-depth error on the renders: median {np.median(ld):+.3f}, "
          f"robust sd (1.4826 MAD) {mad:.3f}, sd {ld.std():.3f} (n = {ld.size}): "
          "FLOOR_MODEL_LIFTER_SD\n")  # fmt: skip

    ok_multi = multi_view_rule(a)
    verdict = "passes: it also lifts two or more views" if ok_multi else "fails: one camera only"
    print(f"\n(2) {verdict}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
