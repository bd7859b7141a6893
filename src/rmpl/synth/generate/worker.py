"""One process's heavy state (:class:`Worker`) and the shard it makes.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from rmpl.synth.generate.config import GenerateConfig, _shard_meshes
from rmpl.synth.generate.detectors import make_detector
from rmpl.synth.generate.frames import frame_shard
from rmpl.synth.generate.scenes import _scene_shard
from rmpl.synth.generate.sequences import MotionBank, _sequence_shard, load_motion_bank

log = logging.getLogger(__name__)


class Worker:
    """One process's heavy state: body model, GL renderer, detector and pose bank.

    Args:
        cfg: the generator config.
        bank_path: the pose bank ``.npz`` (None for random poses).
        cache_dir: anny's cache directory (default ``$ANNY_CACHE_DIR``).
    """

    def __init__(
        self, cfg: GenerateConfig, bank_path: str | Path | None, cache_dir: str | None = None
    ) -> None:
        from rmpl.synth.body import BodyModel
        from rmpl.synth.render import Renderer
        from rmpl.synth.retarget import load_pose_bank

        self.cfg = cfg
        self.body = BodyModel(
            cache_dir=cache_dir or os.environ.get("ANNY_CACHE_DIR"), joints=cfg.joints
        )
        self.renderer = Renderer(self.body.faces, self.body.num_vertices)
        self.detector = make_detector(cfg.detector, cfg.detector_options)
        # Single meshes read a PoseBank (poses.npz); sequences a MotionBank (motion.npz).
        self.bank = None
        self.motion: MotionBank | None = None
        if bank_path and cfg.sequences:
            self.motion = load_motion_bank(bank_path)
        elif bank_path:
            self.bank = load_pose_bank(bank_path)

    def close(self) -> None:
        self.renderer.close()
        close = getattr(self.detector, "close", None)
        if close is not None:
            close()


def generate_shard(worker: Worker, index: int, out: str | Path) -> dict:
    """Make shard ``index`` and write it atomically; returns its counts and stage times."""
    cfg = worker.cfg
    first = index * cfg.shard_size
    n = _shard_meshes(cfg, index)
    if n <= 0:
        raise ValueError(f"shard {index} is beyond num_meshes={cfg.num_meshes}")
    if cfg.sequences:
        return _sequence_shard(worker, index, first, n, out)
    if cfg.scenes:
        return _scene_shard(worker, index, first, n, out)
    return frame_shard(worker, index, first, n, out)
