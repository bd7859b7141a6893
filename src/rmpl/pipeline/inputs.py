"""The inputs of a run: a calibration and 2D keypoints from files or detected in videos.

:func:`load_inputs` reads the calibration and the 2D (any keypoint format rmpl reads, a
Shelf/4D-association folder, or a 2D detector (``detect2d.DETECTORS``) on videos / image
folders with a cache and a fingerprint of the inputs), and matches the 2D views to the
cameras by name (by order, with a warning, only when no name matches; a partial match is
refused). Fewer views than cameras, each named like one of them (``--videos cam01.mp4``
with a 4-camera calibration), use those cameras only, and say so.

The 2D keeps the joints its source gives beyond COCO-17: a file or detector with feet, neck,
head top or mid-hip gives HALPE-26 (:func:`rmpl.io.keypoints.load_keypoints`), otherwise
COCO-17; :attr:`Inputs.skeleton` names it. HALPE-26's first 17 joints are COCO-17.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig

__all__ = ["InputSpec", "Inputs", "load_inputs"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class InputSpec:
    """What to read: ``calib`` and one of ``keypoints`` (files or folders), ``videos`` or
    ``images`` (one per camera); ``fps`` if the input states none; ``skeleton`` when the 2D
    joint set is ambiguous; ``detector`` for videos and images, ``detect_workers`` of them
    detected at once (Ray tasks above 1; the same result); ``sync``: how the videos will be
    put on one clock (``--sync``), None when they are taken as synchronised (then videos of
    different lengths or rates are refused)."""

    calib: str
    keypoints: list[str] | None = None
    videos: list[str] | None = None
    images: list[str] | None = None
    fps: float | None = None
    skeleton: str | None = None
    detector: str | None = None
    detect_workers: int | None = None
    sync: str | None = None

    @classmethod
    def from_args(cls, args) -> InputSpec:
        """From a command's parsed options (absent options are None)."""
        return cls(**{k: getattr(args, k, None) for k in cls.__dataclass_fields__})

    @property
    def source(self) -> str:
        """The 2D input, for messages."""
        return ", ".join(self.keypoints) if self.keypoints else "2D input"


@dataclass
class Inputs:
    """Matched inputs: keypoints (T, V, P, J, 2), scores (T, V, P, J), the rig, frames, and
    the joint set of the keypoints (``"coco17"``, or ``"halpe26"`` when the 2D has feet,
    neck, head top or mid-hip; a key of :data:`rmpl.skeleton.SKELETONS`)."""

    rig: Rig
    keypoints: np.ndarray
    scores: np.ndarray
    frames: np.ndarray
    fps: float | None
    skeleton: str = "coco17"
    sync: dict | None = None  # the offsets applied (rmpl run --sync), for the report


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
    """Shelf/4D-association detections: group each view's candidates into people, in
    HALPE-26 (BODY_25's neck, mid-hip and feet kept; no head top)."""
    from tqdm import tqdm

    from rmpl.data.shelf import load_shelf
    from rmpl.io.keypoints import Keypoints2D, richest
    from rmpl.pipeline.association import group_people
    from rmpl.skeleton import SKELETONS

    data = load_shelf(root)
    groups = [
        [group_people(c, output="auto") for c in frame]
        for frame in tqdm(data.detections, desc="grouping", unit="frame")
    ]
    skeleton = richest(data.detections[0][0].skeleton) if data.detections else "coco17"
    J = SKELETONS[skeleton].num_joints
    P = max(1, max(len(k) for frame in groups for k, _ in frame))
    T, V = len(groups), len(data.rig)
    kp = np.full((T, V, P, J, 2), np.nan)
    sc = np.zeros((T, V, P, J))
    for t, frame in enumerate(groups):
        for v, (k, s) in enumerate(frame):
            kp[t, v, : len(k)], sc[t, v, : len(k)] = k, s
    return Keypoints2D(kp, sc, skeleton, data.rig.names, np.asarray(data.frames), None)


