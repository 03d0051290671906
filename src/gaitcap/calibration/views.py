"""Read calibration views (image files, folders of images, videos) and detect the board in them.

Reading only: the choice of views and the calibration itself live in
:mod:`gaitcap.calibration.intrinsics` and :mod:`gaitcap.calibration.extrinsics`.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from gaitcap.calibration.boards import Board, Detection, detect_board, is_blurred, larger_pattern
from gaitcap.errors import CalibrationError, InputError

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")


@dataclass
class ViewSet:
    """The detections of one camera's views, in input order.

    Attributes:
        image_size: ``(width, height)`` shared by every view.
        detections: usable views.
        rejected: ``source -> reason`` for views that were read but not used.
        frames: for each input frame (in order), its detection or ``None`` (for synchronised
            multi-camera use: frame k of every camera shows the same board pose).
        sources: each input frame's name (``file`` or ``video#frame``), as ``frames``.
    """

    image_size: tuple[int, int] | None = None
    detections: list[Detection] = field(default_factory=list)
    rejected: dict[str, str] = field(default_factory=dict)
    frames: list[Detection | None] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)

    def require(self, n: int, what: str) -> None:
        """Raise :class:`CalibrationError` naming every rejected view when fewer than ``n`` are usable."""
        if len(self.detections) >= n:
            return
        why = "; ".join(f"{src}: {reason}" for src, reason in list(self.rejected.items())[:10])
        more = f" (and {len(self.rejected) - 10} more)" if len(self.rejected) > 10 else ""
        raise CalibrationError(
            f"{what}: only {len(self.detections)} usable view(s), at least {n} needed. Rejected: {why}{more}"
        )


def expand_inputs(paths: Sequence[str | Path]) -> list[Path]:
    """Files named directly, plus the sorted images and videos of any folder named."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES + VIDEO_SUFFIXES)
            if not found:
                raise InputError(f"{p}: folder holds no image or video")
            out.extend(found)
        elif p.is_file():
            out.append(p)
        else:
            raise InputError(f"{p}: file not found")
    return out


def iter_frames(path: Path, video_step: int = 1, max_frames: int | None = None) -> Iterator[tuple[str, np.ndarray]]:
    """Yield ``(source, gray image (H, W))`` for an image file or every ``video_step``-th frame."""
    suffix = path.suffix.lower()
    if suffix in VIDEO_SUFFIXES:
        cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise InputError(f"{path}: cannot open video")
        try:
            k = kept = 0
            while max_frames is None or kept < max_frames:
                ok, frame = cap.read()
                if not ok:
                    break
                if k % video_step == 0:
                    kept += 1
                    yield f"{path.name}#{k}", cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
                k += 1
            if k == 0:
                raise InputError(f"{path}: no frame could be decoded")
        finally:
            cap.release()
    elif suffix in IMAGE_SUFFIXES:
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise InputError(f"{path}: cannot read image")
        yield path.name, image
    else:
        raise InputError(f"{path}: not an image or a video ({', '.join(IMAGE_SUFFIXES + VIDEO_SUFFIXES)})")


def detect_views(
    paths: Sequence[str | Path],
    board: Board,
    video_step: int = 1,
    max_frames: int | None = None,
    max_blur: float | None = None,
) -> ViewSet:
    """Detect ``board`` in every view of ``paths`` (files or folders).

    Raises :class:`InputError` naming the file when views differ in size. Views without the
    (complete) board or too blurred go to ``rejected`` with the reason.
    """
    views = ViewSet()
    first: str = ""
    for path in expand_inputs(paths):
        for source, gray in iter_frames(path, video_step, max_frames):
            size = (gray.shape[1], gray.shape[0])
            if views.image_size is None:
                views.image_size, first = size, source
            elif size != views.image_size:
                raise InputError(
                    f"{path}: image size {size[0]}x{size[1]} differs from {views.image_size[0]}x"
                    f"{views.image_size[1]} of {first}; calibrate one camera at a time"
                )
            det = detect_board(gray, board, source)
            if det is None:
                views.rejected[source] = f"{board.describe()} not found"
            elif max_blur is not None and is_blurred(det, max_blur):
                views.rejected[source] = f"blurred (edges {det.blur_fraction:.2f} of a square wide)"
                det = None
            else:
                if not views.detections and (larger := larger_pattern(gray, board)):  # checked on the first view
                    log.warning("%s: the board shows %dx%d inner corners or more, more than the %dx%d given: give "
                                "its full size (a part of it moves the origin and may turn the board round)", source,
                                *larger, *board.corner_grid)  # fmt: skip
                views.detections.append(det)
            views.frames.append(det)
            views.sources.append(source)
    for source, reason in views.rejected.items():
        log.debug("%s: rejected: %s", source, reason)
    return views


def _pair_number(source: str) -> int | None:
    """The number a view is paired by: a video's frame index, else the last number in the file name."""
    if "#" in source:
        return int(source.rsplit("#", 1)[1])
    numbers = re.findall(r"\d+", Path(source).stem)
    return int(numbers[-1]) if numbers else None


def paired_views(left: ViewSet, right: ViewSet) -> list[tuple[Detection, Detection]]:
    """The views of a synchronised pair taken together, both detected: paired by number (a video's
    frame index, or the last number in each file name: left05.jpg with right05.jpg) when every view
    has its own, else in input order.

    Raises:
        InputError: a view without its partner (named), or, without numbers, two counts of views.
    """
    kl, kr = [_pair_number(s) for s in left.sources], [_pair_number(s) for s in right.sources]
    numbered = all(k is not None for k in kl + kr) and len(set(kl)) == len(kl) and len(set(kr)) == len(kr)
    if numbered:
        alone = [s for s, k in zip(left.sources, kl) if k not in set(kr)]
        alone += [s for s, k in zip(right.sources, kr) if k not in set(kl)]
        if alone:
            raise InputError(f"views without their pair (paired by the number in their names): {', '.join(alone)}")
        by_number = dict(zip(kr, right.frames))
        pairs = [(a, by_number[k]) for k, a in zip(kl, left.frames)]
    elif len(left.frames) != len(right.frames):
        raise InputError(f"{len(left.frames)} left views and {len(right.frames)} right ones, not numbered to pair "
                         "them: give the pairs' files the same number (left05.jpg, right05.jpg)")  # fmt: skip
    else:
        pairs = list(zip(left.frames, right.frames))
    return [(a, b) for a, b in pairs if a is not None and b is not None]
