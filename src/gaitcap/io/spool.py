"""A spool of per-frame image stacks on disk, for a second pass over a clip (reads and writes only).

Each frame's arrays (one per camera, float32, any shapes) are compressed (zlib, losslessly) and
appended to an anonymous temporary file; memory holds only each frame's offset. A tracker's soft
silhouettes at half scale take about 0.6 MB a frame pair raw and a few tens of kB compressed.
Frames may be read from one thread while another appends (the file's position is shared: each
seek and its read or write are done under one lock).
"""

from __future__ import annotations

import tempfile
import threading
import zlib
from typing import Self

import numpy as np


class FrameSpool:
    """Append frames, then read any of them back, bit for bit (from any thread). Use as a context manager."""

    def __init__(self, level: int = 1) -> None:
        self._file = tempfile.TemporaryFile(prefix="gaitcap-spool-")  # noqa: SIM115 - open until close()
        self._level = level
        self._index: list[tuple[int, int]] = []  # (offset, length) per frame
        self._shapes: list[tuple[int, ...]] = []  # every frame's arrays, in order
        self._lock = threading.Lock()  # over each seek and its read or write

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __len__(self) -> int:
        return len(self._index)

    def append(self, arrays: list[np.ndarray]) -> None:
        """Store one frame: arrays of the same shapes as every other frame's (float32)."""
        shapes = [a.shape for a in arrays]
        if self._shapes and shapes != self._shapes:
            raise ValueError(f"frame {len(self)}: arrays of shapes {shapes}, the spool holds {self._shapes}")
        self._shapes = shapes
        blob = zlib.compress(b"".join(np.ascontiguousarray(a, np.float32).tobytes() for a in arrays), self._level)
        with self._lock:
            offset = self._file.seek(0, 2)
            self._file.write(blob)
            self._index.append((offset, len(blob)))

    def read(self, t: int) -> list[np.ndarray]:
        """Frame ``t``'s arrays, as appended."""
        with self._lock:
            offset, length = self._index[t]
            self._file.seek(offset)
            blob = self._file.read(length)
        flat = np.frombuffer(zlib.decompress(blob), np.float32)
        out, start = [], 0
        for shape in self._shapes:
            n = int(np.prod(shape))
            out.append(flat[start : start + n].reshape(shape).copy())
            start += n
        return out

    def close(self) -> None:
        self._file.close()
