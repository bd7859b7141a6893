"""A calibration board carried through the capture volume, filmed by every camera.

The board is held at chest height (1.0-1.6 m up) by someone walking a slow loop through
the walking area; they turn it towards each camera in turn (2.5 s each, less when the
sweep is short), tilting it by up to 35 degrees, and now and then lay it flat (the floor's
orientation). Its back is plain: a camera behind it sees no pattern. Every camera films the
same instants (frame i of every video), as ``rmpl calibrate --extrinsics`` expects: a
board recording is made with the cameras started together (a clap, a hardware trigger, or
frames matched by timestamps as caliscope does).

Each pixel's undistorted ray meets the board's plane and samples the printed board
(:func:`rmpl.calibration.render.board_texture`); elsewhere the room shows. The truth goes
to ``board.json``: the board's pose (board -> world) at every frame.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from rmpl.errors import InputError

__all__ = ["check_board", "sweep", "board_poses"]

log = logging.getLogger(__name__)

#: Fewest pixels a square may span from a camera at the volume's centre.
MIN_SQUARE_PX = 10.0
#: The board's largest side may fill at most this fraction of an image at the centre.
MAX_FILL = 0.8
#: Fewest seconds the board faces each camera (and the floor) during a sweep.
MIN_DWELL = 0.8


def check_board(spec: str, rig, seconds: float | None = None):
    """The board of ``spec``, checked against the rig.

    Raises:
        InputError: a spec that does not parse, or a board that cannot be seen well from
            the cameras: squares under :data:`MIN_SQUARE_PX` pixels, or the board wider
            than :data:`MAX_FILL` of an image, from the volume's centre.
    """
    from rmpl.calibration.boards import parse_board

    board = parse_board(spec)
    if seconds is not None and seconds / (len(rig) + 1) < MIN_DWELL:
        raise InputError(None, "--board-seconds", f"a sweep of at least "
                         f"{MIN_DWELL * (len(rig) + 1):g} s, to face each of the {len(rig)} "
                         "cameras in turn", seconds)  # fmt: skip
    side = float(np.ptp(board.points, axis=0).max()) + board.square
    centre = np.array([0.0, 0.0, 1.3])
    for cam in rig:
        d = float(np.linalg.norm(cam.center - centre))
        f = float(cam.K[0, 0])
        square_px, side_px = f * board.square / d, f * side / d
        if square_px < MIN_SQUARE_PX:
            raise InputError(
                spec,
                "--board",
                f"squares of at least {MIN_SQUARE_PX:g} px in "
                f"{cam.name}, {d:.1f} m away (a board with larger squares)",
                f"{square_px:.1f} px",
            )
        if side_px > MAX_FILL * min(cam.size):
            raise InputError(
                spec,
                "--board",
                f"a board that fits in {cam.name}'s image ({min(cam.size)} px) from {d:.1f} m",
                f"{side_px:.0f} px",
            )
    return board


def _rot(axis, angle: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    axis = np.asarray(axis, float)
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


def board_poses(board, rig, frames: int, fps: float, area: float, rng) -> list:
    """The board's pose (R, t: board -> world) at every frame (see the module docstring)."""
    half = board.points.max(axis=0) / 2
    centres = rig.centers
    T = frames
    s = np.arange(T) / fps
    loop = 2 * np.pi * s / max(T / fps, 1.0) + rng.uniform(0, 2 * np.pi)
    r = 0.5 * area
    path = np.stack([r * np.cos(loop), r * np.sin(loop), 1.3 + 0.25 * np.sin(0.7 * s)], -1)
    # frames facing one camera: 2.5 s, shorter when the sweep would not reach every camera
    dwell = max(int(min(2.5, T / fps / (len(rig) + 1)) * fps), 1)
    poses = []
    for k in range(T):
        c = (k // dwell) % len(rig)
        nxt = (c + 1) % len(rig)
        w = (k % dwell) / dwell
        w = 0.0 if w < 0.6 else (w - 0.6) / 0.4  # hold, then turn to the next camera
        toward = (1 - w) * centres[c] + w * centres[nxt]
        normal = toward - path[k]
        normal /= np.linalg.norm(normal)
        flat = (k // dwell) % (len(rig) + 1) == len(rig)
        if flat:
            normal = np.array([0.0, 0.0, 1.0])
        tilt = 0.6 * np.sin(0.9 * s[k] + np.array([0.0, 1.7]))  # radians, two axes
        z = -normal
        x = np.cross([0.0, 0.0, 1.0], z)
        x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
        y = np.cross(z, x)
        R = np.stack([x, y, z], axis=1) @ _rot([0, 0, 1], 0.3 * np.sin(0.5 * s[k]))
        R = _rot(x, tilt[0] * 0.5) @ _rot(y, tilt[1] * 0.5) @ R
        centre = path[k].copy()
        if flat:
            centre[2] = 0.9
        poses.append((R, centre - R @ half))
    return poses


def _board_layer(board, cam, x, y, pose, background: np.ndarray) -> np.ndarray:
    """The board over ``background`` (H, W, 3) float, seen by ``cam`` whose undistorted
    pixel rays are (x, y) (H, W) each."""
    import cv2

    from rmpl.calibration.render import board_texture

    Rb, tb = pose
    R = cam.R @ Rb
    t = cam.R @ tb + cam.t
    n = R[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (n @ t) / (n[0] * x + n[1] * y + n[2])
    ppm = 60.0 / board.square
    texture, origin = board_texture(board, ppm)
    maps = []
    for axis in (0, 1):
        r = R[:, axis].astype(np.float32)
        value = lam * (r[0] * x + r[1] * y + r[2]) - float(r @ t)
        maps.append((value * ppm + origin).astype(np.float32))
    hidden = ~(lam > 0)
    back = float(n @ t) <= 0  # its back faces the camera: a plain board, no pattern
    maps[0][hidden] = -1e6
    grey = cv2.remap(
        texture.astype(np.float32),
        maps[0],
        maps[1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=-1.0,
    )
    alpha = cv2.remap(
        np.ones_like(texture, np.float32),
        maps[0],
        maps[1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0.0,
    )
    grey = np.clip(grey, 0, 255) * 0.85 + 15  # printed paper under room light
    if back:
        grey = np.full_like(grey, 150.0)
    return background * (1 - alpha[..., None]) + (grey * alpha)[..., None]


def sweep(
    spec: str, rig, folder: Path, seconds: float, fps: float, style, rng, crf: int, progress: bool
) -> None:
    """Render the board sweep: ``folder/<camera>.mp4`` and ``folder/board.json``."""
    import cv2
    from tqdm import tqdm

    from rmpl.io.atomic import atomic_path
    from rmpl.simulate.render import CameraView
    from rmpl.simulate.video import VideoWriter

    board = check_board(spec, rig)
    T = int(round(seconds * fps))
    area = float(np.clip(0.45 * np.linalg.norm(rig.centers[:, :2], axis=1).min(), 0.8, 3.0))
    poses = board_poses(board, rig, T, fps, area, rng)
    for v, cam in enumerate(rig):
        path = folder / f"{cam.name}.mp4"
        if path.exists():
            continue
        view = CameraView(cam, style)
        x, y = view.grid
        noise_rng = np.random.default_rng([v, 17])
        with VideoWriter(path, fps, cam.size, crf) as video:
            for k in tqdm(range(T), desc=f"board {cam.name}", unit="frame", disable=not progress):
                image = _board_layer(board, cam, x, y, poses[k], view.room)
                image = cv2.GaussianBlur(image.astype(np.float32), (0, 0), view.blur)
                image += view._noise(image.shape, noise_rng)
                video.write(np.clip(image + 0.5, 0, 255).astype(np.uint8))
    doc = {
        "board": spec,
        "fps": fps,
        "frames": T,
        "poses": [{"R": np.round(R, 9).tolist(), "t": np.round(t, 9).tolist()} for R, t in poses],
    }
    with atomic_path(folder / "board.json") as tmp:
        tmp.write_text(json.dumps(doc) + "\n", encoding="utf-8")
