"""Synthetic board images through known cameras, for tests and benchmarks.

:func:`render_board` draws a board seen by a camera with lens distortion: every output
pixel is undistorted (``cv2.undistortPoints``, iterated to 1e-9), its ray met with the
board's plane, and the board's texture sampled there (``cv2.remap``), at ``supersample``
times the resolution and then averaged down; then a Gaussian blur and Gaussian noise.
:func:`make_scene` lays out a rig around a capture volume with per-camera close-up
intrinsics views and shared extrinsics views (the first one lying on the floor at the
world origin), and :func:`write_scene` writes them as image folders
``intrinsics/<cam>/`` and ``extrinsics/<cam>/`` plus the true rig.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rmpl.calibration.boards import Board
from rmpl.geometry.camera import Camera, Rig, look_at

__all__ = ["Scene", "board_texture", "make_scene", "render_board", "write_scene"]


def _cv2():
    import cv2

    return cv2


@functools.lru_cache(maxsize=8)
def board_texture(board: Board, ppm: float) -> tuple[np.ndarray, float]:
    """The printed board, grey uint8, ``ppm`` pixels per metre, with a one-square white
    margin; and the texture x (= y) of board point (0, 0), pixels."""
    cv2 = _cv2()
    s = int(round(board.square * ppm))
    nx, ny = board.inner
    w, h = (nx + 1) * s, (ny + 1) * s
    if board.kind == "checkerboard":
        cells = (np.add.outer(np.arange(ny + 1), np.arange(nx + 1)) % 2 * 255).astype(np.uint8)
        pattern = np.kron(cells, np.ones((s, s), np.uint8))
    else:
        aruco = cv2.aruco
        dictionary = aruco.getPredefinedDictionary(getattr(aruco, board.dictionary))
        cv_board = aruco.CharucoBoard(
            (board.cols, board.rows), board.square, board.marker, dictionary
        )
        cv_board.setLegacyPattern(board.legacy)
        pattern = cv_board.generateImage((w, h), marginSize=0, borderBits=1)
    if board.inverted:
        pattern = 255 - pattern
    texture = np.full((h + 2 * s, w + 2 * s), 255, np.uint8)
    texture[s : s + h, s : s + w] = pattern
    return texture, 2.0 * s - 0.5  # pixel centres at integers: an edge at s - 0.5


def render_board(
    board: Board,
    camera: Camera,
    pose: tuple[np.ndarray, np.ndarray],
    *,
    blur: float = 0.0,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
    supersample: int = 2,
    background: int = 110,
) -> np.ndarray:
    """One grey image (H, W) uint8 of the board at ``pose`` (R, t: board -> world) seen by
    ``camera`` (with its size and distortion)."""
    cv2 = _cv2()
    W, H = camera.size
    Rb, tb = pose
    R = camera.R @ Rb  # board -> camera
    t = camera.R @ tb + camera.t
    ss = supersample
    x, y = _normalised_grid(camera, ss)  # (H * ss, W * ss) each
    n = R[:, 2]
    lam = (n @ t) / (n[0] * x + n[1] * y + n[2])  # ray depth at the board's plane
    ppm = 120.0 / board.square  # 120 texture pixels a square
    texture, origin = board_texture(board, ppm)
    maps = []
    for axis in (0, 1):  # board x, y = R^T (lam * (x, y, 1) - t)
        r = R[:, axis].astype(np.float32)
        value = lam * (r[0] * x + r[1] * y + r[2]) - float(r @ t)
        maps.append((value * ppm + origin).astype(np.float32))
    hidden = ~(lam > 0) | (n @ t <= 0)  # behind the camera, or the board's back
    maps[0][hidden] = -1e6
    big = cv2.remap(
        texture, maps[0], maps[1], cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT, borderValue=background,
    )  # fmt: skip
    image = cv2.resize(big, (W, H), interpolation=cv2.INTER_AREA).astype(np.float32)
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur)
    if noise > 0:
        rng = rng or np.random.default_rng(0)
        image = image + rng.normal(0.0, noise, image.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def _normalised_grid(camera: Camera, ss: int) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised x and y of every pixel of a ``ss`` times finer grid, each
    (H * ss, W * ss) float32: exact on every 8th pixel, linearly interpolated between."""
    cv2 = _cv2()
    W, H = camera.size
    step = 8
    gv, gu = np.mgrid[0 : H * ss + step : step, 0 : W * ss + step : step].astype(np.float64)
    pix = np.stack([(gu + 0.5) / ss - 0.5, (gv + 0.5) / ss - 0.5], axis=-1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9)
    xy = cv2.undistortPoints(pix, camera.K, camera.dist, None, None, None, criteria)
    coarse = xy.reshape(*gu.shape, 2).astype(np.float32)
    v, u = np.mgrid[0 : H * ss, 0 : W * ss].astype(np.float32)
    u, v = u / step, v / step
    return tuple(cv2.remap(coarse[..., i], u, v, cv2.INTER_LINEAR) for i in (0, 1))


