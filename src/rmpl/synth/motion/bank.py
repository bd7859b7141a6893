"""The pose bank: clips found in a mocap folder, their usable frames resampled, mirrored,
and saved as one set of COCO-17 poses for training."""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17
from rmpl.synth.motion._common import (
    Motion,
)
from rmpl.synth.motion.asf import AsfSkeleton, load_asf_amc, read_asf
from rmpl.synth.motion.bvh import load_bvh
from rmpl.synth.motion.coco import to_coco17
from rmpl.synth.motion.kinematics import (
    floor_height,
)

_log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class PoseSet:
    """Poses from many clips: COCO-17 from the mocap's own skeleton, or HALPE-26 posed on
    anny bodies (:func:`rmpl.synth.retarget.anny_pose_set`).

    Attributes:
        poses: joint positions, metres, z up, float32, shape (N, 17, 3) or (N, 26, 3).
        subject: subject id per pose, e.g. "01" (CMU subject) or "dance-salsa", shape (N,).
        clip: clip id per pose (the file's path under the data root), shape (N,).
        frame: frame index in the source clip (0-based, at its own fps), shape (N,).
    """

    poses: np.ndarray
    subject: np.ndarray
    clip: np.ndarray
    frame: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.poses)
        if (
            self.poses.shape[1:] not in ((17, 3), (26, 3))
            or not len(self.subject) == len(self.clip) == len(self.frame) == n
        ):
            raise ValueError(
                f"poses must have shape (N, 17 or 26, 3) with N subject/clip/frame entries, got "
                f"{self.poses.shape}, {len(self.subject)}, {len(self.clip)}, {len(self.frame)}"
            )

    def __len__(self) -> int:
        return len(self.poses)

    def select(self, mask: np.ndarray) -> PoseSet:
        """The poses where ``mask`` (bool or indices, shape (N,)) selects."""
        return PoseSet(self.poses[mask], self.subject[mask], self.clip[mask], self.frame[mask])

    def split(self, holdout_subjects: Sequence[str]) -> tuple[PoseSet, PoseSet]:
        """(poses of other subjects, poses of ``holdout_subjects``)."""
        held = np.isin(self.subject, list(holdout_subjects))
        return self.select(~held), self.select(held)

    def counts(self) -> dict[str, int]:
        """Number of poses per subject."""
        names, counts = np.unique(self.subject, return_counts=True)
        return dict(zip(names.tolist(), counts.tolist(), strict=True))

    @staticmethod
    def concatenate(sets: Sequence[PoseSet]) -> PoseSet:
        if not sets:
            return PoseSet(
                np.zeros((0, 17, 3), np.float32),
                np.array([], str),
                np.array([], str),
                np.zeros(0, np.int64),
            )
        return PoseSet(
            *(
                np.concatenate([getattr(s, f) for s in sets])
                for f in ("poses", "subject", "clip", "frame")
            )
        )


@dataclass(frozen=True)
class Clip:
    """One motion file found under a data root.

    Attributes:
        path: the AMC or BVH file.
        asf: the ASF skeleton for an AMC file, else None.
        subject: subject id: the CMU subject ("02") for files named ``<subject>_<trial>``,
            else "<grandparent>-<parent>" folder names (``dance/salsa/01.bvh`` ->
            "dance-salsa").
        clip: the file's path relative to the root (posix), unique in the root.
    """

    path: Path
    asf: Path | None
    subject: str
    clip: str


_CMU_TRIAL = re.compile(r"^(\d+)_\d+$")


def _subject(path: Path) -> str:
    match = _CMU_TRIAL.match(path.stem)
    return match.group(1) if match else f"{path.parent.parent.name}-{path.parent.name}"


def _asf_for(amc: Path) -> Path:
    """The ASF beside an AMC: the only one, or the one named after the AMC's subject."""
    asfs = sorted(amc.parent.glob("*.asf"))
    if len(asfs) == 1:
        return asfs[0]
    named = [a for a in asfs if a.stem == amc.stem.split("_")[0]]
    if len(named) != 1:
        raise InputError(
            amc,
            "skeleton",
            f"one .asf in {amc.parent} or one named {amc.stem.split('_')[0]}.asf",
            [a.name for a in asfs],
        )
    return named[0]


