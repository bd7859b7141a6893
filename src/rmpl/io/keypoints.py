"""2D keypoints in: OpenPose JSON, COCO-style JSON (MMPose, rtmlib) and rmpl's own NPZ/JSON.

Every reader returns a :class:`Keypoints2D`: pixel coordinates (from the top-left corner of
the image, as in :mod:`rmpl.geometry.camera`) of shape (T, V, P, J, 2) with per-joint scores
of shape (T, V, P, J).

- ``T`` frames, matched across views by frame number; a frame missing in one view is NaN
  there.
- ``V`` views, in the order the paths were given.
- ``P`` the most people detected in one view and frame; views with fewer are padded with
  NaN keypoints and zero scores. **People are not associated across views here**: person
  ``p`` of view 0 and person ``p`` of view 1 need not be the same person (nor the same
  person from one frame to the next). Association is a later step.
- ``J`` joints: by default the richest joint set the file supports, HALPE-26
  (:data:`rmpl.skeleton.HALPE26`: COCO-17 in COCO's order, then head top, neck, mid-hip and
  six foot points) when the file's joint set has COCO-17 and any of these nine extra joints,
  else COCO-17. HALPE-26 joints the file's set lacks are missing (NaN, score 0): a BODY_25
  file has no head top, COCO-18 only the neck, BlazePose only the heels and its foot index
  (in the big-toe slot). ``to=`` asks for another joint set; ``to=None`` keeps the file's.

A missing keypoint is NaN pixels with score 0, never a sentinel: the (0, 0, 0) points
OpenPose and COCO write for undetected joints, and any point at exactly pixel (0, 0) or with
a confidence of 0, become NaN / 0.

Formats, chosen with ``format=`` or detected from the content:

``"openpose"``
    One directory per view of per-frame JSON files, each ``{"people": [{"pose_keypoints_2d":
    [x, y, c, ...]}]}``. The frame number is the last run of digits in the file name
    (``cam01.0012.json`` or OpenPose's own ``video_000000000012_keypoints.json`` are frame
    12). Files named unlike the majority of the directory (leftovers such as
    ``del_000001_0.json``) are ignored with a warning. A directory holding no JSON file but
    sub-directories that do is read as one view per sub-directory, in name order. The view
    is named after its directory, without a ``_json`` suffix.

    BODY_25 and BODY_25B both have 25 points and cannot be told apart from the data: the
    ``skeleton`` argument decides; without it the ``pose_model`` of a Pose2Sim
    ``Config.toml`` in one of the three directories above the view directory is used, and
    failing that 25 points are read as BODY_25. 18 points are OpenPose COCO-18. Pose2Sim
    writes the output of every 2D model (RTMPose, AlphaPose, MediaPipe) in this format; the
    number of points tells the model: 17 COCO-17, 26 HALPE-26, 33 BlazePose, 133
    COCO-WholeBody (COCO-17, then the six foot points in its own order), 136 Halpe full
    body (HALPE-26 first).

``"coco"``
    One JSON file per view, written by MMPose, rtmlib or a COCO tool, in any of these forms:

    - a COCO dict ``{"images": [{"id", "file_name"}], "annotations": [{"image_id",
      "keypoints": [x, y, v, ...]}]}``. The frame is the last run of digits in the image's
      ``file_name``, or its ``image_id`` when the names carry no distinct numbers. When the
      annotations have ``num_keypoints`` (ground truth) ``v`` is a visibility flag and a
      labelled point gets score 1; otherwise ``v`` is the detector's confidence;
    - a list of such annotations (COCO results); the frame is ``image_id``;
    - MMPose's video predictions, a list of ``{"frame_id", "instances": [{"keypoints":
      [[x, y], ...], "keypoint_scores": [...]}]}``; the frame is ``frame_id``;
    - MMPose's per-image predictions, a bare list of instances: one frame, numbered by the
      last digits of the file name (0 without). A directory of such files is one view, one
      frame per file, numbered like OpenPose files.

    17 points are COCO-17; 26 HALPE-26; 133 COCO-WholeBody, whose first 23 are COCO-17 and
    the six foot points (its face and hands are dropped).

``"rmpl"``
    What :func:`save_keypoints` writes: ``.npz``, or ``.json`` with ``"format":
    "rmpl.keypoints2d"``.

Views come from the paths: a list gives one view per entry; a mapping ``{name: path}``
names them explicitly.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import re
import tomllib
import zipfile
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import (
    COCO17,
    EMBED_ALIASES,
    HALPE26,
    SKELETONS,
    convert,
    convert_scores,
    embed,
    embed_scores,
)

__all__ = [
    "EXTRA_JOINTS",
    "FAR_MARGIN",
    "FORMATS",
    "Keypoints2D",
    "drop_far_keypoints",
    "load_keypoints",
    "richest",
    "save_keypoints",
]

log = logging.getLogger(__name__)

FORMATS = ("openpose", "coco", "rmpl")
_TAG = "rmpl.keypoints2d"

# Joint sets found in files that rmpl has no Skeleton for: (number of joints, index in the
# file of each HALPE-26 joint the file has). They are read into HALPE-26 (then COCO-17, the
# first 17 HALPE-26 joints, when asked).
_COCO18_TO_COCO17 = (0, 15, 14, 17, 16, 5, 2, 6, 3, 7, 4, 11, 8, 12, 9, 13, 10)
_WHOLEBODY_FEET = (  # COCO-WholeBody points 17-22
    "left_big_toe",
    "left_small_toe",
    "left_heel",
    "right_big_toe",
    "right_small_toe",
    "right_heel",
)
_FOREIGN: dict[str, tuple[int, dict[str, int]]] = {
    # OpenPose COCO: nose, neck, right arm, left arm, right leg, left leg, eyes, ears
    "coco18": (18, dict(zip(COCO17.joints, _COCO18_TO_COCO17, strict=True)) | {"neck": 1}),
    # COCO-WholeBody: the COCO-17 body, the six foot points, then face and hands
    "wholebody133": (
        133,
        {n: i for i, n in enumerate(COCO17.joints + _WHOLEBODY_FEET)},
    ),
    # Halpe full body (AlphaPose): the 26 HALPE-26 points first, then face and hands
    "halpe136": (136, {n: i for i, n in enumerate(HALPE26.joints)}),
}
#: The joints HALPE-26 adds to COCO-17 (head top, neck, mid-hip and the six foot points).
EXTRA_JOINTS: tuple[str, ...] = HALPE26.joints[COCO17.num_joints :]
# The joint set assumed for a number of points when nothing else says.
_BY_COUNT = {
    17: "coco17",
    18: "coco18",
    25: "body25",
    26: "halpe26",
    33: "blazepose33",
    133: "wholebody133",
    136: "halpe136",
}
# Pose2Sim Config.toml [pose] pose_model values.
_POSE2SIM_MODELS = {
    "BODY_25B": "body25b",
    "BODY_25": "body25",
    "COCO": "coco18",
    "COCO_18": "coco18",
    "COCO_17": "coco17",
    "HALPE_26": "halpe26",
    "BODY_WITH_FEET": "halpe26",
    "COCO_133": "wholebody133",
    "COCO_133_WRIST": "wholebody133",
    "WHOLE_BODY": "wholebody133",
    "WHOLE_BODY_WRIST": "wholebody133",
    "BODY": "coco17",
    "HALPE_136": "halpe136",
    "BLAZEPOSE": "blazepose33",
}
_LAST_DIGITS = re.compile(r"(\d+)(?!.*\d)")


def _num_joints(name: str) -> int:
    return SKELETONS[name].num_joints if name in SKELETONS else _FOREIGN[name][0]


@dataclass
class Keypoints2D:
    """2D keypoints of every view and frame.

    Attributes:
        keypoints: pixels from the top-left corner, shape (T, V, P, J, 2); NaN = missing.
        scores: detector confidence, shape (T, V, P, J); 0 where missing.
        skeleton: joint set, a key of :data:`rmpl.skeleton.SKELETONS`.
        views: view names, length V (default ``view0``, ``view1``, ...).
        frames: frame numbers, shape (T,), strictly increasing (default 0..T-1).
        fps: frames per second, or None when unknown.

    Person ``p`` in one view is not necessarily person ``p`` in another view or frame.
    """

    keypoints: np.ndarray
    scores: np.ndarray
    skeleton: str = "coco17"
    views: list[str] | None = None
    frames: np.ndarray | None = None
    fps: float | None = None

    def __post_init__(self) -> None:
        kp = _floats(self.keypoints, "keypoints")
        if kp.ndim != 5 or kp.shape[-1] != 2:
            raise InputError(None, "keypoints", "shape (T, V, P, J, 2)", kp.shape)
        T, V, _, J, _ = kp.shape
        sc = _floats(self.scores, "scores")
        if sc.shape != kp.shape[:-1]:
            raise InputError(None, "scores", f"shape {kp.shape[:-1]} (T, V, P, J)", sc.shape)
        _check_skeleton(self.skeleton, J)
        _check_missing(kp, sc, "keypoints", "scores")
        views = [f"view{v}" for v in range(V)] if self.views is None else self.views
        views = [str(v) for v in views]
        if len(views) != V or len(set(views)) != V:
            raise InputError(None, "views", f"{V} distinct view names", views)
        self.keypoints, self.scores, self.views = kp, sc, views
        self.frames = _check_frames(self.frames, T)
        self.fps = _check_fps(self.fps)

    @property
    def num_frames(self) -> int:
        return self.keypoints.shape[0]

    @property
    def num_views(self) -> int:
        return self.keypoints.shape[1]

    @property
    def num_people(self) -> int:
        return self.keypoints.shape[2]

    @property
    def num_joints(self) -> int:
        return self.keypoints.shape[3]


# --------------------------------------------------------------------------- validation
# Shared with rmpl.io.poses: they raise InputError without a path; readers add theirs.


def _floats(x, field: str) -> np.ndarray:
    """``x`` as a float array; booleans, complex numbers, text and objects are refused."""
    try:
        a = np.asarray(x)
    except (TypeError, ValueError):
        raise InputError(None, field, "an array of numbers (not ragged lists)", "ragged") from None
    if a.dtype.kind not in "iuf":
        raise InputError(None, field, "an array of real numbers", f"a {a.dtype} array")
    return np.array(a, dtype=float)


#: A keypoint more than this many image sizes beyond its image's border (x < -m W or
#: x > (1 + m) W, likewise y with H) is treated as missing (:func:`drop_far_keypoints`).
FAR_MARGIN = 1.0


def drop_far_keypoints(
    keypoints: np.ndarray, scores: np.ndarray, sizes: np.ndarray, view_axis: int = -3
) -> tuple[np.ndarray, np.ndarray, int]:
    """Keypoints far outside their image (see :data:`FAR_MARGIN`) become missing.

    Args:
        keypoints: pixels, shape (..., V, ..., J, 2) with the views on ``view_axis``.
        scores: shape ``keypoints.shape[:-1]``.
        sizes: image (width, height) per view, shape (V, 2); NaN where unknown (then
            nothing is dropped in that view).

    Returns:
        The keypoints (NaN where dropped), the scores (0 there) and how many were dropped.

    >>> kp = np.array([[[10.0, 20.0], [5e12, 3.0]]])  # (V=1, J=2, 2)
    >>> out, sc, n = drop_far_keypoints(kp, np.ones((1, 2)), np.array([[640.0, 480.0]]))
    >>> n, sc.tolist()
    (1, [[1.0, 0.0]])
    """
    shape = [1] * keypoints.ndim
    shape[view_axis], shape[-1] = len(sizes), 2
    size = np.asarray(sizes, float).reshape(shape)
    far = ((keypoints < -FAR_MARGIN * size) | (keypoints > (1 + FAR_MARGIN) * size)).any(-1)
    far &= scores > 0
    n = int(far.sum())
    if n:
        keypoints, scores = keypoints.copy(), scores.copy()
        keypoints[far], scores[far] = np.nan, 0.0
    return keypoints, scores, n


def _check_skeleton(name: str, num_joints: int) -> None:
    if name not in SKELETONS:
        raise InputError(None, "skeleton", f"one of {sorted(SKELETONS)}", repr(name))
    if SKELETONS[name].num_joints != num_joints:
        raise InputError(
            None,
            "skeleton",
            f"{num_joints} joints to match the arrays",
            f"{name!r} with {SKELETONS[name].num_joints} joints",
        )


def _check_missing(points: np.ndarray, scores: np.ndarray | None, pfield: str, sfield: str):
    """Points: all coordinates NaN (missing) or all finite; scores finite, >= 0, 0 if missing."""
    nan = np.isnan(points)
    if np.isinf(points).any():
        raise InputError(None, pfield, "finite coordinates or NaN for missing", "inf")
    if (nan.any(-1) != nan.all(-1)).any():
        raise InputError(None, pfield, "every coordinate of a joint NaN, or none", "partial NaN")
    if scores is None:
        return
    if not np.isfinite(scores).all():
        raise InputError(None, sfield, "finite scores (0 for a missing joint)", "NaN or inf")
    if (scores < 0).any():
        raise InputError(None, sfield, "scores >= 0", float(scores.min()))
    if (scores[nan.all(-1)] != 0).any():
        raise InputError(None, sfield, "score 0 wherever the joint is NaN", "a positive score")


def _check_frames(frames, num_frames: int) -> np.ndarray:
    if frames is None:
        return np.arange(num_frames, dtype=np.int64)
    f = _floats(frames, "frames")
    if f.shape != (num_frames,):
        raise InputError(None, "frames", f"shape ({num_frames},), one number per frame", f.shape)
    if not (np.isfinite(f).all() and (f == np.round(f)).all()):
        raise InputError(None, "frames", "integer frame numbers", f.tolist())
    if (np.diff(f) <= 0).any():
        raise InputError(None, "frames", "strictly increasing frame numbers", f.tolist())
    return f.astype(np.int64)


def _check_fps(fps) -> float | None:
    if fps is None:
        return None
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise InputError(None, "fps", "a positive number or None", repr(fps)) from None
    if not (np.isfinite(value) and value > 0):
        raise InputError(None, "fps", "a positive number or None", fps)
    return value


def _with_path(err: InputError, path: Path) -> InputError:
    return InputError(path, err.field, err.expected, err.got)


# --------------------------------------------------------------------------- file helpers


def _read_json(path: Path):
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(path, None, "a readable UTF-8 JSON file", e) from None
    if not text.strip():
        raise InputError(path, None, "a JSON document", "an empty file")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(path, None, "valid JSON", f"{e.msg} at line {e.lineno}") from None


def _json_floats(a: np.ndarray) -> list:
    """Nested lists with None for NaN (JSON has no NaN)."""
    a = np.asarray(a, dtype=float)
    return np.where(np.isnan(a), None, a).tolist()


def _json_array(doc: dict, key: str, shape: tuple[int, ...], path: Path, dtype=float):
    """``doc[key]`` as an array of ``shape`` (None read as NaN)."""
    if key not in doc:
        raise InputError(path, key, f"an array of shape {shape}", "no such key")
    try:
        a = np.array(doc[key], dtype=dtype)
    except (TypeError, ValueError):
        raise InputError(path, key, f"numbers, shape {shape}", "ragged or text") from None
    if a.size == 0 and np.prod(shape) == 0:
        a = a.reshape(shape)
    if a.shape != shape:
        raise InputError(path, key, f"shape {shape}", a.shape)
    return a


def _open_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of an NPZ; pickled (object) arrays are refused, naming the array."""
    expected = "an .npz archive written by rmpl"
    try:
        z = np.load(path, allow_pickle=False)
    except ValueError:  # numpy's "allow_pickle" advice: the file is no zip archive
        raise InputError(path, None, expected, "not a zip (.npz) archive") from None
    except (OSError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(path, None, expected, e) from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise InputError(path, None, expected, "a single .npy array")
    out = {}
    with z:
        for k in z.files:
            try:
                out[k] = z[k]
            except ValueError:
                raise InputError(
                    path, k, "an array of numbers or text", "an object array (pickled data)"
                ) from None
            except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as e:
                raise InputError(path, k, "a readable array", e) from None
    return out


def _npz_get(data: dict[str, np.ndarray], key: str, path: Path) -> np.ndarray:
    if key not in data:
        raise InputError(path, key, "an array under this name", f"only {sorted(data)}")
    return data[key]


def _npz_str(data: dict[str, np.ndarray], key: str, path: Path) -> str:
    a = _npz_get(data, key, path)
    if a.ndim != 0 or a.dtype.kind != "U":
        raise InputError(path, key, "a text value", a.dtype)
    return str(a)


def _npz_fps(value: float | None) -> np.ndarray:
    return np.array(np.nan if value is None else value)


def _fps_from_npz(a: np.ndarray, path: Path) -> float | None:
    try:
        value = float(a)
    except (TypeError, ValueError):
        raise InputError(path, "fps", "a number (NaN when unknown)", a) from None
    return None if np.isnan(value) else value


# --------------------------------------------------------------------------- public API


def load_keypoints(
    paths: str | Path | Sequence[str | Path] | Mapping[str, str | Path],
    format: str | None = None,
    skeleton: str | None = None,
    *,
    to: str | None = "auto",
    fps: float | None = None,
) -> Keypoints2D:
    """Read 2D keypoints of one or several views.

    Args:
        paths: one path, a list of paths (one view each), or a mapping view name -> path.
            See the module docstring for what each format expects.
        format: ``"openpose"``, ``"coco"`` or ``"rmpl"``; detected from the content when None.
        skeleton: the joint set in the files (``"body25"``, ``"body25b"``, ``"coco18"``,
            ``"coco17"``, ``"halpe26"``, ``"wholebody133"``, ``"halpe136"``,
            ``"blazepose33"``). Needed to tell BODY_25B from BODY_25 (default BODY_25,
            unless a Pose2Sim Config.toml says).
        to: joint set of the result. ``"auto"`` (default): HALPE-26 when the file's joint
            set has COCO-17 and any of :data:`EXTRA_JOINTS` (feet, neck, head top, mid-hip:
            BODY_25, BODY_25B, COCO-18, HALPE-26, COCO-WholeBody, BlazePose), placed by name
            with the joints it lacks missing (:func:`rmpl.skeleton.embed`); else COCO-17.
            None keeps the file's joint set when rmpl has a
            :class:`~rmpl.skeleton.Skeleton` for it (COCO-18, COCO-WholeBody and Halpe-136
            become HALPE-26). A name converts to that joint set.
        fps: frame rate; overrides what the files say (Pose2Sim ``frame_rate``, rmpl files).

    Returns:
        The keypoints, shape (T, V, P, J, 2), and scores, shape (T, V, P, J).

    Raises:
        InputError: a missing path or a file that does not hold what its format requires;
            the message names the file and the field.
    """
    named = _named_paths(paths)
    format = _check_load_arguments(named, format, skeleton, to)
    if format == "rmpl":
        return _load_rmpl(named, to, fps)
    named = _expand_view_dirs(named)
    if format == "openpose":
        hint, file_fps = _pose2sim_config(named[0][1]) if named[0][1].is_dir() else (None, None)
        native = skeleton or hint
        per_view, num_joints = _read_views(named, native, _read_openpose_view)
    else:
        native, file_fps = skeleton, None
        per_view, num_joints = _read_views(named, native, _read_coco_view)
    if native is None:
        native = _BY_COUNT[num_joints] if num_joints else _fallback_native(to)
    fps = fps if fps is not None else file_fps
    return _assemble(per_view, [n for n, _ in named], native, to, fps)


def _check_load_arguments(named, format: str | None, skeleton: str | None, to: str | None) -> str:
    """The paths exist and the options are known; returns the format (detected when None)."""
    for _, p in named:
        if not p.exists():
            raise InputError(p, None, "an existing file or directory", "no such path")
    if format is None:
        found = {_detect(p) for _, p in named}
        if len(found) > 1:
            raise InputError(None, "paths", "files of one format", sorted(found))
        format = found.pop()
    if format not in FORMATS:
        raise InputError(None, "format", f"one of {FORMATS}", repr(format))
    if to is not None and to != "auto" and to not in SKELETONS:
        raise InputError(None, "to", f"'auto', None or one of {sorted(SKELETONS)}", repr(to))
    if skeleton is not None and _num_joints_or_none(skeleton) is None:
        known = sorted(set(SKELETONS) | set(_FOREIGN))
        raise InputError(None, "skeleton", f"None or one of {known}", repr(skeleton))
    return format


def _load_rmpl(named, to: str | None, fps: float | None) -> Keypoints2D:
    if len(named) != 1:
        raise InputError(None, "paths", "a single rmpl .npz or .json file", len(named))
    kp = _read_rmpl(named[0][1])
    if fps is not None:
        kp.fps = _check_fps(fps)
    if to is None or to == kp.skeleton or (to == "auto" and richest(kp.skeleton) == kp.skeleton):
        return kp
    xy, sc, name = _convert(kp.keypoints, kp.scores, kp.skeleton, to)
    return Keypoints2D(xy, sc, name, kp.views, kp.frames, kp.fps)


def save_keypoints(kp: Keypoints2D, path: str | Path) -> Path:
    """Write keypoints to ``.npz`` or ``.json`` (rmpl's format), atomically.

    The JSON holds ``format``, ``version``, ``units`` ("pixels"), ``skeleton``, ``joints``,
    ``views``, ``frames``, ``fps``, ``num_people``, ``keypoints`` (T, V, P, J, 2, ``null``
    for missing) and ``scores`` (T, V, P, J). Returns the path written.
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in (".npz", ".json"):
        raise InputError(path, None, "a file name ending in .npz or .json", path.suffix or "none")
    try:
        kp = dataclasses.replace(kp)  # validate again: fields may have changed since
    except InputError as e:
        raise _with_path(e, path) from None
    with atomic_path(path) as tmp:
        if ext == ".npz":
            with open(tmp, "wb") as f:
                np.savez_compressed(
                    f,
                    format=np.array(_TAG),
                    keypoints=kp.keypoints,
                    scores=kp.scores,
                    skeleton=np.array(kp.skeleton),
                    views=np.array(kp.views, dtype=str),
                    frames=kp.frames,
                    fps=_npz_fps(kp.fps),
                )
        else:
            doc = {
                "format": _TAG,
                "version": 1,
                "units": "pixels",
                "skeleton": kp.skeleton,
                "joints": list(SKELETONS[kp.skeleton].joints),
                "views": kp.views,
                "frames": kp.frames.tolist(),
                "fps": kp.fps,
                "num_people": kp.num_people,
                "keypoints": _json_floats(kp.keypoints),
                "scores": kp.scores.tolist(),
            }
            # dumps, not dump: the same text from json's C encoder, many times faster
            tmp.write_text(json.dumps(doc, allow_nan=False), encoding="utf-8")
    return path


# --------------------------------------------------------------------------- paths, detection


def _num_joints_or_none(name: str) -> int | None:
    return _num_joints(name) if name in SKELETONS or name in _FOREIGN else None


def _view_name(p: Path) -> str:
    name = p.name if p.is_dir() else p.stem
    return name.removesuffix("_json") or name


def _named_paths(paths) -> list[tuple[str, Path]]:
    if isinstance(paths, Mapping):
        named = [(str(k), Path(v)) for k, v in paths.items()]
    elif isinstance(paths, str | Path):
        named = [(_view_name(Path(paths)), Path(paths))]
    else:
        named = [(_view_name(Path(p)), Path(p)) for p in paths]
    if not named:
        raise InputError(None, "paths", "at least one file or directory", "none")
    return named


def _json_files(d: Path) -> list[Path]:
    return sorted(p for p in d.glob("*.json") if p.is_file())


def _view_subdirs(p: Path) -> list[Path]:
    """Sub-directories with JSON files of a directory that has none itself (one per view)."""
    if not p.is_dir() or _json_files(p):
        return []
    return [s for s in sorted(p.iterdir()) if s.is_dir() and _json_files(s)]


def _expand_view_dirs(named: list[tuple[str, Path]]) -> list[tuple[str, Path]]:
    out = []
    for name, p in named:
        subdirs = _view_subdirs(p)
        out += [(_view_name(s), s) for s in subdirs] if subdirs else [(name, p)]
    names = [n for n, _ in out]
    if len(set(names)) != len(names):
        raise InputError(None, "paths", "distinct view names (pass a mapping name -> path)", names)
    return out


def _detect(p: Path) -> str:
    if p.suffix.lower() == ".npz":
        return "rmpl"
    if p.is_dir():
        files = _json_files(p) or [f for s in _view_subdirs(p) for f in _json_files(s)]
        if not files:
            raise InputError(
                p, None, "a directory of JSON files, or of per-view directories", "no JSON file"
            )
        p = files[0]
    doc = _read_json(p)
    if isinstance(doc, dict) and doc.get("format") == _TAG:
        return "rmpl"
    if isinstance(doc, dict) and "people" in doc:
        return "openpose"
    if isinstance(doc, list) or (isinstance(doc, dict) and "annotations" in doc):
        return "coco"
    raise InputError(
        p,
        None,
        "OpenPose ('people'), COCO ('annotations' or a list) or rmpl ('format') JSON",
        f"keys {sorted(doc)[:8]}" if isinstance(doc, dict) else type(doc).__name__,
    )


def _pose2sim_config(view_dir: Path) -> tuple[str | None, float | None]:
    """Joint set and frame rate from the nearest Pose2Sim Config.toml above a view directory."""
    model = fps = None
    for d in list(view_dir.resolve().parents)[:3]:
        cfg = d / "Config.toml"
        if not cfg.is_file():
            continue
        try:
            doc = tomllib.loads(cfg.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise InputError(cfg, None, "a readable Pose2Sim TOML configuration", e) from None
        pose, project = doc.get("pose", {}), doc.get("project", {})
        if model is None and isinstance(pose, dict) and "pose_model" in pose:
            model = _POSE2SIM_MODELS.get(str(pose["pose_model"]).upper())
            if model is None:
                log.warning(
                    "%s: pose_model %r is not a joint set rmpl knows; ignored",
                    cfg,
                    pose["pose_model"],
                )
            else:
                log.info("%s: reading keypoints as %s", cfg, model)
        rate = project.get("frame_rate") if isinstance(project, dict) else None
        if fps is None and isinstance(rate, int | float) and rate > 0:
            fps = float(rate)
    return model, fps


# --------------------------------------------------------------------------- readers


def _frame_files(d: Path) -> dict[int, Path]:
    """JSON files of a directory by frame number (the last digits of the name)."""
    groups: dict[str, dict[int, Path]] = {}
    files = _json_files(d)
    for p in files:
        m = _LAST_DIGITS.search(p.stem)
        if m is None:
            continue
        frame, pattern = int(m.group(1)), p.stem[: m.start()] + "#" + p.stem[m.end() :]
        group = groups.setdefault(pattern, {})
        if frame in group:
            raise InputError(
                p, None, f"one file per frame; frame {frame} is also in {group[frame].name}"
            )
        group[frame] = p
    if not groups:
        raise InputError(
            d,
            None,
            "JSON files named with a frame number (cam01.0000.json)",
            f"{len(files)} JSON files without digits",
        )
    pattern = max(groups, key=lambda k: len(groups[k]))
    skipped = len(files) - len(groups[pattern])
    if skipped:
        log.warning("%s: ignored %d JSON files not named like %s.json", d, skipped, pattern)
    return dict(sorted(groups[pattern].items()))


def _triples(values, num_joints: int | None, path: Path, field: str) -> np.ndarray:
    """Flat [x, y, c, x, y, c, ...] -> (J, 3), checked."""
    try:
        a = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(path, field, "a flat list of numbers x, y, c, ...", "other") from None
    counts = [num_joints] if num_joints else sorted(_BY_COUNT)
    if a.ndim != 1 or a.size not in [3 * n for n in counts]:
        raise InputError(
            path,
            field,
            f"{' or '.join(str(3 * n) for n in counts)} numbers "
            f"(x, y, confidence for {' or '.join(map(str, counts))} joints)",
            f"{a.size} numbers" if a.ndim == 1 else a.shape,
        )
    return _checked_points(a.reshape(-1, 3), path, field)


def _checked_points(a: np.ndarray, path: Path, field: str) -> np.ndarray:
    if not np.isfinite(a).all():
        raise InputError(path, field, "finite numbers (a missing joint is 0, 0, 0)", "NaN or inf")
    if (a[:, 2] < 0).any():
        raise InputError(path, field, "confidences >= 0", float(a[:, 2].min()))
    return a


def _stack(people: list[np.ndarray], num_joints: int | None) -> np.ndarray:
    return np.stack(people) if people else np.zeros((0, num_joints or 0, 3))


def _read_views(named, native: str | None, reader):
    """Read every view with ``reader(path, num_joints) -> ({frame: (P, J, 3)}, J)``."""
    num_joints = _num_joints(native) if native else None
    per_view = []
    for _, p in named:
        frames, num_joints = reader(p, num_joints)
        if not frames:
            raise InputError(p, None, "at least one frame of keypoints", "none")
        per_view.append(frames)
    return per_view, num_joints


def _read_openpose_view(d: Path, num_joints: int | None):
    if not d.is_dir():
        raise InputError(d, None, "a directory of OpenPose JSON files, one per frame", "a file")
    out = {}
    for frame, p in _frame_files(d).items():
        doc = _read_json(p)
        if not isinstance(doc, dict) or not isinstance(doc.get("people"), list):
            raise InputError(p, "people", "a list of people (OpenPose JSON)", "no such list")
        people = []
        for i, person in enumerate(doc["people"]):
            field = f"people[{i}].pose_keypoints_2d"
            if not isinstance(person, dict) or "pose_keypoints_2d" not in person:
                raise InputError(p, field, "a list of x, y, confidence numbers", "no such key")
            people.append(_triples(person["pose_keypoints_2d"], num_joints, p, field))
            num_joints = people[-1].shape[0]
        out[frame] = _stack(people, num_joints)
    return out, num_joints


def _read_coco_view(p: Path, num_joints: int | None):
    if p.is_dir():
        out = {}
        for frame, f in _frame_files(p).items():
            doc = _read_json(f)
            if not isinstance(doc, list):
                raise InputError(f, None, "a list of instances (one image)", type(doc).__name__)
            out[frame], num_joints = _coco_instances(doc, f, "", num_joints)
        return out, num_joints
    doc = _read_json(p)
    if isinstance(doc, dict) and "annotations" in doc:
        return _coco_dataset(doc, p, num_joints)
    if not isinstance(doc, list):
        raise InputError(p, None, "a COCO dict with 'annotations' or a list", type(doc).__name__)
    if doc and all(isinstance(x, dict) and "instances" in x for x in doc):
        return _mmpose_video(doc, p, num_joints)
    if doc and all(isinstance(x, dict) and "image_id" in x for x in doc):
        return _coco_by_image(doc, p, "", num_joints, {}, visibility=False)
    m = _LAST_DIGITS.search(p.stem)
    people, num_joints = _coco_instances(doc, p, "", num_joints)
    return {int(m.group(1)) if m else 0: people}, num_joints


def _coco_instance(inst, path: Path, field: str, num_joints: int | None, visibility: bool):
    if not isinstance(inst, dict) or "keypoints" not in inst:
        raise InputError(path, f"{field}.keypoints", "keypoints of each instance", "no such key")
    if "keypoint_scores" not in inst:  # COCO: flat x, y, v
        a = _triples(inst["keypoints"], num_joints, path, f"{field}.keypoints")
        if visibility:
            a[:, 2] = a[:, 2] > 0
        return a
    try:  # MMPose / rtmlib: [[x, y], ...] and [s, ...]
        xy = np.array(inst["keypoints"], dtype=float)
        s = np.array(inst["keypoint_scores"], dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            path,
            f"{field}.keypoints",
            "[[x, y], ...] and keypoint_scores [s, ...]",
            "ragged or text",
        ) from None
    counts = [num_joints] if num_joints else sorted(_BY_COUNT)
    if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] not in counts:
        raise InputError(
            path,
            f"{field}.keypoints",
            f"[[x, y], ...] for {' or '.join(map(str, counts))} joints",
            xy.shape,
        )
    if s.shape != (xy.shape[0],):
        raise InputError(path, f"{field}.keypoint_scores", f"{xy.shape[0]} scores", s.shape)
    return _checked_points(np.concatenate([xy, s[:, None]], axis=1), path, f"{field}.keypoints")


def _coco_instances(doc: list, path: Path, field: str, num_joints: int | None):
    people = []
    for i, inst in enumerate(doc):
        people.append(_coco_instance(inst, path, f"{field}[{i}]", num_joints, visibility=False))
        num_joints = people[-1].shape[0]
    return _stack(people, num_joints), num_joints


def _mmpose_video(doc: list, path: Path, num_joints: int | None):
    out = {}
    for i, item in enumerate(doc):
        frame = item.get("frame_id")
        if not isinstance(frame, int) or frame in out:
            raise InputError(path, f"[{i}].frame_id", "a distinct integer frame number", frame)
        if not isinstance(item["instances"], list):
            raise InputError(path, f"[{i}].instances", "a list of instances", item["instances"])
        out[frame], num_joints = _coco_instances(
            item["instances"], path, f"[{i}].instances", num_joints
        )
    return dict(sorted(out.items())), num_joints


def _coco_dataset(doc: dict, path: Path, num_joints: int | None):
    images = doc.get("images", [])
    if not isinstance(images, list) or not all(
        isinstance(im, dict) and "id" in im for im in images
    ):
        raise InputError(path, "images", "a list of {id, file_name}", "other")
    if not isinstance(doc["annotations"], list):
        raise InputError(path, "annotations", "a list of annotations", type(doc["annotations"]))
    names = [_LAST_DIGITS.search(Path(str(im.get("file_name", ""))).stem) for im in images]
    numbers = [int(m.group(1)) for m in names if m]
    if len(numbers) == len(images) and len(set(numbers)) == len(numbers):
        frame_of = {im["id"]: n for im, n in zip(images, numbers, strict=True)}
    else:  # names without distinct numbers: the image ids are the frames
        frame_of = {im["id"]: im["id"] for im in images}
    gt = any(isinstance(a, dict) and "num_keypoints" in a for a in doc["annotations"])
    out, num_joints = _coco_by_image(
        doc["annotations"], path, "annotations", num_joints, frame_of, visibility=gt
    )
    for f in frame_of.values():  # images without anybody in them are frames too
        out.setdefault(f, _stack([], num_joints))
    return dict(sorted(out.items())), num_joints


def _coco_by_image(anns: list, path: Path, field: str, num_joints, frame_of: dict, visibility):
    by_frame: dict[int, list[np.ndarray]] = {}
    for i, ann in enumerate(anns):
        where = f"{field}[{i}]"
        image = ann.get("image_id") if isinstance(ann, dict) else None
        if not isinstance(image, int):
            raise InputError(path, f"{where}.image_id", "an integer image id", image)
        if frame_of and image not in frame_of:
            raise InputError(path, f"{where}.image_id", "the id of an entry in 'images'", image)
        person = _coco_instance(ann, path, where, num_joints, visibility)
        by_frame.setdefault(frame_of.get(image, image), []).append(person)
        num_joints = person.shape[0]
    out = {f: _stack(people, num_joints) for f, people in sorted(by_frame.items())}
    return out, num_joints


def _read_rmpl(path: Path) -> Keypoints2D:
    if path.suffix.lower() == ".npz":
        data = _open_npz(path)
        fields = dict(
            keypoints=_npz_get(data, "keypoints", path),
            scores=_npz_get(data, "scores", path),
            skeleton=_npz_str(data, "skeleton", path),
            views=[str(v) for v in _npz_get(data, "views", path).reshape(-1)],
            frames=_npz_get(data, "frames", path),
            fps=_fps_from_npz(_npz_get(data, "fps", path), path),
        )
    else:
        doc = _read_json(path)
        if not isinstance(doc, dict):
            raise InputError(path, None, "a JSON object (rmpl keypoints)", type(doc).__name__)
        for key in ("skeleton", "views", "frames", "num_people"):
            if key not in doc:
                raise InputError(path, key, "a value (rmpl keypoints JSON)", "no such key")
        if doc["skeleton"] not in SKELETONS:
            raise InputError(path, "skeleton", f"one of {sorted(SKELETONS)}", doc["skeleton"])
        for key in ("views", "frames"):
            if not isinstance(doc[key], list):
                raise InputError(path, key, "a list", type(doc[key]).__name__)
        if not isinstance(doc["num_people"], int) or doc["num_people"] < 0:
            raise InputError(path, "num_people", "an integer >= 0", doc["num_people"])
        T, V = len(doc["frames"]), len(doc["views"])
        shape = (T, V, doc["num_people"], SKELETONS[doc["skeleton"]].num_joints)
        fields = dict(
            keypoints=_json_array(doc, "keypoints", (*shape, 2), path),
            scores=_json_array(doc, "scores", shape, path),
            skeleton=doc["skeleton"],
            views=doc["views"],
            frames=doc["frames"],
            fps=doc.get("fps"),
        )
    try:
        return Keypoints2D(**fields)
    except InputError as e:
        raise _with_path(e, path) from None


# --------------------------------------------------------------------------- assembly


def _assemble(per_view, views: list[str], native: str, to: str | None, fps) -> Keypoints2D:
    """Per-view ``{frame: (P, J, 3)}`` -> Keypoints2D, frames matched by number."""
    frames = sorted(set().union(*per_view))
    row = {f: i for i, f in enumerate(frames)}
    J = _num_joints(native)
    P = max((a.shape[0] for view in per_view for a in view.values()), default=0)
    data = np.full((len(frames), len(views), P, J, 3), np.nan)
    data[..., 2] = 0.0
    for v, view in enumerate(per_view):
        for f, people in view.items():
            if len(people):
                data[row[f], v, : len(people)] = people
    xy, sc = data[..., :2], data[..., 2]
    missing = (sc <= 0) | (xy == 0).all(-1)  # OpenPose and COCO write 0, 0, 0
    xy[missing], sc[missing] = np.nan, 0.0
    xy, sc, name = _convert(xy, sc, native, to)
    return Keypoints2D(xy, sc, name, views, np.array(frames), fps)


def _fallback_native(to: str | None) -> str:
    """The joint set of a file with nobody in it: the one asked for, else COCO-17."""
    return to if to in SKELETONS else "coco17"


def _provides(native: str) -> set[str]:
    """Names of the HALPE-26 joints a joint set gives (by name, or an alias standing in)."""
    if native in _FOREIGN:
        return set(_FOREIGN[native][1])
    names = set(SKELETONS[native].joints)
    return names | {dst for dst, src in EMBED_ALIASES.get(native, {}).items() if src in names}


def richest(native: str) -> str:
    """The joint set ``load_keypoints(to="auto")`` gives for a file in ``native``: HALPE-26
    when ``native`` has the COCO-17 joints and any of :data:`EXTRA_JOINTS`, else COCO-17.

    >>> richest("body25"), richest("coco17"), richest("wholebody133"), richest("h36m17")
    ('halpe26', 'coco17', 'halpe26', 'coco17')
    """
    names = _provides(native)
    return "halpe26" if set(COCO17.joints) <= names and names & set(EXTRA_JOINTS) else "coco17"


def _foreign_to_halpe26(xy: np.ndarray, sc: np.ndarray, native: str):
    """(*, J_native, 2), (*, J_native) of a joint set in :data:`_FOREIGN` -> HALPE-26."""
    where = _FOREIGN[native][1]
    out_xy = np.full((*xy.shape[:-2], HALPE26.num_joints, 2), np.nan)
    out_sc = np.zeros((*sc.shape[:-1], HALPE26.num_joints))
    for name, i in where.items():
        out_xy[..., HALPE26.index(name), :] = xy[..., i, :]
        out_sc[..., HALPE26.index(name)] = sc[..., i]
    return out_xy, out_sc


def _convert(xy: np.ndarray, sc: np.ndarray, native: str, to: str | None):
    """(*, J_native, 2), (*, J_native) -> the joint set ``to`` (native when None; see
    :func:`load_keypoints`)."""
    if to == "auto":
        to = richest(native)
    if native in _FOREIGN:
        xy, sc = _foreign_to_halpe26(xy, sc, native)
        native = "halpe26"
        if to not in (None, "halpe26"):  # others from COCO-17, the first 17 HALPE-26 joints
            xy, sc, native = xy[..., :17, :], sc[..., :17], "coco17"
    to = to or native
    if to == native:
        return xy, sc, native
    if to == "halpe26":
        return embed(xy, native, to), embed_scores(sc, native, to), to
    try:
        xy, sc = convert(xy, native, to), convert_scores(sc, native, to)
    except ValueError as e:
        raise InputError(None, "to", f"a joint set reachable from {native!r}", e) from None
    return xy, np.where(np.isnan(xy).any(-1), 0.0, sc), to