@dataclass
class Scene:
    """A rendered calibration set: the true rig, and per camera the board poses of its
    intrinsics views and the shared extrinsics poses (board -> world)."""

    board: Board
    rig: Rig
    intrinsics: list[list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=list)
    extrinsics: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    return _cv2().Rodrigues(np.asarray(axis, float) * angle)[0]


def _camera(i: int, n: int, size, focal, dist, radius, height, rng) -> Camera:
    angle = 2 * np.pi * i / n + rng.uniform(-0.2, 0.2)
    eye = np.array(
        [radius * np.cos(angle), radius * np.sin(angle), height + rng.uniform(-0.2, 0.2)]
    )
    target = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), 0.4])
    R, t = look_at(eye, target)
    f = focal * rng.uniform(0.95, 1.05)
    W, H = size
    K = np.array(
        [[f, 0, W / 2 + rng.uniform(-8, 8)], [0, f * 1.001, H / 2 + rng.uniform(-8, 8)], [0, 0, 1]]
    )
    d = np.asarray(dist, float) * rng.uniform(0.8, 1.2, 5)
    return Camera(K, R, t, d, (W, H), name=f"cam{i + 1}")


def _facing(normal: np.ndarray, centre: np.ndarray, spin: float) -> tuple[np.ndarray, np.ndarray]:
    """A board pose whose printed side (its -z) faces along ``normal``, centred near
    ``centre``."""
    z = -normal / np.linalg.norm(normal)
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-6 else np.array([1.0, 0.0, 0.0])
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1) @ _rot([0, 0, 1], spin)
    return R, centre


def make_scene(
    board: Board,
    *,
    cameras: int = 4,
    size: tuple[int, int] = (1280, 720),
    focal: float = 1000.0,
    dist=(-0.12, 0.05, 0.0005, -0.0005, 0.0),
    intrinsics_views: int = 15,
    extrinsics_views: int = 30,
    radius: float = 3.0,
    height: float = 1.6,
    seed: int = 0,
) -> Scene:
    """A rig of ``cameras`` around the origin and the board poses to render (see module)."""
    rng = np.random.default_rng(seed)
    rig = Rig(
        tuple(_camera(i, cameras, size, focal, dist, radius, height, rng) for i in range(cameras))
    )
    half = board.points.max(axis=0) / 2
    scene = Scene(board, rig)
    for cam in rig:
        poses = []
        for _ in range(intrinsics_views):
            depth = focal * 2 * half[0] / (rng.uniform(0.35, 0.6) * size[0])  # board: 35-60% wide
            off = np.array([rng.uniform(-0.3, 0.3) * size[0], rng.uniform(-0.28, 0.28) * size[1]])
            centre_cam = np.array([off[0] / focal * depth, off[1] / focal * depth, depth])
            tilt = _rot(rng.normal(size=3), rng.uniform(0.15, 0.7))
            Rc = tilt @ _rot([0, 0, 1], rng.uniform(-0.3, 0.3))  # board -> camera
            tc = centre_cam - Rc @ half
            poses.append((cam.R.T @ Rc, cam.R.T @ (tc - cam.t)))
        scene.intrinsics.append(poses)
    floor = np.diag([1.0, -1.0, -1.0])  # printed side up, board x along world x
    scene.extrinsics.append((floor, np.zeros(3)))
    centres = rig.centers
    for k in range(1, extrinsics_views):
        a = rng.integers(cameras)
        toward = (centres[a] + centres[(a + 1) % cameras]) / 2
        centre = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(0.3, 1.4)])
        normal = toward - centre + rng.normal(0, 0.4, 3)
        if k % 5 == 0:
            normal = np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.2, 3)
            centre[2] = rng.uniform(0.0, 0.3)
        R, _ = _facing(normal, centre, rng.uniform(-np.pi, np.pi))
        scene.extrinsics.append((R, centre - R @ half))
    return scene


def write_scene(
    scene: Scene,
    folder: Path,
    *,
    blur: float = 0.6,
    noise: float = 1.5,
    seed: int = 0,
    progress=None,
) -> None:
    """Render every view into ``folder/intrinsics/<cam>/NNN.png`` and
    ``folder/extrinsics/<cam>/NNN.png``; the true rig into ``folder/truth.toml``."""
    from rmpl.io.calibration import save_rig

    cv2 = _cv2()
    rng = np.random.default_rng(seed)
    for v, cam in enumerate(scene.rig):
        for part, poses in (("intrinsics", scene.intrinsics[v]), ("extrinsics", scene.extrinsics)):
            out = Path(folder) / part / cam.name
            out.mkdir(parents=True, exist_ok=True)
            for k, pose in enumerate(poses):
                image = render_board(scene.board, cam, pose, blur=blur, noise=noise, rng=rng)
                cv2.imwrite(str(out / f"{k:03d}.png"), image)
                if progress is not None:
                    progress.update(1)
    save_rig(scene.rig, Path(folder) / "truth.toml")
