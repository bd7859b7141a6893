"""The one exception users see for bad input."""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError"]


class InputError(ValueError):
    """Bad user input: names the file, the field and what was expected.

    >>> str(InputError("calib.toml", "cam_1.matrix", "a 3x3 matrix", "[1, 2]"))
    "calib.toml: field 'cam_1.matrix': expected a 3x3 matrix, got [1, 2]"
    """

    def __init__(
        self,
        path: str | Path | None,
        field: str | None,
        expected: str,
        got: object | None = None,
    ) -> None:
        self.path, self.field, self.expected, self.got = path, field, expected, got
        where = str(path) if path is not None else "input"
        if field:
            where += f": field {field!r}"
        msg = f"{where}: expected {expected}"
        if got is not None:
            text = str(got)
            msg += f", got {text[:200] + '...' if len(text) > 200 else text}"
        super().__init__(msg)
