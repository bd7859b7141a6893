"""Videos as a phone writes them: H.264 (yuv420p, constant quality) in an MP4.

:class:`VideoWriter` pipes raw frames to the ffmpeg of the ``imageio-ffmpeg`` package (in
rmpl's ``synth`` extra; it carries its own ffmpeg with libx264), or, without it, to
OpenCV's writer (MPEG-4 part 2, ``mp4v``: larger files and other artefacts; the log says
so once). The file appears only when complete (:func:`rmpl.io.atomic.atomic_path`).
"""

from __future__ import annotations

import contextlib
import logging
import subprocess
import sys
from pathlib import Path

import numpy as np

from rmpl.io.atomic import atomic_path

__all__ = ["VideoWriter", "encoder"]

log = logging.getLogger(__name__)

#: x264's constant-rate factor: 23 is its default, about what a phone's encoder gives.
CRF = 23


def encoder() -> str:
    """``"h264"`` when imageio-ffmpeg's ffmpeg is there, else ``"mp4v"`` (OpenCV)."""
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        return "mp4v"
    return "h264"


class VideoWriter:
    """Write frames (H, W, 3) uint8 RGB to ``path``; use as a context manager.

    Args:
        path: the .mp4 to write. fps: frames per second. size: (width, height).
        crf: H.264 quality (lower is better; 18 is near lossless, 28 a low bitrate).
    """

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int], crf: int = CRF):
        self.path, self.fps, self.size, self.crf = Path(path), float(fps), tuple(size), int(crf)
        self._stack = contextlib.ExitStack()
        self._proc = self._cv = None

    def __enter__(self) -> VideoWriter:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self._stack.enter_context(atomic_path(self.path))
        w, h = self.size
        if encoder() == "h264":
            import imageio_ffmpeg

            cmd = [
                imageio_ffmpeg.get_ffmpeg_exe(),
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgb24",
                "-s",
                f"{w}x{h}",
                "-r",
                f"{self.fps:g}",
                "-i",
                "-",
                "-an",
                "-c:v",
                "libx264",
                "-preset",
                "veryfast",
                "-crf",
                str(self.crf),
                "-pix_fmt",
                "yuv420p",
                "-g",
                str(max(int(self.fps), 1)),
                "-threads",
                "1",
                "-f",
                "mp4",
                str(tmp),
            ]
            self._proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        else:
            import cv2

            log.warning(
                "imageio-ffmpeg is not installed: videos are MPEG-4 part 2, not H.264 "
                "(pip install imageio-ffmpeg)"
            )
            self._cv = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, (w, h))
        return self

    def write(self, frame: np.ndarray) -> None:
        frame = np.ascontiguousarray(frame, np.uint8)
        if frame.shape != (self.size[1], self.size[0], 3):
            raise ValueError(f"frame of shape {frame.shape}, expected {self.size[::-1]} x 3")
        if self._proc is not None:
            self._proc.stdin.write(frame.tobytes())
        else:
            self._cv.write(frame[..., ::-1])

    def __exit__(self, kind, value, tb) -> None:
        try:
            if self._proc is not None:
                self._proc.stdin.close()
                err = self._proc.stderr.read().decode(errors="replace")
                if self._proc.wait() != 0 and kind is None:
                    raise RuntimeError(f"ffmpeg failed writing {self.path}: {err.strip()}")
            if self._cv is not None:
                self._cv.release()
        except BaseException:
            self._stack.__exit__(*sys.exc_info())
            raise
        self._stack.__exit__(kind, value, tb)
