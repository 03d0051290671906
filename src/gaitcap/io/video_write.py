"""Writing videos atomically with OpenCV (the reading side is gaitcap.video)."""

from __future__ import annotations

import contextlib
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from gaitcap.errors import OutputError
from gaitcap.io.atomic import atomic_path

#: codec name -> (fourcc, file extension)
CODECS: dict[str, tuple[str, str]] = {"mp4v": ("mp4v", ".mp4"), "ffv1": ("FFV1", ".mkv"), "mjpg": ("MJPG", ".avi")}
_CODEC_OF_EXTENSION = {ext: name for name, (_, ext) in CODECS.items()}


class AtomicVideoWriter:
    """A ``cv2.VideoWriter`` writing to a temporary name that is renamed on a clean close.

    ``codec`` defaults to the one of the extension (.mp4: mp4v, .mkv: ffv1, .avi: mjpg). Use as a
    context manager; on an exception the partial file is removed and the target left untouched.
    """

    def __init__(self, path: str | Path, fps: float, size: tuple[int, int], codec: str | None = None) -> None:
        self.path = Path(path)
        codec = codec or _CODEC_OF_EXTENSION.get(self.path.suffix.lower())
        if codec not in CODECS:
            raise OutputError(
                f"{self.path}: unknown codec or video extension (codecs: {', '.join(CODECS)}; "
                f"extensions: {', '.join(_CODEC_OF_EXTENSION)})"
            )
        fourcc, ext = CODECS[codec]
        if self.path.suffix.lower() != ext:
            raise OutputError(f"{self.path}: codec {codec} writes {ext} files")
        self.size = size
        self.frames = 0
        self._stack = contextlib.ExitStack()
        tmp = self._stack.enter_context(atomic_path(self.path, suffix=".part" + ext))
        self._writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*fourcc), float(fps or 25.0), size)
        if not self._writer.isOpened():
            self._stack.close()
            raise OutputError(f"{self.path}: OpenCV cannot open a {codec} video writer")

    def write(self, frame: np.ndarray) -> None:
        """Append one BGR uint8 frame of shape (h, w, 3) of the writer's size."""
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
        self._stack.__exit__(exc_type, exc, tb)