def find_clips(root: str | Path, subjects: Sequence[str] | None = None) -> list[Clip]:
    """Motion files (.amc with their .asf, .bvh) under ``root``, sorted by path.

    Args:
        root: a folder searched recursively.
        subjects: keep only these subject ids (see :class:`Clip`); None keeps all.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, None, "a folder of .asf/.amc and .bvh files", "no such folder")
    clips = []
    for path in sorted(p for p in root.rglob("*") if p.suffix.lower() in (".amc", ".bvh")):
        subject = _subject(path)
        if subjects is not None and subject not in subjects:
            continue
        asf = _asf_for(path) if path.suffix.lower() == ".amc" else None
        clips.append(Clip(path, asf, subject, path.relative_to(root).as_posix()))
    return clips


#: Faster than any human pelvis, m/s: a root moving faster between frames is a glitch or a
#: splice of two takes.
MAX_ROOT_SPEED = 15.0
#: The CMU BVH conversions start with a rest (T-) pose and blend into the motion in ~40 ms.
REST_BLEND = 0.05
#: Clips of the shared CMU subset whose conversion is broken (legs folding through the body
#: in a run), matched against the end of the clip id.
BROKEN_CLIPS: tuple[str, ...] = ("misc/data/09/09_10.bvh",)
#: Clips of the shared CMU subset whose BVH Frame Time is wrong, with their true frame rate,
#: matched like :data:`BROKEN_CLIPS`. 16_01/16_02 say 30 fps, but their jumps stay airborne
#: 39 and 46 frames, the ballistic time of their 0.17 and 0.25 m lifts at 120 fps (45, 54
#: frames), not at 30 fps (11, 14).
FRAME_RATES: dict[str, float] = {"misc/data/16/16_01.bvh": 120.0, "misc/data/16/16_02.bvh": 120.0}


def _is_rest_pose(motion: Motion, t: int, tol: float = 0.03) -> bool:
    """Whether frame ``t`` is the rest pose up to a rigid motion of the root (90% of the
    joints within ``tol`` metres)."""
    rel = (motion.positions[t] - motion.positions[t, 0]) @ motion.rotations[t, 0]  # R^T (p - p0)
    return float(np.percentile(np.linalg.norm(rel - motion.rest, axis=-1), 90)) < tol


def usable_frames(motion: Motion, min_duration: float = 0.5) -> np.ndarray:
    """Frames worth training on, a mask of shape (T,): drops a leading rest pose with the
    converter's blend out of it (:data:`REST_BLEND`), and every piece shorter than
    ``min_duration`` seconds between root jumps faster than :data:`MAX_ROOT_SPEED`."""
    T, fps = motion.num_frames, motion.fps
    keep = np.ones(T, dtype=bool)
    if _is_rest_pose(motion, 0):
        keep[: max(1, round(REST_BLEND * fps))] = False
    speed = np.linalg.norm(np.diff(motion.positions[:, 0], axis=0), axis=-1) * fps  # (T - 1,)
    cuts = np.flatnonzero(speed > MAX_ROOT_SPEED) + 1  # first frame of each new piece
    for start, stop in zip(np.r_[0, cuts], np.r_[cuts, T], strict=True):
        if (stop - start) / fps < min_duration:
            keep[start:stop] = False
    return keep


def _sample(poses: np.ndarray, keep: np.ndarray, fps_in: float, fps: float, min_move: float):
    """Frame indices on a grid of ``fps`` (nearest source frames) among ``keep``, without
    near-duplicates: a frame is kept when some joint moved at least ``min_move`` metres,
    pelvis-centred, since the last kept frame. poses: shape (T, 17, 3); keep: (T,)."""
    T = len(poses)
    idx = np.unique(np.minimum(np.round(np.arange(0, T, fps_in / fps)).astype(int), T - 1))
    idx = idx[keep[idx]]
    hips = [COCO17.index("left_hip"), COCO17.index("right_hip")]
    centred = poses[idx] - poses[idx][:, hips].mean(axis=1, keepdims=True)
    kept = [0] if len(idx) else []
    for i in range(1, len(idx)):  # greedy: depends on the last kept frame
        if np.linalg.norm(centred[i] - centred[kept[-1]], axis=-1).max() >= min_move:
            kept.append(i)
    return idx[kept]


def _load_clip(clip: Clip, skeletons: dict[Path, AsfSkeleton]) -> Motion:
    if clip.asf is None:
        fps = next((v for k, v in FRAME_RATES.items() if _matches(clip.clip, [k])), None)
        return load_bvh(clip.path, fps=fps)
    if clip.asf not in skeletons:
        skeletons[clip.asf] = read_asf(clip.asf)
    return load_asf_amc(skeletons[clip.asf], clip.path)


def _clip_poses(clip: Clip, motion: Motion, fps: float, min_move: float, min_duration: float):
    """The pose set of one clip, its floor at z = 0 (None when nothing is usable)."""
    keep = usable_frames(motion, min_duration)
    if not keep.any():
        _log.info("%s: skipped, no %.1f s of clean motion", clip.path, min_duration)
        return None
    poses = to_coco17(motion)
    poses[..., 2] -= floor_height(motion.positions[keep])  # some BVH clips sit 0.8 m low
    idx = _sample(poses, keep, motion.fps, fps, min_move)
    n = len(idx)
    _log.debug("%s: %d frames -> %d poses", clip.clip, motion.num_frames, n)
    subject, name = np.full(n, clip.subject), np.full(n, clip.clip)
    return PoseSet(poses[idx].astype(np.float32), subject, name, idx.astype(np.int64))


def load_motion_dir(
    root: str | Path,
    subjects: Sequence[str] | None = None,
    fps: float = 10.0,
    min_move: float = 0.02,
    min_duration: float = 0.5,
    exclude: Sequence[str] = BROKEN_CLIPS,
) -> PoseSet:
    """Load every clip under ``root`` as COCO-17 poses for training.

    Args:
        root: folder searched recursively for .asf/.amc and .bvh files.
        subjects: subject ids to keep (see :class:`Clip`); None keeps all.
        fps: poses per second of motion kept before de-duplication.
        min_move: drop a pose whose joints (pelvis-centred) all moved less than this many
            metres since the last kept pose of its clip.
        min_duration: shortest clean stretch of motion used, seconds (see
            :func:`usable_frames`); shorter clips, such as a reference pose, are skipped.
        exclude: skip clips whose id (path under ``root``) ends with one of these.

    Returns:
        A :class:`PoseSet` in clip order, each clip moved vertically so that its floor
        (:func:`floor_height` of all its joints over its usable frames) is z = 0.
    """
    clips = [c for c in find_clips(root, subjects) if not _matches(c.clip, exclude)]
    if not clips:
        which = "" if subjects is None else f" of subjects {list(subjects)}"
        raise InputError(root, None, f"some .amc or .bvh files{which}", "none")
    skeletons: dict[Path, AsfSkeleton] = {}
    sets = [_clip_poses(c, _load_clip(c, skeletons), fps, min_move, min_duration) for c in clips]
    return PoseSet.concatenate([s for s in sets if s is not None])


def _matches(clip: str, patterns: Sequence[str]) -> bool:
    """Whether a clip id is one of ``patterns`` or ends with one (at a folder boundary)."""
    return any(clip == p or clip.endswith("/" + p.lstrip("/")) for p in patterns)


_POSE_SET_FORMAT = "rmpl.pose_set.v1"


def save_pose_set(path: str | Path, poses: PoseSet, **meta: float | str) -> Path:
    """Write a :class:`PoseSet` to an ``.npz`` file atomically; ``meta`` values are stored
    beside it (e.g. fps=10.0). Returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(
            f,
            format=np.array(_POSE_SET_FORMAT),
            poses=poses.poses.astype(np.float32),
            subject=poses.subject.astype(str),
            clip=poses.clip.astype(str),
            frame=poses.frame.astype(np.int64),
            **{f"meta_{k}": np.array(v) for k, v in meta.items()},
        )
    return path


