"""The one exception users see for bad input."""

from __future__ import annotations

from pathlib import Path

__all__ = ["InputError"]


class InputError(ValueError):
    """Bad user input: names the file, the field and what was expected.

    >>> str(InputError("calib.toml", "cam_1.matrix", "a 3x3 matrix", "[1, 2]"))
    "calib.toml: field 'cam_1.matrix': expected a 3x3 matrix, got [1, 2]"

    NumPy scalars print as plain numbers:

    >>> import numpy as np
    >>> str(InputError(None, "fps", "a positive number", np.float64(0.0)))
    "input: field 'fps': expected a positive number, got 0.0"
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
            text = str(_plain(got))
            msg += f", got {text[:200] + '...' if len(text) > 200 else text}"
        super().__init__(msg)


def _plain(x: object) -> object:
    """NumPy scalars (also inside lists and tuples) as Python numbers, for messages."""
    if isinstance(x, list | tuple):
        return type(x)(_plain(v) for v in x)
    if hasattr(x, "item") and getattr(x, "ndim", None) == 0:
        return x.item()
    return x
