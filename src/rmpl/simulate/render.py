"""One camera's frames of a simulated capture: a room, the people, the lens, the noise.

:class:`CameraView` holds what does not change from frame to frame:

- **the room**: a floor (tiles of a random colour, taped lines every metre, smooth
  stains), four walls with doors and posters, and a ceiling, as the camera sees them
  through its lens: every pixel's ray (undistorted exactly, as
  :func:`rmpl.calibration.render.render_board` does) is met with the room's box;
- **the lens warp**: the people are rendered through a pinhole canvas wide enough for the
  whole distorted image (the same focal length, the principal point moved), then every
  output pixel samples the canvas where its undistorted ray lands (``cv2.remap``). With no
  distortion the canvas is the image.

:meth:`CameraView.frame` composes one frame: the people (antialiased by their coverage)
over the room, a small blur for the optics and sensor noise; the video encoder then adds
compression. It also returns which person each pixel shows, to tell hidden joints.

Shape glossary: ``P`` people, ``N`` vertices, ``J`` joints; images (H, W, 3) uint8.
"""

from __future__ import annotations

import numpy as np

from rmpl.geometry.camera import Camera

__all__ = ["CameraView", "RoomStyle", "room_style"]

#: Largest margin of the pinhole canvas around the image, as a fraction of its size.
MAX_MARGIN = 0.3
#: Places in the noise buffer a frame's noise may start at.
_SHIFT = 1 << 20


class RoomStyle:
    """The colours and layout of a room (one per simulation, seeded)."""

    def __init__(self, rng: np.random.Generator, half: float, ceiling: float = 3.2):
        floors = np.array([[150, 120, 90], [110, 110, 115], [70, 100, 140], [160, 150, 130]])
        walls = np.array([[200, 198, 190], [170, 180, 185], [190, 175, 160], [140, 150, 140]])
        self.floor = floors[rng.integers(len(floors))] * rng.uniform(0.85, 1.1)
        self.wall = walls[rng.integers(len(walls))] * rng.uniform(0.85, 1.05)
        self.tape = np.array([230, 230, 225]) if rng.random() < 0.5 else np.array([220, 190, 60])
        self.half, self.ceiling = float(half), float(ceiling)
        self.stains = rng.normal(0, 1, (64, 64))
        # Per wall: a few rectangles (u0, u1, z0, z1, colour); u runs along the wall.
        self.patches = []
        for _ in range(4):
            items = []
            for _ in range(int(rng.integers(2, 6))):
                u0 = rng.uniform(-half, half - 0.8)
                w = rng.uniform(0.4, 1.6)
                z0 = rng.uniform(0.0, 1.2) if rng.random() < 0.4 else 0.0
                h = rng.uniform(0.6, 2.1 - z0) if z0 == 0 else rng.uniform(0.3, 1.0)
                items.append((u0, u0 + w, z0, z0 + h, rng.uniform(30, 230, 3)))
            self.patches.append(items)


def room_style(rng: np.random.Generator, rig_centers: np.ndarray) -> RoomStyle:
    """A room around the rig: its walls 1.5 m behind the farthest camera."""
    half = float(np.abs(rig_centers[:, :2]).max() + 1.5)
    ceiling = float(max(3.2, rig_centers[:, 2].max() + 0.6))
    return RoomStyle(rng, half, ceiling)


def _smooth(table: np.ndarray, u: np.ndarray, v: np.ndarray, cell: float) -> np.ndarray:
    """Bilinear value noise from ``table`` (wrapping) at world coordinates, metres."""
    from scipy.ndimage import map_coordinates

    n = table.shape[0]
    return map_coordinates(
        table, [np.mod(u / cell, n), np.mod(v / cell, n)], order=1, mode="grid-wrap"
    )


