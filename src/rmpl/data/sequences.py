"""Synthetic training windows in time: real motion, one rig per window, temporal detector noise.

A :class:`SequenceBank` keeps motion capture as clean continuous segments (COCO-17, metres,
z up, at ``fps`` frames per second). A :class:`SequenceSource` draws windows from it: each
window plays one segment at a random frame rate (10-120 fps) and speed, places the person in a
room, sees them with one random rig (:func:`rmpl.synth.cameras.sample_cameras`) and runs the
per-frame detector model (:func:`rmpl.synth.noise.detect_like`) with the temporal structure
one frame cannot show (:class:`TemporalNoise`):

- 2D error correlated over time (an AR(1) process per view and joint);
- occlusion bursts: a joint, a limb or the whole person missing in a view for a run of frames;
- left/right swaps and whole-body flips that last several frames;
- identity confusions: a view follows another person for a run of frames (the association
  and tracking errors of ``rmpl run``);
- whole frames missing in every view (the person left all images, or the tracker lost them).

Shape glossary: ``B`` windows, ``T`` frames, ``V`` views, ``J`` joints.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from rmpl.data.synthetic import floor_rows
from rmpl.errors import InputError
from rmpl.geometry.camera import project, rodrigues
from rmpl.geometry.rays import rays_from_keypoints
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17, HALPE26
from rmpl.synth.noise import (
    DEFAULT_INPUT_SETS,
    NoiseConfig,
    check_input_sets,
    detect_like,
    input_joint_sets,
    joint_sigmas,
)

__all__ = [
    "SequenceBank",
    "SequenceBatch",
    "SequenceSource",
    "TemporalNoise",
    "anny_sequence_bank",
]

log = logging.getLogger(__name__)

MAX_JOINT_SPEED = 15.0  # m/s: a joint faster than this between two frames is a capture glitch
_LIMBS = (
    (5, 7, 9),  # left arm
    (6, 8, 10),  # right arm
    (11, 13, 15),  # left leg
    (12, 14, 16),  # right leg
)


#: For :meth:`SequenceBank.on_floor`: the lowest joint's height above the floor when it
#: touches it, metres, by joint set. COCO-17: the ankle, :data:`rmpl.geometry.floor.ANKLE_HEIGHT`.
#: HALPE-26 on anny: a heel or toe point, 0.016 m (the median over the MHP renders of the
#: lowest joint above the mesh's lowest vertex, ``data/mhp26_train``).
FLOOR_CONTACT: dict[str, float] = {"coco17": 0.07, "halpe26": 0.016}


@dataclass
class SequenceBank:
    """Clean motion segments.

    Attributes:
        poses: (N, J, 3) float32, metres, z up, floor at z = 0; segments back to back.
        start: (S,) int, first pose of each segment. length: (S,) int, its poses.
        subject: (S,) str, the subject of each segment (CMU subject id).
        fps: frames per second of ``poses``.
    """

    poses: np.ndarray
    start: np.ndarray
    length: np.ndarray
    subject: np.ndarray
    fps: float

    def __len__(self) -> int:
        return len(self.start)

    def select(self, keep: np.ndarray) -> SequenceBank:
        """The segments where ``keep`` (bool, shape (S,)) is True."""
        starts, lengths = self.start[keep], self.length[keep]
        parts = [self.poses[s : s + n] for s, n in zip(starts, lengths, strict=True)]
        new_start = (np.cumsum(lengths) - lengths).astype(np.int64)
        poses = np.concatenate(parts) if parts else self.poses[:0]
        return SequenceBank(poses, new_start, lengths.copy(), self.subject[keep], self.fps)

    def on_floor(
        self, contact: float, tolerance: float = 0.10, min_fraction: float = 0.5
    ) -> tuple[SequenceBank, np.ndarray]:
        """The segments that stand on a floor, levelled so that the floor is z = 0.

        A segment's lowest point over time is a poor floor (one foot through the ground
        sets it). Here the floor is the 5th percentile over the segment's frames of the
        lowest joint's height, minus ``contact`` (that joint's height above the floor when
        it touches it). A segment is on a floor when at least ``min_fraction`` of its frames
        have their lowest joint within ``tolerance`` metres of that level; the others
        (a playground, a stage, a motion that floats) are left out. Jumps, sitting and lying
        within a kept segment stay as recorded.

        Returns:
            (the kept, levelled segments, the kept mask over the segments (S,)).
        """
        low = np.nanmin(self.poses[..., 2], axis=-1)  # (N,)
        keep = np.zeros(len(self), bool)
        poses = self.poses.copy()
        for i, (s, n) in enumerate(zip(self.start, self.length, strict=True)):
            level = np.percentile(low[s : s + n], 5)
            keep[i] = np.mean(low[s : s + n] - level < tolerance) >= min_fraction
            poses[s : s + n, :, 2] -= level - contact
        levelled = SequenceBank(poses, self.start, self.length, self.subject, self.fps)
        return levelled.select(keep), keep

    def pose_set(self):
        """The bank's poses as a :class:`rmpl.synth.motion.bank.PoseSet` (clip = segment)."""
        from rmpl.synth.motion.bank import PoseSet

        seg = np.repeat(np.arange(len(self)), self.length)
        frame = np.concatenate([np.arange(n) for n in self.length]) if len(self) else seg
        return PoseSet(self.poses, np.repeat(self.subject, self.length), seg.astype(str), frame)

    def split(self, holdout: list[str] | tuple[str, ...]) -> tuple[SequenceBank, SequenceBank]:
        """(segments of other subjects, segments of ``holdout`` subjects)."""
        held = np.isin(self.subject, list(holdout))
        return self.select(~held), self.select(held)

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        with atomic_path(path) as tmp:
            np.savez_compressed(
                tmp,
                poses=self.poses,
                start=self.start,
                length=self.length,
                subject=self.subject.astype(str),
                fps=np.float64(self.fps),
                kind=np.array("rmpl-sequence-bank-1"),
            )
        return path

    @staticmethod
    def load(path: str | Path) -> SequenceBank:
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                if "kind" not in z.files or str(z["kind"]) != "rmpl-sequence-bank-1":
                    raise InputError(path, "kind", "a sequence bank from `rmpl poses --sequences`")
                return SequenceBank(
                    z["poses"].astype(np.float32),
                    z["start"].astype(np.int64),
                    z["length"].astype(np.int64),
                    z["subject"].astype(str),
                    float(z["fps"]),
                )
        except KeyError as e:
            raise InputError(
                path, str(e).strip("'"), "an array of a sequence bank", "none"
            ) from None
        except (OSError, ValueError) as e:
            raise InputError(path, None, "a sequence bank (.npz)", str(e)) from None

    @staticmethod
    def from_motion_dir(
        root: str | Path, fps: float = 60.0, min_seconds: float = 1.0
    ) -> SequenceBank:
        """Every clean stretch of motion below ``root`` (ASF/AMC, BVH), resampled to ``fps``."""
        segments = [
            (clip.subject, seg)
            for clip, motion in _motion_clips(root)
            for seg in _clean_segments(motion, fps, min_seconds)
        ]
        return _packed(segments, fps, root, min_seconds)


