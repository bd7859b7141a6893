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
"""

from __future__ import annotations

import json
import logging
import os
import time
import tomllib
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import SKELETONS

__all__ = [
    "GenerateConfig",
    "SHARD_ARRAYS",
    "SEQUENCE_ARRAYS",
    "MotionBank",
    "build_motion_bank",
    "load_motion_bank",
    "save_motion_bank",
    "generate",
    "generate_shard",
    "shard_path",
    "list_shards",
    "Worker",
]

log = logging.getLogger(__name__)

FORMAT = "rmpl.mhp.v1"
#: The manifest format of a sequence set (``sequence_frames >= 2``).
SEQUENCE_FORMAT = "rmpl.mhp.sequences.v1"
_MOTION_FORMAT = "rmpl.mhp.motion.v1"
#: Config keys that only sequence sets have (left out of a single-frame set's manifest,
#: which stays as it was before sequences existed).
_SEQUENCE_KEYS = ("sequence_frames", "sequence_fps", "sequence_speed")
#: The manifest format of a multi-person scene set (``people`` up to 2 or more).
SCENE_FORMAT = "rmpl.mhp.scenes.v1"
#: A detection slot is of a body when its keypoints lie within this fraction of the body's
#: projected size of the body's projected joints (median over the detected joints).
MATCH_TOLERANCE = 0.2

#: Arrays of a shard: name -> (shape, meaning).
SHARD_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(M, 17, 3) float32", "COCO-17 joints regressed from the mesh, world metres"),
    "keypoints": ("(M, V, 17, 2) float32", "detector keypoints, pixels, NaN = missed"),
    "scores": ("(M, V, 17) float32", "detector confidence in [0, 1], 0 = missed or outside"),
    "projected": ("(M, V, 17, 2) float32", "joints3d projected into each view, pixels"),
    "K": ("(M, V, 3, 3) float64", "intrinsics, pixels"),
    "R": ("(M, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(M, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(M, V, 2) int32", "image (width, height), pixels"),
    "occluded": ("(M, V, 17) bool", "a black square was pasted over the joint"),
    "phenotypes": ("(M, 6) float32", "anny phenotypes (rmpl.synth.body.PHENOTYPES order)"),
    "subject": ("(M,) str", "source subject id ('random' for random poses)"),
    "clip": ("(M,) str", "source clip (path under the motion folder)"),
    "frame": ("(M,) int64", "source frame in the clip (-1 for random poses)"),
    "mirrored": ("(M,) bool", "the pose was mirrored left/right"),
}

#: Arrays of a sequence shard: name -> (shape, meaning).
SEQUENCE_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(S, T, 17, 3) float32", "COCO-17 joints regressed from the mesh, world metres"),
    "keypoints": ("(S, T, V, 17, 2) float32", "detector keypoints, pixels, NaN = missed"),
    "scores": ("(S, T, V, 17) float32", "detector confidence in [0, 1], 0 = missed or outside"),
    "projected": ("(S, T, V, 17, 2) float32", "joints3d projected into each view, pixels"),
    "times": ("(S, T) float64", "time of each frame, seconds from the sequence's first"),
    "fps": ("(S,) float64", "frames per second of the sequence"),
    "speed": ("(S,) float64", "motion seconds per second of the sequence (1 = real time)"),
    "K": ("(S, V, 3, 3) float64", "intrinsics, pixels (one rig per sequence)"),
    "R": ("(S, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(S, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(S, V, 2) int32", "image (width, height), pixels"),
    "phenotypes": ("(S, 6) float32", "anny phenotypes (rmpl.synth.body.PHENOTYPES order)"),
    "subject": ("(S,) str", "source subject id"),
    "clip": ("(S,) str", "source clip (path under the motion folder)"),
    "frame": ("(S, T) int64", "source frame of each frame in the clip"),
    "mirrored": ("(S,) bool", "the motion was mirrored left/right"),
}

#: Arrays of a multi-person scene shard (``M`` scenes, ``P`` body slots = ``people[1]``,
#: ``N`` detector slots = the detector's ``max_people``): name -> (shape, meaning).
SCENE_ARRAYS: dict[str, tuple[str, str]] = {
    "joints3d": ("(M, P, 17, 3) float32", "COCO-17 joints of each body, world metres, NaN = none"),
    "present": ("(M, P) bool", "the body slot holds a body"),
    "keypoints": ("(M, V, N, 17, 2) float32", "detections, unassociated, pixels, NaN = missed"),
    "scores": ("(M, V, N, 17) float32", "detector confidence, 0 = missed or outside"),
    "match": ("(M, V, N) int8", "the body a detection is of (by the projections), -1 = none"),
    "projected": ("(M, V, P, 17, 2) float32", "joints3d projected into each view, pixels"),
    "hidden": ("(M, V, P, 17) bool", "the joint's pixel shows another body (mutual occlusion)"),
    "K": ("(M, V, 3, 3) float64", "intrinsics, pixels"),
    "R": ("(M, V, 3, 3) float64", "world-to-camera rotation"),
    "t": ("(M, V, 3) float64", "world-to-camera translation, metres"),
    "size": ("(M, V, 2) int32", "image (width, height), pixels"),
    "phenotypes": ("(M, P, 6) float32", "anny phenotypes"),
    "subject": ("(M, P) str", "source subject id ('random' for random poses, '' = none)"),
    "clip": ("(M, P) str", "source clip"),
    "frame": ("(M, P) int64", "source frame (-1 for random poses or none)"),
    "mirrored": ("(M, P) bool", "the pose was mirrored left/right"),
}


@dataclass(frozen=True)
class GenerateConfig:
    """What ``rmpl generate`` makes; load with :meth:`from_toml`.

    Attributes:
        poses: a motion folder (CMU ASF/AMC, BVH; searched recursively), a pose bank
            ``.npz`` (:func:`rmpl.synth.retarget.save_pose_bank`), or ``"random"`` for
            :meth:`rmpl.synth.body.BodyModel.sample_poses`.
        subjects: keep only these motion subject ids (empty = all).
        exclude_subjects: drop these subject ids (e.g. ``["03"]``, held out).
        num_meshes: meshes (posed bodies), M.
        views: cameras per mesh, V (thesis: 20).
        camera_preset: ``h36m``, ``panoptic``, ``shelf`` or ``universal``.
        image_size: ``[width, height]`` for every view (the preset's camera is scaled to
            fit, centred), or empty for the preset's own sizes.
        detector: a key of :data:`rmpl.synth.detect.DETECTORS`, or ``"module:factory"``
            naming a callable that returns a :class:`rmpl.synth.detect.Detector`.
        detector_options: keyword arguments given to the detector's constructor (a TOML
            table, e.g. ``{ window_scales = [1.0, 0.5] }`` for ``blazepose-multi``),
            checked against its signature (:func:`check_detector_options`); empty = its
            defaults.
        seed: random seed; shard ``s`` uses ``(seed, s)``.
        shard_size: meshes per shard file.
        batch_size: meshes posed, rendered and detected together.
        mirror: probability of mirroring a pose left/right.
        perturb_deg: standard deviation of a random rotation of each driven bone, degrees.
        pose_fps: motion frames per second read before de-duplication.
        min_move: a motion frame is kept when some joint moved this far, metres, since the
            last kept frame of its clip (no near-duplicates).
        room: people stand uniformly within +-room metres of the room centre.
        min_age: phenotype age lower bound (0.5 is a teenager).
        occlusion_rate: probability that a black square covers a joint before detection
            (thesis 6.11.1); 0 = off.
        occlusion_size: side of the black squares, pixels.
        max_tries: implausible poses are replaced; give up after this many draws per mesh
            (per sequence with ``sequence_frames``).
        sequence_frames: frames per sequence, T; 0 or 1 = single meshes (see the module
            docstring). ``num_meshes`` and ``shard_size`` then count sequences.
        sequence_fps: ``[low, high]`` frames per second, drawn log-uniformly per sequence and
            rounded to a whole step of source frames (CMU: 120 / k).
        sequence_speed: ``[low, high]`` playback speed, uniform per sequence (1 = real time).
        people: ``[low, high]`` bodies per scene, uniform; ``[1, 1]`` = one body. With more,
            ``num_meshes`` and ``shard_size`` count scenes (see :data:`SCENE_ARRAYS`).
        joints: the joint set of every array, J: ``"coco17"`` (17), or ``"halpe26"`` (26:
            COCO-17, then head top, neck, mid-hip and the feet, defined on the mesh in
            :mod:`rmpl.synth.body`); a detector's joints are placed by name
            (BlazePose's heels and foot index, the latter in the big-toe slot).
    """

    poses: str = "random"
    subjects: tuple[str, ...] = ()
    exclude_subjects: tuple[str, ...] = ()
    num_meshes: int = 100
    views: int = 20
    camera_preset: str = "universal"
    image_size: tuple[int, ...] = ()
    detector: str = "mediapipe"
    seed: int = 0
    shard_size: int = 50
    batch_size: int = 8
    mirror: float = 0.5
    perturb_deg: float = 3.0
    pose_fps: float = 10.0
    min_move: float = 0.05
    room: float = 1.0
    min_age: float = 0.5
    occlusion_rate: float = 0.0
    occlusion_size: int = 50
    max_tries: int = 10
    sequence_frames: int = 0
    sequence_fps: tuple[float, ...] = (10.0, 60.0)
    sequence_speed: tuple[float, ...] = (1.0, 1.0)
    people: tuple[int, ...] = (1, 1)
    joints: str = "coco17"
    detector_options: dict = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict, path: str | Path | None = None) -> GenerateConfig:
        """Build and validate; errors name ``path`` and the field."""
        from rmpl.synth.cameras import CAMERA_PRESETS

        known = {f.name: f for f in fields(cls)}
        for key in d:
            if key not in known:
                raise InputError(path, key, f"one of the keys {sorted(known)}", "unknown key")
        d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        defaults = cls()
        for key, value in d.items():
            want = type(getattr(defaults, key))
            ok = isinstance(value, want) or (want is float and isinstance(value, int))
            if isinstance(value, bool) and want is not bool:
                ok = False
            if not ok:
                raise InputError(path, key, f"a {want.__name__}", repr(value))
            if want is float:
                d[key] = float(value)
        for key in ("sequence_fps", "sequence_speed"):
            if key in d and all(isinstance(v, int | float) for v in d[key]):
                d[key] = tuple(float(v) for v in d[key])
        cfg = cls(**d)
        checks = [
            ("num_meshes", cfg.num_meshes >= 1, ">= 1"),
            ("views", cfg.views >= 1, ">= 1"),
            ("shard_size", cfg.shard_size >= 1, ">= 1"),
            ("batch_size", cfg.batch_size >= 1, ">= 1"),
            (
                "camera_preset",
                cfg.camera_preset in CAMERA_PRESETS,
                f"one of {sorted(CAMERA_PRESETS)}",
            ),
            (
                "image_size",
                cfg.image_size == ()
                or (
                    len(cfg.image_size) == 2
                    and all(isinstance(v, int) and v >= 32 for v in cfg.image_size)
                ),
                "[] or [width, height] in pixels (>= 32)",
            ),
            ("mirror", 0 <= cfg.mirror <= 1, "a probability in [0, 1]"),
            ("occlusion_rate", 0 <= cfg.occlusion_rate <= 1, "a probability in [0, 1]"),
            ("occlusion_size", cfg.occlusion_size >= 1, ">= 1 pixel"),
            ("perturb_deg", cfg.perturb_deg >= 0, ">= 0"),
            ("min_age", 0 <= cfg.min_age <= 1, "in [0, 1]"),
            ("max_tries", cfg.max_tries >= 1, ">= 1"),
            ("poses", bool(cfg.poses), "a motion folder, a pose bank .npz or 'random'"),
            ("joints", cfg.joints in ("coco17", "halpe26"), "'coco17' or 'halpe26'"),
        ]
        checks += _sequence_checks(cfg) + _scene_checks(cfg)
        for name, ok, expected in checks:
            if not ok:
                raise InputError(path, name, expected, repr(getattr(cfg, name)))
        check_detector_options(cfg.detector, cfg.detector_options, path)
        return cfg

    @property
    def sequences(self) -> bool:
        """Whether this config makes sequences (``sequence_frames >= 2``)."""
        return self.sequence_frames >= 2

    @property
    def scenes(self) -> bool:
        """Whether this config makes multi-person scenes (``people[1] >= 2``)."""
        return len(self.people) == 2 and self.people[1] >= 2

    @classmethod
    def from_toml(cls, path: str | Path, overrides: list[str] | None = None) -> GenerateConfig:
        """Read a TOML file; ``overrides`` are ``key=value`` strings (TOML values)."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                d = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise InputError(path, None, "valid TOML", e) from None
        for item in overrides or []:
            if "=" not in item:
                raise InputError(path, "--set", "key=value", repr(item))
            key, value = item.split("=", 1)
            try:
                d[key.strip()] = tomllib.loads(f"v = {value}")["v"]
            except tomllib.TOMLDecodeError:
                d[key.strip()] = value  # a bare string, e.g. --set poses=/data/cmu
        return cls.from_dict(d, path)

    @property
    def num_shards(self) -> int:
        return -(-self.num_meshes // self.shard_size)


def _is_range(value: tuple) -> bool:
    """A ``(low, high)`` pair of positive numbers with low <= high."""
    return (
        len(value) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        and 0 < value[0] <= value[1] < float("inf")
    )


def _sequence_checks(cfg: GenerateConfig) -> list[tuple[str, bool, str]]:
    """(field, ok, expected) of the sequence options."""
    seq = cfg.sequences
    return [
        ("sequence_frames", cfg.sequence_frames >= 0, ">= 0 (0 or 1 = single meshes)"),
        ("sequence_fps", _is_range(cfg.sequence_fps), "[low, high] frames/s, 0 < low <= high"),
        ("sequence_speed", _is_range(cfg.sequence_speed), "[low, high] speeds, 0 < low <= high"),
        (
            "poses",
            not seq or cfg.poses != "random",
            "a motion folder or a motion.npz (sequences need real motion, not 'random')",
        ),
        (
            "occlusion_rate",
            not seq or cfg.occlusion_rate == 0,
            "0 with sequence_frames >= 2 (squares are drawn per image, not per sequence)",
        ),
    ]


def _scene_checks(cfg: GenerateConfig) -> list[tuple[str, bool, str]]:
    """(field, ok, expected) of the multi-person scene options."""
    p = cfg.people
    ok = len(p) == 2 and all(type(v) is int for v in p) and 1 <= p[0] <= p[1] <= 8
    return [
        ("people", ok, "[low, high] bodies per scene, 1 <= low <= high <= 8"),
        ("sequence_frames", not (ok and cfg.scenes and cfg.sequences),
         "0 or 1 with people above 1 (multi-person sequences are not made yet)"),
        ("occlusion_rate", not (ok and cfg.scenes) or cfg.occlusion_rate == 0,
         "0 with people above 1 (the bodies occlude each other)"),
        ("room", not (ok and cfg.scenes) or room_fits(p[1], cfg.room),
         f"a floor half-width that fits the scene's bodies {SCENE_GAP} m apart "
         f"(>= {SCENE_GAP * (np.ceil(np.sqrt(p[1] if ok else 1)) - 1):g} m)"),
    ]  # fmt: skip


def _config_dict(cfg: GenerateConfig) -> dict:
    """The config as the manifest stores it: a single-mesh config without the sequence and
    scene keys, so its manifest is the one written before they existed."""
    d = asdict(cfg)
    if not cfg.sequences:
        for key in _SEQUENCE_KEYS:
            d.pop(key)
    if not cfg.scenes:
        d.pop("people")
    if not cfg.detector_options:
        d.pop("detector_options")  # as manifests written before the option existed
    return d


def shard_arrays(cfg: GenerateConfig) -> dict[str, tuple[str, str]]:
    """The arrays of this config's shards: :data:`SEQUENCE_ARRAYS`, :data:`SCENE_ARRAYS` or
    :data:`SHARD_ARRAYS`."""
    return SEQUENCE_ARRAYS if cfg.sequences else SCENE_ARRAYS if cfg.scenes else SHARD_ARRAYS


def shard_path(out: str | Path, index: int) -> Path:
    return Path(out) / f"shard_{index:05d}.npz"


def list_shards(out: str | Path) -> list[Path]:
    """Finished shards of an output directory, sorted (temporary files are ignored)."""
    return sorted(p for p in Path(out).glob("shard_*.npz") if not p.name.startswith("."))


def _shard_ok(path: Path, meshes: int, arrays: dict = SHARD_ARRAYS) -> bool:
    """Whether ``path`` is a finished shard of ``meshes`` meshes (or sequences) with
    ``arrays``."""
    if not path.is_file():
        return False
    try:
        with np.load(path, allow_pickle=False) as z:
            return set(arrays) <= set(z.files) and len(z["joints3d"]) == meshes
    except (OSError, ValueError, EOFError):
        return False


def _shard_meshes(cfg: GenerateConfig, index: int) -> int:
    return min(cfg.shard_size, cfg.num_meshes - index * cfg.shard_size)


# ------------------------------------------------------------------------ per-process work


def make_detector(name: str, options: dict | None = None):
    """A detector from :data:`~rmpl.synth.detect.DETECTORS`, from ``rmpl run``'s
    :data:`~rmpl.pipeline.detect2d.DETECTORS` (e.g. ``blazepose-multi``), or a
    ``module:factory`` spec, built with the keyword arguments ``options``."""
    check_detector_options(name, options)
    return _detector_factory(name)(**(options or {}))


def _detector_factory(name: str):
    """The callable :func:`make_detector` calls for detector ``name``."""
    from rmpl.pipeline.detect2d import DETECTORS as RUN_DETECTORS
    from rmpl.synth.detect import DETECTORS

    if name in DETECTORS:
        return DETECTORS[name]
    if name in RUN_DETECTORS:
        return RUN_DETECTORS[name]
    if ":" in name:
        import importlib

        module, attr = name.split(":", 1)
        return getattr(importlib.import_module(module), attr)
    known = sorted(set(DETECTORS) | set(RUN_DETECTORS))
    raise ValueError(f"unknown detector {name!r}; known: {known} or 'module:factory'")


#: ``rmpl run``'s detectors whose factories only pass keyword arguments on: the class
#: whose constructor ``detector_options`` are checked against.
_OPTION_CLASSES = {
    "blazepose-multi": ("rmpl.synth.detect_multi", "BlazePoseMulti"),
    "blazepose-multi-static": ("rmpl.synth.detect_multi", "BlazePoseMulti"),
    "movenet": ("rmpl.synth.detect_movenet", "MoveNet"),
    "movenet-blazepose": ("rmpl.synth.detect_movenet", "MoveNetBlazePose"),
    "movenet-blazepose-static": ("rmpl.synth.detect_movenet", "MoveNetBlazePose"),
}


def check_detector_options(name: str, options: dict | None, path=None) -> None:
    """Check ``detector_options`` against detector ``name``'s constructor (by name only,
    nothing is built; its values are checked when it is built).

    Raises:
        InputError: an option the constructor does not take (field ``detector_options``);
            a constructor that takes any ``**kwargs`` accepts every name.
    """
    if not options:
        return
    import functools
    import importlib
    import inspect

    if name in _OPTION_CLASSES:
        module, attr = _OPTION_CLASSES[name]
        target = getattr(importlib.import_module(module), attr)
    else:
        target = _detector_factory(name)
        if isinstance(target, functools.partial):
            target = target.func
    params = inspect.signature(target).parameters.values()
    if any(p.kind is p.VAR_KEYWORD for p in params):
        return
    takes = [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    unknown = sorted(set(options) - set(takes))
    if unknown:
        raise InputError(
            path,
            "detector_options",
            f"keyword arguments of detector {name!r}: some of {takes}",
            f"{unknown} (not taken)",
        )


def follows(detector) -> bool:
    """Whether ``detector`` follows people from image to image (it has ``reset``, like
    :class:`rmpl.synth.detect.MultiPersonDetector`; ``track=False`` turns that off)."""
    return callable(getattr(detector, "reset", None)) and getattr(detector, "track", True)


def detect_person(detector, images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The detector's most confident person in each image (one body per scene).

    A single-person detector's output is returned as it is; a detector with a people axis
    gives, per image, the slot with the largest summed score (others are phantoms or
    nobody).

    Returns:
        keypoints (B, 17, 2) pixels, NaN = missed; scores (B, 17).
    """
    from rmpl.synth.detect import max_people, with_people_axis

    kp, sc = detector(images)
    if max_people(detector) == 1:
        return np.asarray(kp), np.asarray(sc)
    kp, sc = with_people_axis(detector, kp, sc, len(images))  # (B, N, J, 2), (B, N, J)
    best = sc.sum(-1).argmax(-1)  # (B,)
    rows = np.arange(len(images))
    return kp[rows, best], sc[rows, best]


def in_joint_set(detector, kp: np.ndarray, sc: np.ndarray, joints: str):
    """A detector's keypoints (..., J_det, 2) and scores (..., J_det) in joint set
    ``joints`` (:func:`rmpl.skeleton.to_joint_set`)."""
    from rmpl.skeleton import to_joint_set

    return to_joint_set(kp, sc, detector.skeleton, joints)


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


def _scale_cameras(K: np.ndarray, size: np.ndarray, target: tuple[int, int]):
    """Fit each camera's image into ``target`` (w, h): scale, then centre. Pixel centres
    at integers: u' = s (u + 0.5) - 0.5 + offset."""
    w, h = target
    s = np.minimum(w / size[..., 0], h / size[..., 1])  # (*, V)
    K = K.copy()
    K[..., 0, 0] *= s
    K[..., 1, 1] *= s
    K[..., 0, 2] = s * (K[..., 0, 2] + 0.5) - 0.5 + (w - s * size[..., 0]) / 2
    K[..., 1, 2] = s * (K[..., 1, 2] + 0.5) - 0.5 + (h - s * size[..., 1]) / 2
    return K, np.broadcast_to(np.array([w, h]), size.shape).copy()


def occlude(
    images: list[np.ndarray],
    points: np.ndarray,
    rate: float,
    side: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Paste black squares over keypoints (thesis 6.11.1), in place.

    Args:
        images: n RGB images (H, W, 3) uint8, modified in place.
        points: the true keypoints per image, shape (n, J, 2), pixels.
        rate: probability per keypoint. side: square side, pixels.

    Returns:
        Which keypoints got a square, shape (n, J) bool.
    """
    hit = rng.random(points.shape[:2]) < rate
    half = side / 2
    for i, im in enumerate(images):
        h, w = im.shape[:2]
        for j in np.flatnonzero(hit[i]):
            u, v = points[i, j]
            if not (np.isfinite(u) and np.isfinite(v)):
                continue
            x0, y0 = int(round(u - half)), int(round(v - half))
            im[max(y0, 0) : max(min(y0 + side, h), 0), max(x0, 0) : max(min(x0 + side, w), 0)] = 0
    return hit


def _draw_poses(worker: Worker, n: int, first: int, rng: np.random.Generator):
    """n plausible posed bodies; returns (bodies, meta dict, rejected count)."""
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.retarget import implausible, mirror_pose, perturb_pose, retarget

    cfg, body, bank = worker.cfg, worker.body, worker.bank
    if bank is not None:
        order = np.random.default_rng([cfg.seed, 2**31 - 1]).permutation(len(bank))
        queue = list(order[(first + np.arange(n)) % len(bank)])
    verts, kps, meta, rejected, tries = [], [], [], 0, 0
    while len(verts) < n:
        b = min(cfg.batch_size, n - len(verts))
        tries += b
        if tries > n * cfg.max_tries:
            raise RuntimeError(
                f"{rejected} of {tries - b} poses were implausible; check 'poses' ({cfg.poses})"
            )
        phen = sample_phenotypes(b, rng, cfg.min_age)
        mirrored = rng.random(b) < cfg.mirror
        if bank is None:
            pose = body.sample_poses(b, rng)[..., :3, :3]
            idx = np.full(b, -1)
        else:
            idx = np.array([queue.pop(0) if queue else rng.integers(len(bank)) for _ in range(b)])
            pose = retarget(body, bank, idx, phen)
            pose = perturb_pose(pose, body.bone_names, rng, cfg.perturb_deg)
        pose = np.where(mirrored[:, None, None, None], mirror_pose(pose, body.bone_names), pose)
        bodies = body(pose, phen)
        bad = implausible(bodies.keypoints)
        rejected += int(bad.sum())
        for i in np.flatnonzero(~bad):
            verts.append(bodies.vertices[i])
            kps.append(bodies.keypoints[i])
            k = int(idx[i])
            meta.append(
                (
                    phen[i],
                    "random" if k < 0 else str(bank.subject[k]),
                    "" if k < 0 else str(bank.clip[k]),
                    -1 if k < 0 else int(bank.frame[k]),
                    bool(mirrored[i]),
                )
            )
    return np.stack(verts), np.stack(kps), meta, rejected


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
    rng = np.random.default_rng([cfg.seed, index])
    # The squares draw from their own stream: a set made with occlusion_rate > 0 has the
    # same meshes, cameras and images as the one made without (a paired experiment).
    occ_rng = np.random.default_rng([cfg.seed, index, 1])
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    parts: dict[str, list] = {k: [] for k in SHARD_ARRAYS}
    rejected = 0
    for start in range(0, n, cfg.batch_size):
        b = min(cfg.batch_size, n - start)
        t0 = time.perf_counter()
        posed = _pose_batch(worker, b, first + start, rng)
        t1 = time.perf_counter()
        images, occ = _render_batch(worker, posed, rng, occ_rng)
        t2 = time.perf_counter()
        kp2d, scores = _detect_apart(worker.detector, images)
        kp2d, scores = in_joint_set(worker.detector, kp2d, scores, cfg.joints)
        t3 = time.perf_counter()
        times["pose"] += t1 - t0
        times["render"] += t2 - t1
        times["detect"] += t3 - t2
        rejected += posed.rejected
        for key, array in _batch_arrays(posed, kp2d, scores, occ).items():
            parts[key].append(array)
    arrays = {k: np.concatenate(v) for k, v in parts.items()}
    stats = {
        "shard": index,
        "meshes": n,
        "views": n * cfg.views,
        "rejected": rejected,
        "missed_joints": int((arrays["scores"] == 0).sum()),
        "missed_views": int((arrays["scores"] == 0).all(-1).sum()),
        "seconds": times,
    }
    _write_shard(shard_path(out, index), arrays, stats)
    return stats


def _detect_apart(detector, images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Detect images of unrelated scenes: a detector that follows people starts afresh on
    each image."""
    if not follows(detector):
        return detect_person(detector, images)
    parts = []
    for im in images:
        detector.reset()
        parts.append(detect_person(detector, [im]))
    return np.concatenate([k for k, _ in parts]), np.concatenate([s for _, s in parts])


def _write_shard(path: Path, arrays: dict[str, np.ndarray], stats: dict) -> None:
    """One compressed NPZ, written atomically (a killed run leaves no partial shard)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays, stats=np.array(json.dumps(stats)))


@dataclass
class _Posed:
    """One batch of b posed bodies placed in the room, with their V cameras."""

    vertices: np.ndarray  # (b, N, 3) world metres
    joints: np.ndarray  # (b, 17, 3) COCO-17, world metres
    meta: list[tuple]  # per body: phenotypes, subject, clip, frame, mirrored
    rejected: int  # implausible poses drawn and replaced
    K: np.ndarray  # (b, V, 3, 3) pixels
    R: np.ndarray  # (b, V, 3, 3)
    t: np.ndarray  # (b, V, 3) metres
    size: np.ndarray  # (b, V, 2) pixels
    projected: np.ndarray  # (b, V, 17, 2) joints projected, pixels
    colors: np.ndarray  # (b, N, 3) vertex RGB of the outfits


def _pose_batch(worker: Worker, b: int, first: int, rng: np.random.Generator) -> _Posed:
    """b plausible bodies (mesh ``first`` onwards) placed in the room, seen by random cameras."""
    from rmpl.geometry.camera import project
    from rmpl.synth.body import place_bodies
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.render import random_outfits

    cfg = worker.cfg
    verts, kps, meta, rejected = _draw_poses(worker, b, first, rng)
    yaw = rng.uniform(-np.pi, np.pi, b)
    where = rng.uniform(-cfg.room, cfg.room, (b, 2))
    verts, kps = place_bodies(verts, kps, yaw, where)
    center = kps[:, 11:13].mean(axis=1).astype(float)
    K, R, t, size = sample_cameras(cfg.views, center, cfg.camera_preset, rng)
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[:, None].astype(float), K[:, :, None], R[:, :, None], t[:, :, None])
    colors = random_outfits(worker.body.vertex_parts, b, rng)
    return _Posed(verts, kps, meta, rejected, K, R, t, size, proj, colors)


def _render_batch(worker: Worker, posed: _Posed, rng, occ_rng) -> tuple[list, np.ndarray]:
    """The b * V images (body-major), and the joints under a pasted square (b * V, 17)."""
    cfg = worker.cfg
    p, bv, J = posed, len(posed.joints) * cfg.views, posed.joints.shape[1]
    images = worker.renderer.render(p.vertices, p.colors, p.K, p.R, p.t, p.size, rng=rng)
    occ = np.zeros((bv, J), bool)
    if cfg.occlusion_rate > 0:
        occ = occlude(
            images, p.projected.reshape(bv, J, 2), cfg.occlusion_rate, cfg.occlusion_size, occ_rng
        )
    return images, occ


def _batch_arrays(posed: _Posed, kp2d, scores, occ: np.ndarray) -> dict[str, np.ndarray]:
    """One batch's part of every :data:`SHARD_ARRAYS` array, in their dtypes."""
    b, V = posed.K.shape[:2]
    J = posed.joints.shape[1]
    phen, subject, clip, frame, mirrored = zip(*posed.meta, strict=True)
    return {
        "joints3d": posed.joints.astype(np.float32),
        "keypoints": np.asarray(kp2d, np.float32).reshape(b, V, J, 2),
        "scores": np.asarray(scores, np.float32).reshape(b, V, J),
        "projected": posed.projected.astype(np.float32),
        "K": posed.K,
        "R": posed.R,
        "t": posed.t,
        "size": posed.size.astype(np.int32),
        "occluded": occ.reshape(b, V, J),
        "phenotypes": np.asarray(phen, np.float32),
        "subject": np.asarray(subject, str),
        "clip": np.asarray(clip, str),
        "frame": np.asarray(frame, np.int64),
        "mirrored": np.asarray(mirrored, bool),
    }


# ------------------------------------------------------------------------------ sequences


@dataclass(frozen=True, eq=False)
class MotionBank:
    """Continuous mocap segments ready to retarget onto anny, at their source frame rate.

    Attributes:
        rotations: driver rotations of every frame, segments back to back, shape
            (N, K, 3, 3) float32 (see :func:`rmpl.synth.retarget.mocap_drivers`).
        joints: the mocap's own COCO-17 joints, metres, z up, shape (N, 17, 3) float32 (for
            the root's path and the leg length).
        start, length: first row and frames of each segment, shape (G,) int64.
        first: each segment's first frame in its clip, shape (G,) int64.
        clip_index: each segment's clip, shape (G,) int64, into the per-clip arrays:
        clips, subjects: clip path and subject id, shape (C,) str.
        fps: source frames per second, shape (C,) float64.
        rest_dirs: driver rest directions, shape (C, K, 3) float32.
    """

    rotations: np.ndarray
    joints: np.ndarray
    start: np.ndarray
    length: np.ndarray
    first: np.ndarray
    clip_index: np.ndarray
    clips: np.ndarray
    subjects: np.ndarray
    fps: np.ndarray
    rest_dirs: np.ndarray

    def __len__(self) -> int:
        return len(self.start)

    def seconds_per_subject(self) -> dict[str, float]:
        """Seconds of motion per subject."""
        secs = (self.length - 1) / self.fps[self.clip_index]
        subj = self.subjects[self.clip_index]
        return {str(s): round(float(secs[subj == s].sum()), 2) for s in np.unique(subj)}

    def select(self, keep: np.ndarray) -> MotionBank:
        """The segments where ``keep`` (bool, shape (G,)) is True."""
        length = self.length[keep]
        rows = [np.arange(a, a + n) for a, n in zip(self.start[keep], length, strict=True)]
        rows = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        return MotionBank(
            self.rotations[rows],
            self.joints[rows],
            (np.cumsum(length) - length).astype(np.int64),
            length,
            self.first[keep],
            self.clip_index[keep],
            self.clips,
            self.subjects,
            self.fps,
            self.rest_dirs,
        )


def _segments(keep: np.ndarray, joints: np.ndarray, fps: float) -> list[tuple[int, int]]:
    """(first, stop) frame ranges of the clean stretches of a clip: ``keep`` frames (T,)
    cut wherever a joint moves faster than :data:`rmpl.data.sequences.MAX_JOINT_SPEED`
    between two frames (capture glitches). joints: (T, 17, 3) metres."""
    from rmpl.data.sequences import MAX_JOINT_SPEED

    speed = np.linalg.norm(np.diff(joints, axis=0), axis=-1).max(-1) * fps  # (T - 1,)
    edges = np.flatnonzero(np.diff(np.r_[0, keep.astype(np.int8), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        cuts = a + 1 + np.flatnonzero(speed[a : b - 1] > MAX_JOINT_SPEED)
        bounds = np.r_[a, cuts, b]
        pieces = zip(bounds[:-1], bounds[1:], strict=True)
        out += [(int(x), int(y)) for x, y in pieces if y - x >= 2]
    return out


def build_motion_bank(
    root: str | Path, subjects: list[str] | None = None, exclude_subjects: tuple[str, ...] = ()
) -> MotionBank:
    """Every clean stretch of motion under ``root`` (ASF/AMC, BVH) at its own frame rate.

    Args:
        root: folder of motion files. subjects: keep only these subject ids (None = all).
        exclude_subjects: drop these subject ids.

    Raises:
        InputError: no clip of the selected subjects, or none with clean motion.
    """
    from rmpl.synth.motion import BROKEN_CLIPS, find_clips, to_coco17, usable_frames
    from rmpl.synth.motion.bank import _load_clip, _matches
    from rmpl.synth.retarget import mocap_drivers

    clips = [
        c
        for c in find_clips(root, subjects)
        if c.subject not in set(exclude_subjects) and not _matches(c.clip, BROKEN_CLIPS)
    ]
    if not clips:
        raise InputError(root, "poses", "motion clips of the selected subjects", "none")
    rot, joints, first, clip_index, names, subj, fps, dirs = [], [], [], [], [], [], [], []
    skeletons: dict = {}
    for c in clips:
        motion = _load_clip(c, skeletons)
        coco = to_coco17(motion)
        segs = _segments(usable_frames(motion), coco, motion.fps)
        if not segs:
            continue
        r, d = mocap_drivers(motion)
        for a, b in segs:
            rot.append(r[a:b].astype(np.float32))
            joints.append(coco[a:b].astype(np.float32))
            first.append(a)
            clip_index.append(len(names))
        names.append(c.clip)
        subj.append(c.subject)
        fps.append(float(motion.fps))
        dirs.append(d.astype(np.float32))
    if not rot:
        raise InputError(root, "poses", "clips with clean motion", "none")
    length = np.array([len(r) for r in rot], np.int64)
    bank = MotionBank(
        np.concatenate(rot),
        np.concatenate(joints),
        (np.cumsum(length) - length).astype(np.int64),
        length,
        np.array(first, np.int64),
        np.array(clip_index, np.int64),
        np.array(names, str),
        np.array(subj, str),
        np.array(fps, np.float64),
        np.stack(dirs),
    )
    log.info("motion bank %s: %d segments, %d frames from %d clips", root, len(bank),
             length.sum(), len(names))  # fmt: skip
    return bank


_MOTION_KEYS = tuple(f.name for f in fields(MotionBank))


def save_motion_bank(path: str | Path, bank: MotionBank) -> Path:
    """Write a :class:`MotionBank` to ``.npz`` atomically."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, format=np.array(_MOTION_FORMAT), **{k: getattr(bank, k) for k in _MOTION_KEYS})
    return path


def load_motion_bank(path: str | Path) -> MotionBank:
    """Read a bank written by :func:`save_motion_bank` (a sequence run's ``motion.npz``)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            if "format" not in z.files or str(z["format"]) != _MOTION_FORMAT:
                got = str(z["format"]) if "format" in z.files else "none"
                raise InputError(path, "format", f"{_MOTION_FORMAT!r} (a motion.npz)", got)
            missing = [k for k in _MOTION_KEYS if k not in z.files]
            if missing:
                raise InputError(path, missing[0], "an array of a motion bank", "missing")
            return MotionBank(**{k: z[k] for k in _MOTION_KEYS})
    except (OSError, ValueError, EOFError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(path, None, "a motion bank .npz (motion.npz)", e) from None


@dataclass
class _Sequence:
    """One sequence: a body moving through T frames, seen by one rig of V cameras."""

    vertices: np.ndarray  # (T, N, 3) world metres
    joints: np.ndarray  # (T, 17, 3) COCO-17, world metres
    phenotypes: np.ndarray  # (6,)
    subject: str
    clip: str
    frames: np.ndarray  # (T,) source frames in the clip
    mirrored: bool
    fps: float  # frames per second
    speed: float  # motion seconds per second
    rejected: int  # implausible sequences drawn and replaced
    K: np.ndarray  # (V, 3, 3) pixels
    R: np.ndarray  # (V, 3, 3)
    t: np.ndarray  # (V, 3) metres
    size: np.ndarray  # (V, 2) pixels
    projected: np.ndarray  # (T, V, 17, 2) pixels


def draw_window(
    bank: MotionBank, frames: int, fps_range, speed_range, rng: np.random.Generator
) -> tuple[int, np.ndarray, float, float]:
    """A window of ``frames`` frames of one segment, its source frames every k-th.

    The segment is drawn in proportion to its length among those with at least ``frames``
    frames; a frame rate log-uniformly in ``fps_range`` and a speed uniformly in
    ``speed_range``; ``k = round(speed * source fps / fps)`` (at least 1, at most what the
    segment holds), so the realised rate is ``source fps * speed / k``.

    Returns:
        (segment, rows of ``bank.rotations`` (frames,), realised fps, speed).
    """
    usable = bank.length >= frames
    p = np.where(usable, bank.length, 0).astype(float)
    seg = int(rng.choice(len(bank), p=p / p.sum()))
    fps = float(np.exp(rng.uniform(*np.log(fps_range))))
    speed = float(rng.uniform(*speed_range))
    source = float(bank.fps[bank.clip_index[seg]])
    n = int(bank.length[seg])
    most = (n - 1) // max(frames - 1, 1)
    k = int(np.clip(round(speed * source / fps), 1, max(most, 1)))
    begin = int(rng.integers(0, n - (frames - 1) * k))
    rows = bank.start[seg] + begin + k * np.arange(frames)
    return seg, rows, source * speed / k, speed


def _sequence_pose(worker: Worker, seg: int, rows: np.ndarray, phen: np.ndarray, mirrored, rng):
    """anny deltas (T, P, 3, 3) of the window ``rows`` on one body: one perturbation of the
    driven bones for the whole sequence, mirrored or not as a whole."""
    from rmpl.synth.retarget import (
        anny_deltas,
        bone_parents,
        mirror_pose,
        perturb_pose,
        reference_heads,
    )

    body, bank, T = worker.body, worker.motion, len(rows)
    ref = reference_heads(body, phen[None])  # (1, P, 3)
    dirs = bank.rest_dirs[bank.clip_index[seg]].astype(float)
    pose = anny_deltas(
        bank.rotations[rows].astype(float),
        dirs,
        np.repeat(ref, T, axis=0),
        body.bone_names,
        bone_parents(body),
    )
    # perturb_pose on the identity gives the rotations it would apply; use them every frame.
    turn = perturb_pose(body.identity_pose(1)[..., :3, :3], body.bone_names, rng,
                        worker.cfg.perturb_deg)[0]  # fmt: skip
    pose = turn @ pose
    return mirror_pose(pose, body.bone_names) if mirrored else pose


def _leg_length(joints: np.ndarray) -> float:
    """Mean hip-knee-ankle length of both legs over the frames, metres. joints: (T, 17, 3)."""
    legs = [(11, 13, 15), (12, 14, 16)]
    bones = [np.linalg.norm(joints[:, a] - joints[:, b], axis=-1) for h, k, f in legs
             for a, b in ((h, k), (k, f))]  # fmt: skip
    return float(np.mean(bones) * 2)


def follow_root(
    vertices: np.ndarray, joints: np.ndarray, mocap: np.ndarray, yaw: float, where: np.ndarray
):
    """Move the posed body along the mocap's path, stand it on the floor, turn and place it.

    The body's mid-hip follows the mocap's mid-hip path, scaled by the ratio of the two leg
    lengths (a shorter body takes shorter steps), centred horizontally on the sequence's
    mean; the lowest vertex of the whole sequence lands on the floor (z = 0, so jumps and
    steps up stay in the air); then the sequence turns by ``yaw`` about +z and moves by
    ``where``.

    Args:
        vertices: (T, N, 3) and joints (T, 17, 3) of the posed body, anny's frame, metres.
        mocap: the mocap's COCO-17 joints of the same frames (T, 17, 3), metres, z up.
        yaw: radians. where: (2,) metres, where the path's centre lands on the floor.

    Returns:
        vertices (T, N, 3) and joints (T, 17, 3), world metres.
    """
    scale = _leg_length(joints) / max(_leg_length(mocap), 1e-6)
    path = mocap[:, 11:13].mean(axis=1)  # (T, 3) mocap mid-hip
    path = scale * (path - np.r_[path[:, :2].mean(axis=0), 0.0])
    shift = path - joints[:, 11:13].mean(axis=1)  # (T, 3)
    vertices, joints = vertices + shift[:, None], joints + shift[:, None]
    floor = vertices[..., 2].min()
    c, s = np.cos(yaw), np.sin(yaw)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    move = np.r_[where, -floor]
    return (
        (vertices @ Rz.T + move).astype(np.float32),
        (joints @ Rz.T + move).astype(np.float32),
    )


def _draw_sequence(worker: Worker, rng: np.random.Generator) -> _Sequence:
    """One plausible sequence placed in the room, seen by one random rig."""
    from rmpl.geometry.camera import project
    from rmpl.synth.body import sample_phenotypes
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.retarget import implausible

    cfg, bank, T = worker.cfg, worker.motion, worker.cfg.sequence_frames
    rejected = 0
    for _ in range(cfg.max_tries):
        seg, rows, fps, speed = draw_window(bank, T, cfg.sequence_fps, cfg.sequence_speed, rng)
        phen = sample_phenotypes(1, rng, cfg.min_age)[0]
        mirrored = bool(rng.random() < cfg.mirror)
        pose = _sequence_pose(worker, seg, rows, phen, mirrored, rng)
        bodies = worker.body(pose, np.repeat(phen[None], T, axis=0))
        if not implausible(bodies.keypoints).any():
            break
        rejected += 1
    else:
        raise RuntimeError(
            f"{cfg.max_tries} sequences in a row had an implausible frame; check 'poses' "
            f"({cfg.poses}) or raise max_tries"
        )
    mocap = bank.joints[rows].astype(float)
    if mirrored:
        mocap = mocap * np.array([-1.0, 1.0, 1.0])
    yaw, where = rng.uniform(-np.pi, np.pi), rng.uniform(-cfg.room, cfg.room, 2)
    verts, kps = follow_root(bodies.vertices, bodies.keypoints, mocap, yaw, where)
    center = kps[:, 11:13].mean(axis=1).mean(axis=0).astype(float)  # (3,)
    K, R, t, size = (a[0] for a in sample_cameras(cfg.views, center[None], cfg.camera_preset, rng))
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[:, None].astype(float), K[None, :, None], R[None, :, None], t[None, :, None])
    ci = int(bank.clip_index[seg])
    return _Sequence(
        verts, kps, phen, str(bank.subjects[ci]), str(bank.clips[ci]),
        bank.first[seg] + rows - bank.start[seg], mirrored, fps, speed, rejected,
        K, R, t, size, proj,
    )  # fmt: skip


def _render_detect(worker: Worker, seq: _Sequence, rng: np.random.Generator, times: dict):
    """Render every frame from every camera and detect: keypoints (T, V, 17, 2) pixels,
    scores (T, V, 17). One outfit and lighting for the sequence; each camera keeps its
    background.

    A detector that detects every image afresh (MediaPipe's legacy ``Pose``, as
    ``rmpl run --videos`` runs it by default) gets the V views of one frame at a time. A
    detector that follows people from frame to frame (:func:`follows`) gets each view as a
    video: reset, then that view's frames in order; each camera's background then comes from
    its own seed. Either way at most V images are held at once.
    """
    from rmpl.synth.render import random_lighting, random_outfits

    colors = random_outfits(worker.body.vertex_parts, 1, rng)
    light = random_lighting(rng)
    backdrop = int(rng.integers(0, 2**63 - 1))
    T, V, J = len(seq.vertices), len(seq.K), seq.joints.shape[1]
    kps, scores = np.full((T, V, J, 2), np.nan, np.float32), np.zeros((T, V, J), np.float32)

    def run(frame: int, views: slice, seed: int) -> None:
        t0 = time.perf_counter()
        images = worker.renderer.render(
            seq.vertices[frame : frame + 1],
            colors,
            seq.K[None, views],
            seq.R[None, views],
            seq.t[None, views],
            seq.size[None, views],
            lighting=[light],
            rng=seed,
        )
        t1 = time.perf_counter()
        kp, sc = detect_person(worker.detector, images)
        kp, sc = in_joint_set(worker.detector, kp, sc, worker.cfg.joints)
        times["render"] += t1 - t0
        times["detect"] += time.perf_counter() - t1
        kps[frame, views] = np.asarray(kp, np.float32).reshape(len(images), J, 2)
        scores[frame, views] = np.asarray(sc, np.float32).reshape(len(images), J)

    if not follows(worker.detector):
        for f in range(T):  # the same seed every frame: the same backgrounds
            run(f, slice(None), backdrop)
        return kps, scores
    seeds = np.random.default_rng(backdrop).integers(0, 2**63 - 1, V)
    for v in range(V):
        worker.detector.reset()
        for f in range(T):
            run(f, slice(v, v + 1), int(seeds[v]))
    return kps, scores


def _sequence_shard(worker: Worker, index: int, first: int, n: int, out: str | Path) -> dict:
    """Sequences ``first .. first + n - 1`` as shard ``index`` (see :func:`generate_shard`)."""
    cfg = worker.cfg
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    parts: dict[str, list] = {k: [] for k in SEQUENCE_ARRAYS}
    rejected = 0
    for i in range(first, first + n):
        rng = np.random.default_rng([cfg.seed, i, 2])  # a sequence is the same in any shard
        t0 = time.perf_counter()
        seq = _draw_sequence(worker, rng)
        times["pose"] += time.perf_counter() - t0
        kp, sc = _render_detect(worker, seq, rng, times)
        rejected += seq.rejected
        T = len(seq.joints)
        row = {
            "joints3d": seq.joints.astype(np.float32),
            "keypoints": kp,
            "scores": sc,
            "projected": seq.projected.astype(np.float32),
            "times": np.arange(T) / seq.fps,
            "fps": np.float64(seq.fps),
            "speed": np.float64(seq.speed),
            "K": seq.K,
            "R": seq.R,
            "t": seq.t,
            "size": seq.size.astype(np.int32),
            "phenotypes": seq.phenotypes.astype(np.float32),
            "subject": np.asarray(seq.subject, str),
            "clip": np.asarray(seq.clip, str),
            "frame": seq.frames.astype(np.int64),
            "mirrored": np.bool_(seq.mirrored),
        }
        for key, value in row.items():
            parts[key].append(value)
    arrays = {k: np.stack(v) for k, v in parts.items()}
    T, V = cfg.sequence_frames, cfg.views
    stats = {
        "shard": index,
        "sequences": n,
        "meshes": n * T,
        "views": n * T * V,
        "rejected": rejected,
        "missed_joints": int((arrays["scores"] == 0).sum()),
        "missed_views": int((arrays["scores"] == 0).all(-1).sum()),
        "seconds": times,
    }
    _write_shard(shard_path(out, index), arrays, stats)
    return stats


# ---------------------------------------------------------------------------- scenes


#: Least distance between two bodies of a scene, metres.
SCENE_GAP = 0.6


def room_fits(n: int, room: float, gap: float = SCENE_GAP) -> bool:
    """Whether +-``room`` metres leaves ``n`` random positions ``gap`` apart easily: a square
    grid of them at twice the gap fits (random draws then succeed within a few tries).

    >>> room_fits(4, 1.0), room_fits(8, 0.5)
    (True, False)
    """
    side = int(np.ceil(np.sqrt(n)))
    return 2 * room >= 2 * gap * (side - 1)


def spread(n: int, room: float, rng: np.random.Generator, gap: float = SCENE_GAP) -> np.ndarray:
    """n floor positions uniform within +-``room`` metres, at least ``gap`` metres apart
    (redrawn up to 100 times; then the last draw is kept, with a warning). Returns (n, 2)
    metres."""
    for _ in range(100):
        where = rng.uniform(-room, room, (n, 2))
        d = np.linalg.norm(where[:, None] - where[None], axis=-1) + np.eye(n) * 1e9
        if d.min() >= gap:
            return where
    log.warning("%d bodies %g m apart did not fit in +-%g m: two may overlap", n, gap, room)
    return where


def match_detections(
    keypoints: np.ndarray, scores: np.ndarray, projected: np.ndarray, present: np.ndarray
) -> np.ndarray:
    """Which body each detection slot of one image is of, by the projected joints.

    The cost of (slot, body) is the median pixel distance over the slot's detected joints,
    divided by the body's projected size (the larger side of its joints' box); slots and
    bodies are paired by the Hungarian method, and a pair counts when its cost is below
    :data:`MATCH_TOLERANCE`.

    Args:
        keypoints: (N, J, 2) pixels; scores: (N, J), 0 = missing.
        projected: (P, J, 2) pixels; present: (P,) bool.

    Returns:
        (N,) int8: the body index, -1 for none.
    """
    import warnings

    from scipy.optimize import linear_sum_assignment

    size = np.ptp(projected, axis=1).max(-1).clip(1.0, None)  # (P,)
    dist = np.linalg.norm(keypoints[:, None] - projected[None], axis=-1)  # (N, P, J)
    dist = np.where((scores > 0)[:, None], dist, np.nan)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # empty slots, absent bodies
        cost = np.nanmedian(dist, axis=-1) / size  # (N, P)
    cost = np.where(present[None] & np.isfinite(cost), cost, 1e6)
    out = np.full(len(keypoints), -1, np.int8)
    for n, p in zip(*linear_sum_assignment(cost), strict=True):
        if cost[n, p] < MATCH_TOLERANCE:
            out[n] = p
    return out


def _hidden(ids: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Joints (P, J) whose pixel shows another body. ids: (H, W) body per pixel, -1 none;
    uv: (P, J, 2) pixels."""
    h, w = ids.shape
    x, y = np.rint(np.nan_to_num(uv, nan=-1.0)).astype(int).transpose(2, 0, 1)  # (P, J) each
    inside = (x >= 0) & (x < w) & (y >= 0) & (y < h)
    shown = ids[y.clip(0, h - 1), x.clip(0, w - 1)]  # (P, J)
    own = np.arange(len(uv))[:, None]
    return inside & (shown >= 0) & (shown != own)


def _scene(worker: Worker, index: int, rng: np.random.Generator, times: dict) -> tuple[dict, int]:
    """Scene ``index``: its row of every :data:`SCENE_ARRAYS` array, and the implausible
    poses replaced."""
    from rmpl.geometry.camera import project
    from rmpl.synth.body import place_bodies
    from rmpl.synth.cameras import sample_cameras
    from rmpl.synth.render import random_outfits

    cfg, V = worker.cfg, worker.cfg.views
    P = cfg.people[1]
    t0 = time.perf_counter()
    k = int(rng.integers(cfg.people[0], P + 1))
    verts, kps, meta, rejected = _draw_poses(worker, k, index * P, rng)
    verts, kps = place_bodies(verts, kps, rng.uniform(-np.pi, np.pi, k), spread(k, cfg.room, rng))
    center = kps[:, 11:13].mean(axis=(0, 1)).astype(float)  # the group's mean mid-hip
    K, R, t, size = (a[0] for a in sample_cameras(V, center[None], cfg.camera_preset, rng))
    if cfg.image_size:
        K, size = _scale_cameras(K, size, tuple(cfg.image_size))
    proj = project(kps[None].astype(float), K[:, None, None], R[:, None, None], t[:, None, None])
    colors = random_outfits(worker.body.vertex_parts, k, rng)
    t1 = time.perf_counter()
    images, ids = worker.renderer.render_scene(
        verts[None], colors[None], K[None], R[None], t[None], size[None], rng=rng
    )
    t2 = time.perf_counter()
    kp, sc = _detect_people_apart(worker.detector, images)  # (V, N, J, 2), (V, N, J)
    kp, sc = in_joint_set(worker.detector, kp, sc, cfg.joints)
    times["pose"] += t1 - t0
    times["render"] += t2 - t1
    times["detect"] += time.perf_counter() - t2

    def pad(a: np.ndarray, fill) -> np.ndarray:  # k bodies -> P slots
        return np.concatenate([a, np.full((P - k, *a.shape[1:]), fill, a.dtype)])

    present = np.arange(P) < k
    proj_p = np.stack([pad(proj[v], np.nan) for v in range(V)])  # (V, P, J, 2)
    phen, subject, clip, frame, mirrored = (np.asarray(x) for x in zip(*meta, strict=True))
    row = {
        "joints3d": pad(kps.astype(np.float32), np.nan),
        "present": present,
        "keypoints": kp.astype(np.float32),
        "scores": sc.astype(np.float32),
        "match": np.stack([match_detections(kp[v], sc[v], proj_p[v], present) for v in range(V)]),
        "projected": proj_p.astype(np.float32),
        "hidden": np.stack([_hidden(ids[v], proj_p[v]) for v in range(V)]),
        "K": K,
        "R": R,
        "t": t,
        "size": size.astype(np.int32),
        "phenotypes": pad(phen.astype(np.float32), 0.0),
        "subject": pad(subject.astype(str), ""),
        "clip": pad(clip.astype(str), ""),
        "frame": pad(frame.astype(np.int64), -1),
        "mirrored": pad(mirrored.astype(bool), False),
    }
    return row, rejected


def _detect_people_apart(detector, images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Every person the detector finds in images of unrelated scenes: keypoints (B, N, J, 2)
    and scores (B, N, J), N = its ``max_people`` (1 for a single-person detector)."""
    from rmpl.synth.detect import with_people_axis

    if not follows(detector):
        return with_people_axis(detector, *detector(images), len(images))
    parts = []
    for im in images:
        detector.reset()
        parts.append(with_people_axis(detector, *detector([im]), 1))
    return np.concatenate([k for k, _ in parts]), np.concatenate([s for _, s in parts])


def _scene_shard(worker: Worker, index: int, first: int, n: int, out: str | Path) -> dict:
    """Scenes ``first .. first + n - 1`` as shard ``index`` (see :func:`generate_shard`)."""
    cfg = worker.cfg
    times = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    parts: dict[str, list] = {k: [] for k in SCENE_ARRAYS}
    rejected = 0
    for i in range(first, first + n):
        rng = np.random.default_rng([cfg.seed, i, 3])  # a scene is the same in any shard
        row, bad = _scene(worker, i, rng, times)
        rejected += bad
        for key, value in row.items():
            parts[key].append(value)
    arrays = {k: np.stack(v) for k, v in parts.items()}
    found = arrays["scores"].max(-1) > 0  # (M, V, N)
    stats = {
        "shard": index,
        "scenes": n,
        "meshes": int(arrays["present"].sum()),
        "views": n * cfg.views,
        "rejected": rejected,
        "missed_joints": int((arrays["scores"] == 0).sum()),
        "missed_views": int((~found.any(-1)).sum()),
        "people_found": int(found.sum()),
        "people_matched": int((arrays["match"] >= 0).sum()),
        "seconds": times,
    }
    _write_shard(shard_path(out, index), arrays, stats)
    return stats


# --------------------------------------------------------------------------- the driver

_WORKER: Worker | None = None


def _init_pool(cfg_dict: dict, bank: str | None, cache_dir: str | None) -> None:
    global _WORKER
    os.environ.setdefault("LP_NUM_THREADS", "1")  # llvmpipe: one thread per worker
    import torch

    torch.set_num_threads(1)
    _WORKER = Worker(GenerateConfig(**cfg_dict), bank, cache_dir)


def _pool_shard(args: tuple[int, str]) -> dict:
    return generate_shard(_WORKER, args[0], args[1])


def _ray_shard(cfg_dict: dict, bank: str | None, cache_dir: str | None, index: int, out: str):
    """Ray task body: a worker state per Ray worker process, reused across its tasks."""
    global _WORKER
    if _WORKER is None or asdict(_WORKER.cfg) != cfg_dict:
        _init_pool(cfg_dict, bank, cache_dir)
    return generate_shard(_WORKER, index, out)


def _versions() -> dict[str, str]:
    from importlib import metadata

    out = {}
    for pkg in ("rmpl", "anny", "moderngl", "mediapipe", "numpy", "torch"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    return out


def _prepare_bank(cfg: GenerateConfig, out: Path) -> Path | None:
    """The pose bank file the workers read (built from a motion folder once)."""
    from rmpl.synth.retarget import PoseBank, build_pose_bank, load_pose_bank, save_pose_bank

    if cfg.poses == "random":
        return None
    if cfg.sequences:
        return _prepare_motion(cfg, out)
    src = Path(cfg.poses)
    target = out / "poses.npz"
    if target.is_file():
        return target
    if src.is_dir():
        bank = build_pose_bank(
            src,
            list(cfg.subjects) or None,
            cfg.exclude_subjects,
            fps=cfg.pose_fps,
            min_move=cfg.min_move,
        )
    elif src.is_file():
        bank = load_pose_bank(src)
        keep = np.ones(len(bank), bool)
        if cfg.subjects:
            keep &= np.isin(bank.subject, list(cfg.subjects))
        keep &= ~np.isin(bank.subject, list(cfg.exclude_subjects))
        bank = PoseBank(*(a[keep] for a in _bank_arrays(bank)))
        if not len(bank):
            raise InputError(src, "subjects", "poses of the selected subjects", "none")
    else:
        raise InputError(None, "poses", "a motion folder, a pose bank .npz or 'random'", src)
    return save_pose_bank(target, bank)


def _prepare_motion(cfg: GenerateConfig, out: Path) -> Path:
    """The motion bank the workers of a sequence run read (``out/motion.npz``, built once
    from a motion folder, or the subjects' segments of a given ``motion.npz``)."""
    src, target = Path(cfg.poses), out / "motion.npz"
    if target.is_file():
        bank = load_motion_bank(target)
    elif src.is_dir():
        bank = build_motion_bank(src, list(cfg.subjects) or None, cfg.exclude_subjects)
    elif src.is_file():
        bank = load_motion_bank(src)
        subj = bank.subjects[bank.clip_index]
        keep = ~np.isin(subj, list(cfg.exclude_subjects))
        if cfg.subjects:
            keep &= np.isin(subj, list(cfg.subjects))
        bank = bank.select(keep)
        if not len(bank):
            raise InputError(src, "subjects", "motion of the selected subjects", "none")
    else:
        raise InputError(None, "poses", "a motion folder or a motion.npz", src)
    longest = int(bank.length.max())
    if longest < cfg.sequence_frames:
        raise InputError(
            src,
            "sequence_frames",
            f"at most the longest clean motion segment ({longest} frames)",
            cfg.sequence_frames,
        )
    return target if target.is_file() else save_motion_bank(target, bank)


def _bank_arrays(bank) -> tuple[np.ndarray, ...]:
    return (bank.rotations, bank.rest_dirs, bank.joints, bank.subject, bank.clip, bank.frame)


def _write_manifest(out: Path, cfg: GenerateConfig, detector: str, extra: dict) -> None:
    manifest = {
        "format": SEQUENCE_FORMAT if cfg.sequences else SCENE_FORMAT if cfg.scenes else FORMAT,
        "config": _config_dict(cfg),
        "detector": detector,
        "skeleton": cfg.joints,
        "joints": list(SKELETONS[cfg.joints].joints),
        "units": {"3d": "metres", "2d": "pixels, pixel (i, j) centred on (i, j)"},
        "world": "z up, floor at z = 0",
        "camera_model": "x_cam = R X + t; pinhole K, no distortion",
        "arrays": {k: {"shape": s, "meaning": m} for k, (s, m) in shard_arrays(cfg).items()},
        "num_shards": cfg.num_shards,
        "versions": _versions(),
        **extra,
    }
    if cfg.scenes:
        manifest["scenes"] = {
            "people": list(cfg.people),
            "views": cfg.views,
            "detections": "every person the detector finds per image (N slots, unassociated); "
            "match pairs them with the bodies by the projected joints",
            "spacing": "mid-hips at least 0.6 m apart on the floor; cameras aimed at the "
            "group's mean mid-hip",
        }
    if cfg.sequences:
        manifest["sequences"] = {
            "frames": cfg.sequence_frames,
            "views": cfg.views,
            "fps_range": list(cfg.sequence_fps),
            "speed_range": list(cfg.sequence_speed),
            "detector_mode": "a detector that follows people (blazepose-multi) sees each "
            "view's frames in order as one video; any other (mediapipe: static-image mode) "
            "detects every image afresh; the most confident person per image is kept",
            "per_sequence": "one body (phenotype, outfit, lighting), one motion window, one rig",
        }
    with atomic_path(out / "manifest.json") as tmp:
        tmp.write_text(json.dumps(manifest, indent=2))


def _check_same_config(out: Path, cfg: GenerateConfig) -> None:
    path = out / "manifest.json"
    if not path.is_file():
        return
    old = json.loads(path.read_text()).get("config", {})
    new = json.loads(json.dumps(_config_dict(cfg)))
    # num_meshes may grow or shrink: shards are seeded by (seed, index) alone.
    diff = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k) and k != "num_meshes")
    if "sequence_frames" in diff:  # sequences or not, and how long: the first thing to say
        diff.remove("sequence_frames")
        diff.insert(0, "sequence_frames")
    if diff:
        raise InputError(
            path,
            diff[0],
            f"the same config as the existing run in {out} (to resume) or a new --out",
            f"{old.get(diff[0])!r} there, {new.get(diff[0])!r} now",
        )


def summarize(out: str | Path) -> dict:
    """Counts over the finished shards of ``out``."""
    totals = {
        "shards": 0,
        "meshes": 0,
        "views": 0,
        "rejected": 0,
        "missed_joints": 0,
        "missed_views": 0,
    }
    seconds = {"pose": 0.0, "render": 0.0, "detect": 0.0}
    extra: dict[str, int] = {}  # counts only sequence or scene shards have
    for p in list_shards(out):
        with np.load(p, allow_pickle=False) as z:
            s = json.loads(str(z["stats"]))
        totals["shards"] += 1
        for k in ("meshes", "views", "rejected", "missed_joints", "missed_views"):
            totals[k] += s[k]
        for k in seconds:
            seconds[k] += s["seconds"][k]
        for k in ("sequences", "scenes", "people_found", "people_matched"):
            if k in s:
                extra[k] = extra.get(k, 0) + s[k]
    # A sequence set's meshes are its frames, its views its renders; a scene set's meshes
    # are its bodies, its views its images.
    return {**totals, **extra, "stage_seconds": seconds}


def generate(
    cfg: GenerateConfig,
    out: str | Path,
    workers: int = 1,
    ray_address: str | None = None,
    cache_dir: str | None = None,
    progress: bool = True,
) -> dict:
    """Generate (or resume) an MHP dataset into ``out``; returns the summary counts.

    Args:
        cfg: what to generate.
        out: output directory (created; resumed when it holds a run of the same config).
        workers: local worker processes (each with its own GL context and detector).
        ray_address: run the shards as Ray tasks on this cluster instead ("auto", an
            address, or "local" for a new local instance); ``out`` must be on a file system
            every Ray node sees.
        cache_dir: anny cache (default ``$ANNY_CACHE_DIR``).
        progress: show a tqdm bar over shards.
    """
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cache_dir = cache_dir or os.environ.get("ANNY_CACHE_DIR")
    _check_same_config(out, cfg)
    bank = _prepare_bank(cfg, out)
    bank_info = _bank_info(bank)
    _write_manifest(out, cfg, cfg.detector, {"status": "running", **bank_info})
    arrays = shard_arrays(cfg)
    todo = [
        i
        for i in range(cfg.num_shards)
        if not _shard_ok(shard_path(out, i), _shard_meshes(cfg, i), arrays)
    ]
    done = cfg.num_shards - len(todo)
    if done:
        log.info("%s: %d of %d shards already done, resuming", out, done, cfg.num_shards)
    t0 = time.time()
    bar = tqdm(
        total=cfg.num_shards,
        initial=done,
        desc="shards",
        unit="shard",
        disable=not progress,
        dynamic_ncols=True,
    )
    runner = _run_on_ray if ray_address else _run_in_process if workers <= 1 else _run_in_pool
    new_views = 0
    if todo:
        new_views = runner(cfg, out, todo, bank, cache_dir, bar, workers, ray_address)
    bar.close()
    return _finish(cfg, out, bank_info, new_views, time.time() - t0, workers)


def _bank_info(bank: Path | None) -> dict:
    """The manifest's description of the pose bank: poses per subject (or, for a motion
    bank, its segments and seconds per subject)."""
    if bank is None:
        return {}
    if bank.name == "motion.npz":
        m = load_motion_bank(bank)
        return {
            "motion": {
                "segments": len(m),
                "frames": int(m.length.sum()),
                "seconds_per_subject": m.seconds_per_subject(),
            }
        }
    from rmpl.synth.retarget import load_pose_bank

    b = load_pose_bank(bank)
    subj, counts = np.unique(b.subject, return_counts=True)
    subjects = dict(zip(subj.tolist(), counts.tolist(), strict=True))
    return {"pose_bank": {"poses": len(b), "subjects": subjects}}


def _run_on_ray(
    cfg: GenerateConfig,
    out: Path,
    todo: list[int],
    bank: Path | None,
    cache_dir: str | None,
    bar,
    workers: int,
    ray_address: str | None,
) -> int:
    """Generate the shards ``todo`` as Ray tasks; returns the number of views made."""
    import ray

    if ray_address == "local":
        ray.init(num_cpus=max(workers, 1), include_dashboard=False, ignore_reinit_error=True)
    else:
        ray.init(address=ray_address, ignore_reinit_error=True)
    task = ray.remote(num_cpus=1)(_ray_shard)
    cfg_dict, bank_s = asdict(cfg), str(bank) if bank else None
    pending = [task.remote(cfg_dict, bank_s, cache_dir, i, str(out.resolve())) for i in todo]
    new_views = 0
    while pending:
        ready, pending = ray.wait(pending, num_returns=1)
        new_views += ray.get(ready[0])["views"]
        bar.update(1)
    return new_views


def _run_in_process(
    cfg: GenerateConfig,
    out: Path,
    todo: list[int],
    bank: Path | None,
    cache_dir: str | None,
    bar,
    workers: int,
    ray_address: str | None,
) -> int:
    """Generate the shards ``todo`` one after another in this process."""
    worker = Worker(cfg, bank, cache_dir)
    new_views = 0
    try:
        for i in todo:
            new_views += generate_shard(worker, i, out)["views"]
            bar.update(1)
    finally:
        worker.close()
    return new_views


def _run_in_pool(
    cfg: GenerateConfig,
    out: Path,
    todo: list[int],
    bank: Path | None,
    cache_dir: str | None,
    bar,
    workers: int,
    ray_address: str | None,
) -> int:
    """Generate the shards ``todo`` in ``workers`` local processes."""
    import multiprocessing as mp

    cfg_dict, bank_s = asdict(cfg), str(bank) if bank else None
    ctx = mp.get_context("spawn")  # fresh processes: one EGL context each
    new_views = 0
    with ctx.Pool(workers, _init_pool, (cfg_dict, bank_s, cache_dir)) as pool:
        for stats in pool.imap_unordered(_pool_shard, [(i, str(out)) for i in todo]):
            new_views += stats["views"]
            bar.update(1)
    return new_views


def _finish(
    cfg: GenerateConfig, out: Path, bank_info: dict, new_views: int, elapsed: float, workers: int
) -> dict:
    """Summarise the shards in ``out``, write the final manifest and log the run's rate."""
    summary = summarize(out)
    rate = new_views / elapsed if elapsed > 0 and new_views else 0.0
    summary["this_run"] = {
        "views": new_views,
        "seconds": round(elapsed, 1),
        "views_per_second": round(rate, 2),
        "workers": workers,
    }
    complete = summary["shards"] == cfg.num_shards
    _write_manifest(
        out,
        cfg,
        cfg.detector,
        {"status": "complete" if complete else "partial", "counts": summary, **bank_info},
    )
    what = f"{summary['meshes']} meshes"
    if cfg.sequences:
        what = f"{summary['sequences']} sequences x {cfg.sequence_frames} frames"
    elif cfg.scenes:
        what = f"{summary['scenes']} scenes of {summary['meshes']} bodies"
    log.info(
        "%s: %s x %d views in %d shards (%d %s rejected); this run %d (mesh, view) "
        "samples in %.1f s = %.2f samples/s",
        out,
        what,
        cfg.views,
        summary["shards"],
        summary["rejected"],
        "sequences" if cfg.sequences else "poses",
        new_views,
        elapsed,
        rate,
    )
    return summary
