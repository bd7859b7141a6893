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
"""

from __future__ import annotations

import logging
import math
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.io.atomic import atomic_path
from rmpl.skeleton import COCO17, flip_left_right

__all__ = [
    "Y_UP_TO_Z_UP",
    "LENGTH_UNITS",
    "PLAUSIBLE_REST_HEIGHT",
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

_log = logging.getLogger(__name__)

#: Rotation taking y-up coordinates to z-up ones: (x, y, z) -> (x, -z, y), det = +1.
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

#: Metres per file length unit, for files that do not say ("cmu" is the CMU ASF unit).
LENGTH_UNITS: dict[str, float] = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": 0.0254 / 0.45,
}
#: Typical vertical extent of a rest pose (soles/toes to head top or eyes), metres.
TYPICAL_REST_HEIGHT = 1.6
#: Rest-pose vertical extents accepted as a human, metres.
PLAUSIBLE_REST_HEIGHT = (1.0, 2.3)

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


@dataclass(frozen=True, eq=False)
class Motion:
    """Joint trajectories of one clip, metres, z up.

    Attributes:
        names: joint names, length J.
        parents: index of each joint's parent joint, -1 for the root, length J.
        positions: joint positions, metres, shape (T, J, 3).
        rotations: rest-relative global segment rotations, shape (T, J, 3, 3).
        rest: rest pose (every rotation identity, root at the origin), metres, shape (J, 3).
        fps: frames per second.
        source: the file the motion came from.
        scale: metres per file length unit.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    positions: np.ndarray
    rotations: np.ndarray
    rest: np.ndarray
    fps: float
    source: str
    scale: float

    @property
    def num_frames(self) -> int:
        return self.positions.shape[0]

    def index(self, name: str) -> int:
        """Index of the joint called ``name``."""
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{self.source}: no joint {name!r}") from None


# ----------------------------------------------------------------------------- rotations


def _euler(angles: np.ndarray, axes: str, fixed: bool) -> np.ndarray:
    """Rotation from Euler angles, shape (*, K) radians about ``axes`` (K letters) -> (*, 3, 3).

    ``fixed``: the first listed rotation acts first about the fixed parent axes (Acclaim),
    so R = R_K ... R_1. Otherwise the axes move with the joint (BVH): R = R_1 ... R_K.
    Rotations are right-handed (counter-clockwise looking down the axis).

    >>> x, angles = np.array([1.0, 0.0, 0.0]), np.radians([90.0, 90.0])
    >>> (np.round(_euler(angles, "xz", fixed=True) @ x, 6) + 0.0).tolist()  # Rz Rx x = y
    [0.0, 1.0, 0.0]
    >>> (np.round(_euler(angles, "xz", fixed=False) @ x, 6) + 0.0).tolist()  # Rx Rz x = z
    [0.0, 0.0, 1.0]
    """
    angles = np.asarray(angles, dtype=float)
    R = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for n, axis in enumerate(axes):
        i = "xyz".index(axis)
        j, k = (i + 1) % 3, (i + 2) % 3
        c, s = np.cos(angles[..., n, None]), np.sin(angles[..., n, None])  # (*, 1)
        if fixed:  # R <- R_axis @ R mixes rows j and k
            rj, rk = R[..., j, :].copy(), R[..., k, :].copy()
            R[..., j, :], R[..., k, :] = c * rj - s * rk, s * rj + c * rk
        else:  # R <- R @ R_axis mixes columns j and k
            cj, ck = R[..., :, j].copy(), R[..., :, k].copy()
            R[..., :, j], R[..., :, k] = c * cj + s * ck, c * ck - s * cj
    return R


# ---------------------------------------------------------------------- units and axes


def detect_length_unit(height: float) -> tuple[str, float]:
    """The unit of :data:`LENGTH_UNITS` that makes a rest pose of ``height`` file units
    closest (in ratio) to :data:`TYPICAL_REST_HEIGHT`. Returns (name, metres per unit).

    >>> detect_length_unit(172.0), detect_length_unit(66.0)
    (('cm', 0.01), ('inch', 0.0254))
    """
    if not height > 0:
        raise ValueError(f"height must be positive, got {height}")
    name = min(
        LENGTH_UNITS, key=lambda u: abs(math.log(height * LENGTH_UNITS[u] / TYPICAL_REST_HEIGHT))
    )
    return name, LENGTH_UNITS[name]


def _checked_scale(
    path: Path, height: float, stated: float | None, override: float | None
) -> float:
    """Metres per file unit: ``override``, else the file's stated unit, else detected; the
    rest height (file units) must then be human."""
    lo, hi = PLAUSIBLE_REST_HEIGHT
    if override is not None:
        return override
    if stated is not None and lo <= height * stated <= hi:
        return stated
    if stated is not None:
        _log.warning(
            "%s: stated unit gives a %.2f m rest pose; detecting the unit", path, height * stated
        )
    if height <= 0:
        raise InputError(path, "rest pose", "a skeleton with some height", height)
    name, scale = detect_length_unit(height)
    if not lo <= height * scale <= hi:
        raise InputError(
            path,
            "length unit",
            f"a rest pose {lo}-{hi} m tall in one of {sorted(LENGTH_UNITS)} (pass scale=)",
            f"{height:.4g} file units",
        )
    _log.debug("%s: length unit %s (rest height %.2f m)", path, name, height * scale)
    return scale


def _axis_map(up: str) -> tuple[np.ndarray, np.ndarray]:
    """The file-to-world axis rotation as a signed permutation: world axis i = sign[i] *
    file axis perm[i]."""
    A = Y_UP_TO_Z_UP if up == "y" else np.eye(3)
    perm = np.abs(A).argmax(axis=1)
    return perm, A[np.arange(3), perm]


def _points_z_up(P: np.ndarray, scale: float, up: str) -> np.ndarray:
    """File positions, shape (*, 3) -> metres, z up."""
    perm, sign = _axis_map(up)
    return P[..., perm] * (sign * scale)


