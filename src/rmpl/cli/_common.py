"""What the 3D commands share: read calibration + 2D input, match views to cameras."""

from __future__ import annotations

import argparse
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig

#: ``--model`` help of the commands that lift (the names of rmpl.inference.PRETRAINED, kept
#: here so that building the parser does not import torch).
MODEL_HELP = (
    "shipped model (default: per frame; occlusion: per frame, for many missing keypoints; "
    "temporal: whole tracks, needs a frame rate) or checkpoint folder"
)

log = logging.getLogger(__name__)

OUTPUT_SUFFIXES = (".npz", ".json", ".trc", ".c3d")


def _number(kind, test, expected: str):
    """An argparse ``type`` refusing impossible values at parse time (exit 2, usage line)."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}") from None
        if not test(value):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text}")
        return value

    parse.__name__ = expected  # argparse names the type in its messages
    return parse


positive = _number(float, lambda x: x > 0 and x < float("inf"), "a number > 0")
fraction = _number(float, lambda x: 0 <= x <= 1, "a confidence in [0, 1]")
count = _number(int, lambda x: x >= 0, "an integer >= 0")
at_least_one = _number(int, lambda x: x >= 1, "an integer >= 1")


def add_io_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--calib", required=True, help="calibration file or folder (any supported format)"
    )
    parser.add_argument(
        "--keypoints",
        required=True,
        nargs="+",
        help="2D keypoints: rmpl .npz/.json, COCO JSON per view, OpenPose JSON folders, "
        "or a Shelf 4D folder",
    )
    parser.add_argument(
        "--skeleton", default=None, help="2D joint set when ambiguous (body25, body25b, coco18)"
    )
    parser.add_argument("--out", required=True, help=f"output file: {', '.join(OUTPUT_SUFFIXES)}")
    parser.add_argument(
        "--fps", type=positive, default=None, help="frame rate for TRC/C3D if the input has none"
    )


@dataclass
class Inputs:
    """Matched inputs: keypoints (T, V, P, J, 2), scores (T, V, P, J), the rig, frames."""

    rig: Rig
    keypoints: np.ndarray
    scores: np.ndarray
    frames: np.ndarray
    fps: float | None


def check_output(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in OUTPUT_SUFFIXES:
        raise InputError(
            path, None, f"an output file ending in one of {', '.join(OUTPUT_SUFFIXES)}"
        )
    return path


def _shelf4d_root(paths: list[str]) -> Path | None:
    """The Shelf 4D folder given as ``--keypoints``: the folder itself or its detection/."""
    if len(paths) != 1:
        return None
    p = Path(paths[0])
    if (p / "detection" / "0.txt").is_file():
        return p
    if p.name == "detection" and (p / "0.txt").is_file():
        return p.parent
    return None


def _shelf4d_keypoints(root: Path):
    """Shelf/4D-association detections: group each view's candidates into people."""
    from tqdm import tqdm

    from rmpl.data.shelf import load_shelf
    from rmpl.io.keypoints import Keypoints2D
    from rmpl.pipeline.association import group_people

    data = load_shelf(root)
    groups = [
        [group_people(c) for c in frame]
        for frame in tqdm(data.detections, desc="grouping", unit="frame")
    ]
    P = max(1, max(len(k) for frame in groups for k, _ in frame))
    T, V = len(groups), len(data.rig)
    kp = np.full((T, V, P, 17, 2), np.nan)
    sc = np.zeros((T, V, P, 17))
    for t, frame in enumerate(groups):
        for v, (k, s) in enumerate(frame):
            kp[t, v, : len(k)], sc[t, v, : len(k)] = k, s
    return Keypoints2D(kp, sc, "coco17", data.rig.names, np.asarray(data.frames), None)


def _load_2d(args: argparse.Namespace, cache: Path | None):
    """Read 2D files, or detect people in videos/images (cached in ``cache``, with the
    fingerprint of the inputs beside it in ``<cache>.inputs.json``: a cache made from other
    inputs, or by another detector, is not reused)."""
    from rmpl.io.keypoints import load_keypoints

    if getattr(args, "keypoints", None):
        shelf = _shelf4d_root(args.keypoints)
        if shelf is not None:
            return _shelf4d_keypoints(shelf)
        return load_keypoints(args.keypoints, skeleton=args.skeleton)
    from rmpl.pipeline.detect2d import detect_images, detect_videos

    kind = "videos" if getattr(args, "videos", None) else "images"
    sources = args.videos if kind == "videos" else args.images
    detector = getattr(args, "detector", None) or "mediapipe"
    stamp = _check_detection_inputs(args, kind, sources, detector)
    stamp_path = None if cache is None else cache.with_name(cache.stem + ".inputs.json")
    if cache is not None and cache.is_file():
        if _same_stamp(stamp_path, stamp):
            log.info("using cached 2D detections %s (delete it to detect again)", cache)
            return load_keypoints(cache)
        log.info("%s was made from other inputs: detecting again", cache)
    resume = None if cache is None else cache.parent / ".detect2d"
    if kind == "videos":
        kp = detect_videos(sources, detector, cache_dir=resume)
    else:
        kp = detect_images(sources, detector, fps=args.fps, cache_dir=resume)
    if cache is not None:
        _save_cache(kp, cache, stamp_path, stamp, resume)
    return kp


