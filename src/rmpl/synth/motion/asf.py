"""Acclaim ASF skeletons and AMC motions (the CMU mocap database)."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.synth.motion._common import (
    Motion,
    _float,
    _floats,
    _Line,
    _read_text,
)
from rmpl.synth.motion.kinematics import (
    _checked_scale,
    _euler,
    _points_z_up,
    _rotations_z_up,
)


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


_ANGLE_UNITS = {"deg": math.pi / 180, "degree": math.pi / 180, "rad": 1.0, "radian": 1.0}


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


def _amc_columns(skeleton: AsfSkeleton) -> dict[str, tuple[int, int]]:
    """AMC line name -> (first column, number of values) of the per-frame vector."""
    cols = {"root": (0, len(skeleton.root_order))}
    start = len(skeleton.root_order)
    for bone in skeleton.bones:
        if bone.dofs:
            cols[bone.name] = (start, len(bone.dofs))
            start += len(bone.dofs)
    return cols


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