def _rotations_z_up(R: np.ndarray, up: str) -> np.ndarray:
    """Rest-relative rotations in file axes, shape (*, 3, 3) -> z-up axes (A R A^T)."""
    perm, sign = _axis_map(up)
    return R[..., perm, :][..., perm] * np.outer(sign, sign)


def floor_height(positions: np.ndarray, percentile: float = 5.0) -> float:
    """Height of the floor a clip was captured on: a low percentile of the lowest joint of
    each frame, metres. positions: shape (T, J, 3), z up."""
    return float(np.percentile(positions[..., 2].min(axis=-1), percentile))


# ------------------------------------------------------------------------------ ASF/AMC


@dataclass(frozen=True, eq=False)
class AsfBone:
    """One ASF bone.

    Attributes:
        name: bone name.
        direction: unit direction of the bone in the rest pose, file axes, shape (3,).
        length: bone length, file units.
        axis: the bone's local frame in the rest pose (columns = local axes), shape (3, 3).
        dofs: rotation degrees of freedom in AMC column order, e.g. ("rx", "ry", "rz").
    """

    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray
    dofs: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class AsfSkeleton:
    """An Acclaim skeleton.

    Attributes:
        path: the ASF file.
        bones: bones, parents before children (depth first).
        parents: index of each bone's parent in ``bones``, -1 for the root.
        root_order: AMC root columns, e.g. ("tx", "ty", "tz", "rx", "ry", "rz").
        root_axis: root pre-set orientation (columns = local axes), shape (3, 3).
        root_position: root pre-set position, file units, shape (3,).
        length_unit: ``:units length`` (None when absent): one file unit is 1/length inch.
        angle_unit: radians per ASF angle unit.
    """

    path: str
    bones: tuple[AsfBone, ...]
    parents: tuple[int, ...]
    root_order: tuple[str, ...]
    root_axis: np.ndarray
    root_position: np.ndarray
    length_unit: float | None
    angle_unit: float

    @property
    def metres_per_unit(self) -> float | None:
        """Metres per file unit by the CMU rule (1/``length_unit`` inch), None if unstated."""
        return None if self.length_unit is None else 0.0254 / self.length_unit


_Line = tuple[int, list[str]]  # (1-based line number, tokens)
_ANGLE_UNITS = {"deg": math.pi / 180, "degree": math.pi / 180, "rad": 1.0, "radian": 1.0}


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise InputError(path, None, "a readable file", e.strerror) from None


def _float(path: Path, line: int, field: str, token: str) -> float:
    try:
        value = float(token)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InputError(path, f"line {line}: {field}", "a finite number", repr(token))
    return value


def _floats(path: Path, line: _Line, count: int, field: str) -> np.ndarray:
    ln, toks = line
    if len(toks) - 1 < count:
        raise InputError(
            path, f"line {ln}: {field}", f"{count} numbers", " ".join(toks[1:]) or "none"
        )
    return np.array([_float(path, ln, field, t) for t in toks[1 : count + 1]])


def _asf_sections(path: Path, text: str) -> dict[str, list[_Line]]:
    """Lines of each ``:keyword`` section; the keyword line's own tokens come first."""
    sections: dict[str, list[_Line]] = {}
    current: list[_Line] | None = None
    for ln, raw in enumerate(text.splitlines(), 1):
        toks = raw.split("#", 1)[0].split()
        if not toks:
            continue
        if toks[0].startswith(":"):
            key = toks[0][1:].lower()
            if key in sections:
                raise InputError(path, f"line {ln}: :{key}", "each section once", "a repeat")
            current = sections[key] = [(ln, toks)]
        elif current is None:
            raise InputError(path, f"line {ln}", "a ':keyword' section first", raw.strip())
        else:
            current.append((ln, toks))
    for key in ("root", "bonedata", "hierarchy"):
        if key not in sections:
            raise InputError(path, f":{key}", f"a :{key} section", "end of file")
    return sections


def _asf_units(path: Path, lines: list[_Line] | None) -> tuple[float | None, float]:
    length, angle = None, math.pi / 180  # Acclaim default: degrees
    for ln, toks in (lines or [])[1:]:
        key = toks[0].lower()
        if key == "length":
            length = _floats(path, (ln, toks), 1, ":units length")[0]
            if not length > 0:
                raise InputError(path, f"line {ln}: :units length", "a positive number", length)
        elif key == "angle":
            unit = toks[1].lower() if len(toks) > 1 else ""
            if unit not in _ANGLE_UNITS:
                raise InputError(path, f"line {ln}: :units angle", "deg or rad", unit or "none")
            angle = _ANGLE_UNITS[unit]
    return length, angle


def _axis_order(path: Path, ln: int, field: str, token: str) -> str:
    order = token.lower()
    if sorted(order) != ["x", "y", "z"]:
        raise InputError(path, f"line {ln}: {field}", "an axis order such as XYZ", token)
    return order


def _asf_root(path: Path, lines: list[_Line], angle: float):
    order, axis, position, orientation = None, "xyz", np.zeros(3), np.zeros(3)
    for ln, toks in lines[1:]:
        key = toks[0].lower()
        if key == "order":
            order = tuple(t.lower() for t in toks[1:])
            bad = [t for t in order if t not in ("tx", "ty", "tz", "rx", "ry", "rz")]
            if bad or len(set(order)) != len(order):
                raise InputError(
                    path, f"line {ln}: :root order", "distinct TX TY TZ RX RY RZ", toks[1:]
                )
        elif key == "axis":
            axis = _axis_order(path, ln, ":root axis", toks[1] if len(toks) > 1 else "")
        elif key == "position":
            position = _floats(path, (ln, toks), 3, ":root position")
        elif key == "orientation":
            orientation = _floats(path, (ln, toks), 3, ":root orientation")
    if order is None:
        raise InputError(path, f"line {lines[0][0]}: :root", "an 'order' line", "none")
    angles = np.array([orientation["xyz".index(a)] for a in axis]) * angle
    return order, _euler(angles, axis, fixed=True), position