def _motion_clips(root: str | Path, progress: bool = False):
    """Every usable clip below ``root``, loaded: ``(clip, motion)`` pairs.

    Raises:
        InputError: no .amc or .bvh file below ``root``.
    """
    from rmpl.synth import motion as M

    clips = [c for c in M.find_clips(root) if not M._matches(c.clip, M.BROKEN_CLIPS)]
    if not clips:
        raise InputError(root, None, "some .amc or .bvh files", "none")
    if progress:
        from tqdm import tqdm

        clips = tqdm(clips, desc="clips", unit="clip")
    skeletons: dict = {}
    for clip in clips:
        yield clip, M._load_clip(clip, skeletons)


def _packed(segments: list, fps: float, root, min_seconds: float) -> SequenceBank:
    """``(subject, poses (T, J, 3))`` segments back to back as a :class:`SequenceBank`."""
    if not segments:
        raise InputError(root, None, f"clean motion of at least {min_seconds} s", "none")
    lengths = np.array([len(seg) for _, seg in segments], np.int64)
    return SequenceBank(
        np.concatenate([seg for _, seg in segments]).astype(np.float32),
        np.cumsum(lengths) - lengths,
        lengths,
        np.array([subject for subject, _ in segments], str),
        float(fps),
    )


def _clean_segments(motion, fps: float, min_seconds: float) -> list[np.ndarray]:
    """The clip's usable stretches as COCO-17 at ``fps``, floor at z = 0, cut where a joint
    moves faster than :data:`MAX_JOINT_SPEED` (capture glitches, rest-pose blends)."""
    return [seg for seg, _ in _clean_segment_frames(motion, fps, min_seconds)]


