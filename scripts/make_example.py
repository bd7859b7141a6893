"""Build the embedded example (src/rmpl/examples/walk) with rmpl's own synthetic pipeline.

A walk of CMU subject 03 (held out of training) is placed in a room, seen by 4 random
Shelf-like cameras, and passed through the parametric detector model. The example holds the
calibration (rmpl TOML), the 2D detections (rmpl JSON) and the 3D ground truth (NPZ).

    python scripts/make_example.py --poses ../shared/data/cmu_mocap --out src/rmpl/examples/walk
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rmpl.geometry.camera import Camera, Rig, rodrigues
from rmpl.io.atomic import atomic_path
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.synth.cameras import sample_cameras
from rmpl.synth.motion import load_motion_dir
from rmpl.synth.noise import detect_like


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--poses", required=True, help="CMU motion folder")
    p.add_argument("--out", type=Path, default=Path("src/rmpl/examples/walk"))
    p.add_argument("--clip", default="03_01")
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--fps", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=3)
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    bank = load_motion_dir(args.poses, subjects=["03"], fps=args.fps, min_move=0.0)
    keep = np.array([args.clip in c for c in bank.clip])
    if not keep.any():
        raise SystemExit(f"clip {args.clip} not found; clips: {sorted(set(bank.clip))[:10]}")
    poses = bank.poses[keep][: args.frames].astype(float)  # (T, 17, 3)
    # Centre the walk in the room and turn it.
    centre = poses[:, 11:13].mean((0, 1))
    yaw = rodrigues(np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)]))
    poses = (poses - [centre[0], centre[1], 0.0]) @ yaw.T
    K, R, t, size = sample_cameras(4, np.array([0.0, 0.0, 1.0]), "shelf", rng)
    rig = Rig(
        tuple(Camera(K[v], R[v], t[v], size=tuple(size[v]), name=f"cam{v + 1}") for v in range(4))
    )
    T = len(poses)
    kp, sc = detect_like(
        poses,
        np.broadcast_to(K, (T, 4, 3, 3)),
        np.broadcast_to(R, (T, 4, 3, 3)),
        np.broadcast_to(t, (T, 4, 3)),
        np.broadcast_to(size, (T, 4, 2)),
        rng,
    )
    args.out.mkdir(parents=True, exist_ok=True)
    save_rig(rig, args.out / "calibration.toml")
    save_keypoints(
        Keypoints2D(kp[:, :, None], sc[:, :, None], "coco17", rig.names, np.arange(T), args.fps),
        args.out / "keypoints.json",
    )
    with atomic_path(args.out / "ground_truth.npz") as tmp, open(tmp, "wb") as f:
        np.savez_compressed(
            f,
            points=poses[:, None].astype(np.float32),
            fps=args.fps,
            source=f"CMU mocap {args.clip} (subject 03, held out of training)",
        )
    print(f"wrote {args.out}: {T} frames, 4 views, {100 * (sc == 0).mean():.0f}% keypoints missing")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
