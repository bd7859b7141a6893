"""``rmpl generate``: the MHP dataset generator (thesis chapter 5), sharded and resumable.

One mesh = one anny body (random phenotype) posed from real motion (CMU ASF/AMC or BVH,
retargeted by :mod:`rmpl.synth.retarget`, mirrored and perturbed at random) or from the
random pose sampler, stood on the floor at a random place and heading, seen by ``views``
random cameras (:mod:`rmpl.synth.cameras`), rendered (:mod:`rmpl.synth.render`) and run
through a real 2D detector (:mod:`rmpl.synth.detect`). Its 3D COCO-17 joints come from the
mesh with anny's keypoint regressor, so targets and detections share the detector's joint
definitions.

Output directory::

    manifest.json           self-describing: config, counts, detector, joints, units, arrays
    poses.npz               the pose bank read from the motion folder (for resuming)
    shard_00000.npz ...     one compressed NPZ per ``shard_size`` meshes (see SHARD_ARRAYS)

Each shard is seeded by ``(seed, shard index)`` and written atomically, so a killed run
loses at most the shards in progress and running the same command again skips the
finished shards.

**Sequences** (``sequence_frames >= 2``): each sample is ``T = sequence_frames`` consecutive
frames of one motion segment (its source frames every ``k``-th, ``k`` chosen so the frame
rate falls near one drawn log-uniformly in ``sequence_fps``, the playback speed drawn in
``sequence_speed``), played by one body (one phenotype, outfit, lighting, mirroring and
bone perturbation), moving through the room as the mocap root moved, and seen by one rig
(each camera keeps its background). Every frame is rendered and detected as
``rmpl run --videos`` detects a recording: a detector that follows people from frame to
frame (``blazepose-multi``, ``rmpl run``'s default) gets each view's frames in order, as
one video; one that does not (MediaPipe's legacy ``Pose``, this config's default
``detector``, static-image mode) detects every image afresh.
The motion is read into ``motion.npz`` (:class:`MotionBank`) instead of ``poses.npz``, the
manifest's format is :data:`SEQUENCE_FORMAT` and the shards hold
:data:`SEQUENCE_ARRAYS`; ``num_meshes`` and ``shard_size`` count sequences, and each
sequence ``i`` is seeded by ``(seed, i, 2)``.

Shape glossary: ``M`` meshes, ``S`` sequences, ``T`` frames, ``V`` views, ``J`` joints (17).

The package: :mod:`~rmpl.synth.generate.config` (:class:`GenerateConfig`),
:mod:`~rmpl.synth.generate.detectors` (the detectors by name), :mod:`~rmpl.synth.generate.worker`
(one process's state and its shard), :mod:`~rmpl.synth.generate.frames`,
:mod:`~rmpl.synth.generate.sequences` and :mod:`~rmpl.synth.generate.scenes` (the three kinds
of shard) and :mod:`~rmpl.synth.generate.driver` (:func:`generate`). The formats and files
of a set are in :mod:`rmpl.synth.shards`, which the datasets read.
"""

from __future__ import annotations

from rmpl.synth.generate.config import (
    _SEQUENCE_KEYS,
    GenerateConfig,
    _config_dict,
    shard_arrays,
)
from rmpl.synth.generate.detectors import (
    check_detector_options,
    detect_person,
    follows,
    in_joint_set,
    make_detector,
)
from rmpl.synth.generate.driver import (
    _prepare_bank,
    _prepare_motion,
    _write_manifest,
    generate,
    summarize,
)
from rmpl.synth.generate.frames import _draw_poses, _scale_cameras, occlude
from rmpl.synth.generate.scenes import (
    MATCH_TOLERANCE,
    SCENE_GAP,
    _detect_people_apart,
    _scene,
    match_detections,
    room_fits,
    spread,
)
from rmpl.synth.generate.sequences import (
    _MOTION_FORMAT,
    MotionBank,
    build_motion_bank,
    draw_window,
    follow_root,
    load_motion_bank,
    save_motion_bank,
)
from rmpl.synth.generate.worker import Worker, generate_shard
from rmpl.synth.shards import (
    FORMAT,
    SCENE_ARRAYS,
    SCENE_FORMAT,
    SEQUENCE_ARRAYS,
    SEQUENCE_FORMAT,
    SHARD_ARRAYS,
    list_shards,
    shard_path,
)

__all__ = [
    "FORMAT",
    "GenerateConfig",
    "MATCH_TOLERANCE",
    "MotionBank",
    "SCENE_ARRAYS",
    "SCENE_FORMAT",
    "SCENE_GAP",
    "SEQUENCE_ARRAYS",
    "SEQUENCE_FORMAT",
    "SHARD_ARRAYS",
    "Worker",
    "build_motion_bank",
    "check_detector_options",
    "detect_person",
    "draw_window",
    "follow_root",
    "follows",
    "generate",
    "generate_shard",
    "in_joint_set",
    "list_shards",
    "load_motion_bank",
    "make_detector",
    "match_detections",
    "occlude",
    "room_fits",
    "save_motion_bank",
    "shard_arrays",
    "shard_path",
    "spread",
    "summarize",
    # used by tests and benchmarks
    "_MOTION_FORMAT",
    "_SEQUENCE_KEYS",
    "_config_dict",
    "_detect_people_apart",
    "_draw_poses",
    "_prepare_bank",
    "_scale_cameras",
    "_prepare_motion",
    "_scene",
    "_write_manifest",
]
