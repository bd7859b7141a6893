"""CMU Panoptic Studio: HD cameras and the ``hdPose3d_stage1_coco19`` ground truth.

The layout on disk, as the Panoptic toolbox downloads and extracts it::

    <root>/<sequence>/calibration_<sequence>.json
    <root>/<sequence>/hdPose3d_stage1_coco19/body3DScene_<frame>.json   (frame: 8 digits)

``root`` may also be the sequence folder itself.

- ``calibration_<sequence>.json``: every camera of the dome (read by
  :func:`rmpl.io.calibration.load_rig`, format ``panoptic``; ``t`` in centimetres). Only
  HD cameras (1920 x 1080) are used; by default the five of VoxelPose's protocol,
  :data:`DEFAULT_CAMERAS`.
- ``body3DScene_<frame>.json``: ``{"bodies": [{"id": int, "joints19": [x, y, z, c, ...]},
  ...]}``, 19 joints in centimetres in the world frame of the calibration (the dome's
  frame: y points down, towards the floor) with a per-joint confidence ``c`` (negative
  where the joint was not reconstructed). The frame is the HD video frame number.

The 19 joints (:data:`COCO19_JOINTS`, Panoptic toolbox order) are: neck, nose, body centre
(mid-hip), left shoulder, elbow, wrist, hip, knee, ankle, right shoulder, elbow, wrist,
hip, knee, ankle, left eye, left ear, right eye, right ear. The ground truth is returned
as COCO-17 (:data:`COCO19_TO_COCO17`); neck and body centre are dropped.

The download has no 2D detections. Pass your detector's output as COCO-style JSON, one
file per camera (``detections=``, read by :func:`rmpl.io.keypoints.load_keypoints`; the
frame is the last number of each image's ``file_name``, as in Panoptic's
``00_03_00000168.jpg``), or use :func:`rmpl.data.base.keypoints_from_projection` as a
stand-in.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from rmpl.data.base import MultiViewDataset, attach_keypoints, keypoints_from_projection
from rmpl.errors import InputError
from rmpl.geometry.camera import Rig
from rmpl.skeleton import COCO17

__all__ = [
    "COCO19_JOINTS",
    "COCO19_TO_COCO17",
    "DEFAULT_CAMERAS",
    "load_panoptic",
    "keypoints_from_projection",
]

#: Joint order of Panoptic's ``joints19`` (the toolbox's "coco19").
COCO19_JOINTS = (
    "neck",
    "nose",
    "mid_hip",
    "left_shoulder",
    "left_elbow",
    "left_wrist",
    "left_hip",
    "left_knee",
    "left_ankle",
    "right_shoulder",
    "right_elbow",
    "right_wrist",
    "right_hip",
    "right_knee",
    "right_ankle",
    "left_eye",
    "left_ear",
    "right_eye",
    "right_ear",
)
#: For each COCO-17 joint, its index in ``joints19``.
COCO19_TO_COCO17 = tuple(COCO19_JOINTS.index(n) for n in COCO17.joints)
#: The five HD cameras of the customary multi-person protocol (VoxelPose and successors).
DEFAULT_CAMERAS = ("00_03", "00_06", "00_12", "00_13", "00_23")
_FRAME = re.compile(r"body3DScene_(\d+)\.json")
_CM = 0.01  # metres per centimetre


def _sequence_dir(root: Path, sequence: str | None) -> tuple[Path, str]:
    if sequence is not None:
        folder = root / sequence
        if not folder.is_dir():
            raise InputError(folder, None, f"the folder of sequence {sequence!r}", "no such folder")
        return folder, sequence
    own = sorted(root.glob("calibration_*.json"))
    if own:
        return root, own[0].stem.removeprefix("calibration_")
    found = sorted(p.name for p in root.iterdir() if (p / f"calibration_{p.name}.json").is_file())
    if len(found) != 1:
        raise InputError(
            root, "sequence", "a sequence name (or a root holding exactly one sequence)", found
        )
    return root / found[0], found[0]


def _load_rig(folder: Path, sequence: str, cameras: Sequence[str] | None) -> Rig:
    from rmpl.io.calibration import load_rig

    path = folder / f"calibration_{sequence}.json"
    if not path.is_file():
        raise InputError(path, None, "the sequence's calibration file", "no such file")
    rig = load_rig(path, "panoptic", camera_type="hd")
    if cameras is None:
        return rig
    missing = [c for c in cameras if c not in rig.names]
    if missing or not cameras:
        raise InputError(path, "cameras", f"HD cameras among {rig.names}", list(cameras))
    return rig[[rig.names.index(c) for c in cameras]]


def _read_bodies(path: Path) -> list[tuple[int, np.ndarray]]:
    """(id, (19, 4) x y z c in cm) of every body in one frame file."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(path, None, "a JSON file", f"{type(e).__name__}: {e}") from None
    bodies = doc.get("bodies") if isinstance(doc, dict) else None
    if not isinstance(bodies, list):
        raise InputError(path, "bodies", "a list of bodies", type(bodies).__name__)
    out = []
    for i, body in enumerate(bodies):
        pid = body.get("id") if isinstance(body, dict) else None
        if not isinstance(pid, int) or isinstance(pid, bool):
            raise InputError(path, f"bodies[{i}].id", "an integer", pid)
        try:
            joints = np.array(body.get("joints19"), dtype=float)
        except (TypeError, ValueError):
            joints = None
        if joints is None or joints.shape != (19 * 4,):
            got = None if joints is None else joints.shape
            raise InputError(path, f"bodies[{i}].joints19", "76 numbers (19 x, y, z, c)", got)
        out.append((pid, joints.reshape(19, 4)))
    return out


