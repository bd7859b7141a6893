"""Temporal RMPL: lift one tracked person over a window of frames, with per-joint uncertainty.

The per-frame lifter (:class:`rmpl.model.lifter.RMPL`, frozen) encodes every frame: its fused
joint tokens and its 3D answer. A small space-time transformer then reads the whole window:
per-joint attention across frames (motion, gaps, occlusions) alternating with per-frame
attention across joints (the body). Its zero-initialised head predicts a correction to the
per-frame answer, so an untrained model *is* the per-frame model, and a log-scale of the
joint's error.

- **Missing is masked, never faked.** A frame with no keypoint in any view is not encoded:
  its tokens are a learned "missing" embedding, its starting point is interpolated in time
  from the frames around it, and it is masked out as a key of temporal attention.
- **Time in seconds.** Each frame carries its timestamp; the transformer sees Fourier
  features of the time relative to the window's middle, so one model serves 10-120 fps.
- **The floor.** With ``TemporalConfig.floor`` (and a per-frame model that reads the floor),
  ``forward(..., floor=)`` takes each window's floor plane: every frame's per-frame answer is
  made with it, and every token carries its starting point's height above it. Over a window
  the feet's contacts and the body's constant size fix the depth one camera lacks.
- **Uncertainty.** ``sigma`` is the scale of an isotropic 3D Gaussian on each joint's error:
  the error's norm is below ``1.538 sigma`` half of the time and below ``2.500 sigma`` 90% of
  the time (:data:`RADIUS_50`, :data:`RADIUS_90`). A scalar fitted after training on
  held-out synthetic windows (``TemporalConfig.sigma_scale``) calibrates it.

Shape glossary: ``B`` windows, ``T`` frames, ``V`` views, ``J`` joints, ``D`` width.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np
import torch
from torch import nn

from rmpl.model.layers import Block
from rmpl.model.lifter import RMPL, floor_parts
from rmpl.skeleton import COCO17

__all__ = ["RADIUS_50", "RADIUS_90", "TemporalConfig", "TemporalRMPL", "interpolate_missing"]

RADIUS_50 = 1.5382  # median of the chi distribution with 3 degrees of freedom
RADIUS_90 = 2.5003  # its 90th percentile
POSITION_SCALE = 1.0  # metres: positions relative to the window centre are divided by this


@dataclass(frozen=True)
class TemporalConfig:
    """Architecture of the temporal stage of a :class:`TemporalRMPL`.

    Attributes:
        dim: D, token width of the space-time transformer.
        depth: space-time blocks (each one temporal + one spatial attention block).
        heads: attention heads.
        mlp_ratio: MLP hidden width / D.
        window: frames per window at training and inference (longer tracks are lifted in
            overlapping windows, stitched with triangular weights).
        time_frequencies: Fourier features of time, geometric from 0.25 to 8 Hz.
        max_correction: metres; the correction is ``max_correction * tanh(head / max)``.
        sigma_scale: calibration factor of the predicted uncertainty (fitted after training).
        frozen_encoder: the per-frame model is not trained (True) or fine-tuned (False).
        interpolate_valid: the interpolated-point input of a joint comes from the frames
            where two or more views agree on it (True), or from every frame where any view
            saw it (False, the first checkpoints).
        body_token: add the track's body (each bone's median length over the window's
            frames where both its ends are triangulable) to every token.
        fused_start: the point the correction starts from, for a joint no two views agree
            on in a frame: its position interpolated in time from the frames where two views
            did, moved onto the ray of the one view that sees it (or kept as it is when none
            does); the per-frame answer when no frame of the window triangulates the joint.
            The time to the nearest such frame is an input. False: always the per-frame
            answer (the first checkpoints).
        floor: the model takes the floor plane (``forward(..., floor=)``): the per-frame
            model (which must read the floor, ``RMPLConfig.floor``) is given it, and each
            token its starting point's height above it. An unknown floor is NaN.
    """

    dim: int = 64
    depth: int = 2
    heads: int = 4
    mlp_ratio: float = 2.0
    window: int = 48
    time_frequencies: int = 6
    max_correction: float = 1.0
    sigma_scale: float = 1.0
    frozen_encoder: bool = True
    interpolate_valid: bool = False
    body_token: bool = False
    fused_start: bool = False
    floor: bool = False

    def __post_init__(self) -> None:
        if self.window < 2 or self.depth < 1 or self.dim % self.heads:
            raise ValueError(
                f"TemporalConfig needs window >= 2, depth >= 1 and dim divisible by heads, "
                f"got window={self.window}, depth={self.depth}, dim={self.dim}, heads={self.heads}"
            )
        if not self.sigma_scale > 0:
            raise ValueError(f"TemporalConfig.sigma_scale must be > 0, got {self.sigma_scale}")

    @classmethod
    def from_dict(cls, d: dict) -> TemporalConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(
                f"unknown TemporalConfig keys {sorted(unknown)}; known: {sorted(known)}"
            )
        return cls(**d)

    def to_dict(self) -> dict:
        return asdict(self)

    def with_(self, **overrides) -> TemporalConfig:
        return replace(self, **overrides)


def interpolate_missing(x: torch.Tensor, ok: torch.Tensor, times: torch.Tensor) -> torch.Tensor:
    """Fill the points of frames where ``ok`` is False by linear interpolation in time.

    Args:
        x: (B, T, J, 3) points (any value where not ok).
        ok: (B, T, J) bool.
        times: (B, T) seconds, increasing.

    Returns:
        (B, T, J, 3): ``x`` where ok; between two ok frames the time-linear blend; before
        the first / after the last ok frame that frame's value; zeros where no frame is ok.
    """
    B, T, J, _ = x.shape
    idx = torch.arange(T, device=x.device).view(1, T, 1).expand(B, T, J)
    neg = torch.full_like(idx, -1)
    prev = torch.where(ok, idx, neg).cummax(1).values  # last ok frame at or before t
    nxt = torch.where(ok, T - 1 - idx, neg).flip(1).cummax(1).values.flip(1)
    nxt = torch.where(nxt >= 0, T - 1 - nxt, neg)  # first ok frame at or after t
    has_prev, has_next = prev >= 0, nxt >= 0
    p, n = prev.clamp_min(0), nxt.clamp_min(0)
    xp = x.gather(1, p[..., None].expand(-1, -1, -1, 3))
    xn = x.gather(1, n[..., None].expand(-1, -1, -1, 3))
    tt = times[:, :, None].expand(B, T, J)
    tp, tn = tt.gather(1, p), tt.gather(1, n)
    w = ((tt - tp) / (tn - tp).clamp_min(1e-9)).clamp(0, 1)
    both = (has_prev & has_next)[..., None]
    mid = xp + w[..., None] * (xn - xp)
    out = torch.where(both, mid, torch.where(has_prev[..., None], xp, xn))
    out = torch.where((has_prev | has_next)[..., None], out, torch.zeros_like(out))
    return torch.where(ok[..., None], x, out)


class _SpaceTimeBlock(nn.Module):
    """Temporal attention per joint (across frames), then spatial attention per frame."""

    def __init__(self, c: TemporalConfig) -> None:
        super().__init__()
        self.time = Block(c.dim, c.heads, c.mlp_ratio)
        self.space = Block(c.dim, c.heads, c.mlp_ratio)

    def forward(self, x: torch.Tensor, frame_ok: torch.Tensor) -> torch.Tensor:
        """x: (B, T, J, D); frame_ok: (B, T) bool, keys a frame may attend to."""
        B, T, J, D = x.shape
        xt = x.permute(0, 2, 1, 3).reshape(B * J, T, D)  # one sequence of frames per joint
        mask = frame_ok[:, None].expand(B, J, T).reshape(B * J, T)
        xt = self.time(xt, mask).view(B, J, T, D).permute(0, 2, 1, 3)
        return self.space(xt.reshape(B * T, J, D)).view(B, T, J, D)


class TemporalRMPL(nn.Module):
    """Per-frame RMPL + space-time transformer. ``forward(rays, scores, times)``.

    >>> import torch
    >>> from rmpl.model.lifter import PRESETS
    >>> model = TemporalRMPL(RMPL(PRESETS["tiny"]), TemporalConfig(window=8)).eval()
    >>> rays = torch.randn(1, 8, 2, 17, 6)
    >>> rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    >>> points, sigma = model(rays, torch.rand(1, 8, 2, 17), torch.arange(8.0)[None] / 25)
    >>> points.shape, sigma.shape
    (torch.Size([1, 8, 17, 3]), torch.Size([1, 8, 17]))
    """

    def __init__(self, frame_model: RMPL, config: TemporalConfig | None = None) -> None:
        super().__init__()
        self.config = c = config or TemporalConfig()
        self.frame_model = frame_model
        fc = frame_model.config
        if not (fc.geometric and fc.recenter and fc.inputs == "rays"):
            raise ValueError("the temporal model needs a per-frame model on rays (geometric)")
        if c.floor and not fc.floor:
            raise ValueError("TemporalConfig.floor needs a per-frame model that reads the floor")
        J = fc.num_joints
        self.token_in = nn.Linear(fc.dim, c.dim)
        self.point_in = nn.Linear(3 + 3 + 3, c.dim)  # answer, interpolated, base (centred)
        # valid intersection, views / 4, seen (+ fused_start: time to a valid frame, has one)
        self.flags_in = nn.Linear(5 if c.fused_start else 3, c.dim)
        self.time_in = nn.Linear(2 * c.time_frequencies, c.dim)
        self.body_in = nn.Linear(len(COCO17.bones), c.dim) if c.body_token else None
        self.floor_in = nn.Linear(2, c.dim) if c.floor else None  # height above it, known
        self.missing = nn.Parameter(torch.zeros(1, 1, 1, c.dim))
        self.joint = nn.Parameter(torch.zeros(1, 1, J, c.dim))
        self.blocks = nn.ModuleList(_SpaceTimeBlock(c) for _ in range(c.depth))
        self.norm = nn.LayerNorm(c.dim)
        self.head = nn.Linear(c.dim, 4)  # correction (3) + log sigma
        freqs = 0.25 * (32.0 ** (torch.arange(c.time_frequencies) / max(c.time_frequencies - 1, 1)))
        self.register_buffer("freqs", 2 * math.pi * freqs, persistent=False)
        self.fast_encoder = None
        self._init()
        if c.frozen_encoder:
            self.frame_model.requires_grad_(False)

    def _init(self) -> None:
        nn.init.trunc_normal_(self.missing, std=0.02)
        nn.init.trunc_normal_(self.joint, std=0.02)
        for m in [
            self.token_in,
            self.point_in,
            self.flags_in,
            self.time_in,
            *self.blocks.modules(),
        ]:
            if isinstance(m, nn.Linear):
                nn.init.trunc_normal_(m.weight, std=0.02)
                nn.init.zeros_(m.bias)
        if self.floor_in is not None:  # zero: starts as the same model without the floor
            nn.init.zeros_(self.floor_in.weight)
            nn.init.zeros_(self.floor_in.bias)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)
        with torch.no_grad():  # start at sigma = 5 cm
            self.head.bias[3] = math.log(0.05)

    @property
    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())

    def train(self, mode: bool = True) -> TemporalRMPL:
        super().train(mode)
        if self.config.frozen_encoder:
            self.frame_model.eval()
        return self

    def encode_frames(
        self, rays: torch.Tensor, scores: torch.Tensor, floor: torch.Tensor | None = None
    ):
        """Run the per-frame model on every frame with a keypoint.

        rays (B, T, V, J, 6), scores (B, T, V, J) [, floor (B, 4), given to a per-frame model
        that reads it] -> answer (B, T, J, 3), base (B, T, J, 3),
        tokens (B, T, J, Df), flags (B, T, J, 3), frame_ok (B, T) bool, and the ray of the most
        confident view of each joint (B, T, J, 6), zero where no view sees it.
        """
        B, T, V, J, _ = rays.shape
        ok = torch.isfinite(rays).all(-1) & torch.isfinite(scores) & (scores > 0)
        frame_ok = ok.flatten(2).any(-1)  # (B, T)
        flat_r, flat_s = rays.reshape(B * T, V, J, 6), scores.reshape(B * T, V, J)
        sel = frame_ok.reshape(-1).nonzero().squeeze(1)
        Df = self.frame_model.config.dim
        answer = rays.new_zeros(B * T, J, 3)
        base = rays.new_zeros(B * T, J, 3)
        tokens = rays.new_zeros(B * T, J, Df)
        flags = rays.new_zeros(B * T, J, 3)
        rows = None
        if floor is not None and self.frame_model.config.floor:
            rows = floor.to(rays.dtype).repeat_interleave(T, 0)[sel]  # (frames, 4)
        if len(sel):
            ans, b, tok, valid, n = self._encode(flat_r[sel], flat_s[sel], rows)
            f = torch.stack([valid, (n / 4).clamp(max=2), (n > 0).to(n)], -1)
            answer, base = answer.index_copy(0, sel, ans), base.index_copy(0, sel, b)
            tokens, flags = tokens.index_copy(0, sel, tok), flags.index_copy(0, sel, f)
        shape = (B, T, J)
        best = torch.where(ok, scores, torch.full_like(scores, -1.0)).argmax(2)  # (B, T, J)
        ray = torch.where(ok[..., None], rays, torch.zeros_like(rays))
        ray = ray.gather(2, best[:, :, None, :, None].expand(B, T, 1, J, 6))[:, :, 0]
        return (
            answer.view(*shape, 3),
            base.view(*shape, 3),
            tokens.view(*shape, Df),
            flags.view(*shape, 3),
            frame_ok,
            ray,
        )

    def use_onnx(self, threads: int = 2) -> TemporalRMPL:
        """Run the frozen per-frame model through onnxruntime (about 3x faster on CPU)."""
        from rmpl.model.export import OnnxEncoder

        if not self.config.frozen_encoder:
            raise ValueError("onnxruntime can only run a frozen per-frame model")
        self.fast_encoder = OnnxEncoder(self.frame_model, threads)
        return self

    def _encode(
        self, rays: torch.Tensor, scores: torch.Tensor, floor: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, ...]:
        """The per-frame model on (N, V, J, 6), (N, V, J) [, (N, 4)]: answer, base, tokens,
        valid, views."""
        if self.fast_encoder is not None:  # in chunks: a long track stays within memory
            rows = lambda i: None if floor is None else floor[i : i + 256].numpy()  # noqa: E731
            parts = [
                self.fast_encoder(rays[i : i + 256].numpy(), scores[i : i + 256].numpy(), rows(i))
                for i in range(0, len(rays), 256)
            ]
            return tuple(
                torch.from_numpy(np.concatenate(o)).to(rays.dtype) for o in zip(*parts, strict=True)
            )
        grad = torch.is_grad_enabled() and not self.config.frozen_encoder
        with torch.set_grad_enabled(grad):
            enc = self.frame_model.encode(rays, scores, floor=floor)
            answer = enc.base + self.frame_model.head(enc.tokens)
        return answer, enc.base, enc.tokens, enc.valid.to(rays.dtype), enc.views.to(rays.dtype)

    def forward(
        self,
        rays: torch.Tensor,
        scores: torch.Tensor,
        times: torch.Tensor,
        floor: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Lift a window of one person.

        Args:
            rays: (B, T, V, J, 6) origin (metres) + unit direction, z-up world.
            scores: (B, T, V, J) confidences; 0 (or a non-finite ray) = missing.
            times: (B, T) seconds, increasing (any origin).
            floor: (B, 4) each window's floor plane ``n . X = h`` as ``[n, h]`` (``n`` unit,
                pointing up), NaN rows = unknown; read by models with ``config.floor`` and
                per-frame models that read it, ignored by the others.

        Returns:
            points (B, T, J, 3) world metres, and sigma (B, T, J) metres (see module doc).
            A window with no keypoint at all gives NaN.
        """
        return self.forward_encoded(*self.encode_frames(rays, scores, floor), times, floor)

    def forward_encoded(
        self,
        answer: torch.Tensor,
        base: torch.Tensor,
        tokens: torch.Tensor,
        flags: torch.Tensor,
        frame_ok: torch.Tensor,
        ray: torch.Tensor,
        times: torch.Tensor,
        floor: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The temporal stage on frames already encoded by :meth:`encode_frames` (so that a
        long track is encoded once and read in overlapping windows; the same ``floor``).
        Returns as :meth:`forward`."""
        c = self.config
        B, T, J, _ = answer.shape
        okj = frame_ok[..., None].expand(B, T, J)
        trusted = flags[..., 0 if c.interpolate_valid else 2] > 0
        start = interpolate_missing(answer, okj, times)  # missing frames: from their neighbours
        interp = interpolate_missing(answer, trusted & okj, times)  # weak joints, likewise
        if c.fused_start:
            start, extra = _fused_start(answer, start, flags, okj, ray, times)
            flags = torch.cat([flags, extra], -1)
        centre = _window_centre(start, frame_ok)  # (B, 3)
        rel = lambda p: (p - centre[:, None, None]) / POSITION_SCALE  # noqa: E731
        pts = torch.cat(
            [rel(start), rel(interp), rel(torch.where(okj[..., None], base, start))], -1
        )
        x = self.token_in(tokens) + self.point_in(pts) + self.flags_in(flags)
        x = torch.where(
            frame_ok[..., None, None], x, self.missing.expand_as(x) + self.point_in(pts)
        )
        x = x + self.time_in(self._time_features(times))[:, :, None] + self.joint
        if self.body_in is not None:
            x = x + self.body_in(_bone_lengths(answer, flags[..., 0] > 0))[:, None, None]
        if self.floor_in is not None:
            x = x + self.floor_in(_floor_features(start, floor))
        for block in self.blocks:
            x = block(x, frame_ok)
        out = self.head(self.norm(x))
        corr = c.max_correction * torch.tanh(out[..., :3] / c.max_correction)
        sigma = out[..., 3].clamp(-7, 2).exp() * c.sigma_scale
        points = start + corr
        none = ~frame_ok.any(1)  # (B,) windows with nothing seen
        points = torch.where(none[:, None, None, None], torch.full_like(points, math.nan), points)
        sigma = torch.where(none[:, None, None], torch.full_like(sigma, math.nan), sigma)
        return points, sigma

    def _time_features(self, times: torch.Tensor) -> torch.Tensor:
        """(B, T) seconds -> (B, T, 2F) sin/cos of the time relative to the window middle."""
        mid = 0.5 * (times[:, :1] + times[:, -1:])
        arg = (times - mid)[..., None] * self.freqs
        return torch.cat([arg.sin(), arg.cos()], -1)


def _fused_start(answer, start, flags, okj, ray, times):
    """See ``TemporalConfig.fused_start``: (start (B, T, J, 3), extra flags (B, T, J, 2))."""
    valid = (flags[..., 0] > 0) & okj
    seen = (flags[..., 2] > 0) & okj
    has = valid.any(1, keepdim=True).expand_as(valid)  # (B, T, J) the window triangulates j
    interp = interpolate_missing(answer, valid, times)
    o, d = ray[..., :3], ray[..., 3:]
    on_ray = o + ((interp - o) * d).sum(-1, keepdim=True) * d  # closest point of the ray
    weak = torch.where(seen[..., None], on_ray, interp)
    fused = torch.where((has & ~valid)[..., None], weak, start)
    # seconds to the nearest frame where two views agree on the joint (2 s at most)
    B, T, J = valid.shape
    tt = times[:, :, None].expand(B, T, J)
    big = torch.full_like(tt, 1e6)
    prev = torch.where(valid, tt, -big).cummax(1).values
    nxt = torch.where(valid, -tt, -big).flip(1).cummax(1).values.flip(1).neg()
    gap = torch.minimum(tt - prev, nxt - tt).clamp(0, 2.0)
    return fused, torch.stack([gap, has.to(gap.dtype)], -1)


def _floor_features(start: torch.Tensor, floor: torch.Tensor | None) -> torch.Tensor:
    """Each starting point's height above the floor (metres, within +-3) and whether the
    floor is known: (B, T, J, 3), (B, 4) or None -> (B, T, J, 2); zeros when unknown."""
    B = start.shape[0]
    fl = floor_parts(floor, B, start)
    height = (start * fl.n[:, None, None]).sum(-1) - fl.h[:, None, None]
    known = fl.known[:, None, None].to(start.dtype).expand_as(height)
    return torch.stack([height.clamp(-3, 3) * known, known], -1)


def _bone_lengths(points: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Each COCO-17 bone's median length over the frames where both its ends are valid
    (else over every frame), metres - 0.3: (B, T, J, 3), (B, T, J) -> (B, num_bones)."""
    a, b = (torch.tensor(i) for i in zip(*COCO17.bones, strict=True))
    length = (points[:, :, a] - points[:, :, b]).norm(dim=-1)  # (B, T, bones)
    ok = valid[:, :, a] & valid[:, :, b]
    trusted = torch.where(ok, length, torch.full_like(length, math.nan)).nanmedian(1).values
    every = length.median(1).values
    return torch.where(torch.isfinite(trusted), trusted, every) - 0.3


def _window_centre(points: torch.Tensor, frame_ok: torch.Tensor) -> torch.Tensor:
    """The joints' centroid averaged over the observed frames: (B, T, J, 3), (B, T) -> (B, 3)."""
    w = frame_ok.to(points.dtype)[..., None]
    mean = points.mean(2)  # (B, T, 3) centroid of the joints
    return (mean * w).sum(1) / w.sum(1).clamp_min(1.0)
