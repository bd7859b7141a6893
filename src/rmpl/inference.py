"""High-level lifting: keypoints + calibration -> 3D joints, with a pretrained model.

Example::

    import rmpl
    lifter = rmpl.Lifter.from_pretrained()           # the model shipped in the wheel
    result = lifter.lift(keypoints, scores, rig)     # (T, V, 17, 2), (T, V, 17), Rig

The network was trained in a z-up world. A user's world may have any up axis (Panoptic's is
-y, OpenSim's +y), so :meth:`Lifter.lift` rotates the rays into a z-up frame first and the
prediction back afterwards. The up axis is estimated from the cameras (upright cameras have
horizontal image x-axes) unless given.
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
from rmpl.model.lifter import RMPL

__all__ = ["Lifter", "LiftResult", "estimate_up", "rotation_to_z", "PRETRAINED"]

log = logging.getLogger(__name__)

_WEIGHTS = Path(__file__).parent / "weights"
#: Models shipped inside the package, by name. ``default``: the best on the joints the
#: detector sees; ``occlusion``: the same recipe with more keypoint removal in training
#: (p=0.4), better when many keypoints are missing (docs/results.md).
PRETRAINED: dict[str, Path] = {
    "default": _WEIGHTS / "default",
    "occlusion": _WEIGHTS / "occlusion",
}


@dataclass
class LiftResult:
    """Lifted joints.

    Attributes:
        points: (*, J, 3) world metres; NaN for frames with no keypoint at all.
        num_views: (*, J) number of views that saw each joint (0, 1, 2+...).
    """

    points: np.ndarray
    num_views: np.ndarray


def estimate_up(rig: Rig) -> np.ndarray:
    """World up direction from camera orientations, shape (3,).

    Upright cameras have image x-axes perpendicular to up, so up is the direction most
    perpendicular to all of them; its sign is set by the cameras' image-up vectors. With
    one camera (or parallel x-axes) the mean image-up vector is used.

    >>> import numpy as np
    >>> from rmpl.geometry.camera import Camera, Rig, look_at
    >>> K = np.diag([500.0, 500, 1]); K[:2, 2] = 320, 240
    >>> cams = [Camera(K, *look_at(e, np.zeros(3)), name=str(i))
    ...         for i, e in enumerate(np.array([[4.0, 0, 2], [0, 4, 1], [-3, -3, 3]]))]
    >>> np.round(estimate_up(Rig(tuple(cams))), 6).tolist()
    [0.0, 0.0, 1.0]
    """
    R = rig.R
    x_axes = R[:, 0, :]  # rows of R are the camera axes in world coordinates
    img_up = -R[:, 1, :]
    mean_up = img_up.sum(0)
    if len(rig) >= 2:
        _, s, vt = np.linalg.svd(x_axes)
        if s.size >= 2 and s[1] > 0.2 * s[0]:
            up = vt[-1]
            return up if up @ mean_up >= 0 else -up
    return mean_up / np.linalg.norm(mean_up)


def rotation_to_z(up: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector ``up`` (3,) to +z, shape (3, 3)."""
    from rmpl.geometry.camera import rodrigues

    up = np.asarray(up, float) / np.linalg.norm(up)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(up, z)
    s, c = np.linalg.norm(axis), float(up @ z)
    if s < 1e-9:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return rodrigues(axis / s * np.arctan2(s, c))


