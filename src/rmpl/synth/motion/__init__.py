"""Real human motion to 3D COCO-17 joints: Acclaim ASF/AMC and BVH readers, forward
kinematics, units and axes, retargeting to COCO-17, and a pose set for training.

Conventions, written once:

* World frame: metres, right-handed, **z up**. The CMU ASF skeletons and the BVH files are
  y up; a point ``(x, y, z)`` becomes ``(x, -z, y)`` (:data:`Y_UP_TO_Z_UP`). The loaders keep
  the file's floor (within 0.1 m of z = 0 for most CMU clips, but 0.8 m below it in some
  BVH clips); :func:`load_motion_dir` puts each clip's floor at z = 0.
* A **joint** is the point where a segment starts, as in BVH. For ASF, the joint called
  ``lfemur`` is the start of the femur bone, i.e. the hip; every bone without children adds
  an end point ``<bone>_end``. So the CMU ASF skeleton and the CMU-named BVH skeleton share
  joint names and meaning.
* ``rotations[t, j]`` is the global rotation of the segment starting at joint ``j``
  relative to the rest pose: it maps a direction of the rest pose (in the z-up world) to
  the same direction at frame ``t``. Identity at rest, for ASF and BVH alike.
* Shapes: ``T`` frames, ``J`` joints, ``N`` poses.

Units: an ASF file states its length unit; the CMU convention is that ``:units length
0.45`` means one file unit is 1/0.45 inch, so metres = value * 0.0254 / 0.45. BVH files
state no unit; it is the one of :data:`LENGTH_UNITS` that makes the rest pose about as tall
as a person (:func:`detect_length_unit`). Either way the rest height must land in
:data:`PLAUSIBLE_REST_HEIGHT` or the file is rejected (pass ``scale`` to override).

Layout, in the order data flows: :mod:`.asf` and :mod:`.bvh` read mocap files;
:mod:`.kinematics` turns their joint angles into positions and rotations (metres, z up);
:mod:`.coco` reads COCO-17 joints off a rig; :mod:`.bank` finds clips, keeps their usable
frames and saves the pose bank. :mod:`._common` holds :class:`Motion` and shared helpers.
"""

from __future__ import annotations

from rmpl.synth.motion import bank as _bank
from rmpl.synth.motion._common import (
    LENGTH_UNITS,
    PLAUSIBLE_REST_HEIGHT,
    TYPICAL_REST_HEIGHT,
    Y_UP_TO_Z_UP,
    Motion,
)
from rmpl.synth.motion.asf import AsfBone, AsfSkeleton, load_asf_amc, read_amc, read_asf
from rmpl.synth.motion.bank import (
    BROKEN_CLIPS,
    FRAME_RATES,
    MAX_ROOT_SPEED,
    REST_BLEND,
    Clip,
    PoseSet,
    build_pose_cache,
    find_clips,
    load_motion_dir,
    load_pose_set,
    save_pose_set,
    usable_frames,
)
from rmpl.synth.motion.bvh import load_bvh
from rmpl.synth.motion.coco import (
    COCO_MAPS,
    FACE_OFFSETS,
    HIP_OFFSET,
    CocoMap,
    detect_rig,
    mirror,
    to_coco17,
)
from rmpl.synth.motion.kinematics import detect_length_unit, floor_height

__all__ = [
    "Y_UP_TO_Z_UP",
    "LENGTH_UNITS",
    "PLAUSIBLE_REST_HEIGHT",
    "TYPICAL_REST_HEIGHT",
    "FACE_OFFSETS",
    "HIP_OFFSET",
    "MAX_ROOT_SPEED",
    "REST_BLEND",
    "BROKEN_CLIPS",
    "FRAME_RATES",
    "CocoMap",
    "COCO_MAPS",
    "Motion",
    "AsfBone",
    "AsfSkeleton",
    "PoseSet",
    "Clip",
    "read_asf",
    "read_amc",
    "load_asf_amc",
    "load_bvh",
    "detect_length_unit",
    "floor_height",
    "detect_rig",
    "to_coco17",
    "find_clips",
    "usable_frames",
    "load_motion_dir",
    "mirror",
    "save_pose_set",
    "load_pose_set",
    "build_pose_cache",
]

# Helpers that rmpl.data.sequences reaches through this module (it walks clips itself).
_load_clip, _matches, _sample = _bank._load_clip, _bank._matches, _bank._sample
