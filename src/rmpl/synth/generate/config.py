"""What ``rmpl generate`` makes: :class:`GenerateConfig`, checked.

Part of :mod:`rmpl.synth.generate` (``rmpl generate``).
"""

from __future__ import annotations

import logging
import tomllib
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.synth.generate.detectors import check_detector_options
from rmpl.synth.generate.scenes import SCENE_GAP, room_fits
from rmpl.synth.shards import (
    SCENE_ARRAYS,
    SEQUENCE_ARRAYS,
    SHARD_ARRAYS,
)

log = logging.getLogger(__name__)

#: Config keys that only sequence sets have (left out of a single-frame set's manifest,
#: which stays as it was before sequences existed).
_SEQUENCE_KEYS = ("sequence_frames", "sequence_fps", "sequence_speed")


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


def _shard_meshes(cfg: GenerateConfig, index: int) -> int:
    return min(cfg.shard_size, cfg.num_meshes - index * cfg.shard_size)
