"""RMPL: the View Fusion Transformer + Pose Fusion Transformer lifter (thesis chapter 4).

Input: for every view ``v`` and joint ``j`` a 3D ray (camera centre, unit direction) and the
detector's confidence; a zero confidence marks a missing keypoint, which is masked out of
attention (never fed as a fake ray). Output: joint positions in world metres.

Geometry the network is given (each switchable in :class:`RMPLConfig` for ablations):

- **Recentering** (thesis 6.4.3): rays are expressed relative to a person anchor ``P``, the
  confidence-weighted mean of the per-joint least-squares ray intersections (weights: the
  minimum confidence over the views that see the joint). A person whose joints are all seen
  in a single view gets ``P`` on that view's mean ray at a depth set by the angular size of
  the keypoints. Without recentering the world origin is used.
- **Geometric tokens** (``geometric=True``): each joint has a base point ``b_j``, its own
  ray intersection when two or more views see it, else ``P``. Each view token also carries
  the perpendicular offset from ``b_j`` to its ray, the joint token carries ``b_j - P`` and
  visibility flags, and the zero-initialised head predicts a correction to ``b_j``; the
  network starts at triangulation and learns what it cannot do.
- **The floor** (``floor=True``): when the floor plane is known, each view token also
  carries its camera's height above the floor and where its ray meets the floor (as a log
  ratio to the anchor's depth), each joint token its base point's height above the floor;
  with one view the anchor's depth combines the keypoints' angular size with the depth at
  which the lowest ray meets the floor. A person on a floor fixes the depth one view lacks;
  the network learns when not to trust it (a jump, a step, a chair).

Shape glossary: ``B`` batch, ``V`` views, ``J`` joints, ``D`` model width.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

import torch
from torch import nn

from rmpl.model.layers import Encoder

__all__ = [
    "RMPLConfig",
    "RMPL",
    "PRESETS",
    "anchors_from_rays",
    "build_model",
    "camera_features",
    "floor_parts",
]

INPUTS = ("rays", "pixels", "pixels+calib")
ARCHITECTURES = ("transformer", "mlp")
PIXEL_SCALE = 1000.0  # pixels: keypoints and K entries are divided by this
ORIGIN_SCALE = 4.0  # metres: camera offsets are divided by this
PERP_SCALE = 0.25  # metres: ray-to-anchor offsets are divided by this
BODY_SPREAD = 0.46  # metres: RMS distance of COCO joints from their centroid across the view, adult
SPREAD_LOG_SD = 0.25  # log-depth error of the angular-size anchor (pose and body size vary)
FLOOR_CONTACT_SD = 0.10  # metres: the lowest keypoint's height above the floor (rest, steps, jumps)
FLOOR_VIEW_FEATURES = 3  # camera height above the floor, log floor-hit / anchor depth, hit flag
FLOOR_JOINT_FEATURES = 2  # base point's height above the floor, floor known


@dataclass(frozen=True)
class RMPLConfig:
    """Architecture of an :class:`RMPL` lifter.

    Attributes:
        num_joints: J, joints per pose.
        dim: D, token width.
        depth_view: blocks in the View Fusion Transformer.
        depth_pose: blocks in the Pose Fusion Transformer.
        heads: attention heads.
        mlp_ratio: MLP hidden width / D.
        drop_path: stochastic depth rate (max, linearly increasing).
        confidence: embed the detector confidence (D/2 of each token); False zeroes it.
        recenter: express rays relative to the person anchor (thesis 6.4.3).
        geometric: per-joint anchors, perpendicular-offset features and a residual head.
        inputs: what each view token is made of (thesis 6.6, table 6.5): ``"rays"`` (the
            method), or for the modality ablation ``"pixels"`` (2D keypoints alone) or
            ``"pixels+calib"`` (2D keypoints + the flattened camera K, R, t). The pixel
            inputs cannot be recentered; they need ``recenter=False, geometric=False``.
        architecture: ``"transformer"`` (VFT + PFT) or ``"mlp"``, the fully connected
            baseline of thesis 6.4 (views padded to ``max_views``; not view-order invariant).
        max_views: the most views an ``"mlp"`` model accepts.
        skeleton: name of the joint set (see :data:`rmpl.skeleton.SKELETONS`).
        robust_anchor: iterations of reweighting in the per-joint ray intersections
            (:func:`anchors_from_rays`): with three or more views a ray far from the others
            (a detector outlier) loses its weight, as in robust triangulation. 0 = the plain
            confidence-weighted least squares of the first checkpoints.
        anchor_parents: a joint no two views locate starts from its parent joint's point
            (:data:`rmpl.skeleton.ANCHOR_PARENTS`, followed up the chain) instead of the
            person's anchor: a hidden heel starts at its ankle, not at the pelvis. False =
            the person's anchor (the first checkpoints).
        floor: the model takes the floor plane (``forward(..., floor=)``; unknown floors are
            allowed) as described in the module docstring. Needs ``geometric``.
    """

    num_joints: int = 17
    dim: int = 128
    depth_view: int = 4
    depth_pose: int = 4
    heads: int = 4
    mlp_ratio: float = 2.0
    drop_path: float = 0.0
    confidence: bool = True
    recenter: bool = True
    geometric: bool = True
    inputs: str = "rays"
    architecture: str = "transformer"
    max_views: int = 8
    skeleton: str = "coco17"
    robust_anchor: int = 0
    anchor_parents: bool = False
    floor: bool = False

    def __post_init__(self) -> None:
        from rmpl.skeleton import SKELETONS

        if self.skeleton not in SKELETONS:
            raise ValueError(f"RMPLConfig.skeleton must be one of {sorted(SKELETONS)}, got "
                             f"{self.skeleton!r}")  # fmt: skip
        if SKELETONS[self.skeleton].num_joints != self.num_joints:
            raise ValueError(
                f"RMPLConfig.num_joints={self.num_joints} does not fit skeleton "
                f"{self.skeleton!r} ({SKELETONS[self.skeleton].num_joints} joints)"
            )
        if (
            not isinstance(self.robust_anchor, int)
            or isinstance(self.robust_anchor, bool)
            or not 0 <= self.robust_anchor <= 10
        ):
            raise ValueError(f"RMPLConfig.robust_anchor must be in 0..10, got {self.robust_anchor}")
        if self.inputs not in INPUTS:
            raise ValueError(f"RMPLConfig.inputs must be one of {INPUTS}, got {self.inputs!r}")
        if self.architecture not in ARCHITECTURES:
            raise ValueError(
                f"RMPLConfig.architecture must be one of {ARCHITECTURES}, got {self.architecture!r}"
            )
        if self.inputs != "rays" and (self.recenter or self.geometric):
            raise ValueError(
                f"RMPLConfig.inputs={self.inputs!r} needs recenter=false and geometric=false "
                "(recentering needs rays)"
            )
        if self.architecture == "mlp" and (self.inputs != "rays" or self.geometric):
            raise ValueError("the mlp baseline takes rays with geometric=false")
        if self.floor and not (self.geometric and self.architecture == "transformer"):
            raise ValueError("RMPLConfig.floor needs geometric=true and the transformer")

    @classmethod
    def from_dict(cls, d: dict) -> RMPLConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"unknown RMPLConfig keys {sorted(unknown)}; known: {sorted(known)}")
        return cls(**d)

    def to_dict(self) -> dict:
        return asdict(self)

    def with_(self, **overrides) -> RMPLConfig:
        return replace(self, **overrides)


#: Named architectures. ``paper`` is the thesis model (D=256, H=8, L=12, MLP ratio 2).
PRESETS: dict[str, RMPLConfig] = {
    "paper": RMPLConfig(dim=256, depth_view=12, depth_pose=12, heads=8, drop_path=0.1),
    "small": RMPLConfig(dim=128, depth_view=4, depth_pose=4, heads=4),
    "tiny": RMPLConfig(dim=64, depth_view=2, depth_pose=2, heads=4),
}


def _solve3(A: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Solve A x = b for 3x3 A by the adjugate (ONNX friendly).

    Returns x (*, 3) and a conditioning measure det / (trace / 3)^3, shape (*,).
    """
    a, bb, c = A[..., 0, 0], A[..., 0, 1], A[..., 0, 2]
    d, e, f = A[..., 1, 0], A[..., 1, 1], A[..., 1, 2]
    g, h, i = A[..., 2, 0], A[..., 2, 1], A[..., 2, 2]
    co = torch.stack(
        [
            torch.stack([e * i - f * h, c * h - bb * i, bb * f - c * e], -1),
            torch.stack([f * g - d * i, a * i - c * g, c * d - a * f], -1),
            torch.stack([d * h - e * g, bb * g - a * h, a * e - bb * d], -1),
        ],
        -2,
    )
    det = a * co[..., 0, 0] + bb * co[..., 1, 0] + c * co[..., 2, 0]
    tr = (a + e + i) / 3
    cond = det / (tr**3).clamp_min(1e-12)
    safe = torch.where(det.abs() > 1e-12, det, torch.ones_like(det))
    x = (co @ b.unsqueeze(-1)).squeeze(-1) / safe.unsqueeze(-1)
    return x, cond