_BONE_FIELDS = ("id", "name", "direction", "length", "axis", "dof", "limits", "bodymass", "cofmass")


def _asf_bone(path: Path, lines: list[_Line], angle: float) -> AsfBone:
    """One begin..end block (without begin/end) -> bone."""
    start = lines[0][0] - 1
    got: dict[str, object] = {}
    for ln, toks in lines:
        key = toks[0].lower()
        if key.startswith("("):
            continue  # continuation of 'limits'
        if key not in _BONE_FIELDS:
            raise InputError(
                path, f"line {ln}", f"a bone field ({', '.join(_BONE_FIELDS)})", toks[0]
            )
        if key == "name":
            got["name"] = toks[1] if len(toks) > 1 else ""
        elif key == "direction":
            got["direction"] = _floats(path, (ln, toks), 3, "direction")
        elif key == "length":
            got["length"] = _floats(path, (ln, toks), 1, "length")[0]
        elif key == "axis":
            values = _floats(path, (ln, toks), 3, "axis")
            order = _axis_order(path, ln, "axis", toks[4] if len(toks) > 4 else "")
            got["axis"] = _euler(
                np.array([values["xyz".index(a)] for a in order]) * angle, order, fixed=True
            )
        elif key == "dof":
            dofs = tuple(t.lower() for t in toks[1:])
            if any(d not in ("rx", "ry", "rz") for d in dofs) or len(set(dofs)) != len(dofs):
                raise InputError(
                    path,
                    f"line {ln}: dof",
                    "distinct rx ry rz (translation dofs are not supported)",
                    toks[1:],
                )
            got["dof"] = dofs
    for key in ("name", "direction", "length", "axis"):
        if got.get(key) is None or (key == "name" and not got["name"]):
            raise InputError(path, f"bone starting line {start}", f"a '{key}' line", "none")
    d = np.asarray(got["direction"])
    norm = float(np.linalg.norm(d))
    if norm == 0 and got["length"] != 0:
        raise InputError(path, f"bone {got['name']!r} direction", "a non-zero vector", d.tolist())
    return AsfBone(
        str(got["name"]), d / (norm or 1.0), float(got["length"]), got["axis"], got.get("dof", ())
    )


def _asf_bones(path: Path, lines: list[_Line], angle: float) -> list[AsfBone]:
    bones, block = [], None
    for ln, toks in lines[1:]:
        key = toks[0].lower()
        if key == "begin":
            if block is not None:
                raise InputError(path, f"line {ln}", "'end' before the next 'begin'", "begin")
            block = []
        elif key == "end":
            if not block:
                raise InputError(path, f"line {ln}", "a bone between 'begin' and 'end'", "end")
            bones.append(_asf_bone(path, block, angle))
            block = None
        elif block is None:
            raise InputError(path, f"line {ln}", "'begin' opening a bone", toks[0])
        else:
            block.append((ln, toks))
    if block is not None:
        raise InputError(path, ":bonedata", "'end' closing the last bone", "end of section")
    names = [b.name for b in bones]
    if len(set(names)) != len(names) or "root" in names:
        raise InputError(path, ":bonedata", "distinct bone names other than 'root'", names)
    return bones


def _asf_hierarchy(path: Path, lines: list[_Line], names: list[str]) -> dict[str, list[str]]:
    children: dict[str, list[str]] = {}
    parent_of: dict[str, str] = {}
    body = [(ln, t) for ln, t in lines[1:] if t[0].lower() not in ("begin", "end")]
    for ln, toks in body:
        for name in toks:
            if name != "root" and name not in names:
                raise InputError(path, f"line {ln}: :hierarchy", "bone names from :bonedata", name)
        for child in toks[1:]:
            if child in parent_of or child == "root":
                raise InputError(path, f"line {ln}: :hierarchy", "one parent per bone", child)
            parent_of[child] = toks[0]
        children.setdefault(toks[0], []).extend(toks[1:])
    missing = [n for n in names if n not in parent_of]
    if missing:
        raise InputError(path, ":hierarchy", "a parent for every bone", f"none for {missing}")
    return children


def read_asf(path: str | Path) -> AsfSkeleton:
    """Read an Acclaim ASF skeleton.

    Raises:
        InputError: naming the line and keyword of the first problem.
    """
    path = Path(path)
    sections = _asf_sections(path, _read_text(path))
    length, angle = _asf_units(path, sections.get("units"))
    order, root_axis, root_position = _asf_root(path, sections["root"], angle)
    bones = {b.name: b for b in _asf_bones(path, sections["bonedata"], angle)}
    children = _asf_hierarchy(path, sections["hierarchy"], list(bones))
    ordered, parents = [], []

    def visit(name: str, parent: int) -> None:  # depth first, parents before children
        for child in children.get(name, []):
            ordered.append(bones[child])
            parents.append(parent)
            visit(child, len(ordered) - 1)

    visit("root", -1)
    if len(ordered) != len(bones):
        cut = sorted(set(bones) - {b.name for b in ordered})
        raise InputError(path, ":hierarchy", "every bone connected to root", f"cycle through {cut}")
    return AsfSkeleton(
        str(path), tuple(ordered), tuple(parents), order, root_axis, root_position, length, angle
    )


def _amc_columns(skeleton: AsfSkeleton) -> dict[str, tuple[int, int]]:
    """AMC line name -> (first column, number of values) of the per-frame vector."""
    cols = {"root": (0, len(skeleton.root_order))}
    start = len(skeleton.root_order)
    for bone in skeleton.bones:
        if bone.dofs:
            cols[bone.name] = (start, len(bone.dofs))
            start += len(bone.dofs)
    return cols