def _load_gt(folder: Path, min_confidence: float):
    """frames (T,), ids (P,), gt (T, P, 17, 3) metres, NaN where absent or unsure."""
    pose_dir = folder / "hdPose3d_stage1_coco19"
    files = {}
    for p in pose_dir.glob("body3DScene_*.json") if pose_dir.is_dir() else ():
        m = _FRAME.fullmatch(p.name)
        if m:
            files[int(m[1])] = p
    if not files:
        raise InputError(pose_dir, None, "body3DScene_<frame>.json files", "none")
    frames = np.array(sorted(files))
    per_frame = [_read_bodies(files[f]) for f in frames]
    ids = np.array(sorted({pid for bodies in per_frame for pid, _ in bodies}), dtype=int)
    slot = {pid: i for i, pid in enumerate(ids)}
    gt = np.full((len(frames), len(ids), 17, 3), np.nan)
    for t, bodies in enumerate(per_frame):
        for pid, joints in bodies:
            j = joints[list(COCO19_TO_COCO17)]
            gt[t, slot[pid]] = np.where(j[:, 3:] >= min_confidence, j[:, :3] * _CM, np.nan)
    return frames, ids, gt


def load_panoptic(
    root: str | Path,
    sequence: str | None = None,
    cameras: Sequence[str] | None = DEFAULT_CAMERAS,
    *,
    detections: Mapping[str, str | Path] | Sequence[str | Path] | None = None,
    min_confidence: float = 0.1,
) -> MultiViewDataset:
    """Load one CMU Panoptic sequence (layout in the module docstring).

    Args:
        root: the folder of sequences, or one sequence folder.
        sequence: the sequence name, e.g. "160906_band1"; None when ``root`` is the
            sequence folder or holds exactly one sequence.
        cameras: HD camera names, in the order of the views; None for every HD camera.
        detections: 2D keypoints, COCO-style JSON (MMPose, rtmlib, COCO results), one
            file per camera: a mapping camera name -> path, or a list in the order of
            ``cameras``. None leaves ``keypoints`` None (see
            :func:`rmpl.data.base.keypoints_from_projection` for a stand-in).
        min_confidence: ground-truth joints whose Panoptic confidence is below this are
            NaN (0.1, as in VoxelPose; negative values mark joints not reconstructed).

    Returns:
        A :class:`~rmpl.data.base.MultiViewDataset`: ground truth in COCO-17, shape
        (T, P, 17, 3), metres; ``person_ids`` the Panoptic body ids.

    Raises:
        InputError: a missing sequence, camera or file, or a malformed file.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, None, "a Panoptic folder", "no such folder")
    folder, sequence = _sequence_dir(root, sequence)
    rig = _load_rig(folder, sequence, cameras)
    frames, ids, gt = _load_gt(folder, min_confidence)
    dataset = MultiViewDataset(
        rig, frames, gt, COCO17.name, None, None, f"panoptic/{sequence}", person_ids=ids
    )
    if detections is None:
        return dataset
    from rmpl.io.keypoints import load_keypoints

    return attach_keypoints(dataset, load_keypoints(detections, format="coco", to="coco17"))