def load_pose_set(path: str | Path) -> PoseSet:
    """Read a :class:`PoseSet` written by :func:`save_pose_set`.

    Raises:
        InputError: not such a file, or arrays missing or of the wrong shape.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise InputError(path, None, "an .npz pose set", e) from None
    if str(data.get("format", "")) != _POSE_SET_FORMAT:
        raise InputError(path, "format", repr(_POSE_SET_FORMAT), data.get("format", "none"))
    missing = [k for k in ("poses", "subject", "clip", "frame") if k not in data]
    if missing:
        raise InputError(path, missing[0], "the array", "none")
    try:
        return PoseSet(data["poses"], data["subject"], data["clip"], data["frame"])
    except ValueError as e:
        raise InputError(path, "poses", "consistent shapes", e) from None


def build_pose_cache(
    root: str | Path,
    out_dir: str | Path,
    holdout_subjects: Sequence[str] = ("03",),
    subjects: Sequence[str] | None = None,
    fps: float = 10.0,
    min_move: float = 0.02,
    exclude: Sequence[str] = BROKEN_CLIPS,
) -> dict[str, Path]:
    """Load ``root`` (see :func:`load_motion_dir`) and write ``train.npz`` and ``val.npz``
    (the ``holdout_subjects``) to ``out_dir``. Returns {"train": path, "val": path}."""
    poses = load_motion_dir(root, subjects, fps=fps, min_move=min_move, exclude=exclude)
    train, val = poses.split(holdout_subjects)
    out_dir = Path(out_dir)
    meta = {"fps": fps, "min_move": min_move, "root": str(root)}
    paths = {
        name: save_pose_set(out_dir / f"{name}.npz", s, **meta)
        for name, s in (("train", train), ("val", val))
    }
    _log.info("pose cache %s: %d train, %d val poses", out_dir, len(train), len(val))
    return paths