def read_amc(path: str | Path, skeleton: AsfSkeleton) -> tuple[np.ndarray, float]:
    """Read an AMC motion of ``skeleton``.

    Returns:
        values: shape (T, C): the root columns in ``skeleton.root_order``, then each bone's
            dofs in ``skeleton.bones`` order; angles in file units.
        angle_unit: radians per angle unit (``:RADIANS``/``:DEGREES``, else the ASF's).

    Raises:
        InputError: unknown bone, wrong number of values, a bone missing from a frame, ...
    """
    path = Path(path)
    lines = _read_text(path).splitlines()
    cols = _amc_columns(skeleton)
    C = sum(n for _, n in cols.values())
    first, angle = _amc_header(path, lines, skeleton.angle_unit)
    frame_lines: list[int] = []
    bases: list[int] = []  # flat index of the first value of each bone line
    counts: list[int] = []
    values: list[str] = []
    seen: set[str] = set()
    for i in range(first, len(lines)):
        toks = lines[i].split()
        if not toks:
            continue
        if len(toks) == 1 and toks[0].isdigit():
            frame_lines.append(i + 1)
            seen = set()
            continue
        name = toks[0]
        if name not in cols:
            expected = f"a bone of {Path(skeleton.path).name} with dofs"
            raise InputError(path, f"line {i + 1}", expected, name)
        start, count = cols[name]
        if len(toks) - 1 != count or name in seen:
            got = f"{len(toks) - 1} values" + (", repeated" if name in seen else "")
            raise InputError(path, f"line {i + 1}", f"{count} values for {name!r}, once", got)
        seen.add(name)
        bases.append((len(frame_lines) - 1) * C + start)
        counts.append(count)
        values.extend(toks[1:])
    if not frame_lines:
        raise InputError(path, "frames", "at least one frame number line", "none")
    numbers = _numbers(" ".join(values))
    if numbers is None:
        _raise_first_bad_number(path, lines, first)
    starts = np.repeat(np.cumsum(counts) - counts, counts)  # position of each value's line
    dst = np.repeat(bases, counts) + np.arange(len(numbers)) - starts
    out = np.full(len(frame_lines) * C, np.nan)
    out[dst] = numbers
    out = out.reshape(len(frame_lines), C)
    _check_complete(path, out, frame_lines, cols)
    return out, angle


def _amc_header(path: Path, lines: list[str], angle: float) -> tuple[int, float]:
    """Index of the first frame-number line, and the angle unit the header sets."""
    for i, raw in enumerate(lines):
        s = raw.strip()
        if s.isdigit():
            return i, angle
        if s.upper() in (":DEGREES", ":RADIANS"):
            angle = math.pi / 180 if s.upper() == ":DEGREES" else 1.0
        elif s and not s.startswith(("#", ":")):
            raise InputError(path, f"line {i + 1}", "a header line or a frame number", s[:40])
    return len(lines), angle


