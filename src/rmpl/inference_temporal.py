"""Lift whole tracks: the temporal model over sliding windows, arrays in, arrays out.

::

    lifter = TemporalLifter.from_pretrained()              # the shipped temporal model
    track = lifter.lift_track(keypoints, scores, rig, fps=30)   # (T, V, 17, 2), (T, V, 17)
    track.points, track.sigma                              # (T, 17, 3) metres, (T, 17) metres

A track longer than the model's window is read in windows overlapping by half, each frame
averaged over the windows that hold it with triangular weights (a window's middle counts
most). Every frame is encoded once by the per-frame model. The world's up axis is handled as
in :class:`rmpl.inference.Lifter`.

How the answer is assembled is the checkpoint's ``"inference": {"assemble": ...}``
(:data:`ASSEMBLE`): ``"network"`` returns the temporal network's output; ``"filtered"``
(the shipped model's) takes the per-frame model's answer where at least two views see the
joint and the network's elsewhere, then runs ``rmpl run``'s filters over the whole track
(:func:`assemble_track`). The second was chosen on synthetic validation windows of a
held-out subject (docs/results.md): the network adds most where fewer than two views see a
joint.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.geometry.rays import rays_from_keypoints
from rmpl.inference import (
    checked_floor,
    estimate_up,
    floor_row,
    model_inputs,
    rotation_to_z,
)
from rmpl.model.temporal import RADIUS_50, RADIUS_90, TemporalRMPL
from rmpl.models import PRETRAINED_TEMPORAL, is_temporal_checkpoint
from rmpl.skeleton import Skeleton, skeleton_for

__all__ = [
    "ASSEMBLE",
    "RadiusCalibration",
    "assemble_track",
    "TemporalLifter",
    "TrackResult",
    "frame_times",
    "is_temporal_checkpoint",
    "window_starts",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RadiusCalibration:
    """Error radii from the model's scale, per number of views that see the joint.

    The network predicts one scale ``sigma`` per joint. How far its errors spread around that
    scale depends on how many views saw the joint (a joint no view sees is interpolated in
    time; one seen by five views is pinned by its rays), so the radius that holds half (nine
    tenths) of the errors is ``r50[k] * sigma`` (``r90[k] * sigma``), with ``k`` the number of
    views seeing the joint in that frame, the last entry serving every larger ``k``. The
    factors are quantiles of error / sigma on held-out windows
    (:func:`rmpl.training.temporal.fit_radius_calibration`; the shipped model's: MHP
    sequences seen by the real detector, ``rmpl.benchmarks.temporal_calibrate --mhp``), stored in
    the checkpoint's ``config.json`` under ``"calibration"``.
    """

    r50: tuple[float, ...]
    r90: tuple[float, ...]

    def __post_init__(self) -> None:
        a, b = np.asarray(self.r50, float), np.asarray(self.r90, float)
        if a.ndim != 1 or a.shape != b.shape or not len(a):
            raise ValueError("r50 and r90 must be non-empty lists of equal length")
        if not (np.isfinite(a).all() and np.isfinite(b).all() and (a > 0).all() and (b >= a).all()):
            raise ValueError("radius factors must be finite, > 0, with r90 >= r50")

    @classmethod
    def from_meta(cls, meta: dict, path: Path | None = None) -> RadiusCalibration | None:
        """The ``"calibration"`` entry of a checkpoint's config (None when it has none)."""
        c = meta.get("calibration")
        if c is None:
            return None
        try:
            return cls(tuple(map(float, c["r50"])), tuple(map(float, c["r90"])))
        except (TypeError, KeyError, ValueError) as e:
            raise InputError(
                path, "calibration", "r50 and r90: equal-length lists of radius factors > 0", e
            ) from None

    def to_meta(self) -> dict:
        return {
            "r50": list(self.r50),
            "r90": list(self.r90),
            "views": "entry k: joints seen by k views; the last entry: k or more",
        }

    def radius(self, sigma: np.ndarray, num_views: np.ndarray, level: float) -> np.ndarray:
        """The ``level`` (0.5 or 0.9) radius, same shape as ``sigma`` (metres)."""
        f = np.asarray(self.r50 if level == 0.5 else self.r90)
        k = np.clip(np.asarray(num_views), 0, len(f) - 1)
        return sigma * f[k]