def _load_2d(spec: InputSpec, cache: Path | None):
    """Read 2D files, or detect people in videos/images (cached in ``cache``, with the
    fingerprint of the inputs beside it in ``<cache>.inputs.json``: a cache made from other
    inputs, or by another detector, is not reused)."""
    from rmpl.io.keypoints import load_keypoints

    if spec.keypoints:
        shelf = _shelf4d_root(spec.keypoints)
        if shelf is not None:
            return _shelf4d_keypoints(shelf)
        return load_keypoints(spec.keypoints, skeleton=spec.skeleton)
    from rmpl.pipeline.detect2d import DEFAULT_DETECTOR, detect_images, detect_videos

    workers = 1 if spec.detect_workers is None else spec.detect_workers
    if workers < 1:
        raise InputError("--detect-workers", None, "a whole number of 1 or more", str(workers))
    kind = "videos" if spec.videos else "images"
    sources = spec.videos if kind == "videos" else spec.images
    detector = spec.detector or DEFAULT_DETECTOR
    stamp = _check_detection_inputs(spec, kind, sources, detector)
    stamp_path = None if cache is None else cache.with_name(cache.stem + ".inputs.json")
    if cache is not None and cache.is_file():
        if _same_stamp(stamp_path, stamp):
            log.info("using cached 2D detections %s (delete it to detect again)", cache)
            return load_keypoints(cache)
        log.info("%s was made from other inputs: detecting again", cache)
    resume = None if cache is None else cache.parent / ".detect2d"
    if kind == "videos":
        kp = detect_videos(sources, detector, cache_dir=resume, workers=workers)
    else:
        kp = detect_images(sources, detector, fps=spec.fps, cache_dir=resume, workers=workers)
    if cache is not None:
        _save_cache(kp, cache, stamp_path, stamp, resume)
    return kp


def _check_detection_inputs(spec, kind: str, sources: list[str], detector: str) -> dict:
    """Every check that can fail, before the (long) detection; returns the inputs' stamp."""
    from rmpl.io.calibration import load_rig
    from rmpl.pipeline.detect2d import (
        check_image_folders,
        check_videos,
        input_fingerprint,
        view_names,
    )

    if kind == "videos":
        check_videos(sources, synchronised=spec.sync is None)
    else:
        check_image_folders(sources)
    rig = load_rig(spec.calib)
    if len(rig) != len(sources) and not _names_subset(view_names(sources), rig):
        raise InputError(
            spec.calib,
            "cameras",
            f"one camera per {kind[:-1]}: {len(sources)} cameras for {', '.join(sources)} "
            "(or fewer inputs, each named like one of the cameras)",
            f"{len(rig)} cameras {rig.names}",
        )
    return {
        "kind": kind,
        "detector": detector,
        "fps": None if kind == "videos" else spec.fps,
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


def load_inputs(spec: InputSpec, cache: Path | None = None) -> Inputs:
    """Read the calibration and the 2D input (files, or detections of videos / image folders
    cached in ``cache``), and put the views in the rig's order. The 2D is in the richest
    joint set its source gives (:attr:`Inputs.skeleton`); a cache of COCO-17 detections
    made before feet were kept is used as it is (delete it to detect the feet)."""
    from rmpl.io.calibration import load_rig

    rig = load_rig(spec.calib)
    kp = _load_2d(spec, cache)
    if len(kp.views) < len(rig) and _names_subset(list(kp.views), rig):
        log.info("2D for %d of the %d cameras of %s: using cameras %s", len(kp.views), len(rig),
                 spec.calib, list(kp.views))  # fmt: skip
        rig = rig[[rig.names.index(v) for v in kp.views]]
    keypoints, scores = _match_views(kp, rig, spec)
    if not (scores > 0).any():
        raise InputError(
            spec.source, "scores", "at least one keypoint with confidence > 0", "all zero"
        )
    return Inputs(rig, keypoints, scores, np.asarray(kp.frames), kp.fps or spec.fps, kp.skeleton)


def _names_subset(views: list[str], rig: Rig) -> bool:
    """Fewer distinct views than cameras, every one named like a camera."""
    return 0 < len(set(views)) == len(views) < len(rig) and set(views) <= set(rig.names)


def _match_views(kp, rig: Rig, spec: InputSpec) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints and scores with the views in the rig's order: by name when every view
    names a camera, by order (with a warning) when none does; a partial match is refused."""
    views, V = list(kp.views), kp.keypoints.shape[1]
    if V != len(rig):
        raise InputError(
            spec.source,
            "views",
            f"{len(rig)} views to match the cameras {rig.names} of {spec.calib}",
            f"{V} views {views}",
        )
    if set(views) == set(rig.names):
        order = [views.index(n) for n in rig.names]
        return kp.keypoints[:, order], kp.scores[:, order]
    if set(views) & set(rig.names):
        raise InputError(
            spec.source,
            "views",
            f"view names that all match the cameras of {spec.calib} (or none, to pair by "
            f"order): views {sorted(set(views) - set(rig.names))} have no camera, cameras "
            f"{sorted(set(rig.names) - set(views))} no view",
            views,
        )
    log.warning("no 2D view is named like a camera: pairing views %s with cameras %s by "
                "order", views, rig.names)  # fmt: skip
    return kp.keypoints, kp.scores