def _numbers(text: str) -> np.ndarray | None:
    """The whitespace-separated numbers of ``text``; None if one is not a finite number."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        try:
            out = np.fromstring(text, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    return out if np.isfinite(out).all() else None


def _raise_first_bad_number(path: Path, lines: list[str], first: int) -> None:
    for i in range(first, len(lines)):
        toks = lines[i].split()
        if len(toks) > 1:
            for tok in toks[1:]:
                _float(path, i + 1, "value", tok)
    raise AssertionError("a bad number vanished")  # pragma: no cover


def _check_complete(path: Path, values: np.ndarray, frame_lines: list[int], cols) -> None:
    bad = np.isnan(values)
    if bad.any():
        f, c = np.argwhere(bad)[0]
        bone = next(n for n, (s, k) in cols.items() if s <= c < s + k)
        where = "truncated file" if f == len(frame_lines) - 1 else "every bone in every frame"
        raise InputError(
            path, f"frame at line {frame_lines[f]}", f"a line for {bone!r} ({where})", "none"
        )


def _asf_fk(skeleton: AsfSkeleton, values: np.ndarray, angle: float):
    """Forward kinematics in file units and axes.

    values: AMC columns, shape (T, C). Returns joint names, parents, positions (T, J, 3) and
    rest-relative rotations (T, J, 3, 3).
    """
    T = values.shape[0]
    cols = _amc_columns(skeleton)
    order = skeleton.root_order
    t = np.broadcast_to(skeleton.root_position, (T, 3)).copy()
    for k, ch in enumerate(order):
        if ch[0] == "t":
            t[:, "xyz".index(ch[1])] += values[:, k]
    rot = [k for k, ch in enumerate(order) if ch[0] == "r"]
    M = _euler(values[:, rot] * angle, "".join(order[k][1] for k in rot), fixed=True)
    C0 = skeleton.root_axis
    G = [C0 @ M @ C0.T]  # segment rotation per bone, root first
    ends = [t]  # end point per bone (the root is a point)
    names, parents, P, R = ["root"], [-1], [t], [G[0]]
    has_child = {p for p in skeleton.parents if p >= 0}
    for b, (bone, p) in enumerate(zip(skeleton.bones, skeleton.parents, strict=True)):
        start, k = cols.get(bone.name, (0, 0))
        Mb = _euler(
            values[:, start : start + k] * angle, "".join(d[1] for d in bone.dofs), fixed=True
        )
        C = bone.axis
        Gb = G[p + 1] @ C @ Mb @ C.T  # G[0] is the root, bone b is G[b + 1]
        end = ends[p + 1] + bone.length * (Gb @ bone.direction)
        G.append(Gb)
        ends.append(end)
        names.append(bone.name)
        parents.append(names.index(skeleton.bones[p].name) if p >= 0 else 0)
        P.append(ends[p + 1])
        R.append(Gb)
        if b not in has_child:
            parents.append(len(names) - 1)
            names.append(bone.name + "_end")
            P.append(end)
            R.append(Gb)
    return tuple(names), tuple(parents), np.stack(P, axis=1), np.stack(R, axis=1)


def load_asf_amc(
    asf: str | Path | AsfSkeleton, amc: str | Path, scale: float | None = None, fps: float = 120.0
) -> Motion:
    """Load an Acclaim motion: ASF skeleton + AMC frames -> :class:`Motion` (metres, z up).

    Args:
        asf: the ASF file, or a skeleton from :func:`read_asf` (read once per subject).
        amc: the AMC file.
        scale: metres per file unit; default from ``:units length`` (checked by height).
        fps: frame rate; AMC files do not store it (CMU: 120).
    """
    skeleton = asf if isinstance(asf, AsfSkeleton) else read_asf(asf)
    values, angle = read_amc(amc, skeleton)
    zero = np.zeros((1, values.shape[1]))
    names, parents, rest, _ = _asf_fk(skeleton, zero, angle)
    height = float(np.ptp(rest[0, :, 1]))
    s = _checked_scale(Path(skeleton.path), height, skeleton.metres_per_unit, scale)
    _, _, P, R = _asf_fk(skeleton, values, angle)
    return Motion(
        names,
        parents,
        _points_z_up(P, s, "y"),
        _rotations_z_up(R, "y"),
        _points_z_up(rest[0] - rest[0, 0], s, "y"),
        fps,
        str(amc),
        s,
    )


# ---------------------------------------------------------------------------------- BVH

_CHANNELS = {
    f"{a}{kind}": f"{a.lower()}{kind[0]}" for a in "XYZ" for kind in ("position", "rotation")
}


@dataclass(frozen=True, eq=False)
class _BvhNode:
    name: str
    parent: int
    offset: np.ndarray  # (3,) file units
    channels: tuple[str, ...]  # "xp" = Xposition, "zr" = Zrotation, ...


class _Tokens:
    """Header tokens with their line numbers."""

    def __init__(self, path: Path, lines: list[str]) -> None:
        self.path = path
        self.items = [(t, n) for n, line in enumerate(lines, 1) for t in line.split()]
        self.pos = 0

    def peek(self) -> str:
        return self.items[self.pos][0] if self.pos < len(self.items) else ""

    def line(self) -> int:
        return self.items[min(self.pos, len(self.items) - 1)][1] if self.items else 1

    def take(self, what: str) -> str:
        """The next token, whatever it is; ``what`` describes it for the error."""
        if self.pos >= len(self.items):
            raise InputError(self.path, f"line {self.line()}", what, "end of file")
        self.pos += 1
        return self.items[self.pos - 1][0]

    def expect(self, word: str) -> None:
        """Consume the keyword ``word`` (any case)."""
        line, tok = self.line(), self.take(repr(word))
        if tok.upper() != word.upper():
            raise InputError(self.path, f"line {line}", repr(word), tok)

    def numbers(self, count: int, field: str) -> np.ndarray:
        return np.array(
            [_float(self.path, self.line(), field, self.take(field)) for _ in range(count)]
        )


def _bvh_joint(tok: _Tokens, name: str, parent: int, nodes: list[_BvhNode]) -> None:
    tok.expect("{")
    tok.expect("OFFSET")
    offset = tok.numbers(3, "OFFSET")
    index = len(nodes)
    channels: tuple[str, ...] = ()
    if tok.peek().upper() == "CHANNELS":
        tok.take("CHANNELS")
        line = tok.line()
        n = tok.take("number of channels")
        if not n.isdigit():
            raise InputError(tok.path, f"line {line}: CHANNELS", "a channel count", n)
        names = [tok.take("channel name") for _ in range(int(n))]
        bad = [c for c in names if c not in _CHANNELS]
        if bad or len(set(names)) != len(names):
            raise InputError(
                tok.path,
                f"line {line}: CHANNELS",
                f"{n} distinct channel names such as Xposition, Zrotation",
                " ".join(names),
            )
        channels = tuple(_CHANNELS[c] for c in names)
    nodes.append(_BvhNode(name, parent, offset, channels))
    ends = 0
    while tok.peek() != "}":
        kind = tok.take("JOINT, End Site or }")
        if kind.upper() == "JOINT":
            _bvh_joint(tok, tok.take("joint name"), index, nodes)
        elif kind.upper() == "END":
            tok.expect("Site")
            tok.expect("{")
            tok.expect("OFFSET")
            end_offset = tok.numbers(3, "OFFSET")
            tok.expect("}")
            nodes.append(
                _BvhNode(f"{name}_end" + (f"{ends}" if ends else ""), index, end_offset, ())
            )
            ends += 1
        else:
            raise InputError(tok.path, f"line {tok.line()}", "JOINT, End Site or }", kind)
    tok.expect("}")


def _bvh_header(path: Path, lines: list[str]) -> list[_BvhNode]:
    tok = _Tokens(path, lines)
    tok.expect("HIERARCHY")
    tok.expect("ROOT")
    nodes: list[_BvhNode] = []
    _bvh_joint(tok, tok.take("root name"), -1, nodes)
    if tok.peek():
        raise InputError(path, f"line {tok.line()}", "MOTION after the one ROOT", tok.peek())
    names = [n.name for n in nodes]
    if len(set(names)) != len(names):
        raise InputError(path, "HIERARCHY", "distinct joint names", names)
    return nodes


def _bvh_motion(
    path: Path, lines: list[str], start: int, num_channels: int
) -> tuple[np.ndarray, float]:
    """Parse from the MOTION line (index ``start``): values (T, C) and the frame time."""

    def field(i: int, key: str) -> str:
        text = lines[i].strip() if i < len(lines) else ""
        if not text.lower().startswith(key.lower()):
            raise InputError(path, f"line {i + 1}", f"'{key} ...'", text[:40] or "end of file")
        return text[len(key) :].strip()

    frames_text, dt_text = field(start + 1, "Frames:"), field(start + 2, "Frame Time:")
    if not frames_text.isdigit():
        raise InputError(path, f"line {start + 2}: Frames", "a frame count", frames_text)
    dt = _float(path, start + 3, "Frame Time", dt_text)
    if not dt > 0:
        raise InputError(path, f"line {start + 3}: Frame Time", "a positive number", dt)
    T = int(frames_text)
    rows = [i for i in range(start + 3, len(lines)) if lines[i].strip()]
    if len(rows) != T:
        raise InputError(
            path,
            "Frames",
            f"{T} motion lines (as 'Frames:' says)",
            f"{len(rows)}" + (" (truncated file)" if len(rows) < T else ""),
        )
    try:  # the C parser checks every row has the same number of columns
        values = np.loadtxt([lines[i] for i in rows], ndmin=2)
    except ValueError:
        values = np.empty((0, 0))
    if values.shape != (T, num_channels) or not np.isfinite(values).all():
        for i in rows:
            toks = lines[i].split()
            if len(toks) != num_channels:
                expected = f"{num_channels} values (one per channel)"
                raise InputError(path, f"line {i + 1}", expected, len(toks))
            for t in toks:
                _float(path, i + 1, "motion value", t)
    return values, dt


def _bvh_fk(nodes: list[_BvhNode], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics in file units and axes. values: (T, C) -> positions (T, J, 3),
    rotations (T, J, 3, 3). Position channels replace the OFFSET on their axis."""
    T, col = values.shape[0], 0
    P = np.empty((T, len(nodes), 3))
    R = np.empty((T, len(nodes), 3, 3))
    for j, node in enumerate(nodes):
        v = values[:, col : col + len(node.channels)]
        col += len(node.channels)
        t = np.broadcast_to(node.offset, (T, 3)).copy()
        rot = [k for k, c in enumerate(node.channels) if c[1] == "r"]
        for k, c in enumerate(node.channels):
            if c[1] == "p":
                t[:, "xyz".index(c[0])] = v[:, k]
        Rl = _euler(np.deg2rad(v[:, rot]), "".join(node.channels[k][0] for k in rot), fixed=False)
        if node.parent < 0:
            P[:, j], R[:, j] = t, Rl
        else:
            Rp = R[:, node.parent]
            P[:, j] = P[:, node.parent] + np.einsum("tij,tj->ti", Rp, t)
            R[:, j] = Rp @ Rl
    return P, R


