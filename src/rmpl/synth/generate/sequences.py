"""Sequences: continuous mocap segments (:class:`MotionBank`) played by one body, seen by
one rig, every frame rendered and detected.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from rmpl.anthropometry import leg_length
from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.synth.generate.detectors import detect_person, follows, in_joint_set
from rmpl.synth.generate.frames import _scale_cameras
from rmpl.synth.shards import (
    SEQUENCE_ARRAYS,
    shard_path,
    write_shard,
)

log = logging.getLogger(__name__)

#: The format of a motion bank file (``motion.npz``).
_MOTION_FORMAT = "rmpl.mhp.motion.v1"


@dataclass(frozen=True, eq=False)
class MotionBank:
    """Continuous mocap segments ready to retarget onto anny, at their source frame rate.

    Attributes:
        rotations: driver rotations of every frame, segments back to back, shape
            (N, K, 3, 3) float32 (see :func:`rmpl.synth.retarget.mocap_drivers`).
        joints: the mocap's own COCO-17 joints, metres, z up, shape (N, 17, 3) float32 (for
            the root's path and the leg length).
        start, length: first row and frames of each segment, shape (G,) int64.
        first: each segment's first frame in its clip, shape (G,) int64.
        clip_index: each segment's clip, shape (G,) int64, into the per-clip arrays:
        clips, subjects: clip path and subject id, shape (C,) str.
        fps: source frames per second, shape (C,) float64.
        rest_dirs: driver rest directions, shape (C, K, 3) float32.
    """

    rotations: np.ndarray
    joints: np.ndarray
    start: np.ndarray
    length: np.ndarray
    first: np.ndarray
    clip_index: np.ndarray
    clips: np.ndarray
    subjects: np.ndarray
    fps: np.ndarray
    rest_dirs: np.ndarray

    def __len__(self) -> int:
        return len(self.start)

    def seconds_per_subject(self) -> dict[str, float]:
        """Seconds of motion per subject."""
        secs = (self.length - 1) / self.fps[self.clip_index]
        subj = self.subjects[self.clip_index]
        return {str(s): round(float(secs[subj == s].sum()), 2) for s in np.unique(subj)}

    def select(self, keep: np.ndarray) -> MotionBank:
        """The segments where ``keep`` (bool, shape (G,)) is True."""
        length = self.length[keep]
        rows = [np.arange(a, a + n) for a, n in zip(self.start[keep], length, strict=True)]
        rows = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        return MotionBank(
            self.rotations[rows],
            self.joints[rows],
            (np.cumsum(length) - length).astype(np.int64),
            length,
            self.first[keep],
            self.clip_index[keep],
            self.clips,
            self.subjects,
            self.fps,
            self.rest_dirs,
        )


def _segments(keep: np.ndarray, joints: np.ndarray, fps: float) -> list[tuple[int, int]]:
    """(first, stop) frame ranges of the clean stretches of a clip: ``keep`` frames (T,)
    cut wherever a joint moves faster than :data:`rmpl.data.sequences.MAX_JOINT_SPEED`
    between two frames (capture glitches). joints: (T, 17, 3) metres."""
    from rmpl.data.sequences import MAX_JOINT_SPEED

    speed = np.linalg.norm(np.diff(joints, axis=0), axis=-1).max(-1) * fps  # (T - 1,)
    edges = np.flatnonzero(np.diff(np.r_[0, keep.astype(np.int8), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        cuts = a + 1 + np.flatnonzero(speed[a : b - 1] > MAX_JOINT_SPEED)
        bounds = np.r_[a, cuts, b]
        pieces = zip(bounds[:-1], bounds[1:], strict=True)
        out += [(int(x), int(y)) for x, y in pieces if y - x >= 2]
    return out


def build_motion_bank(
    root: str | Path, subjects: list[str] | None = None, exclude_subjects: tuple[str, ...] = ()
) -> MotionBank:
    """Every clean stretch of motion under ``root`` (ASF/AMC, BVH) at its own frame rate.

    Args:
        root: folder of motion files. subjects: keep only these subject ids (None = all).
        exclude_subjects: drop these subject ids.

    Raises:
        InputError: no clip of the selected subjects, or none with clean motion.
    """
    from rmpl.synth.motion import BROKEN_CLIPS, find_clips, to_coco17, usable_frames
    from rmpl.synth.motion.bank import _load_clip, _matches
    from rmpl.synth.retarget import mocap_drivers

    clips = [
        c
        for c in find_clips(root, subjects)
        if c.subject not in set(exclude_subjects) and not _matches(c.clip, BROKEN_CLIPS)
    ]
    if not clips:
        raise InputError(root, "poses", "motion clips of the selected subjects", "none")
    rot, joints, first, clip_index, names, subj, fps, dirs = [], [], [], [], [], [], [], []
    skeletons: dict = {}
    for c in clips:
        motion = _load_clip(c, skeletons)
        coco = to_coco17(motion)
        segs = _segments(usable_frames(motion), coco, motion.fps)
        if not segs:
            continue
        r, d = mocap_drivers(motion)
        for a, b in segs:
            rot.append(r[a:b].astype(np.float32))
            joints.append(coco[a:b].astype(np.float32))
            first.append(a)
            clip_index.append(len(names))
        names.append(c.clip)
        subj.append(c.subject)
        fps.append(float(motion.fps))
        dirs.append(d.astype(np.float32))
    if not rot:
        raise InputError(root, "poses", "clips with clean motion", "none")
    length = np.array([len(r) for r in rot], np.int64)
    bank = MotionBank(
        np.concatenate(rot),
        np.concatenate(joints),
        (np.cumsum(length) - length).astype(np.int64),
        length,
        np.array(first, np.int64),
        np.array(clip_index, np.int64),
        np.array(names, str),
        np.array(subj, str),
        np.array(fps, np.float64),
        np.stack(dirs),
    )
    log.info("motion bank %s: %d segments, %d frames from %d clips", root, len(bank),
             length.sum(), len(names))  # fmt: skip
    return bank


_MOTION_KEYS = tuple(f.name for f in fields(MotionBank))


def save_motion_bank(path: str | Path, bank: MotionBank) -> Path:
    """Write a :class:`MotionBank` to ``.npz`` atomically."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, format=np.array(_MOTION_FORMAT), **{k: getattr(bank, k) for k in _MOTION_KEYS})
    return path


