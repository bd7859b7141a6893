"""From a mocap skeleton to COCO-17 joints: which rig joint is which keypoint, face and hip
offsets, left-right mirroring."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rmpl.skeleton import COCO17, flip_left_right
from rmpl.synth.motion._common import (
    Motion,
)

#: Face keypoints in the head frame, metres, as (left, forward, up) offsets from the
#: mid-ear point (the head centre of :class:`CocoMap`). Adult anthropometry, rounded:
#: interpupillary distance ~6.4 cm, pupils ~8.5 cm in front of and ~1.5 cm above the
#: tragion, nose tip ~11 cm in front of and ~3 cm below it, ears ~15 cm apart (COCO marks
#: the outer ear, a little outside the tragion).
FACE_OFFSETS: dict[str, tuple[float, float, float]] = {
    "nose": (0.0, 0.110, -0.030),
    "left_eye": (0.032, 0.085, 0.015),
    "right_eye": (-0.032, 0.085, 0.015),
    "left_ear": (0.075, 0.0, 0.0),
    "right_ear": (-0.075, 0.0, 0.0),
}
#: COCO hip keypoint relative to the mocap femur head, metres, as (outward, forward, up) in
#: the pelvis frame. COCO annotators mark the hip on the body outline near the greater
#: trochanter, which is higher and more lateral than the hip joint centre.
HIP_OFFSET: tuple[float, float, float] = (0.03, 0.0, 0.04)


@dataclass(frozen=True)
class CocoMap:
    """How to read COCO-17 from one rig (a family of skeletons sharing joint names).

    Attributes:
        body: COCO body joint (shoulders to ankles) -> rig joint. ``left_hip`` and
            ``right_hip`` name the femur heads; :data:`HIP_OFFSET` moves them.
        head: rig joint whose position and rotation carry the face.
        shoulder_outset: (left parent, right parent, fraction): move each shoulder, with
            its elbow and wrist, away from its parent joint by this fraction of the
            parent-to-shoulder vector, for rigs whose shoulder joints sit too close to the
            midline.
        head_centre: (left, forward, up) offset in metres, in the head frame, from the head
            joint to the mid-ear point where :data:`FACE_OFFSETS` start.
    """

    body: dict[str, str]
    head: str
    head_centre: tuple[float, float, float]
    shoulder_outset: tuple[str, str, float] | None = None


#: COCO joint -> CMU bone whose start is that joint (prefixed "l"/"r"): the bone carrying
#: the joint's dofs. The wrist is where ``hand`` (wrist flexion, rx rz) starts; ``wrist``
#: (ry) is the twisting distal forearm, its start ~7 cm above the wrist of a hanging arm.
_CMU_BONES = {
    "shoulder": "humerus",
    "elbow": "radius",
    "wrist": "hand",
    "hip": "femur",
    "knee": "tibia",
    "ankle": "foot",
}


COCO_MAPS: dict[str, CocoMap] = {
    # CMU ASF (joint = start of the bone) and the CMU-named BVH (16_01, 16_02). Against
    # stature proportions of subjects 01-03 the ~10 cm head bone runs from about chin to
    # about eye height, so the tragion lies ~6 cm above its start.
    "cmu": CocoMap(
        {f"{side}_{k}": side[0] + v for side in ("left", "right") for k, v in _CMU_BONES.items()},
        head="head",
        head_centre=(0.0, 0.0, 0.06),
    ),
    # Daz/Poser figure of the CMU BVH conversion (root ``hip``). Its eye joints sit 8.0 cm
    # above and 8.0 cm in front of ``head``; the offset puts FACE_OFFSETS' eyes on them.
    "daz": CocoMap(
        {
            "left_shoulder": "lShldr",
            "right_shoulder": "rShldr",
            "left_elbow": "lForeArm",
            "right_elbow": "rForeArm",
            "left_wrist": "lHand",
            "right_wrist": "rHand",
            "left_hip": "lThigh",
            "right_hip": "rThigh",
            "left_knee": "lShin",
            "right_knee": "rShin",
            "left_ankle": "lFoot",
            "right_ankle": "rFoot",
        },
        head="head",
        head_centre=(0.0, -0.005, 0.065),
        # Its shoulder joints are 23 cm apart against 37 cm for the CMU ASF subjects (and
        # 35-40 cm adult biacromial breadth): move them out along the collar bones.
        shoulder_outset=("lCollar", "rCollar", 0.7),
    ),
}


def detect_rig(names: Sequence[str]) -> str:
    """Key of :data:`COCO_MAPS` whose joints are all in ``names``.

    >>> detect_rig(["hip", "lThigh", "rThigh", "lShin", "rShin", "lFoot", "rFoot", "head",
    ...             "lShldr", "rShldr", "lForeArm", "rForeArm", "lHand", "rHand"])
    'daz'
    """
    have = set(names)
    for key, m in COCO_MAPS.items():
        if set(m.body.values()) | {m.head} <= have:
            return key
    raise ValueError(
        f"no COCO-17 map fits joints {sorted(have)[:12]}...; known: {sorted(COCO_MAPS)}"
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rest_frame(motion: Motion, m: CocoMap) -> np.ndarray:
    """Rest-pose body axes as columns (left, forward, up), shape (3, 3): left from the hips,
    up = +z, forward = left x up."""
    left = (
        motion.rest[motion.index(m.body["left_hip"])]
        - motion.rest[motion.index(m.body["right_hip"])]
    )
    left = _unit(left * [1.0, 1.0, 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return np.stack([left, np.cross(left, up), up], axis=1)


def _hips(motion: Motion, m: CocoMap, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """COCO hips: femur heads moved by :data:`HIP_OFFSET` in the pelvis frame, (T, 3) each."""
    left = motion.positions[:, motion.index(m.body["left_hip"])]
    right = motion.positions[:, motion.index(m.body["right_hip"])]
    lateral = _unit(left - right)  # (T, 3)
    up = motion.rotations[:, 0] @ axes[:, 2]  # pelvis up: the root segment's rest up
    up = _unit(up - np.sum(up * lateral, axis=-1, keepdims=True) * lateral)
    forward = np.cross(lateral, up)
    out, fwd, rise = HIP_OFFSET
    shift = fwd * forward + rise * up
    return left + out * lateral + shift, right - out * lateral + shift


def to_coco17(motion: Motion, rig: str | None = None) -> np.ndarray:
    """COCO-17 joints of a motion, metres, z up, shape (T, 17, 3).

    Body joints come from the rig's joints (:data:`COCO_MAPS`), hips moved by
    :data:`HIP_OFFSET`; face points are :data:`FACE_OFFSETS` in the head frame.

    Args:
        motion: a loaded clip.
        rig: key of :data:`COCO_MAPS`; default :func:`detect_rig`.
    """
    m = COCO_MAPS[rig or detect_rig(motion.names)]
    axes = _rest_frame(motion, m)
    out = np.empty((motion.num_frames, COCO17.num_joints, 3))
    for coco, joint in m.body.items():
        out[:, COCO17.index(coco)] = motion.positions[:, motion.index(joint)]
    out[:, COCO17.index("left_hip")], out[:, COCO17.index("right_hip")] = _hips(motion, m, axes)
    if m.shoulder_outset is not None:  # the whole arm moves out, so its bones keep length
        *parents, fraction = m.shoulder_outset
        for side, parent in zip(("left", "right"), parents, strict=True):
            i = COCO17.index(f"{side}_shoulder")
            shift = fraction * (out[:, i] - motion.positions[:, motion.index(parent)])  # (T, 3)
            for joint in ("shoulder", "elbow", "wrist"):
                out[:, COCO17.index(f"{side}_{joint}")] += shift
    h = motion.index(m.head)
    head_axes = motion.rotations[:, h] @ axes  # (T, 3, 3): columns left, forward, up
    centre = motion.positions[:, h] + head_axes @ np.asarray(m.head_centre)
    for name, offset in FACE_OFFSETS.items():
        out[:, COCO17.index(name)] = centre + head_axes @ np.asarray(offset)
    return out


def mirror(poses: np.ndarray) -> np.ndarray:
    """Mirror COCO-17 poses left/right: swap the left and right joints and reflect x about
    the pelvis centre (the mid-hip point stays put). For a person facing along +-y this is
    the reflection in their sagittal plane; otherwise it equals it up to a turn about z.

    poses: shape (*, 17, 3), z up. Returns the same shape; ``mirror(mirror(p)) == p``.

    >>> p = np.zeros((17, 3)); p[5] = [1.0, 0.0, 1.5]  # left shoulder
    >>> mirror(p)[6].tolist()  # becomes the right shoulder, reflected
    [-1.0, 0.0, 1.5]
    """
    poses = np.asarray(poses)
    hips = [COCO17.index("left_hip"), COCO17.index("right_hip")]
    cx = poses[..., hips, 0].mean(axis=-1, keepdims=True)  # (*, 1)
    out = flip_left_right(poses, COCO17).copy()
    out[..., 0] = 2 * cx - out[..., 0]
    return out
