"""Streaming video reading for the whole project (OpenCV / FFmpeg backend).

Frames are BGR ``uint8`` arrays of shape (H, W, 3), read one at a time: memory does not grow
with the length of a video. Every failure is an :class:`~gaitcap.errors.InputError` naming the
file: a missing or unreadable file, a file OpenCV cannot decode, a video with zero frames.

Typical use::

    info = probe_video("videos/cam0.mp4")            # size, fps, frame count; checks 1 frame decodes
    with VideoReader("videos/cam0.mp4") as video:
        for index, frame in video:                   # (H, W, 3) uint8 BGR
            ...
    plates = sample_frames("videos/cam0.mp4", 31)    # (31, H, W, 3), spread over the whole video
    for index, frames in iter_synchronised({"cam0": p0, "cam1": p1}):
        frames["cam0"], frames["cam1"]               # one frame per camera, same index

Writing videos (overlays, synthetic sessions) is not this module's job.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Iterator, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from gaitcap.errors import InputError

log = logging.getLogger(__name__)

#: seeking (instead of decoding every frame in between) pays off beyond this gap
_SEEK_MIN_GAP = 24


@dataclass(frozen=True)
class VideoInfo:
    """What a video declares about itself, and its first decoded frame's shape.

    Attributes:
        path: the video file.
        width, height: decoded frame size in pixels (from the first frame, not the container).
        fps: frame rate the container declares (0 when unknown).
        frame_count: number of frames the container declares; may be approximate or 0 for
            some formats, so readers stop at the first frame that does not decode.
    """

    path: Path
    width: int
    height: int
    fps: float
    frame_count: int

    @property
    def size(self) -> tuple[int, int]:
        """(width, height), the convention of :class:`gaitcap.camera.Camera`."""
        return (self.width, self.height)


def _open_capture(path: Path) -> cv2.VideoCapture:
    if not path.exists():
        raise InputError(f"{path}: video not found")
    if not path.is_file():
        raise InputError(f"{path}: not a file")
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
    if not cap.isOpened():
        cap.release()
        raise InputError(f"{path}: cannot open as a video (unreadable, corrupt or unsupported format)")
    return cap


class VideoReader:
    """Sequential frame reader over one video file; a context manager and an iterator.

    Iterating yields ``(index, frame)`` with ``frame`` of shape (H, W, 3), uint8, BGR, from
    the current position to the end. The first frame is decoded on opening, so a file that
    opens but holds no decodable frame fails here with :class:`InputError`.

    Args:
        path: video file.
        start: index of the first frame to yield.
        stop: index one past the last frame to yield (None: to the end).
    """

    def __init__(self, path: str | Path, start: int = 0, stop: int | None = None) -> None:
        self.path = Path(path)
        if start < 0 or (stop is not None and stop < start):
            raise ValueError(f"{self.path}: bad frame range start={start} stop={stop}")
        self._cap = _open_capture(self.path)
        try:
            ok, first = self._cap.read()
            if not ok or first is None or first.size == 0:
                raise InputError(f"{self.path}: the video has no decodable frame (empty or corrupt)")
            if first.ndim == 2:
                first = cv2.cvtColor(first, cv2.COLOR_GRAY2BGR)
            h, w = first.shape[:2]
            self.info = VideoInfo(
                path=self.path,
                width=int(w),
                height=int(h),
                fps=float(self._cap.get(cv2.CAP_PROP_FPS) or 0.0),
                frame_count=max(int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0), 0),
            )
        except BaseException:
            self._cap.release()
            raise
        self._pending: np.ndarray | None = first  # frame 0, already decoded
        self._next = 0
        self._stop = stop
        self.frames_read = 0
        if start > 0:
            self.seek(start)

    # -- context manager ---------------------------------------------------------------------
    def __enter__(self) -> VideoReader:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Release the decoder (idempotent)."""
        self._cap.release()

    # -- reading -----------------------------------------------------------------------------
    @property
    def position(self) -> int:
        """Index of the frame the next :meth:`read` returns."""
        return self._next

    def seek(self, index: int) -> None:
        """Move so that the next :meth:`read` returns frame ``index``.

        Short forward gaps are decoded through (exact); long gaps use the container's seek.
        """
        if index < 0:
            raise ValueError(f"{self.path}: negative frame index {index}")
        gap = index - self._next
        if 0 <= gap < _SEEK_MIN_GAP:
            for _ in range(gap):
                if self._pending is not None:
                    self._pending = None
                elif not self._cap.grab():
                    break
                self._next += 1
            return
        self._pending = None
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, float(index))
        self._next = index

    def read(self) -> np.ndarray | None:
        """Decode the next frame: (H, W, 3) uint8 BGR, or None at the end of the video."""
        if self._stop is not None and self._next >= self._stop:
            return None
        if self._pending is not None:
            frame, self._pending = self._pending, None
        else:
            ok, frame = self._cap.read()
            if not ok or frame is None:
                return None
            if frame.ndim == 2:
                frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
        if frame.shape[:2] != (self.info.height, self.info.width):
            raise InputError(
                f"{self.path}: frame {self._next} is {frame.shape[1]}x{frame.shape[0]}, "
                f"the video started at {self.info.width}x{self.info.height}"
            )
        self._next += 1
        self.frames_read += 1
        return frame

    def __iter__(self) -> Iterator[tuple[int, np.ndarray]]:
        while True:
            index = self._next
            frame = self.read()
            if frame is None:
                self._warn_if_truncated(index)
                return
            yield index, frame

    def _warn_if_truncated(self, end: int) -> None:
        declared = self.info.frame_count
        if self._stop is None and declared > 0 and end < declared - 1:
            log.warning(
                "%s: decoding stopped at frame %d of %d declared (truncated or corrupt file?)",
                self.path, end, declared,
            )


