"""MHP shards (``rmpl generate``) as training batches and as an evaluation set.

:class:`ShardSource` has the interface of :class:`rmpl.data.synthetic.PairSource`
(``.batch(batch_size, V, train=True) -> Batch`` and a ``.rng`` Generator whose state the
trainer saves), so the trainer reads rendered, really-detected pairs the same way it reads
the fast parametric ones. :class:`MixSource` draws each batch from one of several sources.
:func:`load_mhp` returns the raw arrays for evaluation.

MHP *sequence* sets (``sequence_frames >= 2``): :func:`load_mhp_sequences` returns their
arrays, and :class:`SequenceShardSource` has the interface of
:class:`rmpl.data.sequences.SequenceSource` (``.batch(size, frames, V, train=True) ->
SequenceBatch``, ``.rng``), so the temporal trainer can read rendered, really-detected
windows as it reads the parametric ones.

Shape glossary: ``B`` batch, ``M`` meshes, ``S`` sequences, ``T`` frames, ``V`` views,
``J`` joints (17).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rmpl.data.sequences import SequenceBatch
from rmpl.data.shards import load_arrays
from rmpl.data.synthetic import Batch, floor_rows
from rmpl.errors import InputError
from rmpl.geometry.camera import rodrigues
from rmpl.geometry.rays import rays_from_keypoints

__all__ = ["load_mhp", "load_mhp_sequences", "ShardSource", "SequenceShardSource", "MixSource"]

_ARRAYS = ("joints3d", "keypoints", "scores", "K", "R", "t", "size", "subject", "clip", "frame")


def load_mhp(
    root: str | Path,
    subjects: Sequence[str] | None = None,
    exclude_subjects: Sequence[str] = (),
    joints: str | None = None,
) -> dict[str, np.ndarray]:
    """Read an MHP directory (every finished shard) into arrays.

    Args:
        root: a directory written by ``rmpl generate`` (``manifest.json`` + shards).
        subjects: keep only meshes posed from these motion subjects (None = all).
        exclude_subjects: drop meshes of these subjects (a held-out split).
        joints: the joint set to return (``"coco17"`` or ``"halpe26"``; None: as the set
            was made). COCO-17 sets read as HALPE-26 have the other nine joints missing.

    Returns:
        ``joints3d`` (M, J, 3) metres, ``keypoints`` (M, V, J, 2) pixels (NaN where the
        score is 0), ``scores`` (M, V, J), ``K`` (M, V, 3, 3), ``R`` (M, V, 3, 3),
        ``t`` (M, V, 3), ``size`` (M, V, 2), ``subject``, ``clip``, ``frame`` (M,), and
        ``projected`` (M, V, J, 2) when present; J = 17 (COCO-17) or 26 (HALPE-26).

    Raises:
        InputError: not an MHP directory, another joint set, or nothing selected.

    A multi-person scene set (``rmpl.mhp.scenes.v1``) is read as one pair per body
    (:func:`rmpl.data.scenes.load_scene_pairs`).
    """
    from rmpl.data.scenes import is_scene_set, load_scene_pairs
    from rmpl.synth.shards import FORMAT

    if is_scene_set(root):
        return load_scene_pairs(root, subjects, exclude_subjects, joints)
    return load_arrays(root, FORMAT, (*_ARRAYS, "projected"), ("projected",), subjects,
                 exclude_subjects, "meshes", joints)  # fmt: skip


_SEQUENCE_KEYS = (
    "joints3d",
    "keypoints",
    "scores",
    "projected",
    "times",
    "fps",
    "K",
    "R",
    "t",
    "size",
    "phenotypes",
    "subject",
    "clip",
    "frame",
    "mirrored",
)


def load_mhp_sequences(
    root: str | Path,
    subjects: Sequence[str] | None = None,
    exclude_subjects: Sequence[str] = (),
    joints: str | None = None,
) -> dict[str, np.ndarray]:
    """Read an MHP sequence directory (``rmpl generate`` with ``sequence_frames >= 2``).

    Args:
        root: the directory (``manifest.json`` of format ``rmpl.mhp.sequences.v1`` + shards).
        subjects: keep only sequences of these motion subjects (None = all).
        exclude_subjects: drop sequences of these subjects.

    Returns:
        ``joints3d`` (S, T, J, 3) metres; ``keypoints`` (S, T, V, J, 2) pixels, NaN where
        the score is 0; ``scores`` (S, T, V, J); ``projected`` (S, T, V, J, 2) pixels;
        ``times`` (S, T) seconds; ``fps`` (S,); one rig per sequence: ``K`` (S, V, 3, 3),
        ``R`` (S, V, 3, 3), ``t`` (S, V, 3) metres, ``size`` (S, V, 2) pixels;
        ``phenotypes`` (S, 6); ``subject``, ``clip``, ``mirrored`` (S,); ``frame`` (S, T)
        source frames.

    Raises:
        InputError: not a sequence directory, another joint set, a missing array, or
            nothing selected.
    """
    from rmpl.synth.shards import SEQUENCE_FORMAT

    return load_arrays(root, SEQUENCE_FORMAT, _SEQUENCE_KEYS, (), subjects, exclude_subjects,
                 "sequences", joints)  # fmt: skip


def _pad_views(part: dict[str, np.ndarray], key: str, width: int) -> np.ndarray:
    """``part[key]`` with its view axis (axis 1 of the per-view arrays) padded to ``width``."""
    a = part[key]
    missing = width - part["scores"].shape[1]
    if missing == 0 or key not in ("keypoints", "scores", "K", "R", "t", "size"):
        return a
    fill = {"keypoints": np.nan, "scores": 0.0, "size": 0, "t": 0.0}
    if key in fill:
        pad = np.full((a.shape[0], missing, *a.shape[2:]), fill[key], a.dtype)
    else:  # K, R: identity matrices keep any geometry on padded views finite
        pad = np.broadcast_to(np.eye(3, dtype=a.dtype), (a.shape[0], missing, 3, 3))
    return np.concatenate([a, pad], axis=1)


def turn_and_shift(target, R, t, shift: float, rng: np.random.Generator):
    """Turn each sample's scene about the vertical by a random angle and move it up to
    ``shift`` metres on the floor, joints and cameras together (the 2D stays exact).

    Args:
        target: (B, ..., 3) world metres. R: (B, V, 3, 3), t: (B, V, 3) world-to-camera.

    Returns:
        target, R, t of the moved scenes.
    """
    B = len(target)
    yaw = rng.uniform(-np.pi, np.pi, B)
    Rz = rodrigues(np.stack([np.zeros(B), np.zeros(B), yaw], -1))  # (B, 3, 3)
    c = np.concatenate([rng.uniform(-shift, shift, (B, 2)), np.zeros((B, 1))], -1)
    extra = (1,) * (target.ndim - 2)
    target = np.einsum("bij,b...j->b...i", Rz, target) + c.reshape(B, *extra, 3)
    # x_cam = R X + t = R Rz^T (X' - c) + t
    R = R @ np.swapaxes(Rz, -1, -2)[:, None]
    t = t - np.einsum("bvij,bj->bvi", R, c)
    return target, R, t


class ShardSource:
    """Training batches from MHP shards: each sample is one mesh seen by ``V`` of its views.

    A training batch's sample with no keypoint in its drawn views (a scene's body that none
    of them detected) gets a NaN target, which the loss leaves out.

    Args:
        root: MHP directory (or several, concatenated; they may differ in views per mesh:
            a batch of V views draws from the meshes that have at least V).
        subjects, exclude_subjects: mesh selection by motion subject (see :func:`load_mhp`).
        drop_rate: random keypoint removal on training batches (thesis 6.11.2).
        augment: on training batches, turn each scene about the vertical by a random angle
            and move it up to ``shift`` metres on the floor (joints and cameras together,
            so the 2D keypoints stay exact).
        shift: see ``augment``, metres.
        seed: random seed.
        joints: the joint set of the batches (see :func:`load_mhp`); None: the sets' own
            (they must then agree).
        floor: ``(rate, noise_m, tilt_deg)`` of the floor (z = 0, where the renders stand)
            given in ``Batch.floor`` (see :func:`rmpl.data.synthetic.floor_rows`; no noise
            on validation batches); None: no floor.
    """

    def __init__(
        self,
        root: str | Path | Sequence[str | Path],
        subjects: Sequence[str] | None = None,
        exclude_subjects: Sequence[str] = (),
        drop_rate: float = 0.2,
        augment: bool = True,
        shift: float = 1.0,
        seed: int | None = None,
        joints: str | None = None,
        floor: tuple[float, float, float] | None = None,
    ) -> None:
        roots = [root] if isinstance(root, str | Path) else list(root)
        parts = [load_mhp(r, subjects, exclude_subjects, joints) for r in roots]
        if len({p["joints3d"].shape[1] for p in parts}) > 1:
            raise InputError(", ".join(map(str, roots)), "joints", "one joint set", "several")
        # Directories may have different numbers of views per mesh: pad to the largest
        # with empty views (score 0, identity camera) that sampling never picks.
        width = max(p["scores"].shape[1] for p in parts)
        self.views_per_mesh = np.concatenate(
            [np.full(len(p["joints3d"]), p["scores"].shape[1]) for p in parts]
        )
        self.data = {k: np.concatenate([_pad_views(p, k, width) for p in parts]) for k in _ARRAYS}
        if not 0 <= drop_rate < 1:
            raise ValueError(f"drop_rate must be in [0, 1), got {drop_rate}")
        self.drop_rate = float(drop_rate)
        self.augment = augment
        self.shift = float(shift)
        self.floor = floor
        self.rng = np.random.default_rng(seed)

    @property
    def num_meshes(self) -> int:
        return len(self.data["joints3d"])

    @property
    def num_views(self) -> int:
        """The largest number of views a batch can ask for (the most any mesh has)."""
        return int(self.views_per_mesh.max())

    def batch(self, size: int, num_views: int, train: bool = True) -> Batch:
        """``size`` meshes, each seen by ``num_views`` of its views drawn without repeats."""
        if not 1 <= num_views <= self.num_views:
            raise ValueError(
                f"num_views must be in [1, {self.num_views}] (views per mesh in the shards), "
                f"got {num_views}"
            )
        rng, d = self.rng, self.data
        # Only meshes with at least num_views views (all of them when the directories agree).
        eligible = np.flatnonzero(self.views_per_mesh >= num_views)
        idx = eligible[rng.integers(0, len(eligible), size)]
        keys = rng.random((size, self.data["scores"].shape[1]))
        keys[np.arange(keys.shape[1]) >= self.views_per_mesh[idx][:, None]] = np.inf
        views = np.argsort(keys, axis=1)[:, :num_views]
        take = (idx[:, None], views)
        kp = d["keypoints"][take].astype(np.float64)  # (B, V, J, 2)
        scores = d["scores"][take].astype(np.float64)
        K, R, t = d["K"][take], d["R"][take].copy(), d["t"][take].copy()
        target = d["joints3d"][idx].astype(np.float64)
        if train and self.augment:
            target, R, t = turn_and_shift(target, R, t, self.shift, rng)
        if train and self.drop_rate > 0:
            drop = rng.random(scores.shape) < self.drop_rate
            scores = np.where(drop, 0.0, scores)
        if train:  # nothing seen (a scene's body no drawn view detected): nothing to learn
            target = np.where((scores > 0).any((1, 2))[:, None, None], target, np.nan)
        kp = np.where(scores[..., None] > 0, kp, np.nan)
        rays = rays_from_keypoints(kp, K=K, R=R, t=t)
        rays = np.where(scores[..., None] > 0, rays, 0.0)
        floor = None
        if self.floor is not None:
            rate, noise_m, tilt = self.floor
            floor = floor_rows(size, rate, *((noise_m, tilt) if train else (0.0, 0.0)), rng)
        return Batch(
            rays.astype(np.float32),
            scores.astype(np.float32),
            target.astype(np.float32),
            kp,
            K,
            R,
            t,
            floor,
        )


class MixSource:
    """Each batch from one of several sources (e.g. MHP shards and the fast PairSource).

    The sources share this object's ``rng``, so saving ``rng.bit_generator.state`` saves
    the whole sampling state.

    Args:
        sources: objects with ``.batch(size, V, train)`` and a ``.rng`` attribute.
        weights: probability of each source per batch (normalised).
        seed: random seed.
    """

    def __init__(self, sources: Sequence, weights: Sequence[float], seed: int | None = None):
        if len(sources) != len(weights) or not sources:
            raise ValueError("need one weight per source and at least one source")
        w = np.asarray(weights, float)
        if np.any(w < 0) or w.sum() <= 0:
            raise ValueError(f"weights must be >= 0 with a positive sum, got {list(weights)}")
        self.sources, self.weights = list(sources), w / w.sum()
        self.rng = np.random.default_rng(seed)
        for s in self.sources:
            s.rng = self.rng

    def batch(self, size: int, num_views: int, train: bool = True) -> Batch:
        k = int(self.rng.choice(len(self.sources), p=self.weights))
        return self.sources[k].batch(size, num_views, train)


class SequenceShardSource:
    """Training windows from MHP sequence shards: each sample is a window of consecutive
    frames of one sequence, seen by ``V`` of its views (one rig for the window).

    The batches are :class:`rmpl.data.sequences.SequenceBatch`, as
    :class:`rmpl.data.sequences.SequenceSource` makes them, so the temporal trainer can read
    either.

    Args:
        root: MHP sequence directory, or several with the same frames and views per sequence.
        subjects, exclude_subjects: sequence selection by motion subject.
        drop_rate: random keypoint removal on training batches.
        augment: on training batches, turn each window about the vertical by a random angle
            and move it up to ``shift`` metres on the floor (joints and cameras together, so
            the 2D keypoints stay exact), and start its clock at a random time (0-100 s).
        shift: see ``augment``, metres.
        seed: random seed.
        joints: the joint set of the batches (see :func:`load_mhp`).
    """

    def __init__(
        self,
        root: str | Path | Sequence[str | Path],
        subjects: Sequence[str] | None = None,
        exclude_subjects: Sequence[str] = (),
        drop_rate: float = 0.0,
        augment: bool = True,
        shift: float = 1.0,
        seed: int | None = None,
        joints: str | None = None,
    ) -> None:
        roots = [root] if isinstance(root, str | Path) else list(root)
        parts = [load_mhp_sequences(r, subjects, exclude_subjects, joints) for r in roots]
        shape = parts[0]["scores"].shape[1:3]  # (T, V)
        for r, p in zip(roots, parts, strict=True):
            if p["scores"].shape[1:3] != shape:
                raise InputError(
                    r,
                    "sequence_frames, views",
                    f"{shape[0]} frames and {shape[1]} views per sequence like {roots[0]}",
                    f"{p['scores'].shape[1]} frames, {p['scores'].shape[2]} views",
                )
        if not 0 <= drop_rate < 1:
            raise ValueError(f"drop_rate must be in [0, 1), got {drop_rate}")
        keys = ("joints3d", "keypoints", "scores", "times", "K", "R", "t")
        self.data = {k: np.concatenate([p[k] for p in parts]) for k in keys}
        self.drop_rate = float(drop_rate)
        self.augment = augment
        self.shift = float(shift)
        self.rng = np.random.default_rng(seed)

    @property
    def num_sequences(self) -> int:
        return len(self.data["joints3d"])

    @property
    def num_frames(self) -> int:
        """Frames per stored sequence: the longest window a batch can ask for."""
        return self.data["scores"].shape[1]

    @property
    def num_views(self) -> int:
        """Views per stored sequence: the most a batch can ask for."""
        return self.data["scores"].shape[2]

    def batch(self, size: int, frames: int, num_views: int, train: bool = True) -> SequenceBatch:
        """``size`` windows of ``frames`` consecutive frames, each from a random sequence and
        start, seen by ``num_views`` of its views drawn without repeats."""
        if not 1 <= frames <= self.num_frames:
            raise ValueError(f"frames must be in [1, {self.num_frames}], got {frames}")
        if not 1 <= num_views <= self.num_views:
            raise ValueError(f"num_views must be in [1, {self.num_views}], got {num_views}")
        rng, d, B, T = self.rng, self.data, size, frames
        seq = rng.integers(0, self.num_sequences, B)
        start = rng.integers(0, self.num_frames - T + 1, B)
        rows = start[:, None] + np.arange(T)  # (B, T)
        views = np.argsort(rng.random((B, self.num_views)), axis=1)[:, :num_views]  # (B, V)
        at = (seq[:, None, None], rows[:, :, None], views[:, None, :])  # (B, T, V) index
        kp = d["keypoints"][at].astype(np.float64)  # (B, T, V, J, 2)
        scores = d["scores"][at].astype(np.float64)
        rig = (seq[:, None], views)
        K, R, t = d["K"][rig], d["R"][rig].copy(), d["t"][rig].copy()
        target = d["joints3d"][seq[:, None], rows].astype(np.float64)  # (B, T, J, 3)
        times = d["times"][seq[:, None], rows]
        times = times - times[:, :1]
        if train and self.augment:
            target, R, t = turn_and_shift(target, R, t, self.shift, rng)
            times = times + rng.uniform(0, 100, (B, 1))
        if train and self.drop_rate > 0:
            scores = np.where(rng.random(scores.shape) < self.drop_rate, 0.0, scores)
        kp = np.where(scores[..., None] > 0, kp, np.nan)
        rays = rays_from_keypoints(kp, K=K[:, None], R=R[:, None], t=t[:, None])
        rays = np.where(scores[..., None] > 0, rays, 0.0)
        return SequenceBatch(
            rays.astype(np.float32),
            scores.astype(np.float32),
            times.astype(np.float32),
            target.astype(np.float32),
            kp,
            K,
            R,
            t,
        )