ROBUST_SCALE = 0.1  # metres: ray-to-point distance at which a view's weight halves


def _perpendicular(rel: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
    """The part of ``rel`` (a point minus a ray origin) across the unit ray direction ``d``."""
    return rel - (rel * d).sum(-1, keepdim=True) * d


def _ray_terms(
    w: torch.Tensor, M: torch.Tensor, o: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-view terms of the weighted least-squares ray intersection ``A x = b``:
    ``w M`` (B, V, J, 3, 3) and ``w M o`` (B, V, J, 3); A and b are their sums over views."""
    wM = w[..., None, None] * M
    return wM, (wM @ o.unsqueeze(-1)).squeeze(-1)


def anchors_from_rays(
    rays: torch.Tensor,
    scores: torch.Tensor,
    max_offset: float = 1.5,
    robust: int = 0,
    floor: FloorParts | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per-joint ray intersections and the person anchor.

    Args:
        rays: (B, V, J, 6) origin + unit direction, finite (missing views have score 0).
        scores: (B, V, J) confidences, 0 = missing.
        max_offset: joint intersections farther than this (metres) from the anchor are
            treated as failed.
        robust: > 0 makes the intersections robust to one outlying view, then refines
            them with this many iterations of Cauchy reweighting (see
            :func:`_robust_intersections`). With two views there is no outlier to find:
            rays that meet are unchanged, rays that miss each other move the point by a
            fraction of their miss distance.
        floor: the floor (:func:`floor_parts`); it only changes the anchor of a person no
            two views locate (:func:`_single_view_anchor`).

    Returns:
        joint_points (B, J, 3), joint_valid (B, J) bool (>= 2 non-parallel views),
        person anchor (B, 3).
    """
    o, d = rays[..., :3], rays[..., 3:]
    w = scores.clamp_min(0)
    seen = w > 0
    eye = torch.eye(3, dtype=rays.dtype, device=rays.device)
    M = eye - d.unsqueeze(-1) * d.unsqueeze(-2)  # (B, V, J, 3, 3)
    wM, wMo = _ray_terms(w, M, o)
    A, b = wM.sum(1), wMo.sum(1)  # (B, J, 3, 3), (B, J, 3)
    X, cond = _solve3(A, b)
    valid = (seen.sum(1) >= 2) & (cond > 1e-4)
    if robust > 0:
        X = _robust_intersections(o, d, w, M, wM, wMo, X, valid, robust)
    # Joint weight: the minimum confidence over the views that see it (thesis 6.4.3).
    wmin = torch.where(seen, w, torch.full_like(w, 2.0)).amin(1)
    wj = torch.where(valid, wmin, torch.zeros_like(wmin))
    total = wj.sum(-1, keepdim=True)
    P_tri = (torch.where(valid[..., None], X, torch.zeros_like(X)) * wj[..., None]).sum(1)
    P_tri = P_tri / total.clamp_min(1e-9)
    # Outlying joint intersections (bad matches, near-parallel rays) fall back to the anchor.
    valid = valid & ((X - P_tri[:, None]).norm(dim=-1) < max_offset)
    wj = torch.where(valid, wmin, torch.zeros_like(wmin))
    total = wj.sum(-1, keepdim=True)
    P_tri = (torch.where(valid[..., None], X, torch.zeros_like(X)) * wj[..., None]).sum(1)
    P_tri = P_tri / total.clamp_min(1e-9)
    P = torch.where(total > 0, P_tri, _single_view_anchor(o, d, w, floor))
    X = torch.where(valid[..., None], X, P[:, None].expand_as(X))
    return X, valid, P


def parent_fallback(X: torch.Tensor, valid: torch.Tensor, parents: torch.Tensor) -> torch.Tensor:
    """Joints that are not ``valid`` take their parent's point, up the chain.

    Args:
        X: (B, J, 3) joint points; valid: (B, J) bool; parents: (J,) long, -1 = none.

    Returns:
        (B, J, 3): a valid joint's own point; else the first valid joint up its chain of
        parents; else (no valid ancestor) its point as given (the person's anchor).
    """
    has = parents >= 0
    idx = torch.where(has, parents, torch.arange(len(parents), device=parents.device))
    have = valid
    for _ in range(4):  # the longest chain (small toe -> big toe -> ankle -> knee -> hip)
        take = ~have & has[None] & have[:, idx]
        X = torch.where(take[..., None], X[:, idx], X)
        have = have | take
    return X


def _robust_intersections(o, d, w, M, wM, wMo, X, valid, iterations: int) -> torch.Tensor:
    """Ray intersections robust to an outlying view (only broadcasting: any V, ONNX-friendly).

    Candidates are the least-squares point and, for every view, the point without it. The
    candidate with the lowest Cauchy cost ``sum_v w_v log(1 + (r_v / ROBUST_SCALE)^2)`` (``r_v``
    the distance to ray ``v``) starts ``iterations`` rounds of reweighted least squares
    (weight ``w_v / (1 + (r_v / ROBUST_SCALE)^2)``). ``wM``, ``wMo``: :func:`_ray_terms` of
    the confidences ``w``. Shapes as in :func:`anchors_from_rays`.
    """
    seen = w > 0
    X_loo, cond_loo = _solve3(wM.sum(1)[:, None] - wM, wMo.sum(1)[:, None] - wMo)
    ok_loo = seen & (seen.sum(1, keepdim=True) >= 3) & (cond_loo > 1e-4)
    cands = torch.cat([X[:, None], X_loo], 1)  # (B, V + 1, J, 3)
    perp = _perpendicular(cands[:, :, None] - o[:, None], d[:, None])  # (B, V + 1, V, J, 3)
    cost = (w[:, None] * torch.log(1 + (perp**2).sum(-1) / ROBUST_SCALE**2)).sum(2)
    ok = torch.cat([valid[:, None], ok_loo], 1)
    cost = torch.where(ok, cost, torch.full_like(cost, float("inf")))
    best = cost.argmin(1)  # (B, J)
    X = cands.gather(1, best[:, None, :, None].expand(-1, 1, -1, 3))[:, 0]
    for _ in range(iterations):
        perp = _perpendicular(X[:, None] - o, d)  # (B, V, J, 3)
        wr = w / (1 + (perp**2).sum(-1) / ROBUST_SCALE**2)
        wrM, wrMo = _ray_terms(wr, M, o)
        Xr, cond_r = _solve3(wrM.sum(1), wrMo.sum(1))
        X = torch.where((valid & (cond_r > 1e-4))[..., None], Xr, X)
    return X


def camera_features(K: torch.Tensor, R: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """Flattened calibration for the ``pixels+calib`` ablation: (*, 3, 3), (*, 3, 3), (*, 3)
    -> (*, 16) = fx, fy, cx, cy (/1000), R (9), t (/4 m)."""
    k = torch.stack([K[..., 0, 0], K[..., 1, 1], K[..., 0, 2], K[..., 1, 2]], -1) / PIXEL_SCALE
    return torch.cat([k, R.flatten(-2), t / ORIGIN_SCALE], -1)


def _pixel_features(
    c: RMPLConfig,
    keypoints: torch.Tensor | None,
    cameras: torch.Tensor | None,
    ok: torch.Tensor,
    J: int,
) -> list[torch.Tensor]:
    if keypoints is None or (c.inputs == "pixels+calib" and cameras is None):
        raise ValueError(f"a model with inputs={c.inputs!r} needs keypoints (and cameras)")
    kp = torch.where(ok[..., None], keypoints, torch.zeros_like(keypoints)) / PIXEL_SCALE
    if c.inputs == "pixels":
        return [kp]
    return [kp, cameras[:, :, None].expand(-1, -1, J, -1)]


@dataclass
class FloorParts:
    """The floor of each sample as tensors: unit normal ``n`` (B, 3) pointing up, offset
    ``h`` (B,) (the plane ``n . X = h``), ``known`` (B,) bool. Unknown rows hold z = 0."""

    n: torch.Tensor
    h: torch.Tensor
    known: torch.Tensor


def floor_parts(floor: torch.Tensor | None, B: int, like: torch.Tensor) -> FloorParts:
    """:class:`FloorParts` from a (B, 4) tensor ``[n_x, n_y, n_z, h]`` (a row with a
    non-finite entry = floor unknown) or None (all unknown). ``like`` gives dtype and device."""
    z = torch.zeros(B, 4, dtype=like.dtype, device=like.device)
    z[:, 2] = 1.0
    if floor is None:
        return FloorParts(z[:, :3], z[:, 3], torch.zeros(B, dtype=torch.bool, device=like.device))
    if floor.shape != (B, 4):
        raise ValueError(f"floor must have shape ({B}, 4), got {tuple(floor.shape)}")
    known = torch.isfinite(floor).all(-1)
    f = torch.where(known[:, None], floor.to(like.dtype), z)
    n = f[:, :3] / f[:, :3].norm(dim=-1, keepdim=True).clamp_min(1e-9)
    return FloorParts(n, f[:, 3], known)


def _single_view_anchor(
    o: torch.Tensor, d: torch.Tensor, w: torch.Tensor, floor: FloorParts | None = None
) -> torch.Tensor:
    """Anchor from the most confident view alone: on its mean ray, at the depth where the
    keypoints' angular spread matches a standing adult's; with a known floor, that depth's
    log is averaged (inverse variance) with the depth at which the view's lowest ray meets
    the floor (the person stands on it, within :data:`FLOOR_CONTACT_SD`). Shapes as in
    :func:`anchors_from_rays`."""
    best = w.sum(-1).argmax(1)  # (B,)
    idx = best[:, None, None, None].expand(-1, 1, *o.shape[2:])
    ob, db = o.gather(1, idx)[:, 0], d.gather(1, idx)[:, 0]  # (B, J, 3)
    wb = w.gather(1, best[:, None, None].expand(-1, 1, w.shape[-1]))[:, 0]  # (B, J)
    tot = wb.sum(-1, keepdim=True).clamp_min(1e-9)
    m = (db * wb[..., None]).sum(1) / tot  # (B, 3)
    spread = (((db - m[:, None]) ** 2).sum(-1) * wb).sum(-1, keepdim=True) / tot
    depth = (BODY_SPREAD / spread.sqrt().clamp_min(1e-3)).clamp(0.5, 30.0)
    m = m / m.norm(dim=-1, keepdim=True).clamp_min(1e-9)
    origin = (ob * wb[..., None]).sum(1) / tot
    if floor is not None:
        depth = _floor_depth(depth, ob, db, wb, m, origin, floor)
    anchor = origin + depth * m
    # No keypoint at all: the world origin.
    return torch.where(wb.sum(-1, keepdim=True) > 0, anchor, torch.zeros_like(anchor))


def _floor_depth(depth, ob, db, wb, m, origin, floor: FloorParts) -> torch.Tensor:
    """The single-view anchor's depth (B, 1) with the floor: see :func:`_single_view_anchor`.

    The view's lowest ray meets the floor at the foot ``F``; the body stands above it, so
    the floor's depth is that of the point of the mean ray ``m`` above ``F`` (horizontally
    nearest; along ``m`` to ``F``'s depth when the camera looks nearly straight down)."""
    n = floor.n
    height = (origin * n).sum(-1) - floor.h  # (B,) the camera above the floor
    down = -(db * n[:, None]).sum(-1)  # (B, J) how steeply each ray descends
    hits = (wb > 0) & (down > 0.05) & floor.known[:, None] & (height[:, None] > 0.2)
    t = torch.where(hits, height[:, None] / down.clamp_min(0.05), torch.full_like(down, 1e6))
    t_low, j = t.min(-1)  # the lowest keypoint's ray meets the floor nearest the camera
    d_low = db.gather(1, j[:, None, None].expand(-1, 1, 3))[:, 0]
    foot = d_low * t_low[:, None]  # F - origin
    m_h = m - (m * n).sum(-1, keepdim=True) * n  # the mean ray's horizontal part
    f_h = foot - (foot * n).sum(-1, keepdim=True) * n
    flat = (m_h * m_h).sum(-1)
    above = (f_h * m_h).sum(-1) / flat.clamp_min(1e-6)
    along = t_low * (d_low * m).sum(-1).clamp_min(0.1)
    floor_depth = torch.where(flat > 0.1, above, along).clamp(0.5, 30.0)
    sd = (FLOOR_CONTACT_SD / height.clamp_min(0.2)).clamp_min(0.03)
    w_floor = torch.where(hits.any(-1), sd**-2, torch.zeros_like(sd))[:, None]
    w_size = SPREAD_LOG_SD**-2
    log_depth = (w_size * depth.log() + w_floor * floor_depth.log()[:, None]) / (w_size + w_floor)
    return log_depth.exp()


class RMPL(nn.Module):
    """The lifter. ``forward(rays, scores) -> joints``.

    >>> import torch
    >>> model = RMPL(PRESETS["tiny"]).eval()
    >>> rays = torch.randn(2, 3, 17, 6); rays[..., 3:] /= rays[..., 3:].norm(dim=-1, keepdim=True)
    >>> model(rays, torch.rand(2, 3, 17)).shape
    torch.Size([2, 17, 3])
    """

    def __init__(self, config: RMPLConfig | None = None) -> None:
        super().__init__()
        self.config = c = config or RMPLConfig()
        half = c.dim // 2
        ray_features = {"rays": 9 if c.geometric else 6, "pixels": 2, "pixels+calib": 18}[c.inputs]
        ray_features += FLOOR_VIEW_FEATURES if c.floor else 0
        self.ray_embed = nn.Linear(ray_features, half)
        self.conf_embed = nn.Linear(1, c.dim - half)
        self.fusion_token = nn.Parameter(torch.zeros(1, 1, c.dim))
        self.view_encoder = Encoder(c.dim, c.depth_view, c.heads, c.mlp_ratio, c.drop_path)
        self.anatomy = nn.Parameter(torch.zeros(1, c.num_joints, c.dim))
        joint_features = 6 + (FLOOR_JOINT_FEATURES if c.floor else 0)
        self.joint_embed = nn.Linear(joint_features, c.dim) if c.geometric else None
        self.pose_encoder = Encoder(c.dim, c.depth_pose, c.heads, c.mlp_ratio, c.drop_path)
        self.head = nn.Linear(c.dim, 3)
        if c.anchor_parents:
            from rmpl.skeleton import anchor_parents

            parents = torch.tensor(anchor_parents(c.skeleton), dtype=torch.long)
            if len(parents) != c.num_joints:
                raise ValueError(f"skeleton {c.skeleton!r} has {len(parents)} joints, not "
                                 f"num_joints={c.num_joints}")  # fmt: skip
            self.register_buffer("parents", parents, persistent=False)
        self._init()

    def _init(self) -> None:
        nn.init.trunc_normal_(self.fusion_token, std=0.02)
        nn.init.trunc_normal_(self.anatomy, std=0.02)
        for m in self.modules():
            if isinstance(m, nn.Linear):
                nn.init.trunc_normal_(m.weight, std=0.02)
                nn.init.zeros_(m.bias)
        if self.config.geometric:  # start at the triangulated solution
            nn.init.zeros_(self.head.weight)

    @property
    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())

    def forward(
        self,
        rays: torch.Tensor,
        scores: torch.Tensor,
        keypoints: torch.Tensor | None = None,
        cameras: torch.Tensor | None = None,
        floor: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Lift rays to 3D joints.

        Args:
            rays: (B, V, J, 6) origin (metres) + unit direction, in a z-up world.
            scores: (B, V, J) confidences in [0, 1]; 0 (or a non-finite ray) = missing.
            keypoints: (B, V, J, 2) pixels; only for ``inputs="pixels"`` / ``"pixels+calib"``.
            cameras: (B, V, 16) from :func:`camera_features`; only for ``"pixels+calib"``.
            floor: (B, 4) the floor plane ``n . X = h`` as ``[n_x, n_y, n_z, h]``, ``n``
                pointing up; a row with NaN = unknown; None = unknown for all. Only models
                with ``config.floor`` read it.

        Returns:
            Joints, shape (B, J, 3), world metres.
        """
        enc = self.encode(rays, scores, keypoints, cameras, floor)
        return enc.base + self.head(enc.tokens)

    def encode(
        self,
        rays: torch.Tensor,
        scores: torch.Tensor,
        keypoints: torch.Tensor | None = None,
        cameras: torch.Tensor | None = None,
        floor: torch.Tensor | None = None,
    ) -> Encoding:
        """Everything but the output head: the fused joint tokens and the points the head
        corrects. Arguments as in :meth:`forward`; ``forward = base + head(tokens)``."""
        c = self.config
        B, V, J, _ = rays.shape
        if J != c.num_joints:
            raise ValueError(
                f"model expects {c.num_joints} joints, got rays of shape {tuple(rays.shape)}"
            )
        ok = torch.isfinite(rays).all(-1) & torch.isfinite(scores) & (scores > 0)
        rays = torch.where(ok[..., None], rays, torch.zeros_like(rays))
        scores = torch.where(ok, scores, torch.zeros_like(scores))
        fl = floor_parts(floor, B, rays) if c.floor else None
        if c.recenter or c.geometric:
            base, valid, P = anchors_from_rays(rays, scores, robust=c.robust_anchor, floor=fl)
            if c.anchor_parents:
                base = parent_fallback(base, valid, self.parents)
        else:
            valid = torch.zeros(B, J, dtype=torch.bool, device=rays.device)
        if not c.recenter:
            P = torch.zeros(B, 3, dtype=rays.dtype, device=rays.device)
        fused = self._fuse_views(
            rays, scores, ok, P, base if c.geometric else None, keypoints, cameras, fl
        )
        y = fused + self.anatomy  # (B, J, D)
        if c.geometric:
            y = y + self.joint_embed(_joint_features(base, P, valid, ok, fl))
        tokens = self.pose_encoder(y)
        return Encoding(
            tokens, base if c.geometric else P[:, None].expand(B, J, 3), valid, ok.sum(1)
        )

    def _fuse_views(self, rays, scores, ok, P, base, keypoints, cameras, fl) -> torch.Tensor:
        """The View Fusion Transformer: one fused token per joint, (B, J, D)."""
        c = self.config
        B, V, J, _ = rays.shape
        o, d = rays[..., :3], rays[..., 3:]
        feats = [(o - P[:, None, None]) / ORIGIN_SCALE, d]
        if c.inputs != "rays":
            feats = _pixel_features(c, keypoints, cameras, ok, J)
        if base is not None:
            perp = _perpendicular(o - base[:, None], d)  # (B, V, J, 3)
            feats.append((perp / PERP_SCALE).clamp(-8, 8))
        if fl is not None:
            feats.append(_floor_view_features(o, d, P, fl))
        x = torch.cat(feats, -1)
        conf = scores[..., None] if c.confidence else torch.zeros_like(scores[..., None])
        tokens = torch.cat([self.ray_embed(x), self.conf_embed(conf)], -1)  # (B, V, J, D)
        tokens = tokens.permute(0, 2, 1, 3).reshape(B * J, V, c.dim)  # views of one joint
        fusion = self.fusion_token.expand(B * J, 1, c.dim)
        mask = torch.cat(
            [
                torch.ones(B * J, 1, dtype=torch.bool, device=rays.device),
                ok.permute(0, 2, 1).reshape(B * J, V),
            ],
            1,
        )
        return self.view_encoder(torch.cat([fusion, tokens], 1), mask)[:, 0].view(B, J, c.dim)


@dataclass
class Encoding:
    """What :meth:`RMPL.encode` returns.

    Attributes:
        tokens: (B, J, D) the Pose Fusion Transformer's output tokens.
        base: (B, J, 3) the points the head corrects (ray intersections or the anchor), metres.
        valid: (B, J) bool, the joint's ray intersection is valid (>= 2 views agree).
        views: (B, J) int, the number of views that see the joint.
    """

    tokens: torch.Tensor
    base: torch.Tensor
    valid: torch.Tensor
    views: torch.Tensor


def _joint_features(base, P, valid, ok, fl: FloorParts | None = None) -> torch.Tensor:
    """Per-joint geometric features (B, J, 6): base - anchor, validity, view counts; with
    the floor (B, J, 8): + the base point's height above the floor, floor known."""
    n = ok.sum(1).to(base.dtype)  # (B, J)
    feats = [
        base - P[:, None],
        valid[..., None].to(base.dtype),
        (n[..., None] / 4).clamp(max=2),
        (n[..., None] > 0).to(base.dtype),
    ]
    if fl is not None:
        known = fl.known[:, None, None].to(base.dtype).expand(*base.shape[:2], 1)
        height = ((base * fl.n[:, None]).sum(-1, keepdim=True) - fl.h[:, None, None]).clamp(-3, 3)
        feats += [height * known, known]
    return torch.cat(feats, -1)


def _floor_view_features(o, d, P, fl: FloorParts) -> torch.Tensor:
    """Per view and joint (B, V, J, 3): the camera's height above the floor (/ 4 m), the log
    of the depth at which the ray meets the floor over the anchor's depth along it, and
    whether it meets the floor (in front of the camera, descending); zeros when unknown."""
    n, h = fl.n[:, None, None], fl.h[:, None, None]
    known = fl.known[:, None, None].to(o.dtype).expand(o.shape[:-1])
    height = (o * n).sum(-1) - h  # (B, V, J)
    down = -(d * n).sum(-1)
    hits = (known > 0) & (down > 0.02) & (height > 0)
    depth_anchor = ((P[:, None, None] - o) * d).sum(-1).clamp_min(0.1)
    ratio = (height.clamp_min(1e-3) / down.clamp_min(0.02) / depth_anchor).log().clamp(-2, 2)
    hit = hits.to(o.dtype)
    return torch.stack([height / ORIGIN_SCALE * known, ratio * hit, hit], -1)


class MLPLifter(nn.Module):
    """The fully connected baseline (thesis 6.4): recentered rays + confidences of up to
    ``max_views`` views, zero-padded and flattened, through a residual MLP to J x 3.

    Same call as :class:`RMPL`; it depends on the order of the views, which the
    transformer does not.
    """

    def __init__(self, config: RMPLConfig) -> None:
        super().__init__()
        self.config = c = config
        width = 4 * c.dim
        self.inp = nn.Linear(c.max_views * c.num_joints * 7, width)
        self.blocks = nn.ModuleList(
            nn.Sequential(
                nn.LayerNorm(width),
                nn.Linear(width, width),
                nn.GELU(),
                nn.Linear(width, width),
            )
            for _ in range(max(c.depth_pose, 1))
        )
        self.head = nn.Sequential(nn.LayerNorm(width), nn.Linear(width, c.num_joints * 3))
        nn.init.zeros_(self.head[1].weight)
        nn.init.zeros_(self.head[1].bias)

    @property
    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())

    def forward(self, rays: torch.Tensor, scores: torch.Tensor, *_) -> torch.Tensor:
        """rays (B, V, J, 6), scores (B, V, J) -> joints (B, J, 3), world metres."""
        c = self.config
        B, V, J, _ = rays.shape
        if V > c.max_views or J != c.num_joints:
            raise ValueError(
                f"mlp model takes at most {c.max_views} views of {c.num_joints} joints, "
                f"got rays of shape {tuple(rays.shape)}"
            )
        ok = torch.isfinite(rays).all(-1) & torch.isfinite(scores) & (scores > 0)
        rays = torch.where(ok[..., None], rays, torch.zeros_like(rays))
        scores = torch.where(ok, scores, torch.zeros_like(scores))
        P = anchors_from_rays(rays, scores)[2] if c.recenter else rays.new_zeros(B, 3)
        o = (rays[..., :3] - P[:, None, None]) / ORIGIN_SCALE
        x = torch.cat([o, rays[..., 3:], scores[..., None]], -1) * ok[..., None]  # (B,V,J,7)
        x = torch.cat([x, x.new_zeros(B, c.max_views - V, J, 7)], 1).reshape(B, -1)
        h = self.inp(x)
        for block in self.blocks:
            h = h + block(h)
        return P[:, None] + self.head(h).view(B, J, 3)


def build_model(config: RMPLConfig) -> nn.Module:
    """The network a config describes: :class:`RMPL` or the :class:`MLPLifter` baseline."""
    return MLPLifter(config) if config.architecture == "mlp" else RMPL(config)
