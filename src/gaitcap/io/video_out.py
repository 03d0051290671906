"""Video writing (overlays for people to look at), atomically, with a codec OpenCV always has."""

from __future__ import annotations

import contextlib
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from gaitcap.errors import OutputError
from gaitcap.io.atomic import atomic_path

_FOURCC = {".mp4": "mp4v", ".avi": "MJPG"}


class VideoWriter:
    """Write BGR frames of one size to ``path`` (.mp4: MPEG-4 part 2; .avi: MJPEG)."""

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int]) -> None:
        self.path = Path(path)
        fourcc = _FOURCC.get(self.path.suffix.lower())
        if fourcc is None:
            raise OutputError(f"{self.path}: video extension must be one of {', '.join(_FOURCC)}")
        self.size = size
        self._stack = contextlib.ExitStack()
        tmp = self._stack.enter_context(atomic_path(self.path, suffix=".part" + self.path.suffix))
        self._writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*fourcc), float(fps or 25.0), size)
        if not self._writer.isOpened():
            self._stack.close()
            raise OutputError(f"{self.path}: OpenCV cannot open a {fourcc} video writer")

    def write(self, frame: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 BGR frame of the writer's size."""
        if (frame.shape[1], frame.shape[0]) != self.size:
            raise OutputError(f"{self.path}: frame is {frame.shape[1]}x{frame.shape[0]}, expected {self.size}")
        self._writer.write(frame)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._writer.release()
        self._stack.__exit__(exc_type, exc, tb)