def _clean_segment_frames(motion, fps: float, min_seconds: float):
    """:func:`_clean_segments`, each with its fractional source frames: [(seg, t)]."""
    from rmpl.synth import motion as M

    keep = M.usable_frames(motion, min_seconds)
    if not keep.any():
        return []
    joints = M.to_coco17(motion)
    joints[..., 2] -= M.floor_height(motion.positions[keep])
    edges = np.flatnonzero(np.diff(np.r_[0, keep.astype(np.int8), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        dur = (b - a - 1) / motion.fps
        if dur < min_seconds:
            continue
        t = np.arange(0, dur, 1.0 / fps) * motion.fps + a  # fractional source frames
        i0 = np.floor(t).astype(int).clip(a, b - 1)
        i1 = np.minimum(i0 + 1, b - 1)
        w = (t - i0)[:, None, None]
        out += _continuous((1 - w) * joints[i0] + w * joints[i1], t, fps, min_seconds)
    return out


def _continuous(seg: np.ndarray, t: np.ndarray, fps: float, min_seconds: float):
    """``seg`` (T, J, 3) and its source frames ``t`` (T,) cut at every frame where a joint
    jumps, pieces shorter than ``min_seconds`` dropped: [(seg, t)]."""
    speed = np.linalg.norm(np.diff(seg, axis=0), axis=-1).max(-1) * fps  # (T - 1,)
    cuts = np.flatnonzero(speed > MAX_JOINT_SPEED) + 1
    parts = zip(np.split(seg, cuts), np.split(t, cuts), strict=True)
    return [(p, q) for p, q in parts if (len(p) - 1) / fps >= min_seconds]


def anny_sequence_bank(
    root: str | Path,
    body_model,
    fps: float = 30.0,
    min_seconds: float = 1.0,
    seed: int = 0,
    batch: int = 256,
    progress: bool = False,
) -> SequenceBank:
    """The segments of :meth:`SequenceBank.from_motion_dir`, each retargeted onto one random
    anny body (a track keeps its body), with ``body_model``'s joints (HALPE-26 from
    ``BodyModel(joints="halpe26")``: the same mesh definitions as the MHP renders).

    Each frame takes the mocap's rotations at its nearest source frame; the body's mid-hip
    follows the mocap's, scaled by the ratio of leg lengths (as ``rmpl generate`` moves its
    sequences); the segment's lowest vertex stands on the floor (z = 0).
    """
    from rmpl.anthropometry import leg_length
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.retarget import anny_deltas, bone_parents, mocap_drivers, reference_heads

    rng = np.random.default_rng(seed)
    parents = bone_parents(body_model)
    out = []
    for clip, motion in _motion_clips(root, progress):
        segments = _clean_segment_frames(motion, fps, min_seconds)
        if not segments:
            continue
        rot, dirs = mocap_drivers(motion)
        for mocap, t in segments:
            phen = sample_phenotypes(1, rng)
            ref = reference_heads(body_model, phen)
            src = np.clip(np.rint(t).astype(int), 0, len(rot) - 1)
            joints, floor = [], np.inf
            for i in range(0, len(src), batch):
                rows = src[i : i + batch]
                deltas = anny_deltas(rot[rows].astype(float), dirs.astype(float),
                                     np.repeat(ref, len(rows), 0), body_model.bone_names,
                                     parents)  # fmt: skip
                bodies = body_model(deltas, np.repeat(phen, len(rows), 0))
                joints.append(bodies.keypoints.astype(float))
                floor = min(floor, float(bodies.vertices[..., 2].min()))
            joints = np.concatenate(joints)
            scale = leg_length(joints) / max(leg_length(mocap), 1e-6)
            path = scale * mocap[:, 11:13].mean(1)
            shift = path - joints[:, 11:13].mean(1)  # (T, 3): the body's mid-hip on the path
            shift[:, 2] = 0.0
            joints = joints + shift[:, None]
            joints[..., 2] -= floor
            out.append((clip.subject, joints.astype(np.float32)))
    return _packed(out, fps, root, min_seconds)


@dataclass(frozen=True)
class TemporalNoise:
    """The temporal part of the detector model (rates per window unless said otherwise).

    Attributes:
        fps_range: frame rates drawn log-uniformly, frames per second.
        speed_range: playback speed of the motion.
        iid_scale: factor on the per-frame (independent) 2D error of :class:`NoiseConfig`.
        corr_scale: the correlated error's std, as a factor of the per-joint 2D error.
        corr_tau: range of its time constant, seconds (log-uniform).
        burst_rate: mean occlusion bursts per view and window.
        burst_seconds: range of a burst's duration (log-uniform), seconds.
        swap_rate: probability per view and left/right pair of a swap run.
        flip_rate: probability per view of a whole-body flip run.
        swap_seconds: range of a swap or flip run's duration, seconds.
        identity_rate: probability per window that one view follows another person.
        identity_seconds: range of that run's duration, seconds.
        gap_rate: probability per window of a run of frames missing in every view.
        gap_frames: the most frames of such a run.
        drop_rate: independent keypoint removal per frame.
    """

    fps_range: tuple[float, float] = (10.0, 120.0)
    speed_range: tuple[float, float] = (0.8, 1.25)
    iid_scale: float = 0.7
    corr_scale: float = 0.7
    corr_tau: tuple[float, float] = (0.05, 1.0)
    burst_rate: float = 0.5
    burst_seconds: tuple[float, float] = (0.1, 2.0)
    swap_rate: float = 0.03
    flip_rate: float = 0.02
    swap_seconds: tuple[float, float] = (0.1, 0.6)
    identity_rate: float = 0.08
    identity_seconds: tuple[float, float] = (0.2, 1.0)
    gap_rate: float = 0.15
    gap_frames: int = 12
    drop_rate: float = 0.1

    @classmethod
    def from_dict(cls, d: dict) -> TemporalNoise:
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(
                f"unknown TemporalNoise keys {sorted(unknown)}; known: {sorted(known)}"
            )
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


@dataclass
class SequenceBatch:
    """Windows of one person each.

    Attributes:
        rays: (B, T, V, J, 6) float32; scores: (B, T, V, J) float32, 0 = missing.
        times: (B, T) float32 seconds. target: (B, T, J, 3) float32 metres.
        keypoints: (B, T, V, J, 2) pixels, NaN = missing. K, R, t: (B, V, ...) the rig.
        floor: (B, 4) each window's floor ``[n, h]`` for a model that reads it, NaN rows =
            not given; None = no floor at all (see :class:`rmpl.data.synthetic.Batch`).
    """

    rays: np.ndarray
    scores: np.ndarray
    times: np.ndarray
    target: np.ndarray
    keypoints: np.ndarray
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    floor: np.ndarray | None = None


class SequenceSource:
    """Fresh training windows from a :class:`SequenceBank`.

    Args:
        bank: the motion.
        noise: the per-frame detector model; its per-frame view misses, flips, swaps and
            truncations are replaced by temporal runs (:class:`TemporalNoise`).
        temporal: the temporal detector model.
        camera_preset: random camera setup preset; room: half-extent of the floor area.
        seed: random seed.
        input_sets: with HALPE-26 motion, how often each kind of detector draws a window
            (see :class:`rmpl.data.synthetic.SamplerConfig`).
        floor: (rate, height error sd in metres, tilt error sd in degrees): the share of
            windows whose floor (z = 0: the bank's segments levelled by
            :meth:`SequenceBank.on_floor`) is given, and its error; validation windows get
            the exact floor. Rate 0: ``SequenceBatch.floor`` is None.
    """

    def __init__(
        self,
        bank: SequenceBank,
        noise: NoiseConfig | None = None,
        temporal: TemporalNoise | None = None,
        camera_preset: str = "universal",
        room: float = 2.0,
        scale_range: tuple[float, float] = (0.88, 1.22),
        seed: int | None = None,
        input_sets: tuple[tuple[str, float], ...] = DEFAULT_INPUT_SETS,
        floor: tuple[float, float, float] = (0.0, 0.02, 1.0),
    ) -> None:
        if len(bank) == 0:
            raise ValueError("the sequence bank has no segment")
        self.bank = bank
        self.temporal = temporal or TemporalNoise()
        base = noise or NoiseConfig()
        self.noise = replace(
            base,
            joint_sigma=tuple(self.temporal.iid_scale * np.asarray(base.joint_sigma)),
            swap_rate=0.0,
            flip_rate=0.0,
            miss_view_rate=0.01,
            truncate_rate=0.02,
        )
        self.joint_sigma = joint_sigmas(base.joint_sigma, bank.poses.shape[1])
        self.input_sets = check_input_sets(input_sets)
        self.camera_preset, self.room, self.scale_range = camera_preset, room, scale_range
        if not 0 <= floor[0] <= 1 or min(floor[1:]) < 0:
            raise ValueError(f"floor must be (rate in [0, 1], sd >= 0, sd >= 0), got {floor}")
        self.floor = tuple(float(x) for x in floor)
        self.rng = np.random.default_rng(seed)

    def motion(self, B: int, T: int) -> tuple[np.ndarray, np.ndarray]:
        """B windows of T frames: placed joints (B, T, J, 3) and times (B, T) seconds."""
        rng, bank, tn = self.rng, self.bank, self.temporal
        seg = rng.choice(len(bank), B, p=bank.length / bank.length.sum())
        fps = np.exp(rng.uniform(*np.log(tn.fps_range), B))
        speed = rng.uniform(*tn.speed_range, B)
        dur = (bank.length[seg] - 1) / bank.fps  # seconds of motion available
        step = np.minimum(speed / fps, dur / max(T - 1, 1))  # source seconds per frame
        t0 = rng.uniform(0, 1, B) * (dur - step * (T - 1))
        src = (t0[:, None] + step[:, None] * np.arange(T)) * bank.fps  # fractional frames
        i0 = np.floor(src).astype(int)
        i1 = np.minimum(i0 + 1, bank.length[seg][:, None] - 1)
        w = (src - i0)[..., None, None]
        off = bank.start[seg][:, None]
        joints = (1 - w) * bank.poses[off + i0] + w * bank.poses[off + i1]
        times = np.arange(T)[None] / fps[:, None] + rng.uniform(0, 100, (B, 1))
        return self._place(joints.astype(np.float64)), times

    def _place(self, joints: np.ndarray) -> np.ndarray:
        """Mirror, scale, turn and place each window as a whole: (B, T, J, 3)."""
        rng = self.rng
        B = len(joints)
        mirror = rng.random(B) < 0.5
        skel = HALPE26 if joints.shape[2] == HALPE26.num_joints else COCO17
        flipped = joints[:, :, skel.flip_permutation()] * np.array([-1.0, 1.0, 1.0])
        joints = np.where(mirror[:, None, None, None], flipped, joints)
        root = joints[:, :, 11:13].mean(2).mean(1)  # (B, 3) mean mid-hip of the window
        origin = np.stack([root[:, 0], root[:, 1], np.zeros(B)], -1)[:, None, None]
        scale = rng.uniform(*self.scale_range, (B, 1, 1, 1))
        Rz = rodrigues(np.stack([np.zeros(B), np.zeros(B), rng.uniform(-np.pi, np.pi, B)], -1))
        local = np.einsum("bij,btnj->btni", Rz, (joints - origin) * scale)
        place = np.concatenate([rng.uniform(-self.room, self.room, (B, 2)), np.zeros((B, 1))], -1)
        return local + place[:, None, None]

    def batch(self, size: int, frames: int, num_views: int, train: bool = True) -> SequenceBatch:
        """Draw ``size`` windows of ``frames`` frames seen by ``num_views`` cameras."""
        from rmpl.synth.cameras import sample_cameras

        rng = self.rng
        B, T, V = size, frames, num_views
        joints, times = self.motion(B, T)
        J = joints.shape[2]
        centre = joints[:, :, 11:13].mean(2).mean(1)  # (B, 3)
        K, R, t, wh = sample_cameras(V, centre, self.camera_preset, rng)
        tile = lambda a: np.repeat(a, T, axis=0)  # noqa: E731  (B, ...) -> (B*T, ...)
        flat = joints.reshape(B * T, J, 3)
        kp, sc = detect_like(flat, tile(K), tile(R), tile(t), tile(wh), rng, self.noise)
        kp, sc = kp.reshape(B, T, V, J, 2), sc.reshape(B, T, V, J)
        uv = project(
            joints[:, :, None], K[:, None, :, None], R[:, None, :, None], t[:, None, :, None]
        )
        kp, sc = _temporal_noise(kp, sc, uv, joints, times, (K, R, t, wh), self, rng, train)
        if J == HALPE26.num_joints:  # the detector's joint set, one per window
            given = input_joint_sets(B, dict(self.input_sets), rng)[:, None, None]
            sc = np.where(given, sc, 0.0)
            kp = np.where(given[..., None], kp, np.nan)
        rays = rays_from_keypoints(kp, K=K[:, None], R=R[:, None], t=t[:, None])
        rays = np.where(sc[..., None] > 0, rays, 0.0)
        rate, noise_m, tilt_deg = self.floor
        noisy = (noise_m, tilt_deg) if train else (0.0, 0.0)
        return SequenceBatch(
            rays.astype(np.float32),
            sc.astype(np.float32),
            times.astype(np.float32),
            joints.astype(np.float32),
            kp,
            K,
            R,
            t,
            floor_rows(B, rate, *noisy, rng),  # drawn last: without a floor, nothing drawn
        )


def _runs(rng, shape, rate, seconds, times) -> np.ndarray:
    """A boolean mask (*shape, T): at most one run per entry, drawn with probability ``rate``,
    lasting a log-uniform duration in ``seconds``. times: (B, T); shape starts with B."""
    B, T = times.shape
    on = rng.random(shape) < rate
    dur = np.exp(rng.uniform(*np.log(seconds), shape))
    span = times[:, -1] - times[:, 0]  # (B,)
    span = span.reshape((B,) + (1,) * (len(shape) - 1))
    begin = times[:, :1].reshape(span.shape) + rng.uniform(-0.5, 1.0, shape) * span
    tt = times.reshape((B,) + (1,) * (len(shape) - 1) + (T,))
    return on[..., None] & (tt >= begin[..., None]) & (tt < (begin + dur)[..., None])


def _temporal_noise(kp, sc, uv, joints, times, rig, src: SequenceSource, rng, train: bool):
    """Add the temporal detector model to per-frame keypoints.

    kp (B, T, V, J, 2), sc (B, T, V, J), uv (B, T, V, J, 2) the true projections, joints
    (B, T, J, 3), times (B, T). Returns new (kp, sc).
    """
    tn = src.temporal
    height = np.nan_to_num(np.ptp(uv, axis=3).max(-1), nan=1.0).clip(5, None)  # (B, T, V)
    kp = kp + _correlated_error(kp.shape, times, height, src, rng)
    kp, sc = _swap_runs(kp, sc.copy(), times, tn, rng)
    if len(kp) > 1:
        kp, sc = _identity_confusion(kp, sc, joints, times, rig, height, tn, rng)
    missing = _occlusions(kp.shape[:-1], times, tn, rng, train)
    w, h = rig[3][:, None, :, None, 0], rig[3][:, None, :, None, 1]
    outside = (kp[..., 0] < 0) | (kp[..., 0] > w - 1) | (kp[..., 1] < 0) | (kp[..., 1] > h - 1)
    missing |= outside | ~np.isfinite(kp).all(-1) | (sc <= 0)
    kp[missing] = np.nan
    sc[missing] = 0.0
    return kp, sc


def _correlated_error(shape, times, height, src: SequenceSource, rng) -> np.ndarray:
    """2D error (B, T, V, J, 2) pixels, an AR(1) process per window, view and joint."""
    tn = src.temporal
    B, T, V, J, _ = shape
    tau = np.exp(rng.uniform(*np.log(tn.corr_tau), (B, 1, 1)))
    dt = np.diff(times, axis=1, prepend=times[:, :1])[:, :, None, None]  # (B, T, 1, 1)
    rho = np.exp(-dt / tau[:, None])  # (B, T, 1, 1)
    e = np.empty((B, T, V, J, 2))
    e[:, 0] = rng.standard_normal((B, V, J, 2))
    white = rng.standard_normal((B, T, V, J, 2))
    for k in range(1, T):  # the recursion runs over frames only
        r = rho[:, k, ..., None]
        e[:, k] = r * e[:, k - 1] + np.sqrt(1 - r**2) * white[:, k]
    scale = tn.corr_scale * src.joint_sigma[None, None, None, :, None] * height[..., None, None]
    return e * scale


def _swap_runs(kp, sc, times, tn: TemporalNoise, rng):
    """Left/right swap runs of single pairs and whole-body flip runs, per view."""
    B, T, V, J, _ = kp.shape
    pairs = np.array((HALPE26 if J == HALPE26.num_joints else COCO17).flip_pairs)
    swap = _runs(rng, (B, V, len(pairs)), tn.swap_rate, tn.swap_seconds, times)  # (B,V,P,T)
    swap |= _runs(rng, (B, V, 1), tn.flip_rate, tn.swap_seconds, times)
    swap = swap.transpose(0, 3, 1, 2)  # (B, T, V, P)
    perm = np.broadcast_to(np.arange(J), (B, T, V, J)).copy()
    for i, (a, b) in enumerate(pairs):
        perm[..., a] = np.where(swap[..., i], b, perm[..., a])
        perm[..., b] = np.where(swap[..., i], a, perm[..., b])
    kp = np.take_along_axis(kp, perm[..., None].repeat(2, -1), axis=3)
    return kp, np.take_along_axis(sc, perm, axis=3)


def _identity_confusion(kp, sc, joints, times, rig, height, tn: TemporalNoise, rng):
    """One view follows the next window's person for a run of frames."""
    B, T, V = kp.shape[:3]
    other = np.roll(joints, 1, axis=0)
    K, R, t, _ = rig
    uv_o = project(other[:, :, None], K[:, None, :, None], R[:, None, :, None], t[:, None, :, None])
    which = rng.integers(0, V, B)
    run = _runs(rng, (B,), tn.identity_rate, tn.identity_seconds, times)  # (B, T)
    hit = run[:, :, None] & (np.arange(V)[None, None] == which[:, None, None])  # (B, T, V)
    jitter = 0.01 * height[..., None, None] * rng.standard_normal(kp.shape)
    conf = rng.uniform(0.3, 0.9, sc.shape)
    return np.where(hit[..., None, None], uv_o + jitter, kp), np.where(hit[..., None], conf, sc)


def _occlusions(shape, times, tn: TemporalNoise, rng, train: bool) -> np.ndarray:
    """Missing (B, T, V, J): bursts of a joint, a limb or the whole person in one view, runs
    of frames missing in every view, and (training) independent keypoint removal."""
    B, T, V, J = shape
    missing = np.zeros(shape, bool)
    for _ in range(2):
        run = _runs(rng, (B, V), tn.burst_rate / 2, tn.burst_seconds, times)  # (B, V, T)
        kind = rng.random((B, V))
        joint = rng.integers(0, J, (B, V))
        limb = np.array(_LIMBS)[rng.integers(0, len(_LIMBS), (B, V))]  # (B, V, 3)
        sel = np.zeros((B, V, J), bool)
        np.put_along_axis(sel, joint[..., None], True, axis=2)
        sel_limb = np.zeros((B, V, J), bool)
        np.put_along_axis(sel_limb, limb, True, axis=2)
        sel = np.where((kind >= 0.4)[..., None], sel_limb, sel)
        sel = np.where((kind >= 0.7)[..., None], True, sel)
        missing |= run.transpose(0, 2, 1)[..., None] & sel[:, None]
    gap = rng.random(B) < tn.gap_rate
    length = rng.integers(1, tn.gap_frames + 1, B)
    first = rng.integers(0, T, B)
    k = np.arange(T)[None]
    gaps = gap[:, None] & (k >= first[:, None]) & (k < (first + length)[:, None])  # (B, T)
    missing |= gaps[:, :, None, None]
    if train and tn.drop_rate > 0:
        missing |= rng.random(missing.shape) < tn.drop_rate
    return missing
