"""Run the whole job on the embedded example: lift a 4-camera walk, export it, draw it.

Writes poses.{npz,json,trc,c3d}, skeleton.png and reprojection.png into --out and prints
the error of RMPL and of triangulation against the example's ground truth.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "walk"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="out/example", help="output folder")
    parser.add_argument("--model", default="default", help="shipped model name or checkpoint folder")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from rmpl.geometry.triangulate import triangulate_robust
    from rmpl.inference import Lifter
    from rmpl.io.calibration import load_rig
    from rmpl.io.keypoints import load_keypoints
    from rmpl.io.poses import JointSource, Poses3D, save_poses
    from rmpl.metrics import mpjpe
    from rmpl.skeleton import COCO17, KP_STAR
    from rmpl.viz import plot_reprojection, plot_skeletons

    out = Path(args.out)
    rig = load_rig(EXAMPLE / "calibration.toml")
    kp2d = load_keypoints(EXAMPLE / "keypoints.json")
    gt = np.load(EXAMPLE / "ground_truth.npz")["points"][:, 0]  # (T, J, 3)
    kp, sc = kp2d.keypoints[:, :, 0], kp2d.scores[:, :, 0]  # one person: (T, V, J, 2)
    lifter = Lifter.from_pretrained(args.model)
    res = lifter.lift(kp, sc, rig)
    tri = triangulate_robust(kp, sc, rig, swap_pairs=COCO17.flip_pairs)
    poses = Poses3D(
        points=res.points[:, None],
        scores=None,
        flags=np.where(np.isfinite(res.points).all(-1), int(JointSource.LIFTED), 0)[:, None].astype(np.uint8),
        num_views=res.num_views[:, None].astype(np.int32),
        skeleton="coco17",
        frames=kp2d.frames,
        fps=kp2d.fps,
        person_ids=np.array([0]),
    )
    for suffix in (".npz", ".json", ".trc", ".c3d"):
        save_poses(poses, out / f"poses{suffix}")
    plot_skeletons(res.points, out / "skeleton.png", rig=rig, reference=gt,
                   title="RMPL (colour) vs ground truth (dashed)")  # fmt: skip
    plot_reprojection(kp, sc, res.points, rig, out / "reprojection.png")
    kps = list(KP_STAR)
    print(f"example: {len(kp)} frames, {len(rig)} views, {100 * (sc == 0).mean():.0f}% of keypoints missing")
    print(f"  RMPL                 MPJPE {1000 * mpjpe(res.points, gt):6.1f} mm   KP* {1000 * mpjpe(res.points, gt, kps):6.1f} mm")
    cov = np.isfinite(tri.points).all(-1).mean() * 100
    print(f"  robust triangulation MPJPE {1000 * mpjpe(tri.points, gt):6.1f} mm   KP* "
          f"{1000 * mpjpe(tri.points, gt, kps):6.1f} mm   ({cov:.0f}% of joints triangulated)")  # fmt: skip
    print(f"wrote {out}/poses.{{npz,json,trc,c3d}}, skeleton.png, reprojection.png")
    return 0