@dataclass
class TrackResult:
    """One lifted track.

    Attributes:
        points: (T, J, 3) world metres; NaN where no window saw the person.
        sigma: (T, J) metres, the network's scale of each joint's error. :meth:`radius`
            turns it into the radius that holds half (or nine tenths) of the errors.
        num_views: (T, J) number of views that saw each joint.
        calibration: the checkpoint's per-view-count radius factors; None: the chi
            distribution's (``RADIUS_50``, ``RADIUS_90``) for every joint.
    """

    points: np.ndarray
    sigma: np.ndarray
    num_views: np.ndarray
    calibration: RadiusCalibration | None = None

    def radius(self, level: float = 0.5) -> np.ndarray:
        """The predicted error radius (T, J) at ``level`` 0.5 or 0.9, metres."""
        if level not in (0.5, 0.9):
            raise ValueError(f"level must be 0.5 or 0.9, got {level}")
        if self.calibration is not None:
            return self.calibration.radius(self.sigma, self.num_views, level)
        return self.sigma * (RADIUS_50 if level == 0.5 else RADIUS_90)


#: Ways to assemble a track's answer (see the module doc).
ASSEMBLE = ("network", "filtered")


def assemble_track(
    network: np.ndarray, frame: np.ndarray, num_views: np.ndarray, times: np.ndarray
) -> np.ndarray:
    """The ``"filtered"`` answer of one track.

    The per-frame answer where at least two views see the joint, the network's elsewhere,
    then ``rmpl run``'s filters with its defaults: a Hampel filter (7 frames, 3 cm floor),
    gaps of up to 20 frames filled, and a zero-phase 4th-order Butterworth at 6 Hz (at most
    0.45 x the frame rate). A point the filters leave empty (an outlier at the end of a run)
    takes the network's answer.

    Args:
        network: (T, J, 3) the temporal network's output, NaN where it has none.
        frame: (T, J, 3) the per-frame model's answer (anything where unused).
        num_views: (T, J) views that see each joint.
        times: (T,) seconds, increasing.

    Returns:
        (T, J, 3), NaN where ``network`` is NaN.
    """
    from rmpl.pipeline import filters

    has = np.isfinite(network).all(-1, keepdims=True)  # (T, J, 1)
    x = np.where((num_views >= 2)[..., None] & np.isfinite(frame), frame, network)
    x = np.where(has, x, np.nan)[:, None]  # (T, 1, J, 3)
    if len(x) >= 7:
        x = filters.hampel(x, window=7, min_deviation=0.03)
    x, _ = filters.fill_gaps(x, max_gap=20)
    if len(x) >= 2:
        rate = 1.0 / float(np.median(np.diff(times)))
        x = filters.butterworth(x, rate, cutoff=min(6.0, 0.45 * rate), order=4)
    # A point the filters left empty (an outlier at a run's end) keeps the network's answer;
    # a frame the network has no answer for stays empty.
    x = np.where(np.isfinite(x[:, 0]), x[:, 0], network)
    return np.where(has, x, np.nan)


def frame_times(num_frames: int, fps: float | None, times: np.ndarray | None) -> np.ndarray:
    """Timestamps (T,) in seconds from ``times`` or ``fps`` (exactly one must be given)."""
    if (fps is None) == (times is None):
        raise InputError(None, "fps / times", "exactly one of a frame rate or frame times")
    if times is None:
        if not np.isfinite(fps) or fps <= 0:
            raise InputError(None, "fps", "a frame rate > 0 frames per second", fps)
        return np.arange(num_frames) / float(fps)
    t = np.asarray(times, dtype=float)
    if t.shape != (num_frames,) or not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise InputError(
            None, "times", f"{num_frames} finite, strictly increasing seconds", t.shape
        )
    return t


