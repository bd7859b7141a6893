"""Build the embedded example (src/rmpl/examples/walk) with rmpl's own synthetic pipeline.

A walk of CMU subject 03 (held out of training) is placed in a room and seen by 4 random
Shelf-like cameras. With ``--detector mediapipe`` (the default; needs rmpl[synth] and
anny's cache) the walk is retargeted onto an anny body, rendered on the CPU and passed
through MediaPipe BlazePose, so the 2D is a real detector's; the ground truth is the mesh's
regressed COCO-17 joints. With ``--detector parametric`` the mocap joints go through the
detector-noise model instead. The example holds the calibration (rmpl TOML), the 2D
detections (rmpl JSON) and the 3D ground truth (NPZ).

    ANNY_CACHE_DIR=~/.cache/rmpl/anny python -m rmpl.benchmarks.make_example \
        --poses ../shared/data/cmu_mocap --out src/rmpl/examples/walk
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rmpl.benchmarks._common import run_main
from rmpl.errors import InputError
from rmpl.geometry.camera import Camera, Rig, rodrigues
from rmpl.io.atomic import atomic_path
from rmpl.io.calibration import save_rig
from rmpl.io.keypoints import Keypoints2D, save_keypoints
from rmpl.synth.cameras import sample_cameras
from rmpl.synth.motion import load_motion_dir
from rmpl.synth.noise import detect_like


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--poses", required=True, help="CMU motion folder")
    p.add_argument("--out", type=Path, default=Path("src/rmpl/examples/walk"))
    p.add_argument("--clip", default="03_01")
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--fps", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=3)
    p.add_argument("--detector", default="mediapipe", choices=["mediapipe", "parametric"])
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    bank = load_motion_dir(args.poses, subjects=["03"], fps=args.fps, min_move=0.0)
    keep = np.array([args.clip in c for c in bank.clip])
    if not keep.any():
        raise InputError(None, "--clip", f"one of {sorted(set(bank.clip))[:10]}", args.clip)
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
    if args.detector == "mediapipe":
        frames = bank.frame[keep][: args.frames]
        poses, kp, sc = render_and_detect(args, poses, frames, rig, rng)
    else:
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
            source=f"CMU mocap {args.clip} (subject 03, held out of training), "
            + (
                "anny mesh joints, MediaPipe on renders"
                if args.detector == "mediapipe"
                else "mocap joints, parametric detector noise"
            ),
        )
    print(f"wrote {args.out}: {T} frames, 4 views, {100 * (sc == 0).mean():.0f}% keypoints missing")
    return 0


def render_and_detect(args, poses: np.ndarray, frames: np.ndarray, rig: Rig, rng):
    """The walk on an anny body, rendered from ``rig`` and detected by MediaPipe.

    Each frame's body is turned and moved so its hips match the mocap frame's (heading and
    floor position). Returns the mesh's COCO-17 joints (T, 17, 3), 2D keypoints
    (T, V, 17, 2) and scores (T, V, 17).
    """
    import os

    from rmpl.synth.body import BodyModel, place_bodies, sample_phenotypes
    from rmpl.synth.generate import make_detector
    from rmpl.synth.render import Renderer, random_lighting, random_outfits
    from rmpl.synth.retarget import build_pose_bank, retarget

    bank = build_pose_bank(args.poses, ["03"], fps=args.fps, min_move=0.0)
    where = {(c, int(f)): i for i, (c, f) in enumerate(zip(bank.clip, bank.frame, strict=True))}
    clip = next(c for c in set(bank.clip.tolist()) if args.clip in c)
    idx = np.array([where[(clip, int(f))] for f in frames])
    body = BodyModel(cache_dir=os.environ.get("ANNY_CACHE_DIR"))
    T, V = len(idx), len(rig)
    phen = np.repeat(sample_phenotypes(1, rng), T, axis=0)
    bodies = body(retarget(body, bank, idx, phen), phen)

    def heading(j):  # angle of the left-minus-right hip vector in the floor plane
        d = j[:, 11] - j[:, 12]
        return np.arctan2(d[:, 1], d[:, 0])

    yaw = heading(poses) - heading(bodies.keypoints)
    verts, joints = place_bodies(
        bodies.vertices, bodies.keypoints, yaw, poses[:, 11:13].mean(1)[:, :2]
    )
    colors = np.repeat(random_outfits(body.vertex_parts, 1, rng=rng), T, axis=0)
    light = random_lighting(rng)
    detector = make_detector("mediapipe")
    kp, sc = np.zeros((T, V, 17, 2)), np.zeros((T, V, 17))
    with Renderer(body.faces, body.num_vertices) as renderer:
        for s in range(0, T, 10):
            b = slice(s, min(T, s + 10))
            n = b.stop - b.start
            images = renderer.render(
                verts[b],
                colors[b],
                np.broadcast_to(rig.K, (n, V, 3, 3)),
                np.broadcast_to(rig.R, (n, V, 3, 3)),
                np.broadcast_to(rig.t, (n, V, 3)),
                np.broadcast_to(rig.sizes, (n, V, 2)),
                lighting=[light] * n,
                rng=args.seed,
            )
            k, c = detector(images)
            kp[b] = np.asarray(k).reshape(n, V, 17, 2)
            sc[b] = np.asarray(c).reshape(n, V, 17)
    close = getattr(detector, "close", None)
    if close is not None:
        close()
    kp = np.where(sc[..., None] > 0, kp, np.nan)
    return joints, kp, sc


if __name__ == "__main__":
    raise SystemExit(run_main(main))