def _room_colors(style: RoomStyle, C: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Colours (M, 3) float of rays from ``C`` (3,) along ``d`` (M, 3) in the room."""
    half, top = style.half, style.ceiling
    M = len(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        hits = np.stack(
            [
                np.where(d[:, 2] < 0, -C[2] / d[:, 2], np.inf),
                np.where(d[:, 2] > 0, (top - C[2]) / d[:, 2], np.inf),
                np.where(d[:, 0] > 0, (half - C[0]) / d[:, 0], np.inf),
                np.where(d[:, 0] < 0, (-half - C[0]) / d[:, 0], np.inf),
                np.where(d[:, 1] > 0, (half - C[1]) / d[:, 1], np.inf),
                np.where(d[:, 1] < 0, (-half - C[1]) / d[:, 1], np.inf),
            ],
            axis=1,
        )
    hits = np.where(hits > 0, hits, np.inf)
    which = np.argmin(hits, axis=1)
    s = hits[np.arange(M), which]
    s = np.where(np.isfinite(s), s, 1.0)
    X = C + d * s[:, None]
    out = np.empty((M, 3))
    floor = which == 0
    if floor.any():
        x, y = X[floor, 0], X[floor, 1]
        tone = 1 + 0.08 * _smooth(style.stains, x, y, 0.35)
        tile = ((np.floor(x / 0.5) + np.floor(y / 0.5)) % 2) * 0.06 + 0.97
        c = style.floor[None] * (tone * tile)[:, None]
        line = (np.abs(x / 2 - np.round(x / 2)) < 0.01) | (np.abs(y / 2 - np.round(y / 2)) < 0.01)
        c[line] = style.tape
        out[floor] = c
    ceil = which == 1
    out[ceil] = (
        np.array([215.0, 215, 212])
        * (1 + 0.03 * _smooth(style.stains, X[ceil, 0], X[ceil, 1], 1.0))[:, None]
    )
    for k in range(4):
        m = which == 2 + k
        if not m.any():
            continue
        u = X[m, 1] if k < 2 else X[m, 0]
        z = X[m, 2]
        c = style.wall[None] * (1 + 0.04 * _smooth(style.stains, u, z, 0.6))[:, None]
        for u0, u1, z0, z1, colour in style.patches[k]:
            inside = (u >= u0) & (u <= u1) & (z >= z0) & (z <= z1)
            c[inside] = colour
        c[z < 0.1] *= 0.7  # skirting
        out[m] = c
    return out


def _undistorted_grid(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted normalised x, y of every pixel centre, each (H, W) float32."""
    from rmpl.calibration.render import _normalised_grid

    return _normalised_grid(camera, 1)


class CameraView:
    """Render one camera's frames (see the module docstring).

    Args:
        camera: the camera, with its size and distortion.
        style: the room.
        blur: Gaussian blur sigma, pixels (the optics). noise: sensor noise sigma, grey levels.
    """

    def __init__(self, camera: Camera, style: RoomStyle, blur: float = 0.5, noise: float = 2.0):
        import cv2

        self.camera, self.blur, self.noise = camera, float(blur), float(noise)
        self._buffer: np.ndarray | None = None
        W, H = camera.size
        x, y = _undistorted_grid(camera)
        self.grid = (x, y)
        K = camera.K
        self.distorted = bool(np.any(np.abs(camera.dist) > 0))
        u = K[0, 0] * x + K[0, 1] * y + K[0, 2]
        v = K[1, 1] * y + K[1, 2]
        if self.distorted:
            lo_u = max(float(np.floor(u.min())), -MAX_MARGIN * W)
            hi_u = min(float(np.ceil(u.max())), (1 + MAX_MARGIN) * W)
            lo_v = max(float(np.floor(v.min())), -MAX_MARGIN * H)
            hi_v = min(float(np.ceil(v.max())), (1 + MAX_MARGIN) * H)
            lo_u, lo_v = min(lo_u, 0.0), min(lo_v, 0.0)
            hi_u, hi_v = max(hi_u, W - 1.0), max(hi_v, H - 1.0)
            self.canvas_K = K.copy()
            self.canvas_K[0, 2] -= lo_u
            self.canvas_K[1, 2] -= lo_v
            self.canvas_size = (int(hi_u - lo_u) + 2, int(hi_v - lo_v) + 2)
            self.map_u = (u - lo_u).astype(np.float32)
            self.map_v = (v - lo_v).astype(np.float32)
        else:
            self.canvas_K, self.canvas_size = K.copy(), (W, H)
        rays = np.stack([x, y, np.ones_like(x)], -1).reshape(-1, 3).astype(float)
        d = rays @ camera.R  # camera -> world directions: R^T r, row-wise
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        self.room = np.clip(_room_colors(style, camera.center, d), 0, 255).reshape(H, W, 3)
        self.room = cv2.GaussianBlur(self.room.astype(np.float32), (0, 0), 0.8)

    def _noise(self, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
        """Sensor noise for one frame: a window of one long buffer of Gaussian noise, at a
        random place each frame (drawing every frame anew costs more than the render)."""
        n = int(np.prod(shape))
        if self._buffer is None or len(self._buffer) < n + _SHIFT:
            self._buffer = rng.standard_normal(n + _SHIFT, dtype=np.float32) * self.noise
        at = int(rng.integers(0, _SHIFT))
        return self._buffer[at : at + n].reshape(shape)

    def frame(self, rgb: np.ndarray, ids: np.ndarray, rng: np.random.Generator):
        """One frame from the canvas render of the people: ``rgb`` (Hc, Wc, 3) uint8 on black
        and ``ids`` (Hc, Wc) the person of each pixel, -1 none. Returns the image
        (H, W, 3) uint8 and the ids (H, W) int16 in the camera's own pixels."""
        import cv2

        body = rgb.astype(np.float32)
        cover = (ids >= 0).astype(np.float32)
        if self.distorted:
            body = cv2.remap(
                body,
                self.map_u,
                self.map_v,
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            )
            cover = cv2.remap(
                cover,
                self.map_u,
                self.map_v,
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            )
            ids = cv2.remap(
                ids.astype(np.float32),
                self.map_u,
                self.map_v,
                cv2.INTER_NEAREST,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=-1,
            ).astype(np.int16)
        image = body + (1.0 - cover)[..., None] * self.room  # premultiplied: black behind
        if self.blur > 0:
            image = cv2.GaussianBlur(image, (0, 0), self.blur)
        if self.noise > 0:
            image += self._noise(image.shape, rng)
        return np.clip(image + 0.5, 0, 255).astype(np.uint8), ids.astype(np.int16)
