"""The MHP shard sets ``rmpl generate`` writes: their manifest formats, arrays and files.

A set is a folder with ``manifest.json`` and ``shard_00000.npz`` ...; the generator
(:mod:`rmpl.synth.generate`) writes them, the datasets (:mod:`rmpl.data.mhp`,
:mod:`rmpl.data.scenes`) read them through this module alone.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from rmpl.io.atomic import atomic_path

log = logging.getLogger(__name__)

#: The manifest format of a single-frame, single-body set.
FORMAT = "rmpl.mhp.v1"
#: The manifest format of a sequence set (``sequence_frames >= 2``).
SEQUENCE_FORMAT = "rmpl.mhp.sequences.v1"
#: The manifest format of a multi-person scene set (``people`` up to 2 or more).
SCENE_FORMAT = "rmpl.mhp.scenes.v1"

#: Arrays of a shard: name -> (shape, meaning).
SHARD_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(M, 17, 3) float32", "COCO-17 joints regressed from the mesh, world metres"),
    "keypoints": ("(M, V, 17, 2) float32", "detector keypoints, pixels, NaN = missed"),
    "scores": ("(M, V, 17) float32", "detector confidence in [0, 1], 0 = missed or outside"),
    "projected": ("(M, V, 17, 2) float32", "joints3d projected into each view, pixels"),
    "K": ("(M, V, 3, 3) float64", "intrinsics, pixels"),
    "R": ("(M, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(M, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(M, V, 2) int32", "image (width, height), pixels"),
    "occluded": ("(M, V, 17) bool", "a black square was pasted over the joint"),
    "phenotypes": ("(M, 6) float32", "anny phenotypes (rmpl.synth.body.PHENOTYPES order)"),
    "subject": ("(M,) str", "source subject id ('random' for random poses)"),
    "clip": ("(M,) str", "source clip (path under the motion folder)"),
    "frame": ("(M,) int64", "source frame in the clip (-1 for random poses)"),
    "mirrored": ("(M,) bool", "the pose was mirrored left/right"),
}

#: Arrays of a sequence shard: name -> (shape, meaning).
SEQUENCE_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(S, T, 17, 3) float32", "COCO-17 joints regressed from the mesh, world metres"),
    "keypoints": ("(S, T, V, 17, 2) float32", "detector keypoints, pixels, NaN = missed"),
    "scores": ("(S, T, V, 17) float32", "detector confidence in [0, 1], 0 = missed or outside"),
    "projected": ("(S, T, V, 17, 2) float32", "joints3d projected into each view, pixels"),
    "times": ("(S, T) float64", "time of each frame, seconds from the sequence's first"),
    "fps": ("(S,) float64", "frames per second of the sequence"),
    "speed": ("(S,) float64", "motion seconds per second of the sequence (1 = real time)"),
    "K": ("(S, V, 3, 3) float64", "intrinsics, pixels (one rig per sequence)"),
    "R": ("(S, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(S, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(S, V, 2) int32", "image (width, height), pixels"),
    "phenotypes": ("(S, 6) float32", "anny phenotypes (rmpl.synth.body.PHENOTYPES order)"),
    "subject": ("(S,) str", "source subject id"),
    "clip": ("(S,) str", "source clip (path under the motion folder)"),
    "frame": ("(S, T) int64", "source frame of each frame in the clip"),
    "mirrored": ("(S,) bool", "the motion was mirrored left/right"),
}

#: Arrays of a multi-person scene shard (``M`` scenes, ``P`` body slots = ``people[1]``,
#: ``N`` detector slots = the detector's ``max_people``): name -> (shape, meaning).
SCENE_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(M, P, 17, 3) float32", "COCO-17 joints of each body, world metres, NaN = none"),
    "present": ("(M, P) bool", "the body slot holds a body"),
    "keypoints": ("(M, V, N, 17, 2) float32", "detections, unassociated, pixels, NaN = missed"),
    "scores": ("(M, V, N, 17) float32", "detector confidence, 0 = missed or outside"),
    "match": ("(M, V, N) int8", "the body a detection is of (by the projections), -1 = none"),
    "projected": ("(M, V, P, 17, 2) float32", "joints3d projected into each view, pixels"),
    "hidden": ("(M, V, P, 17) bool", "the joint's pixel shows another body (mutual occlusion)"),
    "K": ("(M, V, 3, 3) float64", "intrinsics, pixels"),
    "R": ("(M, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(M, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(M, V, 2) int32", "image (width, height), pixels"),
    "phenotypes": ("(M, P, 6) float32", "anny phenotypes"),
    "subject": ("(M, P) str", "source subject id ('random' for random poses, '' = none)"),
    "clip": ("(M, P) str", "source clip"),
    "frame": ("(M, P) int64", "source frame (-1 for random poses or none)"),
    "mirrored": ("(M, P) bool", "the pose was mirrored left/right"),
}


def shard_path(out: str | Path, index: int) -> Path:
    return Path(out) / f"shard_{index:05d}.npz"


def list_shards(out: str | Path) -> list[Path]:
    """Finished shards of an output directory, sorted (temporary files are ignored)."""
    return sorted(p for p in Path(out).glob("shard_*.npz") if not p.name.startswith("."))


def shard_ok(path: Path, meshes: int, arrays: dict = SHARD_ARRAYS) -> bool:
    """Whether ``path`` is a finished shard of ``meshes`` meshes (or sequences) with
    ``arrays``."""
    if not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as z:
            return set(arrays) <= set(z.files) and len(z["joints3d"]) == meshes
    except (OSError, ValueError, EOFError):
        return False


def write_shard(path: Path, arrays: dict[str, np.ndarray], stats: dict) -> None:
    """One compressed NPZ, written atomically (a killed run leaves no partial shard)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays, stats=np.array(json.dumps(stats)))