def load_bvh(
    path: str | Path, scale: float | None = None, up: str = "y", fps: float | None = None
) -> Motion:
    """Load a BVH file -> :class:`Motion` (metres, z up).

    Rotation channels may come in any order (applied as listed, about the moving axes);
    End Sites become joints ``<joint>_end``.

    Args:
        path: the BVH file.
        scale: metres per file unit; default: detected from the rest-pose height.
        up: the file's up axis, "y" (usual) or "z".
        fps: frame rate; default from the Frame Time line.

    Raises:
        InputError: naming the line and keyword of the first problem.
    """
    path = Path(path)
    if up not in ("y", "z"):
        raise ValueError(f"up must be 'y' or 'z', got {up!r}")
    lines = _read_text(path).splitlines()
    start = next((i for i, s in enumerate(lines) if s.strip().upper() == "MOTION"), None)
    if start is None:
        raise InputError(path, "MOTION", "a MOTION section", "end of file")
    nodes = _bvh_header(path, lines[:start])
    values, dt = _bvh_motion(path, lines, start, sum(len(n.channels) for n in nodes))
    rest, _ = _bvh_fk(nodes, np.zeros((1, values.shape[1])))
    height = float(np.ptp(rest[0, :, "xyz".index(up)]))
    s = _checked_scale(path, height, None, scale)
    P, R = _bvh_fk(nodes, values)
    if fps is None:
        fps = 1.0 / dt
        fps = float(round(fps)) if abs(fps - round(fps)) < 1e-4 * fps else fps  # 0.0083333 s
    return Motion(
        tuple(n.name for n in nodes),
        tuple(n.parent for n in nodes),
        _points_z_up(P, s, up),
        _rotations_z_up(R, up),
        _points_z_up(rest[0] - rest[0, 0], s, up),
        fps,
        str(path),
        s,
    )


# --------------------------------------------------------------------------- to COCO-17


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


# ----------------------------------------------------------------------------- pose set


@dataclass(frozen=True, eq=False)
class PoseSet:
    """COCO-17 poses from many clips.

    Attributes:
        poses: joint positions, metres, z up, float32, shape (N, 17, 3).
        subject: subject id per pose, e.g. "01" (CMU subject) or "dance-salsa", shape (N,).
        clip: clip id per pose (the file's path under the data root), shape (N,).
        frame: frame index in the source clip (0-based, at its own fps), shape (N,).
    """

    poses: np.ndarray
    subject: np.ndarray
    clip: np.ndarray
    frame: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.poses)
        if (
            self.poses.shape[1:] != (17, 3)
            or not len(self.subject) == len(self.clip) == len(self.frame) == n
        ):
            raise ValueError(
                f"poses must have shape (N, 17, 3) with N subject/clip/frame entries, got "
                f"{self.poses.shape}, {len(self.subject)}, {len(self.clip)}, {len(self.frame)}"
            )

    def __len__(self) -> int:
        return len(self.poses)

    def select(self, mask: np.ndarray) -> PoseSet:
        """The poses where ``mask`` (bool or indices, shape (N,)) selects."""
        return PoseSet(self.poses[mask], self.subject[mask], self.clip[mask], self.frame[mask])

    def split(self, holdout_subjects: Sequence[str]) -> tuple[PoseSet, PoseSet]:
        """(poses of other subjects, poses of ``holdout_subjects``)."""
        held = np.isin(self.subject, list(holdout_subjects))
        return self.select(~held), self.select(held)

    def counts(self) -> dict[str, int]:
        """Number of poses per subject."""
        names, counts = np.unique(self.subject, return_counts=True)
        return dict(zip(names.tolist(), counts.tolist(), strict=True))

    @staticmethod
    def concatenate(sets: Sequence[PoseSet]) -> PoseSet:
        if not sets:
            return PoseSet(
                np.zeros((0, 17, 3), np.float32),
                np.array([], str),
                np.array([], str),
                np.zeros(0, np.int64),
            )
        return PoseSet(
            *(
                np.concatenate([getattr(s, f) for s in sets])
                for f in ("poses", "subject", "clip", "frame")
            )
        )


