"""EasyMocap ``intri.yml`` + ``extri.yml`` (OpenCV FileStorage YAML), with a small parser."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from rmpl.errors import InputError
from rmpl.geometry.camera import Rig, rodrigues, rotation_to_rodrigues
from rmpl.io.calibration._base import (
    SAFE_NAME,
    CalibOptions,
    Source,
    brief,
    make_camera,
    read_text,
    unit_scale,
)


def _easymocap_paths(path: Path) -> tuple[Path, Path]:
    """(intri.yml, extri.yml) for a folder, for extri.yml, or for an intrinsics file."""
    if path.is_dir() or not path.suffix:
        return path / "intri.yml", path / "extri.yml"
    if path.name == "extri.yml":
        return path.parent / "intri.yml", path
    return path, path.parent / "extri.yml"


def read_easymocap(path: Path, options: CalibOptions) -> Rig:
    """Read EasyMocap ``intri.yml`` + ``extri.yml`` (a folder or either file; metres)."""
    intri_path, extri_path = _easymocap_paths(path)
    intri, extri = Source(intri_path), Source(extri_path)
    idoc = _parse_opencv_yaml(intri_path, read_text(intri_path))
    edoc = _parse_opencv_yaml(extri_path, read_text(extri_path))
    scale = unit_scale(path, options.units or "m")
    names = intri.value(idoc, "names", "", "a list of camera names")
    if not isinstance(names, list):
        raise InputError(intri_path, "names", "a list of camera names", brief(names))
    cams = []
    for name in names:
        K = intri.intrinsics(
            intri.array(idoc, f"K_{name}", "", (3, 3), "a 3x3 opencv-matrix"), f"K_{name}"
        )
        dist = intri.distortion(
            intri.value(idoc, f"dist_{name}", "", "a 1x5 opencv-matrix"), f"dist_{name}"
        )
        size = None
        if f"W_{name}" in idoc and f"H_{name}" in idoc:
            size = intri.size([idoc[f"W_{name}"], idoc[f"H_{name}"]], f"W_{name}/H_{name}")
        R = _easymocap_rotation(extri, edoc, name)
        t = extri.array(edoc, f"T_{name}", "", (3,), "a 3x1 opencv-matrix") * scale
        cams.append(make_camera(name, K, R, t, dist, size))
    return intri.rig(cams, "names")


def _easymocap_rotation(src: Source, doc: dict, name: str) -> np.ndarray:
    rot_key, rvec_key = f"Rot_{name}", f"R_{name}"
    if rot_key not in doc:
        return rodrigues(src.array(doc, rvec_key, "", (3,), "a 3x1 Rodrigues opencv-matrix"))
    R = src.rotation(src.array(doc, rot_key, "", (3, 3), "a 3x3 opencv-matrix"), rot_key)
    if rvec_key in doc:
        rvec = src.array(doc, rvec_key, "", (3,), "a 3x1 Rodrigues opencv-matrix")
        if np.abs(rodrigues(rvec) - R).max() > 1e-4:
            raise InputError(
                src.path, rvec_key, f"a Rodrigues vector agreeing with {rot_key}", rvec.tolist()
            )
    return R


def write_easymocap(rig: Rig, path: Path, options: CalibOptions) -> dict[Path, str]:
    """EasyMocap ``intri.yml`` and ``extri.yml`` in the folder ``path`` (or beside it)."""
    intri_path, extri_path = _easymocap_paths(path)
    scale = unit_scale(path, options.units or "m")
    for c in rig:
        if not SAFE_NAME.fullmatch(c.name):
            raise InputError(
                path,
                "name",
                "camera names of letters, digits, '_' or '-' (they become YAML keys)",
                c.name,
            )
    names = "names:\n" + "".join(f'   - "{c.name}"\n' for c in rig)
    intri, extri = [_YAML_HEADER, names], [_YAML_HEADER, names]
    for c in rig:
        intri += [_yaml_matrix(f"K_{c.name}", c.K), _yaml_matrix(f"dist_{c.name}", c.dist[None])]
        if c.size is not None:
            intri += [f"W_{c.name}: {c.size[0]}\n", f"H_{c.name}: {c.size[1]}\n"]
        extri += [
            _yaml_matrix(f"R_{c.name}", rotation_to_rodrigues(c.R)[:, None]),
            _yaml_matrix(f"Rot_{c.name}", c.R),
            _yaml_matrix(f"T_{c.name}", c.t[:, None] / scale),
        ]
    return {intri_path: "".join(intri), extri_path: "".join(extri)}


_YAML_HEADER = "%YAML:1.0\n---\n"


def _yaml_matrix(key: str, a: np.ndarray) -> str:
    data = ", ".join(repr(float(x)) for x in a.ravel())
    return (
        f"{key}: !!opencv-matrix\n   rows: {a.shape[0]}\n   cols: {a.shape[1]}\n"
        f"   dt: d\n   data: [ {data} ]\n"
    )


def _parse_opencv_yaml(path: Path, text: str) -> dict[str, object]:
    """Parse the subset of OpenCV FileStorage YAML that calibration files use.

    Top-level ``key: value`` entries only: scalars (returned as strings), sequences of
    scalars (block ``- x`` or flow ``[x, y]``; lists of strings) and ``!!opencv-matrix``
    (float arrays of shape (rows, cols)).
    """
    lines = text.splitlines()
    if not lines[0].startswith("%YAML"):
        raise InputError(
            path, None, "an OpenCV FileStorage YAML starting with '%YAML:1.0'", brief(lines[0])
        )
    entries: list[tuple[str, str, list[str]]] = []
    for number, raw in enumerate(lines[1:], start=2):
        line = _strip_yaml_comment(raw).rstrip()
        if not line.strip() or line.strip() == "---":
            continue
        if line[0] not in " \t-":
            key, sep, rest = line.partition(":")
            if not sep:
                raise InputError(path, f"line {number}", "'key: value'", brief(raw))
            entries.append((key.strip(), rest.strip(), []))
        elif entries:
            entries[-1][2].append(line.strip())
        else:
            raise InputError(path, f"line {number}", "a top-level 'key: value'", brief(raw))
    return {key: _yaml_value(path, key, rest, block) for key, rest, block in entries}


def _yaml_value(path: Path, key: str, rest: str, block: list[str]) -> object:
    if rest.startswith("!!opencv-matrix"):
        return _yaml_opencv_matrix(path, key, "\n".join(block))
    if rest.startswith("["):
        flow = " ".join([rest, *block])
        if not flow.endswith("]"):
            raise InputError(path, key, "a flow sequence closed by ']'", brief(flow))
        return [_unquote(x) for x in _split_flow(flow[1:-1])]
    if not rest and block and all(b.startswith("-") for b in block):
        return [_unquote(b[1:].strip()) for b in block]
    if block:
        raise InputError(
            path, key, "a scalar, a sequence or an !!opencv-matrix", brief([rest, *block])
        )
    return _unquote(rest)


def _yaml_opencv_matrix(path: Path, key: str, body: str) -> np.ndarray:
    expected = "an !!opencv-matrix with rows, cols, dt and data"
    rows = re.search(r"^rows:\s*(\d+)\s*$", body, re.M)
    cols = re.search(r"^cols:\s*(\d+)\s*$", body, re.M)
    data = re.search(r"^data:\s*\[(.*)\]\s*$", body, re.M | re.S)
    if not (rows and cols and data):
        raise InputError(path, key, expected, brief(body))
    tokens = [x for x in _split_flow(data[1]) if x]
    shape = (int(rows[1]), int(cols[1]))
    if len(tokens) != shape[0] * shape[1]:
        raise InputError(
            path, key, f"{shape[0] * shape[1]} data values for {shape}", f"{len(tokens)} values"
        )
    return np.array([_yaml_float(path, key, x) for x in tokens]).reshape(shape)


def _yaml_float(path: Path, key: str, token: str) -> float:
    special = {".nan": math.nan, ".inf": math.inf, "+.inf": math.inf, "-.inf": -math.inf}
    low = token.strip().lower()
    if low in special:
        return special[low]
    try:
        return float(low)
    except ValueError:
        raise InputError(path, key, "numbers in data", brief(token)) from None


def _strip_yaml_comment(line: str) -> str:
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i]
    return line


def _split_flow(text: str) -> list[str]:
    items, current, quote = [], [], None
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == ",":
            items.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    last = "".join(current).strip()
    return items + [last] if last else items


def _unquote(token: str) -> str:
    token = token.strip()
    if len(token) >= 2 and token[0] == token[-1] == '"':
        return re.sub(r"\\(.)", r"\1", token[1:-1])
    if len(token) >= 2 and token[0] == token[-1] == "'":
        return token[1:-1].replace("''", "'")
    return token