def _check_detection_inputs(args, kind: str, sources: list[str], detector: str) -> dict:
    """Every check that can fail, before the (long) detection; returns the inputs' stamp."""
    from rmpl.io.calibration import load_rig
    from rmpl.pipeline.detect2d import check_image_folders, check_videos, input_fingerprint

    if kind == "videos":
        check_videos(sources)
    else:
        check_image_folders(sources)
    rig = load_rig(args.calib)
    if len(rig) != len(sources):
        raise InputError(
            args.calib,
            "cameras",
            f"one camera per {kind[:-1]}: {len(sources)} cameras for {', '.join(sources)}",
            f"{len(rig)} cameras {rig.names}",
        )
    return {
        "kind": kind,
        "detector": detector,
        "fps": None if kind == "videos" else args.fps,
        "inputs": input_fingerprint(sources, kind),
    }


def _same_stamp(stamp_path: Path, stamp: dict) -> bool:
    import json

    try:
        return json.loads(stamp_path.read_text(encoding="utf-8")) == stamp
    except (OSError, ValueError):
        return False


def _save_cache(kp, cache: Path, stamp_path: Path, stamp: dict, resume: Path) -> None:
    """The detections and their inputs' stamp; the per-view partial results go."""
    import json

    from rmpl.io.atomic import atomic_path
    from rmpl.io.keypoints import save_keypoints

    save_keypoints(kp, cache)
    with atomic_path(stamp_path) as tmp:
        tmp.write_text(json.dumps(stamp, indent=1), encoding="utf-8")
    for f in resume.glob("*.npz"):  # the per-view partial results are in the cache now
        f.unlink()
    if resume.is_dir() and not any(resume.iterdir()):
        resume.rmdir()


def load_calibration_and_2d(args: argparse.Namespace, cache: Path | None = None) -> Inputs:
    """Read the calibration and the 2D input, and put the views in the rig's order."""
    from rmpl.io.calibration import load_rig

    rig = load_rig(args.calib)
    kp = _load_2d(args, cache)
    keypoints, scores = _match_views(kp, rig, args)
    source = _source(args)
    if not (scores > 0).any():
        raise InputError(source, "scores", "at least one keypoint with confidence > 0", "all zero")
    return Inputs(rig, keypoints, scores, np.asarray(kp.frames), kp.fps or args.fps)


def _source(args: argparse.Namespace) -> str:
    return ", ".join(args.keypoints) if getattr(args, "keypoints", None) else "2D input"


def _match_views(kp, rig: Rig, args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints and scores with the views in the rig's order: by name when every view
    names a camera, by order (with a warning) when none does; a partial match is refused."""
    views, V = list(kp.views), kp.keypoints.shape[1]
    if V != len(rig):
        raise InputError(
            _source(args),
            "views",
            f"{len(rig)} views to match the cameras {rig.names} of {args.calib}",
            f"{V} views {views}",
        )
    if set(views) == set(rig.names):
        order = [views.index(n) for n in rig.names]
        return kp.keypoints[:, order], kp.scores[:, order]
    if set(views) & set(rig.names):
        raise InputError(
            _source(args),
            "views",
            f"view names that all match the cameras of {args.calib} (or none, to pair by "
            f"order): views {sorted(set(views) - set(rig.names))} have no camera, cameras "
            f"{sorted(set(rig.names) - set(views))} no view",
            views,
        )
    log.warning("no 2D view is named like a camera: pairing views %s with cameras %s by "
                "order", views, rig.names)  # fmt: skip
    return kp.keypoints, kp.scores


def check_estimated(poses, args: argparse.Namespace, method: str) -> None:
    """A result with no joint at all is an error (exit 2), not an empty file."""
    if np.isfinite(poses.points).any():
        return
    why = (
        "no frame in which two views see the same joint" if method != "rmpl"
        else "no frame with a keypoint"
    )  # fmt: skip
    raise InputError(_source(args), None, "2D input from which some joint can be estimated",
                     f"nothing estimated ({why})")  # fmt: skip


def check_cameras(rig: Rig, calib: str, method: str) -> None:
    if method != "rmpl" and len(rig) < 2:
        raise InputError(calib, "cameras", "at least 2 cameras to triangulate", len(rig))


def run_single_method(args: argparse.Namespace, method: str, **config) -> int:
    """``rmpl lift`` / ``rmpl triangulate``: per-frame estimates, associated and tracked,
    without temporal smoothing, written to one file."""
    from rmpl.io.poses import save_poses
    from rmpl.pipeline.runner import RunConfig, run

    out = check_output(args.out)
    inputs = load_calibration_and_2d(args)
    check_cameras(inputs.rig, args.calib, method)
    cfg = RunConfig(method=method, **config)
    poses = run(
        inputs.keypoints, inputs.scores, inputs.rig, inputs.frames, inputs.fps, cfg, temporal=False
    )
    check_estimated(poses, args, method)
    if out.suffix.lower() in (".trc", ".c3d") and not poses.fps:
        raise InputError(out, "fps", "a frame rate for TRC/C3D (the input has none: pass --fps)")
    save_poses(poses, out)
    ok = np.isfinite(poses.points).all(-1)
    log.info(
        "wrote %s: %d frames x %d people, %.0f%% of joints present",
        out,
        ok.shape[0],
        ok.shape[1],
        100 * ok.mean(),
    )
    return 0