@dataclass(frozen=True)
class Clip:
    """One motion file found under a data root.

    Attributes:
        path: the AMC or BVH file.
        asf: the ASF skeleton for an AMC file, else None.
        subject: subject id: the CMU subject ("02") for files named ``<subject>_<trial>``,
            else "<grandparent>-<parent>" folder names (``dance/salsa/01.bvh`` ->
            "dance-salsa").
        clip: the file's path relative to the root (posix), unique in the root.
    """

    path: Path
    asf: Path | None
    subject: str
    clip: str


_CMU_TRIAL = re.compile(r"^(\d+)_\d+$")


def _subject(path: Path) -> str:
    match = _CMU_TRIAL.match(path.stem)
    return match.group(1) if match else f"{path.parent.parent.name}-{path.parent.name}"


def _asf_for(amc: Path) -> Path:
    """The ASF beside an AMC: the only one, or the one named after the AMC's subject."""
    asfs = sorted(amc.parent.glob("*.asf"))
    if len(asfs) == 1:
        return asfs[0]
    named = [a for a in asfs if a.stem == amc.stem.split("_")[0]]
    if len(named) != 1:
        raise InputError(
            amc,
            "skeleton",
            f"one .asf in {amc.parent} or one named {amc.stem.split('_')[0]}.asf",
            [a.name for a in asfs],
        )
    return named[0]


def find_clips(root: str | Path, subjects: Sequence[str] | None = None) -> list[Clip]:
    """Motion files (.amc with their .asf, .bvh) under ``root``, sorted by path.

    Args:
        root: a folder searched recursively.
        subjects: keep only these subject ids (see :class:`Clip`); None keeps all.
    """
    root = Path(root)
    if not root.is_dir():
        raise InputError(root, None, "a folder of .asf/.amc and .bvh files", "no such folder")
    clips = []
    for path in sorted(p for p in root.rglob("*") if p.suffix.lower() in (".amc", ".bvh")):
        subject = _subject(path)
        if subjects is not None and subject not in subjects:
            continue
        asf = _asf_for(path) if path.suffix.lower() == ".amc" else None
        clips.append(Clip(path, asf, subject, path.relative_to(root).as_posix()))
    return clips


#: Faster than any human pelvis, m/s: a root moving faster between frames is a glitch or a
#: splice of two takes.
MAX_ROOT_SPEED = 15.0
#: The CMU BVH conversions start with a rest (T-) pose and blend into the motion in ~40 ms.
REST_BLEND = 0.05
#: Clips of the shared CMU subset whose conversion is broken (legs folding through the body
#: in a run), matched against the end of the clip id.
BROKEN_CLIPS: tuple[str, ...] = ("misc/data/09/09_10.bvh",)
#: Clips of the shared CMU subset whose BVH Frame Time is wrong, with their true frame rate,
#: matched like :data:`BROKEN_CLIPS`. 16_01/16_02 say 30 fps, but their jumps stay airborne
#: 39 and 46 frames, the ballistic time of their 0.17 and 0.25 m lifts at 120 fps (45, 54
#: frames), not at 30 fps (11, 14).
FRAME_RATES: dict[str, float] = {"misc/data/16/16_01.bvh": 120.0, "misc/data/16/16_02.bvh": 120.0}


def _is_rest_pose(motion: Motion, t: int, tol: float = 0.03) -> bool:
    """Whether frame ``t`` is the rest pose up to a rigid motion of the root (90% of the
    joints within ``tol`` metres)."""
    rel = (motion.positions[t] - motion.positions[t, 0]) @ motion.rotations[t, 0]  # R^T (p - p0)
    return float(np.percentile(np.linalg.norm(rel - motion.rest, axis=-1), 90)) < tol


def usable_frames(motion: Motion, min_duration: float = 0.5) -> np.ndarray:
    """Frames worth training on, a mask of shape (T,): drops a leading rest pose with the
    converter's blend out of it (:data:`REST_BLEND`), and every piece shorter than
    ``min_duration`` seconds between root jumps faster than :data:`MAX_ROOT_SPEED`."""
    T, fps = motion.num_frames, motion.fps
    keep = np.ones(T, dtype=bool)
    if _is_rest_pose(motion, 0):
        keep[: max(1, round(REST_BLEND * fps))] = False
    speed = np.linalg.norm(np.diff(motion.positions[:, 0], axis=0), axis=-1) * fps  # (T - 1,)
    cuts = np.flatnonzero(speed > MAX_ROOT_SPEED) + 1  # first frame of each new piece
    for start, stop in zip(np.r_[0, cuts], np.r_[cuts, T], strict=True):
        if (stop - start) / fps < min_duration:
            keep[start:stop] = False
    return keep


def _sample(poses: np.ndarray, keep: np.ndarray, fps_in: float, fps: float, min_move: float):
    """Frame indices on a grid of ``fps`` (nearest source frames) among ``keep``, without
    near-duplicates: a frame is kept when some joint moved at least ``min_move`` metres,
    pelvis-centred, since the last kept frame. poses: shape (T, 17, 3); keep: (T,)."""
    T = len(poses)
    idx = np.unique(np.minimum(np.round(np.arange(0, T, fps_in / fps)).astype(int), T - 1))
    idx = idx[keep[idx]]
    hips = [COCO17.index("left_hip"), COCO17.index("right_hip")]
    centred = poses[idx] - poses[idx][:, hips].mean(axis=1, keepdims=True)
    kept = [0] if len(idx) else []
    for i in range(1, len(idx)):  # greedy: depends on the last kept frame
        if np.linalg.norm(centred[i] - centred[kept[-1]], axis=-1).max() >= min_move:
            kept.append(i)
    return idx[kept]


