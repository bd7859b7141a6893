"""Benchmark the 2D detector options on synchronised videos, and summarise a run's tracks.

Speed and people found per frame, per view, for each option (frames are decoded first, so
the detector's own time is measured; decoding is timed separately):

    python -m rmpl.benchmarks.bench_detect speed \
        ../shared/data/pose2sim_videos/Demo_MultiPerson/videos \
        --frames 100 --options mediapipe,tasks,blazepose-multi,blazepose-multi-static,hog

Options:
    mediapipe                MediaPipe's legacy Pose solution, one person (rmpl's old default)
    tasks                    MediaPipe Tasks' PoseLandmarker (num_poses=4, video mode) on a
                             .task bundle built from the wheel's two networks
    tasks-image              the same in image mode (every frame afresh)
    blazepose-multi          rmpl.synth.detect_multi.BlazePoseMulti, following people
    blazepose-multi-every2   the same with the detector on every 2nd frame
    blazepose-multi-static   BlazePoseMulti, every frame afresh (all detector windows)
    hog                      OpenCV's HOG people detector (its weights are in the opencv
                             wheel) at half resolution: people boxes only, no keypoints

``--mosaic cam01,cam04`` measures one more stream: those two views' frames scaled to 1080
pixels high side by side on a 1920 x 1080 canvas (4 people in the multi-person demo).

Each line is printed with the load average (``os.getloadavg``) measured beside it: the
machine is shared, so compare options measured at similar load.

Per-track statistics of an ``rmpl run`` folder (views per frame from ``membership`` in
poses.npz, the largest frame-to-frame hip step as an identity-swap check), and per-track
2D files for ``rmpl evaluate --dataset recording`` (each holding only the 2D person that
the track used in each view and frame):

    python -m rmpl.benchmarks.bench_detect tracks /tmp/mp_demo --split /tmp/mp_demo_tracks
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from rmpl.benchmarks._common import run_main
from rmpl.errors import InputError


def _frames(video: Path, count: int) -> tuple[list[np.ndarray], float]:
    """The first ``count`` RGB frames and the decoding time per frame, seconds."""
    import cv2

    cap = cv2.VideoCapture(str(video))
    frames, start = [], time.perf_counter()
    while len(frames) < count:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB))
    cap.release()
    return frames, (time.perf_counter() - start) / max(len(frames), 1)


class _Tasks:
    """MediaPipe Tasks' PoseLandmarker on the wheel's networks: frames -> people per frame."""

    def __init__(self, video_mode: bool, num_poses: int = 4) -> None:
        import tempfile

        from mediapipe.tasks.python import BaseOptions, vision

        from rmpl.synth.detect_multi import pose_landmarker_bundle

        bundle = pose_landmarker_bundle(Path(tempfile.mkdtemp()) / "pose_landmarker.task")
        mode = vision.RunningMode.VIDEO if video_mode else vision.RunningMode.IMAGE
        options = vision.PoseLandmarkerOptions(
            base_options=BaseOptions(model_asset_path=str(bundle)),
            running_mode=mode,
            num_poses=num_poses,
        )
        self._make = lambda: vision.PoseLandmarker.create_from_options(options)
        self._video = video_mode

    def __call__(self, frames: list[np.ndarray]) -> np.ndarray:
        import mediapipe as mp

        counts = []
        with self._make() as landmarker:
            for t, frame in enumerate(frames):
                image = mp.Image(image_format=mp.ImageFormat.SRGB, data=frame)
                if self._video:
                    result = landmarker.detect_for_video(image, int(t * 1000 / 60))
                else:
                    result = landmarker.detect(image)
                counts.append(len(result.pose_landmarks))
        return np.array(counts)


class _Hog:
    """OpenCV's default HOG people detector at half resolution: boxes per frame."""

    def __init__(self) -> None:
        import cv2

        self._hog = cv2.HOGDescriptor()
        self._hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())

    def __call__(self, frames: list[np.ndarray]) -> np.ndarray:
        import cv2

        counts = []
        for frame in frames:
            small = cv2.resize(frame, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
            boxes, _ = self._hog.detectMultiScale(small, winStride=(8, 8), scale=1.1)
            counts.append(len(boxes))
        return np.array(counts)


class _Keypoints:
    """A keypoint detector (rmpl's protocol): people with 8+ joints scored > 0.5 per frame."""

    def __init__(self, name: str) -> None:
        from rmpl.pipeline.detect2d import DETECTORS
        from rmpl.synth.detect_multi import BlazePoseMulti

        if name == "blazepose-multi-every2":
            self.det = BlazePoseMulti(detect_every=2)
        else:
            self.det = DETECTORS[name]()

    def __call__(self, frames: list[np.ndarray]) -> np.ndarray:
        from rmpl.synth.detect import with_people_axis

        if hasattr(self.det, "reset"):
            self.det.reset()
        kp, sc = with_people_axis(self.det, *self.det(frames), len(frames))
        return ((sc > 0.5).sum(-1) >= 8).sum(-1)


def _option(name: str):
    if name in ("tasks", "tasks-image"):
        return _Tasks(video_mode=name == "tasks")
    if name == "hog":
        return _Hog()
    return _Keypoints(name)


def _mosaic(views: list, names: list[str]) -> tuple:
    """One stream of 1920 x 1080 frames: the named views, scaled to 1080 high, side by side."""
    import cv2

    parts = [v for v in views if v[0] in names]
    if len(parts) != len(names):
        raise InputError(None, "--mosaic", f"views among {[v[0] for v in views]}", names)
    frames = []
    for t in range(min(len(p[1]) for p in parts)):
        canvas = np.zeros((1080, 1920, 3), np.uint8)
        x = 0
        for p in parts:
            h, w = p[1][t].shape[:2]
            im = cv2.resize(p[1][t], (round(w * 1080 / h), 1080), interpolation=cv2.INTER_AREA)
            canvas[:, x : x + im.shape[1]] = im[:, : 1920 - x]
            x += im.shape[1]
        frames.append(canvas)
    return ("mosaic " + "+".join(names) + " 1920x1080", frames, max(p[2] for p in parts))


def speed(args: argparse.Namespace) -> None:
    videos = sorted(Path(args.videos).glob("*.mp4"))
    if not videos:
        raise InputError(args.videos, None, "a folder holding .mp4 videos", "none")
    views = [(v.stem, *_frames(v, args.frames)) for v in videos]
    if args.mosaic:
        views.append(_mosaic(views, args.mosaic.split(",")))
    h, w = views[0][1][0].shape[:2]
    print(f"{len(videos)} views, {len(views[0][1])} frames of {w}x{h}, {os.cpu_count()} cores")
    print("| option | view | frames/s (detector) | frames/s (with decoding) | people/frame "
          "(0,1,2,3,4+) | load (1 min) |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for name in args.options.split(","):
        run = _option(name)
        run(views[0][1][:2])  # warm-up: graphs, XNNPACK
        for view, frames, decode in views:
            start = time.perf_counter()
            counts = run(frames)
            dt = (time.perf_counter() - start) / len(frames)
            hist = np.bincount(np.minimum(counts, 4), minlength=5).tolist()
            print(f"| {name} | {view} | {1 / dt:.1f} | {1 / (dt + decode):.1f} | {hist} | "
                  f"{os.getloadavg()[0]:.2f} |", flush=True)  # fmt: skip


def tracks(args: argparse.Namespace) -> None:
    from rmpl.io.keypoints import Keypoints2D, load_keypoints, save_keypoints
    from rmpl.io.poses import load_poses

    run = Path(args.run)
    poses = load_poses(run / "poses.npz")
    if poses.membership is None:
        raise InputError(run / "poses.npz", "membership", "a run's poses (rmpl run)", "none")
    m = poses.membership  # (T, P, V): which 2D person of each view the track used
    T, P, V = m.shape
    report = []
    for p in range(P):
        present = np.isfinite(poses.points[:, p]).any(axis=(-1, -2))
        views = (m[:, p] >= 0).sum(-1)[present]
        hip = poses.points[:, p, 11:13].mean(1)
        step = np.linalg.norm(np.diff(hip, axis=0), axis=-1)
        report.append({
            "track": int(poses.person_ids[p]) if poses.person_ids is not None else p,
            "frames": int(present.sum()),
            "views_per_frame": np.bincount(views, minlength=V + 1).tolist(),
            "frames_with_3plus_views": int((views >= 3).sum()),
            "mean_views": round(float(views.mean()), 2) if len(views) else 0.0,
            "max_hip_step_m": round(float(np.nanmax(step)), 3) if np.isfinite(step).any()
            else None,
            "slots_per_view": [sorted(set(m[present, p, v].tolist()) - {-1}) for v in range(V)],
        })  # fmt: skip
    print(f"{run}: {T} frames, {P} tracks")
    for row in report:
        print(json.dumps(row))
    if args.split:
        kp2d = load_keypoints(run / "keypoints2d.npz")
        out = Path(args.split)
        out.mkdir(parents=True, exist_ok=True)
        order = [list(kp2d.views).index(n) for n in poses.camera_names]
        kp, sc = kp2d.keypoints[:, order], kp2d.scores[:, order]  # (T, V, N, J, ·)
        for p in range(P):
            k = np.full((T, V, 1, *kp.shape[3:]), np.nan)
            s = np.zeros((T, V, 1, sc.shape[3]))
            t, v = np.nonzero(m[:, p] >= 0)
            k[t, v, 0], s[t, v, 0] = kp[t, v, m[t, p, v]], sc[t, v, m[t, p, v]]
            path = out / f"track{p}.npz"
            save_keypoints(
                Keypoints2D(k, s, kp2d.skeleton, list(poses.camera_names), kp2d.frames,
                            kp2d.fps), path)  # fmt: skip
            print(f"wrote {path}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(required=True)
    s = sub.add_parser("speed", help="frames/s and people per frame of each option")
    s.add_argument("videos", help="a folder of synchronised .mp4 videos")
    s.add_argument("--frames", type=int, default=100)
    s.add_argument("--options", default="mediapipe,tasks,blazepose-multi,blazepose-multi-static")
    s.add_argument("--mosaic", help="also a 1920x1080 stream of these views side by side")
    s.set_defaults(fn=speed)
    t = sub.add_parser("tracks", help="per-track statistics of an rmpl run folder")
    t.add_argument("run", help="an rmpl run --out folder (poses.npz, keypoints2d.npz)")
    t.add_argument("--split", help="write per-track 2D files (track<p>.npz) here")
    t.set_defaults(fn=tracks)
    args = parser.parse_args(argv)
    args.fn(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(run_main(main))
