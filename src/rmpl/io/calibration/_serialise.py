"""Text serialisers for the writers: JSON with short number lists, and a small TOML writer."""

from __future__ import annotations

import json
import math
import re

from rmpl.io.calibration._base import SAFE_NAME


def json_dumps(doc: object) -> str:
    text = json.dumps(doc, indent=2, ensure_ascii=False, allow_nan=False)
    # Keep each innermost list of numbers on one line.
    return re.sub(r"\[([^\[\]{}\"]*)\]", lambda m: "[" + " ".join(m[1].split()) + "]", text) + "\n"


def toml_dumps(doc: dict) -> str:
    """TOML for a document of scalars, tables of scalars/arrays, and arrays of such tables."""
    tables = {k: v for k, v in doc.items() if isinstance(v, dict) or _is_table_array(v)}
    out = [_toml_fields({k: v for k, v in doc.items() if k not in tables})]
    for key, value in tables.items():
        for table in [value] if isinstance(value, dict) else value:
            brackets = ("[", "]") if isinstance(value, dict) else ("[[", "]]")
            out.append(f"\n{brackets[0]}{_toml_key(key)}{brackets[1]}\n{_toml_fields(table)}")
    return "".join(out).lstrip("\n")


def _is_table_array(value: object) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _toml_fields(table: dict) -> str:
    return "".join(f"{_toml_key(k)} = {_toml_value(v)}\n" for k, v in table.items())


def _toml_key(key: str) -> str:
    return key if SAFE_NAME.fullmatch(key) else _toml_str(key)


def _toml_str(text: str) -> str:
    escapes = {'"': '\\"', "\\": "\\\\", "\n": "\\n", "\t": "\\t", "\r": "\\r"}
    out = []
    for ch in text:
        if ch in escapes:
            out.append(escapes[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"cannot write a non-finite number {value} to TOML")
        return repr(value)
    if isinstance(value, str):
        return _toml_str(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")