def _load_clip(clip: Clip, skeletons: dict[Path, AsfSkeleton]) -> Motion:
    if clip.asf is None:
        fps = next((v for k, v in FRAME_RATES.items() if _matches(clip.clip, [k])), None)
        return load_bvh(clip.path, fps=fps)
    if clip.asf not in skeletons:
        skeletons[clip.asf] = read_asf(clip.asf)
    return load_asf_amc(skeletons[clip.asf], clip.path)


def _clip_poses(clip: Clip, motion: Motion, fps: float, min_move: float, min_duration: float):
    """The pose set of one clip, its floor at z = 0 (None when nothing is usable)."""
    keep = usable_frames(motion, min_duration)
    if not keep.any():
        _log.info("%s: skipped, no %.1f s of clean motion", clip.path, min_duration)
        return None
    poses = to_coco17(motion)
    poses[..., 2] -= floor_height(motion.positions[keep])  # some BVH clips sit 0.8 m low
    idx = _sample(poses, keep, motion.fps, fps, min_move)
    n = len(idx)
    _log.debug("%s: %d frames -> %d poses", clip.clip, motion.num_frames, n)
    subject, name = np.full(n, clip.subject), np.full(n, clip.clip)
    return PoseSet(poses[idx].astype(np.float32), subject, name, idx.astype(np.int64))


def load_motion_dir(
    root: str | Path,
    subjects: Sequence[str] | None = None,
    fps: float = 10.0,
    min_move: float = 0.02,
    min_duration: float = 0.5,
    exclude: Sequence[str] = BROKEN_CLIPS,
) -> PoseSet:
    """Load every clip under ``root`` as COCO-17 poses for training.

    Args:
        root: folder searched recursively for .asf/.amc and .bvh files.
        subjects: subject ids to keep (see :class:`Clip`); None keeps all.
        fps: poses per second of motion kept before de-duplication.
        min_move: drop a pose whose joints (pelvis-centred) all moved less than this many
            metres since the last kept pose of its clip.
        min_duration: shortest clean stretch of motion used, seconds (see
            :func:`usable_frames`); shorter clips, such as a reference pose, are skipped.
        exclude: skip clips whose id (path under ``root``) ends with one of these.

    Returns:
        A :class:`PoseSet` in clip order, each clip moved vertically so that its floor
        (:func:`floor_height` of all its joints over its usable frames) is z = 0.
    """
    clips = [c for c in find_clips(root, subjects) if not _matches(c.clip, exclude)]
    if not clips:
        which = "" if subjects is None else f" of subjects {list(subjects)}"
        raise InputError(root, None, f"some .amc or .bvh files{which}", "none")
    skeletons: dict[Path, AsfSkeleton] = {}
    sets = [_clip_poses(c, _load_clip(c, skeletons), fps, min_move, min_duration) for c in clips]
    return PoseSet.concatenate([s for s in sets if s is not None])


def _matches(clip: str, patterns: Sequence[str]) -> bool:
    """Whether a clip id is one of ``patterns`` or ends with one (at a folder boundary)."""
    return any(clip == p or clip.endswith("/" + p.lstrip("/")) for p in patterns)


_POSE_SET_FORMAT = "rmpl.pose_set.v1"


def save_pose_set(path: str | Path, poses: PoseSet, **meta: float | str) -> Path:
    """Write a :class:`PoseSet` to an ``.npz`` file atomically; ``meta`` values are stored
    beside it (e.g. fps=10.0). Returns the path."""
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez(
            f,
            format=np.array(_POSE_SET_FORMAT),
            poses=poses.poses.astype(np.float32),
            subject=poses.subject.astype(str),
            clip=poses.clip.astype(str),
            frame=poses.frame.astype(np.int64),
            **{f"meta_{k}": np.array(v) for k, v in meta.items()},
        )
    return path


def load_pose_set(path: str | Path) -> PoseSet:
    """Read a :class:`PoseSet` written by :func:`save_pose_set`.

    Raises:
        InputError: not such a file, or arrays missing or of the wrong shape.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise InputError(path, None, "an .npz pose set", e) from None
    if str(data.get("format", "")) != _POSE_SET_FORMAT:
        raise InputError(path, "format", repr(_POSE_SET_FORMAT), data.get("format", "none"))
    missing = [k for k in ("poses", "subject", "clip", "frame") if k not in data]
    if missing:
        raise InputError(path, missing[0], "the array", "none")
    try:
        return PoseSet(data["poses"], data["subject"], data["clip"], data["frame"])
    except ValueError as e:
        raise InputError(path, "poses", "consistent shapes", e) from None


def build_pose_cache(
    root: str | Path,
    out_dir: str | Path,
    holdout_subjects: Sequence[str] = ("03",),
    subjects: Sequence[str] | None = None,
    fps: float = 10.0,
    min_move: float = 0.02,
    exclude: Sequence[str] = BROKEN_CLIPS,
) -> dict[str, Path]:
    """Load ``root`` (see :func:`load_motion_dir`) and write ``train.npz`` and ``val.npz``
    (the ``holdout_subjects``) to ``out_dir``. Returns {"train": path, "val": path}."""
    poses = load_motion_dir(root, subjects, fps=fps, min_move=min_move, exclude=exclude)
    train, val = poses.split(holdout_subjects)
    out_dir = Path(out_dir)
    meta = {"fps": fps, "min_move": min_move, "root": str(root)}
    paths = {
        name: save_pose_set(out_dir / f"{name}.npz", s, **meta)
        for name, s in (("train", train), ("val", val))
    }
    _log.info("pose cache %s: %d train, %d val poses", out_dir, len(train), len(val))
    return paths
