"""3D poses out (NPZ, JSON, OpenSim TRC, C3D, BVH) and back in (NPZ, JSON, TRC).

A :class:`Poses3D` holds world points in metres, shape (T, P, J, 3), NaN where a joint is
missing, with optional per-joint scores, source flags (:class:`JointSource`) and view counts,
and optional per-view records of a run (shape (T, P, V): which 2D person of each view a track
used, how many of its keypoints the estimator left out, and how the view's 2D relates to the
3D, :class:`ViewStatus`) and per-person heights.

File formats, chosen from the extension by :func:`save_poses`:

``.npz``, ``.json``
    Everything in the dataclass, in metres. The JSON names its ``units`` and the skeleton's
    ``joints``, writes ``null`` for a missing coordinate, and lists the flag values. With a
    ``view_status`` it lists the status values and adds ``suspect`` (T, P, J): the joints
    present in a frame where at least one view disagrees with the person's 3D (derived
    on writing, ignored on reading). Files without the per-view fields load as before.
``.trc``
    OpenSim marker trajectories: tab-separated, the header lines ``PathFileType 4 (X/Y/Z)
    <file name>``, ``DataRate CameraRate NumFrames NumMarkers Units OrigDataRate
    OrigDataStartFrame OrigNumFrames`` and their values, the row ``Frame# Time <marker>...``
    (each marker name over its three columns), the row ``X1 Y1 Z1 X2 ...``, a blank line,
    then one row per frame. ``Frame#`` is the rmpl frame number + 1 (TRC counts from 1) and
    ``Time`` is frame / fps. A missing marker is three empty fields, which OpenSim reads as
    NaN; every field of a data row is followed by a tab, as OpenSim itself writes, so that a
    row whose last marker is missing still has all its fields. Markers are the skeleton's
    joint names; with more than one person each gets a suffix ``_p<person id>``. Units are
    ``m`` (default) or ``mm``. Scores, flags and view counts are not stored.
``.c3d``
    Through the ``c3d`` package: float points in ``m`` or ``mm`` (``POINT:UNITS``), labels as
    in TRC, residual -1 for a missing point and 0 otherwise (0 means "computed, not
    measured" in C3D). C3D frames are contiguous and count from 1: the file spans frames
    ``frames[0] + 1`` to ``frames[-1] + 1``, frames in between that are not in the poses are
    written missing.

``.bvh``
    One person's COCO-17 joints (HALPE-26 poses: their first 17; head top, neck, mid-hip and
    feet are not in the BVH hierarchy) as a skeleton with constant bone lengths and per-frame joint
    rotations, fitted by :mod:`rmpl.io.bvh`; ``m`` (default) or ``mm``; contiguous frames
    from ``frames[0]`` to ``frames[-1]`` (missing ones interpolated).

``up_axis``: rmpl writes world coordinates as they are (``None``, the default). OpenSim
expects +Y up; when the world is Z-up (Shelf, Pose2Sim's Qualisys calibrations)
``up_axis="y"`` rotates it by -90 degrees about X for TRC, C3D and BVH: ``(x, y, z) -> (x, z,
-y)``. Pass the same ``up_axis`` to :func:`load_poses` to rotate a TRC back.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path, finish_commit
from rmpl.io.keypoints import (
    _check_fps,
    _check_frames,
    _check_missing,
    _check_skeleton,
    _floats,
    _fps_from_npz,
    _json_array,
    _json_floats,
    _npz_fps,
    _npz_get,
    _npz_str,
    _open_npz,
    _read_json,
    _with_path,
)
from rmpl.skeleton import SKELETONS

__all__ = ["JointSource", "POSE_FORMATS", "Poses3D", "ViewStatus", "load_poses", "save_poses"]

POSE_FORMATS = ("npz", "json", "trc", "c3d", "bvh")
#: The optional arrays of :class:`Poses3D`, stored as they are in NPZ and JSON.
_OPTIONAL = (
    "scores",
    "flags",
    "num_views",
    "uncertainty",
    "membership",
    "views_excluded",
    "view_status",
    "heights",
)
_TAG = "rmpl.poses3d"
_UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}  # metres per unit
_TRC_KEYS = (
    "DataRate",
    "CameraRate",
    "NumFrames",
    "NumMarkers",
    "Units",
    "OrigDataRate",
    "OrigDataStartFrame",
    "OrigNumFrames",
)
# Z-up world -> Y-up file: rotation by -90 degrees about X, (x, y, z) -> (x, z, -y).
_C3D_MAX_ITEMS = 255  # a C3D parameter dimension is one unsigned byte
_Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


class JointSource(IntEnum):
    """Where a 3D joint came from, stored per joint in :attr:`Poses3D.flags` (uint8)."""

    MISSING = 0  #: no estimate; the point is NaN
    LIFTED = 1  #: predicted by the lifter
    TRIANGULATED = 2  #: triangulated from the 2D keypoints
    INTERPOLATED = 3  #: filled in from neighbouring frames


class ViewStatus(IntEnum):
    """How one view's 2D relates to one tracked person in one frame, stored in
    :attr:`Poses3D.view_status` (uint8); :mod:`rmpl.pipeline.consistency` decides it."""

    ABSENT = 0  #: the person has no 3D in this frame
    AGREES = 1  #: the view's 2D of the person lies near the 3D the other views support
    DISAGREES = 2  #: it lies far from it: another person, or a gross detection error
    MISSED = 3  #: no 2D of the person in the view, though its 3D projects into the image
    OUT_OF_VIEW = 4  #: no 2D, and its 3D projects outside the image or behind the camera
    UNCHECKED = 5  #: 2D present, but too few joints or views to compare it


@dataclass
class Poses3D:
    """3D poses of every frame and person.

    Attributes:
        points: world coordinates in metres, shape (T, P, J, 3); NaN = missing.
        scores: per-joint confidence, shape (T, P, J), finite and >= 0; or None.
        flags: :class:`JointSource` per joint, shape (T, P, J), uint8; MISSING exactly where
            the point is NaN; or None.
        num_views: number of views that saw each joint, shape (T, P, J); or None.
        skeleton: joint set, a key of :data:`rmpl.skeleton.SKELETONS`.
        frames: frame numbers, shape (T,), strictly increasing (default 0..T-1).
        fps: frames per second, or None (then TRC and C3D cannot be written).
        person_ids: identity of each person, shape (P,), distinct (default 0..P-1).
        uncertainty: the predicted 50% error radius of each joint, metres, shape (T, P, J):
            half of the time the joint is closer than this to the truth (the temporal
            lifter's calibrated uncertainty); NaN where the point is NaN or has none; or None.
        membership: which 2D person of each view the track used, shape (T, P, V) int: the
            index on the people axis of the run's 2D input (``Keypoints2D.keypoints[t, v,
            membership[t, p, v]]``), -1 where none; or None.
        views_excluded: per view, how many of the person's 2D keypoints (confidence > 0)
            the estimator left out of a joint it estimated (robust triangulation's view
            exclusion, a confidence threshold), shape (T, P, V) int; or None.
        view_status: :class:`ViewStatus` per view, shape (T, P, V), uint8; ABSENT exactly
            where the person has no joint in the frame; or None.
        camera_names: the V views' names, in the order of the per-view fields; or None.
        heights: each person's estimated standing height, metres, shape (P,); NaN where
            unknown (:func:`rmpl.anthropometry.estimate_height`); or None.
        identity: how the tracks were formed (:meth:`rmpl.pipeline.identity.Identities.to_json`:
            fragments, merges, drops), for the run report; or None. Not saved in the files.
    """

    points: np.ndarray
    scores: np.ndarray | None = None
    flags: np.ndarray | None = None
    num_views: np.ndarray | None = None
    skeleton: str = "coco17"
    frames: np.ndarray | None = None
    fps: float | None = None
    person_ids: np.ndarray | None = None
    uncertainty: np.ndarray | None = None
    membership: np.ndarray | None = None
    views_excluded: np.ndarray | None = None
    view_status: np.ndarray | None = None
    camera_names: tuple[str, ...] | None = None
    heights: np.ndarray | None = None
    identity: dict | None = None

    def __post_init__(self) -> None:
        pts = _floats(self.points, "points")
        if pts.ndim != 4 or pts.shape[-1] != 3:
            raise InputError(None, "points", "shape (T, P, J, 3)", pts.shape)
        T, P, J, _ = pts.shape
        _check_skeleton(self.skeleton, J)
        scores = None if self.scores is None else _per_joint(self.scores, pts, "scores")
        _check_missing(pts, None, "points", "scores")
        if scores is not None and not (np.isfinite(scores).all() and (scores >= 0).all()):
            raise InputError(None, "scores", "finite scores >= 0", "NaN, inf or negative")
        self.points, self.scores = pts, scores
        self.flags = _check_flags(self.flags, pts)
        self.num_views = _check_counts(self.num_views, pts)
        self.frames = _check_frames(self.frames, T)
        self.fps = _check_fps(self.fps)
        self.person_ids = _check_ids(self.person_ids, P)
        self.uncertainty = _check_uncertainty(self.uncertainty, pts)
        self._check_per_view(pts)
        self.heights = _check_heights(self.heights, P)

    def _check_per_view(self, pts: np.ndarray) -> None:
        """The (T, P, V) fields share one V, the camera names too."""
        T, P = pts.shape[:2]
        views = set()
        for field in ("membership", "views_excluded", "view_status"):
            a = getattr(self, field)
            if a is None:
                continue
            a = _floats(a, field)
            if a.ndim != 3 or a.shape[:2] != (T, P):
                raise InputError(None, field, f"shape ({T}, {P}, V) (T, P, views)", a.shape)
            if not (np.isfinite(a).all() and (a == np.round(a)).all()):
                raise InputError(None, field, "integers", "other values")
            views.add(a.shape[2])
            setattr(self, field, a)
        if self.camera_names is not None:
            names = self.camera_names
            if isinstance(names, np.ndarray):
                names = names.tolist()
            if isinstance(names, str) or not all(isinstance(n, str) for n in names):
                raise InputError(None, "camera_names", "a list of names", names)
            if len(set(names)) != len(names):
                raise InputError(None, "camera_names", "distinct names", list(names))
            self.camera_names = tuple(names)
            views.add(len(names))
        if len(views) > 1:
            raise InputError(
                None, "camera_names", "one number of views V for all per-view fields", sorted(views)
            )
        if self.membership is not None:
            if (self.membership < -1).any():
                raise InputError(None, "membership", "indices >= 0, or -1 for none", "< -1")
            self.membership = self.membership.astype(np.int64)
        if self.views_excluded is not None:
            if (self.views_excluded < 0).any():
                raise InputError(None, "views_excluded", "counts >= 0", "negative")
            self.views_excluded = self.views_excluded.astype(np.int32)
        if self.view_status is not None:
            s = self.view_status
            if ((s < 0) | (s > max(ViewStatus))).any():
                raise InputError(
                    None, "view_status", f"ViewStatus values 0..{int(max(ViewStatus))}", "other"
                )
            absent = np.isnan(pts).all((-1, -2))[..., None]  # (T, P, 1)
            if ((s == ViewStatus.ABSENT) != absent).any():
                raise InputError(
                    None, "view_status", "ABSENT (0) exactly where the person has no joint", "other"
                )
            self.view_status = s.astype(np.uint8)

    def person(self, p: int) -> Poses3D:
        """Person ``p`` (an index, not an id) alone: every per-person field sliced."""

        def one(x):
            return None if x is None else x[:, p : p + 1]

        return dataclasses.replace(
            self,
            points=self.points[:, p : p + 1],
            person_ids=self.person_ids[p : p + 1],
            heights=None if self.heights is None else self.heights[p : p + 1],
            **{k: one(getattr(self, k)) for k in _OPTIONAL if k != "heights"},
        )

    @property
    def num_frames(self) -> int:
        return self.points.shape[0]

    @property
    def num_people(self) -> int:
        return self.points.shape[1]

    @property
    def joint_names(self) -> tuple[str, ...]:
        return SKELETONS[self.skeleton].joints


def _check_uncertainty(u, pts: np.ndarray) -> np.ndarray | None:
    """Radii (T, P, J) >= 0, finite or NaN; NaN wherever the point is."""
    if u is None:
        return None
    a = _per_joint(u, pts, "uncertainty")
    if np.isinf(a).any() or (a < 0).any():
        raise InputError(None, "uncertainty", "radii >= 0 in metres, or NaN", "inf or negative")
    a[np.isnan(pts).any(-1)] = np.nan
    return a


def _per_joint(x, pts: np.ndarray, field: str) -> np.ndarray:
    a = _floats(x, field)
    if a.shape != pts.shape[:-1]:
        raise InputError(None, field, f"shape {pts.shape[:-1]} (T, P, J)", a.shape)
    return a


def _integers(x, pts: np.ndarray, field: str) -> np.ndarray:
    a = _per_joint(x, pts, field)
    if not (np.isfinite(a).all() and (a == np.round(a)).all() and (a >= 0).all()):
        raise InputError(None, field, "integers >= 0", "other values")
    return a


def _check_flags(flags, pts: np.ndarray) -> np.ndarray | None:
    if flags is None:
        return None
    a = _integers(flags, pts, "flags")
    if (a > max(JointSource)).any():
        raise InputError(None, "flags", f"JointSource values 0..{int(max(JointSource))}", a.max())
    if ((a == JointSource.MISSING) != np.isnan(pts).any(-1)).any():
        raise InputError(None, "flags", "MISSING (0) exactly where the point is NaN", "other")
    return a.astype(np.uint8)


def _check_counts(counts, pts: np.ndarray) -> np.ndarray | None:
    return None if counts is None else _integers(counts, pts, "num_views").astype(np.int32)


def _check_heights(heights, num_people: int) -> np.ndarray | None:
    if heights is None:
        return None
    a = _floats(heights, "heights")
    if a.shape != (num_people,):
        raise InputError(None, "heights", f"shape ({num_people},), one per person", a.shape)
    if np.isinf(a).any() or (a <= 0).any():
        raise InputError(None, "heights", "heights > 0 in metres, or NaN", a.tolist())
    return a


def _check_ids(ids, num_people: int) -> np.ndarray:
    if ids is None:
        return np.arange(num_people, dtype=np.int64)
    a = _floats(ids, "person_ids")
    if a.shape != (num_people,) or not (np.isfinite(a).all() and (a == np.round(a)).all()):
        raise InputError(None, "person_ids", f"{num_people} integers", a.tolist())
    if len(set(a.tolist())) != num_people:
        raise InputError(None, "person_ids", "distinct ids", a.tolist())
    return a.astype(np.int64)


# --------------------------------------------------------------------------- public API


def save_poses(
    poses: Poses3D,
    path: str | Path,
    format: str | None = None,
    *,
    units: str = "m",
    up_axis: str | None = None,
) -> Path:
    """Write poses atomically (nothing is left behind on failure).

    Args:
        poses: what to write.
        path: output file.
        format: ``"npz"``, ``"json"``, ``"trc"``, ``"c3d"`` or ``"bvh"``; from the extension
            when None.
        units: ``"m"`` or ``"mm"`` for TRC, C3D and BVH (NPZ and JSON are always metres).
        up_axis: None writes world axes unchanged; ``"y"`` turns a Z-up world Y-up for
            OpenSim (TRC and C3D only), see the module docstring.

    Returns:
        The path written.
    """
    path = Path(path)
    fmt = _format_of(path, format)
    if units not in ("m", "mm") or (units != "m" and fmt in ("npz", "json")):
        raise InputError(path, "units", "'m' or 'mm' (TRC/C3D; NPZ/JSON are metres)", units)
    if up_axis not in (None, "z", "y") or (up_axis == "y" and fmt in ("npz", "json")):
        raise InputError(path, "up_axis", "None, 'z' or 'y' (TRC/C3D only)", up_axis)
    try:
        poses = dataclasses.replace(poses)  # validate again: fields may have changed since
    except InputError as e:
        raise _with_path(e, path) from None
    if fmt in ("trc", "c3d", "bvh"):
        _check_trajectories(poses, path)
    if fmt == "bvh":
        _check_bvh(poses, path)
    if fmt == "c3d" and poses.frames[0] < 0:
        raise InputError(path, "frames", "frame numbers >= 0 for C3D", int(poses.frames[0]))
    with atomic_path(path) as tmp:
        if fmt == "npz":
            _write_npz(poses, tmp)
        elif fmt == "json":
            # dumps, not dump: the same text from json's C encoder, many times faster
            tmp.write_text(json.dumps(_json_doc(poses), allow_nan=False), encoding="utf-8")
        elif fmt == "trc":
            tmp.write_text(_trc_text(poses, path.name, units, up_axis), encoding="utf-8")
        elif fmt == "bvh":
            tmp.write_text(_bvh_text(poses, units, up_axis), encoding="utf-8")
        else:
            _write_c3d(poses, tmp, units, up_axis)
    return path


def load_poses(
    path: str | Path, format: str | None = None, *, up_axis: str | None = None
) -> Poses3D:
    """Read poses written by :func:`save_poses` (NPZ, JSON or TRC).

    Args:
        path: the file.
        format: ``"npz"``, ``"json"`` or ``"trc"``; from the extension when None.
        up_axis: ``"y"`` when the TRC was written with ``up_axis="y"``: rotates it back to a
            Z-up world.

    Returns:
        A :class:`Poses3D` in metres. A TRC gives no scores, flags or view counts; its
        markers must be one of rmpl's skeletons, per person (suffix ``_p<id>``) when several.

    Raises:
        InputError: a missing or malformed file, naming the file and the field.
    """
    path = Path(path)
    fmt = _format_of(path, format)
    if fmt in ("c3d", "bvh"):
        raise InputError(path, None, f"an .npz, .json or .trc file ({fmt} is write-only)", fmt)
    if up_axis not in (None, "z", "y") or (up_axis == "y" and fmt != "trc"):
        raise InputError(path, "up_axis", "None, 'z' or 'y' (TRC only)", up_axis)
    finish_commit(path.parent)  # a run killed while committing its outputs
    if not path.is_file():
        raise InputError(path, None, "an existing file", "no such file")
    fields = {"npz": _npz_fields, "json": _json_fields, "trc": _trc_fields}[fmt](path)
    if up_axis == "y":
        fields["points"] = fields["points"] @ _Z_UP_TO_Y_UP  # row vectors: R^T undoes R
    try:
        return Poses3D(**fields)
    except InputError as e:
        raise _with_path(e, path) from None


def _format_of(path: Path, format: str | None) -> str:
    fmt = format or path.suffix.lower().lstrip(".")
    if fmt not in POSE_FORMATS:
        raise InputError(path, "format", f"one of {POSE_FORMATS} (or that extension)", fmt)
    return fmt


def _check_trajectories(poses: Poses3D, path: Path) -> None:
    if poses.fps is None:
        raise InputError(path, "fps", "a frame rate in Poses3D.fps for TRC and C3D files")
    if poses.points.shape[0] == 0 or poses.points.shape[1] == 0:
        raise InputError(path, "points", "at least one frame and one person", poses.points.shape)


def _marker_names(poses: Poses3D) -> list[str]:
    joints = poses.joint_names
    if poses.num_people == 1:
        return list(joints)
    return [f"{j}_p{pid}" for pid in poses.person_ids.tolist() for j in joints]


def _file_points(poses: Poses3D, units: str, up_axis: str | None) -> np.ndarray:
    """World metres -> file units and axes, shape (T, P * J, 3)."""
    pts = poses.points @ _Z_UP_TO_Y_UP.T if up_axis == "y" else poses.points
    return pts.reshape(pts.shape[0], -1, 3) / _UNITS[units]


# --------------------------------------------------------------------------- npz / json


def _write_npz(poses: Poses3D, tmp: Path) -> None:
    optional = {k: getattr(poses, k) for k in _OPTIONAL}
    if poses.camera_names is not None:
        optional["camera_names"] = np.array(poses.camera_names)
    with open(tmp, "wb") as f:
        np.savez_compressed(
            f,
            format=np.array(_TAG),
            units=np.array("m"),
            points=poses.points,
            skeleton=np.array(poses.skeleton),
            frames=poses.frames,
            fps=_npz_fps(poses.fps),
            person_ids=poses.person_ids,
            **{k: v for k, v in optional.items() if v is not None},
        )


def _npz_fields(path: Path) -> dict:
    data = _open_npz(path)
    units = _npz_str(data, "units", path)
    if units not in _UNITS:
        raise InputError(path, "units", f"one of {sorted(_UNITS)}", units)
    return dict(
        points=_npz_get(data, "points", path) * _UNITS[units],
        scores=data.get("scores"),
        flags=data.get("flags"),
        num_views=data.get("num_views"),
        skeleton=_npz_str(data, "skeleton", path),
        frames=_npz_get(data, "frames", path),
        fps=_fps_from_npz(_npz_get(data, "fps", path), path),
        person_ids=_npz_get(data, "person_ids", path),
        uncertainty=data.get("uncertainty"),
        membership=data.get("membership"),
        views_excluded=data.get("views_excluded"),
        view_status=data.get("view_status"),
        camera_names=_npz_names(data, path),
        heights=data.get("heights"),
    )


def _npz_names(data: dict, path: Path) -> list[str] | None:
    a = data.get("camera_names")
    if a is None:
        return None
    if a.ndim != 1 or a.dtype.kind != "U":
        raise InputError(path, "camera_names", "a list of names", a.dtype)
    return a.tolist()


def _json_doc(poses: Poses3D) -> dict:
    def opt(a):
        return None if a is None else a.tolist()

    return {
        "format": _TAG,
        "version": 1,
        "units": "m",
        "skeleton": poses.skeleton,
        "joints": list(poses.joint_names),
        "fps": poses.fps,
        "frames": poses.frames.tolist(),
        "person_ids": poses.person_ids.tolist(),
        "points": _json_floats(poses.points),
        "scores": opt(poses.scores),
        "flags": opt(poses.flags),
        "flag_values": {s.name.lower(): int(s) for s in JointSource},
        "num_views": opt(poses.num_views),
        "uncertainty": None if poses.uncertainty is None else _json_floats(poses.uncertainty),
        **_json_views(poses),
    }


def _json_views(poses: Poses3D) -> dict:
    """The per-view fields, heights and the derived ``suspect`` joints (only those present)."""
    doc = {}
    if poses.camera_names is not None:
        doc["camera_names"] = list(poses.camera_names)
    for key in ("membership", "views_excluded"):
        if getattr(poses, key) is not None:
            doc[key] = getattr(poses, key).tolist()
    if poses.view_status is not None:
        doc["view_status"] = poses.view_status.tolist()
        doc["view_status_values"] = {s.name.lower(): int(s) for s in ViewStatus}
        disagrees = (poses.view_status == ViewStatus.DISAGREES).any(-1)  # (T, P)
        doc["suspect"] = (disagrees[..., None] & ~np.isnan(poses.points).any(-1)).tolist()
    if poses.heights is not None:
        doc["heights"] = _json_floats(poses.heights)
    return doc


def _json_fields(path: Path) -> dict:
    doc = _read_json(path)
    if not isinstance(doc, dict):
        raise InputError(path, None, "a JSON object (rmpl poses)", type(doc).__name__)
    for key in ("units", "skeleton", "frames", "person_ids", "points"):
        if key not in doc:
            raise InputError(path, key, "a value (rmpl poses JSON)", "no such key")
    if doc["units"] not in _UNITS:
        raise InputError(path, "units", f"one of {sorted(_UNITS)}", doc["units"])
    if doc["skeleton"] not in SKELETONS:
        raise InputError(path, "skeleton", f"one of {sorted(SKELETONS)}", doc["skeleton"])
    for key in ("frames", "person_ids"):
        if not isinstance(doc[key], list):
            raise InputError(path, key, "a list", type(doc[key]).__name__)
    shape = (len(doc["frames"]), len(doc["person_ids"]), SKELETONS[doc["skeleton"]].num_joints)

    def opt(key):
        return None if doc.get(key) is None else _json_array(doc, key, shape, path)

    names = doc.get("camera_names")
    if names is not None and not isinstance(names, list):
        raise InputError(path, "camera_names", "a list of names", type(names).__name__)

    def per_view(key):  # (T, P, V), V from the camera names or the first row
        if doc.get(key) is None:
            return None
        if names is not None:
            V = len(names)
        else:
            try:
                V = len(doc[key][0][0])
            except (TypeError, IndexError, KeyError):
                V = 0
        return _json_array(doc, key, (*shape[:2], V), path)

    return dict(
        points=_json_array(doc, "points", (*shape, 3), path) * _UNITS[doc["units"]],
        scores=opt("scores"),
        flags=opt("flags"),
        num_views=opt("num_views"),
        skeleton=doc["skeleton"],
        frames=doc["frames"],
        fps=doc.get("fps"),
        person_ids=doc["person_ids"],
        uncertainty=opt("uncertainty"),
        membership=per_view("membership"),
        views_excluded=per_view("views_excluded"),
        view_status=per_view("view_status"),
        camera_names=names,
        heights=None
        if doc.get("heights") is None
        else _json_array(doc, "heights", shape[1:2], path),
    )


# --------------------------------------------------------------------------- TRC


def _trc_text(poses: Poses3D, name: str, units: str, up_axis: str | None) -> str:
    pts = _file_points(poses, units, up_axis)  # (T, M, 3)
    T, M, _ = pts.shape
    markers = _marker_names(poses)
    rate = f"{poses.fps:.12g}"
    header = [
        f"PathFileType\t4\t(X/Y/Z)\t{name}",
        "\t".join(_TRC_KEYS),
        "\t".join([rate, rate, str(T), str(M), units, rate, str(poses.frames[0] + 1), str(T)]),
        "\t".join(["Frame#", "Time", *(f"{m}\t\t" for m in markers)]),
        # ends with a tab like the data rows: Pose2Sim's reader counts the columns here
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, M + 1)) + "\t",
        "",
    ]
    decimals = 6 if units == "m" else 3  # micrometres either way
    text = np.char.mod(f"%.{decimals}f", pts.reshape(T, 3 * M))
    text[np.isnan(pts.reshape(T, 3 * M))] = ""
    time = np.char.mod("%.6f", poses.frames / poses.fps)
    rows = [
        f"{f + 1}\t{t}\t" + "".join(v + "\t" for v in row)
        for f, t, row in zip(poses.frames.tolist(), time, text.tolist(), strict=True)
    ]
    return "\n".join(header + rows) + "\n"


def _trc_fields(path: Path) -> dict:
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(path, None, "a readable text TRC file", e) from None
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise InputError(
            path,
            "PathFileType",
            "a TRC header starting 'PathFileType'",
            lines[0][:40] if lines else "an empty file",
        )
    keys = [k for k in lines[1].split() if k]
    if tuple(keys) != _TRC_KEYS:
        raise InputError(path, "line 2", " ".join(_TRC_KEYS), " ".join(keys))
    values = dict(zip(_TRC_KEYS, lines[2].split(), strict=False))
    try:
        rate, T, M = float(values["DataRate"]), int(values["NumFrames"]), int(values["NumMarkers"])
    except (KeyError, ValueError):
        raise InputError(
            path, "line 3", "DataRate, NumFrames and NumMarkers numbers", lines[2]
        ) from None
    units = values.get("Units")
    if units not in _UNITS:
        raise InputError(path, "Units", f"one of {sorted(_UNITS)}", units)
    labels = [x.strip() for x in lines[3].split("\t") if x.strip()]
    if labels[:2] != ["Frame#", "Time"] or len(labels) != M + 2:
        raise InputError(path, "line 4", f"Frame#, Time and {M} marker names", len(labels))
    rows = [ln for ln in lines[5:] if ln.strip()]
    if len(rows) != T:
        raise InputError(path, "NumFrames", f"{T} data rows as the header says", len(rows))
    data = np.full((T, 2 + 3 * M), np.nan)
    for i, row in enumerate(rows):
        fields = [x.strip() for x in row.split("\t")]
        if len(fields) == 3 * M + 3 and fields[-1] == "":
            fields.pop()  # the tab after the last field
        if len(fields) != 3 * M + 2:
            raise InputError(
                path, f"data row {i + 1}", f"{3 * M + 2} tab-separated fields", len(fields)
            )
        try:
            data[i] = [float(x) if x else np.nan for x in fields]
        except ValueError:
            raise InputError(path, f"data row {i + 1}", "numbers or empty fields", row) from None
    skeleton, ids = _people_from_markers(labels[2:], path)
    points = data[:, 2:].reshape(T, len(ids), -1, 3) * _UNITS[units]
    frames = data[:, 0] - 1
    return dict(points=points, skeleton=skeleton, frames=frames, fps=rate, person_ids=ids)


def _people_from_markers(markers: list[str], path: Path) -> tuple[str, list[int]]:
    """Marker names -> skeleton name and person ids (``joint`` or ``joint_p<id>``)."""
    by_joints = {s.joints: s.name for s in SKELETONS.values()}
    if tuple(markers) in by_joints:
        return by_joints[tuple(markers)], [0]
    for joints, name in by_joints.items():
        J = len(joints)
        if len(markers) % J:
            continue
        ids = [m.rpartition("_p")[2] for m in markers[::J]]
        if not all(i.isdigit() for i in ids):
            continue
        want = [f"{j}_p{i}" for i in ids for j in joints]
        if markers == want:
            return name, [int(i) for i in ids]
    raise InputError(
        path,
        "marker names",
        "the joints of an rmpl skeleton, per person with the suffix _p<id>",
        markers[:4],
    )


# --------------------------------------------------------------------------- C3D


def _write_c3d(poses: Poses3D, tmp: Path, units: str, up_axis: str | None) -> None:
    import c3d

    pts = _file_points(poses, units, up_axis).astype(np.float32)  # (T, M, 3)
    first, last = int(poses.frames[0]), int(poses.frames[-1])
    block = np.zeros((last - first + 1, pts.shape[1], 5), np.float32)
    block[..., 3] = -1.0  # residual -1: no point
    rows = poses.frames - first
    ok = ~np.isnan(pts).any(-1)
    block[rows, :, :3] = np.where(ok[..., None], pts, 0.0)
    block[rows, :, 3] = np.where(ok, 0.0, -1.0)
    writer = c3d.Writer(point_rate=poses.fps, analog_rate=0.0, point_units=units)
    _c3d_labels(writer, _marker_names(poses))
    writer.set_start_frame(first + 1)
    no_analog = np.zeros((0, 0), np.float32)
    writer.add_frames([(frame, no_analog) for frame in block])
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "No analog data", UserWarning)
        with open(tmp, "wb") as f:
            writer.write(f)


def _c3d_labels(writer, labels: list[str]) -> None:
    """POINT:LABELS and POINT:DESCRIPTIONS, 255 a parameter (a C3D dimension is one byte):
    the points after the first 255 go to LABELS2, LABELS3, ... (DESCRIPTIONS2, ...), the
    extension C3D readers (Vicon, Motion Lab's C3D spec, ezc3d) follow."""
    group = writer.point_group
    for i in range(0, len(labels), _C3D_MAX_ITEMS):
        suffix = "" if i == 0 else str(i // _C3D_MAX_ITEMS + 1)
        chunk = labels[i : i + _C3D_MAX_ITEMS]
        text, size = writer.pack_labels(chunk)
        group.add_str(f"LABELS{suffix}", "Point labels.", text, size, len(chunk))
        blank = " " * len(chunk)
        group.add_str(f"DESCRIPTIONS{suffix}", "Point descriptions.", blank, 1, len(chunk))


# --------------------------------------------------------------------------- BVH


def _check_bvh(poses: Poses3D, path: Path) -> None:
    if poses.skeleton not in ("coco17", "halpe26"):
        raise InputError(path, "skeleton", "coco17 or halpe26 for BVH", poses.skeleton)
    if poses.num_people != 1:
        raise InputError(path, "points", "one person per BVH file", f"{poses.num_people}")
    seen = ~np.isnan(poses.points[:, 0, [5, 6, 11, 12]]).any(-1)
    if not seen.all(-1).any():
        raise InputError(path, "points", "both hips and both shoulders in some frame", "none")


def _bvh_text(poses: Poses3D, units: str, up_axis: str | None) -> str:
    from rmpl.io.bvh import bvh_text

    first = int(poses.frames[0])
    points = np.full((int(poses.frames[-1]) - first + 1, 17, 3), np.nan)
    points[poses.frames - first] = poses.points[:, 0, :17]  # COCO-17: HALPE-26's first 17
    axes = _Z_UP_TO_Y_UP if up_axis == "y" else None
    return bvh_text(points, poses.fps, scale=1.0 / _UNITS[units], axes=axes)