def probe_video(path: str | Path) -> VideoInfo:
    """Open ``path``, decode its first frame and return its :class:`VideoInfo`.

    Raises:
        InputError: missing file, not a video, or no decodable frame.
    """
    with VideoReader(path) as video:
        return video.info


#: relative tolerance between two cameras' frame rates
FPS_RTOL = 1e-3


def differing_rates(rates: Mapping[str, float]) -> str | None:
    """``"cam1 30 fps, cam2 25 fps"`` when the cameras' frame rates (camera -> fps) differ by more than
    :data:`FPS_RTOL` (their frames k are then not one instant), else None."""
    first = next(iter(rates.values()), None)
    if first is None or all(math.isclose(fps, first, rel_tol=FPS_RTOL) for fps in rates.values()):
        return None
    return ", ".join(f"{cam} {fps:g} fps" for cam, fps in rates.items())


def sample_indices(frame_count: int, n: int) -> np.ndarray:
    """``n`` frame indices spread evenly over ``[0, frame_count)`` (fewer if the video is short).

    Returns: (m,) int array, sorted, unique, m = min(n, frame_count).
    """
    if frame_count <= 0 or n <= 0:
        return np.zeros(0, dtype=int)
    if n >= frame_count:
        return np.arange(frame_count)
    # centres of n equal bins: never the very first/last frame only
    return np.unique(((np.arange(n) + 0.5) * frame_count / n).astype(int))


def sample_frames(path: str | Path, n: int, scale: float = 1.0) -> np.ndarray:
    """Read ``n`` frames spread evenly over the whole video (for a background estimate).

    Memory is bounded by ``n`` frames whatever the video's length.

    Args:
        path: video file.
        n: number of frames wanted.
        scale: resize factor applied to each frame (1.0: native size).

    Returns:
        (m, H', W', 3) uint8 BGR, m <= n (m < n when the video is shorter or its declared
        frame count overstates it).
    """
    with VideoReader(path) as video:
        count = video.info.frame_count
    if count <= 0:  # the container does not say: count by decoding once
        with VideoReader(path) as video:
            count = sum(1 for _ in video)
    indices = sample_indices(count, n)
    frames = read_frames(path, indices)
    if len(frames) < len(indices):
        log.warning("%s: frame %d of %d declared does not decode", path, indices[len(frames)], count)
    if not frames:
        raise InputError(f"{path}: no frame could be read for the background estimate")
    return np.stack([_rescale(frame, scale) for frame in frames.values()])


def read_frames(path: str | Path, indices: Iterable[int]) -> dict[int, np.ndarray]:
    """The frames ``indices`` of a video, in increasing order: index -> (H, W, 3) uint8 BGR. Stops
    at the first that does not decode (past the end): the later ones are left out."""
    out: dict[int, np.ndarray] = {}
    with VideoReader(path) as video:
        for index in sorted({int(i) for i in indices}):
            video.seek(index)
            frame = video.read()
            if frame is None:
                break
            out[index] = frame
    return out


def _rescale(frame: np.ndarray, scale: float) -> np.ndarray:
    if scale == 1.0:
        return frame
    h, w = frame.shape[:2]
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    return cv2.resize(frame, size, interpolation=cv2.INTER_AREA)


def iter_synchronised(
    paths: Mapping[str, str | Path], start: int = 0, stop: int | None = None,
    offsets: Mapping[str, int] | None = None,
) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
    """Iterate over several synchronised videos together, one frame of each per step.

    Yields ``(index, {camera: frame})`` with each frame (H_c, W_c, 3) uint8 BGR. Stops at the
    end of the shortest video; a warning names the cameras whose videos are longer.

    Args:
        paths: camera name -> video file (all cameras start at the same instant, but for ``offsets``).
        start, stop: frame range, as for :class:`VideoReader`.
        offsets: camera -> frames skipped at the start of its video (``session.yaml``'s ``skip_frames``):
            step ``index`` holds frame ``index + offset`` of that camera's video (missing: 0).
    """
    if not paths:
        raise InputError("no video to read (empty camera list)")
    shift = {cam: int((offsets or {}).get(cam, 0)) for cam in paths}
    with ExitStack() as stack:
        readers = {cam: stack.enter_context(VideoReader(p, start + shift[cam], None if stop is None else stop + shift[cam]))
                   for cam, p in paths.items()}  # fmt: skip
        index = start
        while True:
            frames = {cam: r.read() for cam, r in readers.items()}
            ended = [cam for cam, f in frames.items() if f is None]
            if ended:
                running = [cam for cam in readers if cam not in ended]
                if running and stop is None:
                    log.warning(
                        "videos of different lengths: %s ended at frame %d, %s had more frames",
                        ", ".join(ended), index, ", ".join(running),
                    )
                return
            yield index, frames  # type: ignore[misc]
            index += 1