def window_starts(num_frames: int, window: int) -> list[int]:
    """First frames of windows of ``window`` frames overlapping by half, the last one ending
    at the track's end. A track shorter than a window is one window."""
    if num_frames <= window:
        return [0]
    step = max(window // 2, 1)
    starts = list(range(0, num_frames - window + 1, step))
    if starts[-1] != num_frames - window:
        starts.append(num_frames - window)
    return starts


def _triangle(n: int) -> np.ndarray:
    """Weights (n,) highest in the middle of a window, never zero."""
    k = np.arange(n)
    return np.minimum(k + 1, n - k).astype(float)


class TemporalLifter:
    """A trained :class:`TemporalRMPL` ready for inference.

    Args:
        model: the network. meta: the checkpoint's description. onnx: run the per-frame
            model through onnxruntime when it is installed. assemble: one of
            :data:`ASSEMBLE`; None: the checkpoint's (``"network"`` when it names none).
    """

    def __init__(
        self,
        model: TemporalRMPL,
        meta: dict | None = None,
        onnx: bool = True,
        assemble: str | None = None,
    ) -> None:
        self.model = model.eval()
        self.meta = meta or {}
        self.calibration = RadiusCalibration.from_meta(self.meta)
        self.assemble = assemble or _assemble_of(self.meta)
        if self.assemble not in ASSEMBLE:
            raise ValueError(f"assemble must be one of {ASSEMBLE}, got {self.assemble!r}")
        if onnx and self.model.fast_encoder is None:
            try:
                self.model.use_onnx()
            except ImportError:
                log.debug("onnxruntime not installed; the per-frame model runs in torch")

    @classmethod
    def from_pretrained(cls, name_or_path: str | Path = "temporal") -> TemporalLifter:
        """Load the shipped temporal model by name or a checkpoint directory."""
        from rmpl.training.temporal import load_temporal

        path = Path(PRETRAINED_TEMPORAL.get(str(name_or_path), name_or_path))
        if not (path / "config.json").is_file():
            raise InputError(
                path, None, "a temporal checkpoint (config.json + model.safetensors) or 'temporal'"
            )
        model, meta = load_temporal(path)
        RadiusCalibration.from_meta(meta, path / "config.json")  # a damaged entry: one error
        _assemble_of(meta, path / "config.json")
        return cls(model, meta)

    @property
    def num_joints(self) -> int:
        return self.model.frame_model.config.num_joints

    @property
    def skeleton(self) -> Skeleton:
        """The joint set the model outputs (see :attr:`rmpl.Lifter.skeleton`)."""
        return skeleton_for(self.model.frame_model.config.skeleton)

    @property
    def window(self) -> int:
        return self.model.config.window

    @property
    def reads_floor(self) -> bool:
        """Whether the model reads the floor (``lift_track(floor=)``; others ignore it)."""
        return bool(self.model.config.floor or self.model.frame_model.config.floor)

    def _rays(self, kp, sc, rig: Rig, up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Checked input -> rays (T, V, J, 6) and scores in the z-up frame, and that rotation."""
        J = self.num_joints
        if kp.ndim != 4 or kp.shape[-2:] != (J, 2):
            raise InputError(None, "keypoints", f"one track, shape (T, V, {J}, 2)", kp.shape)
        if sc.shape != kp.shape[:-1]:
            raise InputError(None, "scores", f"shape {kp.shape[:-1]} matching keypoints", sc.shape)
        if kp.shape[0] == 0:
            raise InputError(None, "keypoints", "at least one frame", "0 frames")
        if kp.shape[1] != len(rig):
            raise InputError(
                None, "keypoints", f"{len(rig)} views to match the rig {rig.names}", kp.shape[1]
            )
        ok = np.isfinite(kp).all(-1) & np.isfinite(sc) & (sc > 0)
        rays = rays_from_keypoints(np.where(ok[..., None], kp, 0.0), rig)
        Rc = rotation_to_z(estimate_up(rig) if up is None else np.asarray(up, float))
        rays = np.concatenate([rays[..., :3] @ Rc.T, rays[..., 3:] @ Rc.T], -1)
        rays = np.where(ok[..., None], rays, 0.0).astype(np.float32)
        return rays, np.where(ok, np.clip(sc, 0, 1), 0.0).astype(np.float32), Rc

    @torch.no_grad()
    def lift_track(
        self,
        keypoints: np.ndarray,
        scores: np.ndarray,
        rig: Rig,
        fps: float | None = None,
        times: np.ndarray | None = None,
        up: np.ndarray | None = None,
        batch_windows: int = 32,
        joints: str | None = None,
        floor=None,
    ) -> TrackResult:
        """Lift one person's track.

        Args:
            keypoints: (T, V, J, 2) pixels, NaN = missing (a frame may be missing entirely).
            scores: (T, V, J) confidences, 0 = missing.
            rig: the V cameras. fps or times: the frame rate, or each frame's time (T,) s.
            up: world up direction (3,); estimated from the rig when None.
            batch_windows: windows per forward pass.
            joints: the keypoints' joint set, as for :meth:`rmpl.Lifter.lift`.
            floor: the floor (:class:`rmpl.geometry.floor.Floor`) for a model that reads it
                (:attr:`reads_floor`; its normal is then the up direction unless ``up`` is
                given); other models ignore it. None = unknown.

        Returns:
            :class:`TrackResult`; frames before the first and after the last frame with a
            keypoint are NaN (the track has not started or has ended there).
        """
        kp, sc = model_inputs(keypoints, scores, self.skeleton, joints)
        floor = checked_floor(floor, rig)
        floor = floor if self.reads_floor else None
        if up is None and floor is not None:
            up = floor.n  # the floor's normal is the world's up
        rays, s, Rc = self._rays(kp, sc, rig, up)
        t = frame_times(len(kp), fps, times)
        t = t - t[0]  # in float64: a clock's origin (e.g. Unix time) would swamp float32
        row = None if floor is None else torch.from_numpy(floor_row(floor, Rc))[None]
        points, sigma, frame = self._windows(rays, s, t, batch_windows, row)
        if self.assemble == "filtered":
            points = assemble_track(points, frame, (s > 0).sum(1), t)
        points = points @ Rc  # back to the user's world
        seen = np.flatnonzero((s > 0).any((1, 2)))
        outside = np.ones(len(t), bool)
        if len(seen):
            outside[seen[0] : seen[-1] + 1] = False
        points[outside], sigma[outside] = np.nan, np.nan
        return TrackResult(points, sigma, (s > 0).sum(1), self.calibration)

    def _windows(self, rays, s, t: np.ndarray, batch: int, floor: torch.Tensor | None = None):
        """Overlapping windows, ``batch`` at a time: each group's frames are encoded by the
        per-frame model, read by the temporal stage, and stitched with triangular weights
        (memory stays that of one group, whatever the track's length). ``floor``: (1, 4) the
        track's floor row in the z-up frame, or None.

        Returns:
            the network's points (T, J, 3) and sigma (T, J), and the per-frame model's
            answer (T, J, 3), all in the z-up frame."""
        T = len(t)
        W = min(self.window, T)
        starts = window_starts(T, W)
        acc = np.zeros((T, self.num_joints, 3))
        acc_s = np.zeros((T, self.num_joints))
        frame = np.full((T, self.num_joints, 3), np.nan)
        weight = np.zeros(T)
        tri = _triangle(W)
        times = torch.from_numpy(t.astype(np.float32))
        for i in range(0, len(starts), batch):
            chunk = starts[i : i + batch]
            a0, a1 = chunk[0], chunk[-1] + W  # the frames this group reads
            r, sc = torch.from_numpy(rays[a0:a1])[None], torch.from_numpy(s[a0:a1])[None]
            enc = self.model.encode_frames(r, sc, floor)
            frame[a0:a1] = enc[0][0].numpy()
            parts = [torch.stack([e[0, a - a0 : a - a0 + W] for a in chunk]) for e in enc]
            tt = torch.stack([times[a : a + W] for a in chunk])
            rows = None if floor is None else floor.expand(len(chunk), 4)
            p, sg = self.model.forward_encoded(*parts, tt, rows)
            for k, a in enumerate(chunk):
                ok = np.isfinite(p[k].numpy()).all((-1, -2))  # (W,)
                w = tri * ok
                acc[a : a + W] += w[:, None, None] * np.nan_to_num(p[k].numpy())
                acc_s[a : a + W] += w[:, None] * np.nan_to_num(sg[k].numpy())
                weight[a : a + W] += w
        with np.errstate(invalid="ignore", divide="ignore"):
            points = acc / weight[:, None, None]
            sigma = acc_s / weight[:, None]
        points[weight == 0] = np.nan
        sigma[weight == 0] = np.nan
        return points, sigma, frame


def _assemble_of(meta: dict, path: Path | None = None) -> str:
    """The checkpoint's ``"inference": {"assemble": ...}``, ``"network"`` when absent."""
    entry = meta.get("inference") or {}
    value = entry.get("assemble", "network") if isinstance(entry, dict) else entry
    if value not in ASSEMBLE:
        raise InputError(path, "inference.assemble", f"one of {', '.join(ASSEMBLE)}", value)
    return value