def load_motion_bank(path: str | Path) -> MotionBank:
    """Read a bank written by :func:`save_motion_bank` (a sequence run's ``motion.npz``)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if "format" not in z.files or str(z["format"]) != _MOTION_FORMAT:
                got = str(z["format"]) if "format" in z.files else "none"
                raise InputError(path, "format", f"{_MOTION_FORMAT!r} (a motion.npz)", got)
            missing = [k for k in _MOTION_KEYS if k not in z.files]
            if missing:
                raise InputError(path, missing[0], "an array of a motion bank", "missing")
            return MotionBank(**{k: z[k] for k in _MOTION_KEYS})
    except (OSError, ValueError, EOFError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(path, None, "a motion bank .npz (motion.npz)", e) from None


@dataclass
class _Sequence:
    """One sequence: a body moving through T frames, seen by one rig of V cameras."""

    vertices: np.ndarray  # (T, N, 3) world metres
    joints: np.ndarray  # (T, 17, 3) COCO-17, world metres
    phenotypes: np.ndarray  # (6,)
    subject: str
    clip: str
    frames: np.ndarray  # (T,) source frames in the clip
    mirrored: bool
    fps: float  # frames per second
    speed: float  # motion seconds per second
    rejected: int  # implausible sequences drawn and replaced
    K: np.ndarray  # (V, 3, 3) pixels
    R: np.ndarray  # (V, 3, 3)
    t: np.ndarray  # (V, 3) metres
    size: np.ndarray  # (V, 2) pixels
    projected: np.ndarray  # (T, V, 17, 2) pixels


def draw_window(
    bank: MotionBank, frames: int, fps_range, speed_range, rng: np.random.Generator
) -> tuple[int, np.ndarray, float, float]:
    """A window of ``frames`` frames of one segment, its source frames every k-th.

    The segment is drawn in proportion to its length among those with at least ``frames``
    frames; a frame rate log-uniformly in ``fps_range`` and a speed uniformly in
    ``speed_range``; ``k = round(speed * source fps / fps)`` (at least 1, at most what the
    segment holds), so the realised rate is ``source fps * speed / k``.

    Returns:
        (segment, rows of ``bank.rotations`` (frames,), realised fps, speed).
    """
    usable = bank.length >= frames
    p = np.where(usable, bank.length, 0).astype(float)
    seg = int(rng.choice(len(bank), p=p / p.sum()))
    fps = float(np.exp(rng.uniform(*np.log(fps_range))))
    speed = float(rng.uniform(*speed_range))
    source = float(bank.fps[bank.clip_index[seg]])
    n = int(bank.length[seg])
    most = (n - 1) // max(frames - 1, 1)
    k = int(np.clip(round(speed * source / fps), 1, max(most, 1)))
    begin = int(rng.integers(0, n - (frames - 1) * k))
    rows = bank.start[seg] + begin + k * np.arange(frames)
    return seg, rows, source * speed / k, speed


def _sequence_pose(worker, seg: int, rows: np.ndarray, phen: np.ndarray, mirrored, rng):
    """anny deltas (T, P, 3, 3) of the window ``rows`` on one body: one perturbation of the
    driven bones for the whole sequence, mirrored or not as a whole."""
    from rmpl.synth.retarget import (
        anny_deltas,
        bone_parents,
        mirror_pose,
        perturb_pose,
        reference_heads,
    )

    body, bank, T = worker.body, worker.motion, len(rows)
    ref = reference_heads(body, phen[None])  # (1, P, 3)
    dirs = bank.rest_dirs[bank.clip_index[seg]].astype(float)
    pose = anny_deltas(
        bank.rotations[rows].astype(float),
        dirs,
        np.repeat(ref, T, axis=0),
        body.bone_names,
        bone_parents(body),
    )
    # perturb_pose on the identity gives the rotations it would apply; use them every frame.
    turn = perturb_pose(body.identity_pose(1)[..., :3, :3], body.bone_names, rng,
                        worker.cfg.perturb_deg)[0]  # fmt: skip
    pose = turn @ pose
    return mirror_pose(pose, body.bone_names) if mirrored else pose


def follow_root(
    vertices: np.ndarray, joints: np.ndarray, mocap: np.ndarray, yaw: float, where: np.ndarray
):
    """Move the posed body along the mocap's path, stand it on the floor, turn and place it.

    The body's mid-hip follows the mocap's mid-hip path, scaled by the ratio of the two leg
    lengths (a shorter body takes shorter steps), centred horizontally on the sequence's
    mean; the lowest vertex of the whole sequence lands on the floor (z = 0, so jumps and
    steps up stay in the air); then the sequence turns by ``yaw`` about +z and moves by
    ``where``.

    Args:
        vertices: (T, N, 3) and joints (T, 17, 3) of the posed body, anny's frame, metres.
        mocap: the mocap's COCO-17 joints of the same frames (T, 17, 3), metres, z up.
        yaw: radians. where: (2,) metres, where the path's centre lands on the floor.

    Returns:
        vertices (T, N, 3) and joints (T, 17, 3), world metres.
    """
    scale = leg_length(joints) / max(leg_length(mocap), 1e-6)
    path = mocap[:, 11:13].mean(axis=1)  # (T, 3) mocap mid-hip
    path = scale * (path - np.r_[path[:, :2].mean(axis=0), 0.0])
    shift = path - joints[:, 11:13].mean(axis=1)  # (T, 3)
    vertices, joints = vertices + shift[:, None], joints + shift[:, None]
    floor = vertices[..., 2].min()
    c, s = np.cos(yaw), np.sin(yaw)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    move = np.r_[where, -floor]
    return (
        (vertices @ Rz.T + move).astype(np.float32),
        (joints @ Rz.T + move).astype(np.float32),
    )


def _draw_sequence(worker, rng: np.random.Generator) -> _Sequence:
    """One plausible sequence placed in the room, seen by one random rig."""
    from rmpl.geometry.camera import project
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.retarget import implausible

    cfg, bank, T = worker.cfg, worker.motion, worker.cfg.sequence_frames
    rejected = 0
    for _ in range(cfg.max_tries):
        seg, rows, fps, speed = draw_window(bank, T, cfg.sequence_fps, cfg.sequence_speed, rng)
        phen = sample_phenotypes(1, rng, cfg.min_age)[0]
        mirrored = bool(rng.random() < cfg.mirror)
        pose = _sequence_pose(worker, seg, rows, phen, mirrored, rng)
        bodies = worker.body(pose, np.repeat(phen[None], T, axis=0))
        if not implausible(bodies.keypoints).any():
            break
        rejected += 1
    else:
        raise RuntimeError(
            f"{cfg.max_tries} sequences in a row had an implausible frame; check 'poses' "
            f"({cfg.poses}) or raise max_tries"
        )
    mocap = bank.joints[rows].astype(float)
    if mirrored:
        mocap = mocap * np.array([-1.0, 1.0, 1.0])
    yaw, where = rng.uniform(-np.pi, np.pi), rng.uniform(-cfg.room, cfg.room, 2)
    verts, kps = follow_root(bodies.vertices, bodies.keypoints, mocap, yaw, where)
    center = kps[:, 11:13].mean(axis=1).mean(axis=0).astype(float)  # (3,)
    K, R, t, size = (a[0] for a in sample_cameras(cfg.views, center[None], cfg.camera_preset, rng))
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[:, None].astype(float), K[None, :, None], R[None, :, None], t[None, :, None])
    ci = int(bank.clip_index[seg])
    return _Sequence(
        verts, kps, phen, str(bank.subjects[ci]), str(bank.clips[ci]),
        bank.first[seg] + rows - bank.start[seg], mirrored, fps, speed, rejected,
        K, R, t, size, proj,
    )  # fmt: skip


def _render_detect(worker, seq: _Sequence, rng: np.random.Generator, times: dict):
    """Render every frame from every camera and detect: keypoints (T, V, 17, 2) pixels,
    scores (T, V, 17). One outfit and lighting for the sequence; each camera keeps its
    background.

    A detector that detects every image afresh (MediaPipe's legacy ``Pose``, as
    ``rmpl run --videos`` runs it by default) gets the V views of one frame at a time. A
    detector that follows people from frame to frame (:func:`follows`) gets each view as a
    video: reset, then that view's frames in order; each camera's background then comes from
    its own seed. Either way at most V images are held at once.
    """
    from rmpl.synth.render import random_lighting, random_outfits

    colors = random_outfits(worker.body.vertex_parts, 1, rng)
    light = random_lighting(rng)
    backdrop = int(rng.integers(0, 2**63 - 1))
    T, V, J = len(seq.vertices), len(seq.K), seq.joints.shape[1]
    kps, scores = np.full((T, V, J, 2), np.nan, np.float32), np.zeros((T, V, J), np.float32)

    def run(frame: int, views: slice, seed: int) -> None:
        t0 = time.perf_counter()
        images = worker.renderer.render(
            seq.vertices[frame : frame + 1],
            colors,
            seq.K[None, views],
            seq.R[None, views],
            seq.t[None, views],
            seq.size[None, views],
            lighting=[light],
            rng=seed,
        )
        t1 = time.perf_counter()
        kp, sc = detect_person(worker.detector, images)
        kp, sc = in_joint_set(worker.detector, kp, sc, worker.cfg.joints)
        times["render"] += t1 - t0
        times["detect"] += time.perf_counter() - t1
        kps[frame, views] = np.asarray(kp, np.float32).reshape(len(images), J, 2)
        scores[frame, views] = np.asarray(sc, np.float32).reshape(len(images), J)

    if not follows(worker.detector):
        for f in range(T):  # the same seed every frame: the same backgrounds
            run(f, slice(None), backdrop)
        return kps, scores
    seeds = np.random.default_rng(backdrop).integers(0, 2**63 - 1, V)
    for v in range(V):
        worker.detector.reset()
        for f in range(T):
            run(f, slice(v, v + 1), int(seeds[v]))
    return kps, scores


def _sequence_shard(worker, index: int, first: int, n: int, out: str | Path) -> dict:
    """Sequences ``first .. first + n - 1`` as shard ``index`` (see :func:`generate_shard`)."""
    cfg = worker.cfg
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    parts: dict[str, list] = {k: [] for k in SEQUENCE_ARRAYS}
    rejected = 0
    for i in range(first, first + n):
        rng = np.random.default_rng([cfg.seed, i, 2])  # a sequence is the same in any shard
        t0 = time.perf_counter()
        seq = _draw_sequence(worker, rng)
        times["pose"] += time.perf_counter() - t0
        kp, sc = _render_detect(worker, seq, rng, times)
        rejected += seq.rejected
        T = len(seq.joints)
        row = {
            "joints3d": seq.joints.astype(np.float32),
            "keypoints": kp,
            "scores": sc,
            "projected": seq.projected.astype(np.float32),
            "times": np.arange(T) / seq.fps,
            "fps": np.float64(seq.fps),
            "speed": np.float64(seq.speed),
            "K": seq.K,
            "R": seq.R,
            "t": seq.t,
            "size": seq.size.astype(np.int32),
            "phenotypes": seq.phenotypes.astype(np.float32),
            "subject": np.asarray(seq.subject, str),
            "clip": np.asarray(seq.clip, str),
            "frame": seq.frames.astype(np.int64),
            "mirrored": np.bool_(seq.mirrored),
        }
        for key, value in row.items():
            parts[key].append(value)
    arrays = {k: np.stack(v) for k, v in parts.items()}
    T, V = cfg.sequence_frames, cfg.views
    stats = {
        "shard": index,
        "sequences": n,
        "meshes": n * T,
        "views": n * T * V,
        "rejected": rejected,
        "missed_joints": int((arrays["scores"] == 0).sum()),
        "missed_views": int((arrays["scores"] == 0).all(-1).sum()),
        "seconds": times,
    }
    write_shard(shard_path(out, index), arrays, stats)
    return stats
