"""The calibration formats by name, and how a file's format is told from its name and content.

:data:`FORMATS` maps a format name to its reader and writer (None for read-only formats).
A new format is a module beside this one with ``read_<name>(path, options) -> Rig`` and,
if it can be written, ``write_<name>(rig, path, options) -> {path: text}``; add it to
:data:`FORMATS` and, if its files can be recognised, to :func:`detect_format`.
"""

from __future__ import annotations

from pathlib import Path

from rmpl.errors import InputError
from rmpl.io.calibration._base import Reader, Writer, load_json, load_toml, read_text
from rmpl.io.calibration.anipose import read_anipose, write_anipose
from rmpl.io.calibration.easymocap import read_easymocap, write_easymocap
from rmpl.io.calibration.h36m import read_h36m, read_h36m_pkl
from rmpl.io.calibration.native import (
    read_rmpl_json,
    read_rmpl_toml,
    write_rmpl_json,
    write_rmpl_toml,
)
from rmpl.io.calibration.panoptic import read_panoptic, write_panoptic
from rmpl.io.calibration.qualisys import read_qualisys
from rmpl.io.calibration.shelf import read_shelf4d, read_voxelpose, write_shelf4d, write_voxelpose

FORMATS: dict[str, tuple[Reader, Writer | None]] = {
    "rmpl-toml": (read_rmpl_toml, write_rmpl_toml),
    "rmpl-json": (read_rmpl_json, write_rmpl_json),
    "anipose": (read_anipose, write_anipose),
    "panoptic": (read_panoptic, write_panoptic),
    "shelf4d": (read_shelf4d, write_shelf4d),
    "voxelpose": (read_voxelpose, write_voxelpose),
    "easymocap": (read_easymocap, write_easymocap),
    "h36m": (read_h36m, None),
    "h36m-pkl": (read_h36m_pkl, None),
    "qualisys": (read_qualisys, None),
}


def detect_format(path: str | Path) -> str:
    """Guess a calibration file's format from its extension and content.

    Args:
        path: a calibration file, or a folder holding EasyMocap ``intri.yml``.

    Returns:
        A key of :data:`FORMATS`.

    Raises:
        InputError: the file is missing or empty, or no known format matches.
    """
    p = Path(path)
    if p.is_dir():
        if (p / "intri.yml").is_file():
            return "easymocap"
        raise InputError(
            p,
            None,
            "a calibration file or a folder with intri.yml/extri.yml",
            "a folder without intri.yml",
        )
    lower = p.name.lower()
    if lower.endswith((".yml", ".yaml")):
        return "easymocap"
    if lower.endswith((".pkl", ".pickle")):
        return "h36m-pkl"
    if lower.endswith((".qca.txt", ".qca", ".xml")):
        return "qualisys"
    if lower.endswith(".toml"):
        return _toml_kind(load_toml(p))
    if lower.endswith(".json"):
        return _json_kind(p, load_json(p))
    if lower.endswith(".txt") and read_text(p).lstrip().startswith("<"):
        return "qualisys"
    raise InputError(
        p,
        "format",
        "a known extension (.toml .json .yml .pkl .qca.txt) or an explicit format, "
        f"one of {sorted(FORMATS)}",
        p.suffix or "no extension",
    )


def lookup(path: Path, name: str) -> tuple[Reader, Writer | None]:
    if name not in FORMATS:
        raise InputError(path, "format", f"one of {sorted(FORMATS)}", name)
    return FORMATS[name]


def writable() -> list[str]:
    return sorted(k for k, (_, w) in FORMATS.items() if w is not None)


def output_format(path: Path) -> str:
    lower = path.name.lower()
    if lower.endswith(".toml"):
        return "rmpl-toml"
    if lower.endswith(".json"):
        return "rmpl-json"
    if lower.endswith((".yml", ".yaml")) or not path.suffix:
        return "easymocap"
    raise InputError(
        path,
        "format",
        f"an extension .toml/.json/.yml or a format, one of {writable()}",
        path.suffix,
    )


def _toml_kind(doc: dict) -> str:
    meta = doc.get("metadata")
    if (isinstance(meta, dict) and meta.get("format") == "rmpl") or isinstance(
        doc.get("cameras"), list
    ):
        return "rmpl-toml"
    return "anipose"


def _json_kind(path: Path, doc: object) -> str:
    if isinstance(doc, dict):
        meta = doc.get("metadata")
        if isinstance(meta, dict) and meta.get("format") == "rmpl":
            return "rmpl-json"
        cams = doc.get("cameras")
        if isinstance(cams, list):
            panoptic = any(isinstance(c, dict) and "distCoef" in c for c in cams)
            return "panoptic" if panoptic else "rmpl-json"
        if "intrinsics" in doc and "extrinsics" in doc:
            return "h36m"
        entries = list(doc.values())
        if entries and all(isinstance(v, dict) for v in entries):
            if "RT" in entries[0]:
                return "shelf4d"
            if "fx" in entries[0] or "T" in entries[0]:
                return "voxelpose"
    keys = list(doc)[:6] if isinstance(doc, dict) else type(doc).__name__
    raise InputError(
        path,
        "format",
        "a known JSON calibration layout (rmpl-json, panoptic, shelf4d, voxelpose, h36m) "
        "or an explicit format",
        f"top-level {keys}",
    )
