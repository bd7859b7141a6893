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
from rmpl.models import PRETRAINED, checkpoint_reads_floor
from rmpl.skeleton import Skeleton, skeleton_for, to_model_joints

__all__ = [
    "Lifter",
    "LiftResult",
    "checkpoint_reads_floor",
    "estimate_up",
    "rotation_to_z",
    "PRETRAINED",
]

log = logging.getLogger(__name__)


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


def checked_floor(floor, rig: Rig):
    """``floor`` (an :class:`rmpl.geometry.floor.Floor` or None) checked against the rig's
    cameras (:func:`rmpl.geometry.floor.check_floor`); an InputError names the problem."""
    if floor is None:
        return None
    from rmpl.geometry.floor import Floor, check_floor

    if not isinstance(floor, Floor):
        raise InputError(None, "floor", "an rmpl.geometry.floor.Floor or None",
                         type(floor).__name__)  # fmt: skip
    return check_floor(floor, rig.centers, field="floor")


def floor_row(floor, Rc: np.ndarray) -> np.ndarray:
    """The floor plane in the z-up frame ``X' = Rc X`` as a network's row ``[n, h]`` (4,)."""
    return np.r_[Rc @ np.asarray(floor.normal, float), float(floor.height)].astype(np.float32)


def model_inputs(keypoints, scores, skeleton: Skeleton, joints: str | None):
    """A user's keypoints and scores in a model's joint set (:func:`to_model_joints`); a
    joint count that fits no joint set is one :class:`InputError`."""
    from rmpl.io.keypoints import _floats

    kp, sc = _floats(keypoints, "keypoints"), _floats(scores, "scores")
    if kp.ndim < 2 or kp.shape[-1] != 2 or sc.shape != kp.shape[:-1]:
        return kp, sc  # the shape checks that follow name the problem
    try:
        return to_model_joints(kp, sc, skeleton, joints)
    except ValueError as e:
        expected = "17 (COCO-17) or 26 (HALPE-26) joints, or a named joint set"
        raise InputError(None, "keypoints", expected, str(e)) from None


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

    def _forward(self, rays: np.ndarray, scores: np.ndarray, floor: np.ndarray | None = None):
        """The network; ``floor`` (N, 4) rows are read only by a model that reads the floor."""
        if self._onnx is not None:
            return self._onnx(rays, scores, floor)
        f = None if floor is None else torch.from_numpy(floor)
        return self.model(torch.from_numpy(rays), torch.from_numpy(scores), floor=f).numpy()

    @property
    def reads_floor(self) -> bool:
        """The model takes the floor plane as an input (``lift(..., floor=)``)."""
        return bool(getattr(self.model.config, "floor", False))

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

    @property
    def skeleton(self) -> Skeleton:
        """The joint set the model outputs (COCO-17, or HALPE-26 whose first 17 are COCO-17)."""
        return skeleton_for(self.model.config.skeleton)

    @torch.no_grad()
    def lift(
        self,
        keypoints: np.ndarray,
        scores: np.ndarray,
        rig: Rig,
        up: np.ndarray | None = None,
        batch_size: int = 128,
        progress: bool = False,
        joints: str | None = None,
        floor=None,
    ) -> LiftResult:
        """Lift 2D keypoints from calibrated views to 3D.

        Args:
            keypoints: pixels, shape (*, V, J, 2); NaN = missing. One person: for a file's
                (T, V, P, J, 2) keypoints pass ``keypoints[:, :, p]``.
            scores: confidences, shape (*, V, J); 0 = missing.
            rig: the V cameras (a :class:`~rmpl.Rig`, e.g. from :func:`rmpl.load_rig`), in
                the order of axis -3.
            up: world up direction (3,); estimated from the rig when None.
            batch_size: frames per forward pass (128 keeps a 10,000-frame, 4-view lift
                under 1 GB of memory at no cost in speed on 2 cores).
            progress: show a progress bar.
            joints: the keypoints' joint set (a name in :data:`rmpl.skeleton.SKELETONS`);
                None: the model's own (:attr:`skeleton`) when J matches, else COCO-17 for 17
                joints and HALPE-26 for 26.
                Joints the input lacks are missing; the model still estimates them.
            floor: the floor (:class:`rmpl.geometry.floor.Floor`) for a model that reads it
                (:attr:`reads_floor`; its normal is then the up direction unless ``up`` is
                given); other models ignore it. None = unknown.

        Keypoints more than one image size outside their image (cameras with a known
        size; :data:`rmpl.io.keypoints.FAR_MARGIN`) are treated as missing, with a warning.

        Returns:
            :class:`LiftResult` with points (*, J, 3) in world metres, J and its order those
            of :attr:`skeleton`; ``num_views`` counts the views of the model's joints.

        Raises:
            InputError: wrong types or shapes (a people axis is named as such), views not
                matching the rig, a bad ``up`` or ``batch_size``, or no keypoint at all.
        """
        kp, sc = model_inputs(keypoints, scores, self.skeleton, joints)
        kp, sc = self._checked(kp, sc, rig, up, batch_size, floor)
        ok = np.isfinite(kp).all(-1) & (sc > 0)
        if not ok.any():
            raise InputError(
                None, "scores", "at least one keypoint with confidence > 0", "all zero"
            )
        lead, (V, J) = kp.shape[:-3], kp.shape[-3:-1]
        if up is None and floor is not None and self.reads_floor:
            up = floor.n  # the floor's normal is the world's up
        Rc = rotation_to_z(estimate_up(rig) if up is None else np.asarray(up, float))
        rays = rays_from_keypoints(np.where(ok[..., None], kp, 0.0), rig)
        rays = np.concatenate([rays[..., :3] @ Rc.T, rays[..., 3:] @ Rc.T], -1)
        rays = rays.reshape(-1, V, J, 6).astype(np.float32)  # one row per frame
        s = np.where(ok, np.clip(sc, 0, 1), 0.0).reshape(-1, V, J).astype(np.float32)
        rows = None
        if floor is not None and self.reads_floor:
            rows = np.broadcast_to(floor_row(floor, Rc), (len(rays), 4)).copy()
        out = self._batched(rays, s, batch_size, progress, rows)
        points = (out.astype(float) @ Rc).reshape(*lead, J, 3)  # back to the user's world
        empty = ~ok.reshape(*lead, V * J).any(-1) if lead else ~ok.any()
        points[empty] = np.nan
        return LiftResult(points, ok.sum(-2))

    def _batched(self, rays, s, batch_size: int, progress: bool, floor=None) -> np.ndarray:
        """The network on (N, V, J, 6) rays (and (N, 4) floor rows), ``batch_size`` rows at a
        time: (N, J, 3)."""
        out = np.empty((rays.shape[0], rays.shape[2], 3), np.float32)
        starts = range(0, rays.shape[0], batch_size)
        if progress:
            from tqdm import tqdm

            starts = tqdm(starts, desc="lift", unit="batch")
        for i in starts:
            sl = slice(i, i + batch_size)
            out[sl] = self._forward(rays[sl], s[sl], None if floor is None else floor[sl])
        return out

    def _checked(
        self, keypoints, scores, rig, up, batch_size, floor=None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Validate :meth:`lift`'s arguments; keypoints far outside the image become missing."""
        from rmpl.io.keypoints import FAR_MARGIN, _floats, drop_far_keypoints

        if not isinstance(rig, Rig):
            raise InputError(
                None, "rig", "an rmpl.Rig (rmpl.load_rig(path) reads a calibration file)",
                type(rig).__name__,
            )  # fmt: skip
        if isinstance(batch_size, bool) or not isinstance(batch_size, int | np.integer):
            raise InputError(None, "batch_size", "an integer >= 1", repr(batch_size))
        if batch_size < 1:
            raise InputError(None, "batch_size", "an integer >= 1", batch_size)
        checked_floor(floor, rig)
        if up is not None:
            u = _floats(up, "up")
            if u.shape != (3,) or not np.isfinite(u).all() or not np.linalg.norm(u) > 0:
                raise InputError(None, "up", "a finite, non-zero 3-vector", u.tolist())
        kp, sc = _floats(keypoints, "keypoints"), _floats(scores, "scores")
        self._check_shapes(kp, sc, rig)
        seen = np.isfinite(kp).all(-1) & np.isfinite(sc)
        kp, sc, far = drop_far_keypoints(kp, np.where(seen, sc, 0.0), rig.sizes)
        if far:
            log.warning(
                "%d keypoints lie more than %g image size beyond their image: treated as "
                "missing", far, FAR_MARGIN,
            )  # fmt: skip
        return kp, sc

    def _check_shapes(self, kp: np.ndarray, sc: np.ndarray, rig: Rig) -> None:
        J, V = self.num_joints, len(rig)
        if kp.ndim < 3 or kp.shape[-2:] != (J, 2):
            raise InputError(None, "keypoints", f"shape (*, V, {J}, 2)", kp.shape)
        if kp.shape[-3] != V and kp.ndim >= 4 and kp.shape[-4] == V:
            raise InputError(
                None, "keypoints",
                f"shape (*, V, {J}, 2), one person: this has a people axis after the {V} "
                "views (T, V, P, J, 2); lift one person, keypoints[:, :, p] and scores[:, :, p]",
                kp.shape,
            )  # fmt: skip
        if kp.shape[-3] != V:
            raise InputError(
                None,
                "keypoints",
                f"{V} views to match the calibration's cameras {rig.names}",
                f"{kp.shape[-3]} views",
            )
        if sc.shape != kp.shape[:-1]:
            raise InputError(None, "scores", f"shape {kp.shape[:-1]} matching keypoints", sc.shape)
