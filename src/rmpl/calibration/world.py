"""The world frame of a calibration.

``board`` (the default): the first board view seen by two or more cameras sets the world:
origin at the board's first inner corner (corner 0, as OpenCV numbers them in the view
of the camera that saw it first), x along its first row, z up out of the printed side, so
a board lying on the floor gives z = 0 on the floor and cameras above it at z > 0.
``camera:NAME``: the world is that camera's frame (x right, y down, z forward).
"""

from __future__ import annotations

import numpy as np

from rmpl.errors import InputError

__all__ = ["parse_origin", "world_from_board", "world_from_camera", "to_world"]

#: Board frame (OpenCV: z into the board, away from the cameras) -> world (z up out of it).
_UP = np.diag([1.0, -1.0, -1.0, 1.0])


def parse_origin(text: str, names: list[str]) -> str | None:
    """None for ``board``, else the camera's name from ``camera:NAME``."""
    if text == "board":
        return None
    if text.startswith("camera:") and text[7:] in names:
        return text[7:]
    raise InputError(None, "--origin", f"board or camera:NAME with NAME one of {names}", text)


def world_from_board(T_wb: np.ndarray) -> np.ndarray:
    """4x4 map from the adjustment's frame to the world set by this board pose."""
    return _UP @ np.linalg.inv(T_wb)


def world_from_camera(T_cw: np.ndarray) -> np.ndarray:
    """4x4 map from the adjustment's frame to that camera's frame."""
    return T_cw.copy()


def to_world(T_cw: list[np.ndarray], G: np.ndarray) -> list[np.ndarray]:
    """Camera poses (world -> camera, 4x4) re-expressed in the new world ``X' = G X``."""
    Ginv = np.linalg.inv(G)
    return [T @ Ginv for T in T_cw]
