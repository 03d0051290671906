"""Writing videos atomically with OpenCV (the reading side is gaitcap.video)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from gaitcap.errors import OutputError
from gaitcap.io.atomic import default_file_mode

#: codec name -> (fourcc, file extension)
CODECS: dict[str, tuple[str, str]] = {"mp4v": ("mp4v", ".mp4"), "ffv1": ("FFV1", ".mkv"), "mjpg": ("MJPG", ".avi")}


class AtomicVideoWriter:
    """A ``cv2.VideoWriter`` that writes to a temporary file and renames it on a clean close.

    Use as a context manager; on an exception the partial file is removed.
    """

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int], codec: str = "mp4v") -> None:
        if codec not in CODECS:
            raise OutputError(f"unknown codec {codec!r} (choose from {', '.join(CODECS)})")
        fourcc, ext = CODECS[codec]
        self.path = Path(path)
        if self.path.suffix.lower() != ext:
            raise OutputError(f"{self.path}: codec {codec} writes {ext} files")
        self.size = size
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.stem}.", suffix=f".part{ext}", dir=self.path.parent)
        os.close(fd)
        self._tmp = Path(tmp)
        self._writer = cv2.VideoWriter(str(self._tmp), cv2.VideoWriter_fourcc(*fourcc), float(fps), size)
        if not self._writer.isOpened():
            self._tmp.unlink(missing_ok=True)
            raise OutputError(f"{self.path}: OpenCV cannot open a {codec} video writer")
        self.frames = 0

    def write(self, frame: np.ndarray) -> None:
        """Append one BGR uint8 frame of shape (h, w, 3)."""
        if frame.shape[:2] != (self.size[1], self.size[0]) or frame.dtype != np.uint8:
            raise OutputError(f"{self.path}: frame {frame.shape} {frame.dtype} does not match {self.size} uint8")
        self._writer.write(frame)
        self.frames += 1

    def __enter__(self) -> AtomicVideoWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._writer.release()
        if exc_type is None:
            os.chmod(self._tmp, default_file_mode())
            os.replace(self._tmp, self.path)
        else:
            self._tmp.unlink(missing_ok=True)