class Lifter:
    """A trained RMPL model ready for inference.

    Args:
        model: the network.
        meta: the checkpoint's description (config, skeleton, training summary).
    """

    def __init__(self, model: RMPL, meta: dict | None = None, backend: str = "auto") -> None:
        if model.config.inputs != "rays":
            raise ValueError(
                f"this checkpoint is a modality-ablation model (inputs={model.config.inputs!r}); "
                "only ray models lift real data"
            )
        self.model = model.eval()
        self.meta = meta or {}
        if backend not in ("auto", "torch", "onnx"):
            raise ValueError(f"backend must be 'auto', 'torch' or 'onnx', got {backend!r}")
        self._onnx = None
        if backend in ("auto", "onnx"):
            try:
                from rmpl.model.export import OnnxLifter

                self._onnx = OnnxLifter(self.model)
            except ImportError:
                if backend == "onnx":
                    raise ImportError(
                        "backend='onnx' needs onnxruntime: pip install 'rmpl[fast]'"
                    ) from None
                log.debug("onnxruntime not installed; lifting with torch")

    @property
    def backend(self) -> str:
        return "onnx" if self._onnx is not None else "torch"

    def _forward(self, rays: np.ndarray, scores: np.ndarray) -> np.ndarray:
        if self._onnx is not None:
            return self._onnx(rays, scores)
        return self.model(torch.from_numpy(rays), torch.from_numpy(scores)).numpy()

    @classmethod
    def from_pretrained(cls, name_or_path: str | Path = "default", backend: str = "auto") -> Lifter:
        """Load a shipped model by name (see :data:`PRETRAINED`) or a checkpoint directory.

        ``backend``: "onnx" (onnxruntime, fastest on CPU), "torch", or "auto" (onnx when
        onnxruntime is installed)."""
        from rmpl.training.loop import load_checkpoint

        path = PRETRAINED.get(str(name_or_path), Path(name_or_path))
        if not (Path(path) / "config.json").is_file():
            names = ", ".join(sorted(PRETRAINED))
            raise InputError(path, None, f"a checkpoint directory or a shipped model ({names})")
        model, meta = load_checkpoint(path)
        return cls(model, meta, backend)

    @property
    def num_joints(self) -> int:
        return self.model.config.num_joints

    @torch.no_grad()
    def lift(
        self,
        keypoints: np.ndarray,
        scores: np.ndarray,
        rig: Rig,
        up: np.ndarray | None = None,
        batch_size: int = 128,
        progress: bool = False,
    ) -> LiftResult:
        """Lift 2D keypoints from calibrated views to 3D.

        Args:
            keypoints: pixels, shape (*, V, J, 2); NaN = missing.
            scores: confidences, shape (*, V, J); 0 = missing.
            rig: the V cameras, in the order of axis -3.
            up: world up direction (3,); estimated from the rig when None.
            batch_size: frames per forward pass (128 keeps a 10,000-frame, 4-view lift
                under 1 GB of memory at no cost in speed on 2 cores).
            progress: show a progress bar.

        Returns:
            :class:`LiftResult` with points (*, J, 3) in world metres.

        Raises:
            InputError: wrong shapes, views not matching the rig, or no keypoint at all.
        """
        kp = np.asarray(keypoints, dtype=float)
        sc = np.asarray(scores, dtype=float)
        J = self.num_joints
        if kp.ndim < 3 or kp.shape[-2:] != (J, 2):
            raise InputError(None, "keypoints", f"shape (*, V, {J}, 2)", kp.shape)
        if sc.shape != kp.shape[:-1]:
            raise InputError(None, "scores", f"shape {kp.shape[:-1]} matching keypoints", sc.shape)
        if kp.shape[-3] != len(rig):
            raise InputError(
                None,
                "keypoints",
                f"{len(rig)} views to match the calibration's cameras {rig.names}",
                f"{kp.shape[-3]} views",
            )
        ok = np.isfinite(kp).all(-1) & np.isfinite(sc) & (sc > 0)
        if not ok.any():
            raise InputError(
                None, "scores", "at least one keypoint with confidence > 0", "all zero"
            )
        lead = kp.shape[:-3]
        V = kp.shape[-3]
        rays = rays_from_keypoints(np.where(ok[..., None], kp, 0.0), rig)
        Rc = rotation_to_z(estimate_up(rig) if up is None else np.asarray(up, float))
        o = rays[..., :3] @ Rc.T
        d = rays[..., 3:] @ Rc.T
        rays = np.concatenate([o, d], -1).reshape(-1, V, J, 6).astype(np.float32)
        s = np.where(ok, np.clip(sc, 0, 1), 0.0).reshape(-1, V, J).astype(np.float32)
        out = np.empty((rays.shape[0], J, 3), np.float32)
        starts = range(0, rays.shape[0], batch_size)
        if progress:
            from tqdm import tqdm

            starts = tqdm(starts, desc="lift", unit="batch")
        for i in starts:
            sl = slice(i, i + batch_size)
            out[sl] = self._forward(rays[sl], s[sl])
        points = (out.astype(float) @ Rc).reshape(*lead, J, 3)  # back to the user's world
        empty = ~ok.reshape(*lead, V * J).any(-1) if lead else ~ok.any()
        points[empty] = np.nan
        return LiftResult(points, ok.sum(-2))
