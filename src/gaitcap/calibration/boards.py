"""Calibration boards (checkerboard, ChArUco) and their detection in images.

A checkerboard is described by its **inner corners** ``cols x rows`` (OpenCV's ``patternSize``,
e.g. 9x6) and its square side in metres. A ChArUco board is described by its **squares**
``cols x rows`` (OpenCV's ``CharucoBoard`` size), its square side and its marker side.

Board frame: corner ``k = j * cols + i`` (row j, column i) sits at ``(i * s, -j * s, 0)``: x along
the rows, y across them, z = x cross y pointing out of the printed face. Laid on the floor, this
frame is a z-up world frame with the origin at corner 0 (see :mod:`gaitcap.calibration.extrinsics`).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np

from gaitcap.errors import ConfigError

log = logging.getLogger(__name__)

BoardKind = Literal["checkerboard", "charuco"]

#: a view whose corner edges are blurred over more than this fraction of a square is rejected
MAX_BLUR_FRACTION = 0.25
_FIND_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_FAST_CHECK
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 1e-4)


@dataclass(frozen=True)
class Board:
    """A planar calibration target.

    Attributes:
        cols, rows: inner corners per row and number of rows (checkerboard), or squares
            (ChArUco).
        square_m: side of one square, metres.
        kind: ``"checkerboard"`` or ``"charuco"``.
        marker_m: ArUco marker side (ChArUco only), metres.
        dictionary: OpenCV ArUco dictionary name (ChArUco only).
    """

    cols: int
    rows: int
    square_m: float
    kind: BoardKind = "checkerboard"
    marker_m: float | None = None
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2:
            raise ConfigError(f"board: {self.cols}x{self.rows} is too small (at least 2x2)")
        if not self.square_m > 0:
            raise ConfigError("board: the square size must be positive")
        if self.kind == "charuco":
            if self.marker_m is None:
                object.__setattr__(self, "marker_m", 0.75 * self.square_m)
            if not 0 < float(self.marker_m) < self.square_m:  # type: ignore[arg-type]
                raise ConfigError("board: the ChArUco marker must be smaller than the square")
            if not hasattr(cv2.aruco, self.dictionary):
                raise ConfigError(f"board: unknown ArUco dictionary {self.dictionary!r}")

    @property
    def corner_grid(self) -> tuple[int, int]:
        """Inner corners ``(cols, rows)``."""
        if self.kind == "charuco":
            return self.cols - 1, self.rows - 1
        return self.cols, self.rows

    @property
    def n_corners(self) -> int:
        c, r = self.corner_grid
        return c * r

    def object_points(self) -> np.ndarray:
        """Corner coordinates in the board frame, shape (N, 3), metres (see module docstring)."""
        c, r = self.corner_grid
        j, i = np.mgrid[0:r, 0:c]
        pts = np.zeros((c * r, 3))
        pts[:, 0] = i.ravel() * self.square_m
        pts[:, 1] = -j.ravel() * self.square_m
        return pts

    @property
    def orientation_is_unique(self) -> bool:
        """Whether the colours tell corner 0 from the last corner (a 180-degree turn)."""
        c, r = self.corner_grid
        return self.kind == "charuco" or (c + r) % 2 == 1

    def describe(self) -> str:
        if self.kind == "charuco":
            return f"ChArUco {self.cols}x{self.rows} squares of {self.square_m * 1000:g} mm"
        return f"checkerboard {self.cols}x{self.rows} inner corners, {self.square_m * 1000:g} mm squares"

    def _charuco(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols, self.rows), self.square_m, float(self.marker_m), dictionary)


@dataclass
class Detection:
    """The board found in one view.

    Attributes:
        source: file name (and frame index for videos) of the view.
        image_size: ``(width, height)`` of the image.
        corners: sub-pixel corner positions, shape (M, 2).
        ids: index of each corner into :meth:`Board.object_points`, shape (M,).
        sharpness: mean width of the black-white edges at the corners, pixels (NaN if unknown).
        square_px: median distance between neighbouring corners, pixels.
    """

    source: str
    image_size: tuple[int, int]
    corners: np.ndarray
    ids: np.ndarray
    sharpness: float = float("nan")
    square_px: float = float("nan")
    extra: dict = field(default_factory=dict)

    @property
    def blur_fraction(self) -> float:
        """Edge width as a fraction of a square (0.1 is crisp, above 0.25 is blurred)."""
        return self.sharpness / self.square_px if self.square_px > 0 else float("nan")


_SIZE_RE = re.compile(r"^\s*(\d+)\s*[xX*]\s*(\d+)\s*$")
_LEN_RE = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*(mm|cm|m)?\s*$")


def parse_board_size(text: str) -> tuple[int, int]:
    """``"9x6"`` -> ``(9, 6)``; a :class:`ConfigError` for anything else."""
    m = _SIZE_RE.match(str(text))
    if not m:
        raise ConfigError(f"board size {text!r}: expected COLSxROWS such as 9x6")
    return int(m.group(1)), int(m.group(2))


def parse_length(text: str, default_unit: str = "mm") -> float:
    """``"25mm"``, ``"2.5cm"``, ``"0.025m"`` or ``"25"`` (``default_unit``) -> metres."""
    m = _LEN_RE.match(str(text))
    if not m:
        raise ConfigError(f"length {text!r}: expected a number with mm, cm or m, such as 25mm")
    unit = m.group(2) or default_unit
    return float(m.group(1)) * {"mm": 1e-3, "cm": 1e-2, "m": 1.0}[unit]


def to_gray(image: np.ndarray) -> np.ndarray:
    """BGR or gray image -> 8-bit gray, shape (H, W)."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype != np.uint8:
        image = cv2.normalize(image, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return image


def detect_board(image: np.ndarray, board: Board, source: str = "image") -> Detection | None:
    """Find ``board`` in ``image`` (H, W[, 3]); ``None`` when it is not (completely) visible.

    Checkerboards must show every inner corner (partial views are rejected by OpenCV's
    detector); corners are refined to sub-pixel with ``cornerSubPix`` and put in the canonical
    order of :func:`canonical_order`. ChArUco views need at least 6 corners.
    """
    gray = to_gray(image)
    size = (gray.shape[1], gray.shape[0])
    if board.kind == "charuco":
        return _detect_charuco(gray, board, source, size)
    pattern = board.corner_grid
    found, corners = cv2.findChessboardCorners(gray, pattern, flags=_FIND_FLAGS)
    if not found or corners is None or len(corners) != board.n_corners:
        return None
    win = _subpix_window(corners.reshape(-1, 2), pattern)
    corners = cv2.cornerSubPix(gray, corners, (win, win), (-1, -1), _SUBPIX_CRITERIA)
    pts = canonical_order(gray, corners.reshape(-1, 2), pattern)
    sharp = float(cv2.estimateChessboardSharpness(gray, pattern, pts.reshape(-1, 1, 2).astype(np.float32))[0][0])
    return Detection(source, size, pts, np.arange(len(pts)), sharp, _square_px(pts, pattern))


def larger_pattern(image: np.ndarray, board: Board) -> tuple[int, int] | None:
    """A checkerboard pattern one corner wider or taller than ``board``'s that ``image`` also shows
    (``board`` then names only part of the board: its origin and orientation are those of a part), or
    None (and always for ChArUco, whose markers fix its size)."""
    if board.kind == "charuco":
        return None
    gray = to_gray(image)
    cols, rows = board.corner_grid
    for pattern in ((cols + 1, rows), (cols, rows + 1)):
        found, _ = cv2.findChessboardCorners(gray, pattern, flags=_FIND_FLAGS)
        if found:
            return pattern
    return None


def _detect_charuco(gray: np.ndarray, board: Board, source: str, size: tuple[int, int]) -> Detection | None:
    detector = cv2.aruco.CharucoDetector(board._charuco())
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < 6:
        return None
    pts = corners.reshape(-1, 2).astype(np.float64)
    ids = ids.ravel().astype(int)
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    np.fill_diagonal(d, np.inf)
    return Detection(source, size, pts, ids, float("nan"), float(np.median(d.min(axis=1))))


def _square_px(pts: np.ndarray, pattern: tuple[int, int]) -> float:
    c, r = pattern
    g = pts.reshape(r, c, 2)
    steps = np.r_[np.linalg.norm(np.diff(g, axis=1), axis=2).ravel(), np.linalg.norm(np.diff(g, axis=0), axis=2).ravel()]
    return float(np.median(steps))


def _subpix_window(pts: np.ndarray, pattern: tuple[int, int]) -> int:
    """Half-window for ``cornerSubPix``: 11 px (OpenCV's sample), less for small squares."""
    return int(np.clip(0.4 * _square_px(pts, pattern), 3, 11))


def canonical_order(gray: np.ndarray, corners: np.ndarray, pattern: tuple[int, int]) -> np.ndarray:
    """Order checkerboard corners (N, 2) so that the square after corner 0 is dark.

    OpenCV may return the corners of a view in either of two orders (a 180-degree turn). When
    ``cols + rows`` is odd the two end squares differ in colour, which fixes corner 0 on the
    printed board, so every camera and every view agrees on the board frame.
    """
    c, r = pattern
    if (c + r) % 2 == 0:
        return corners
    first = _square_mean(gray, corners[[0, 1, c + 1, c]])
    last = _square_mean(gray, corners[[-1, -2, -c - 2, -c - 1]])
    return corners if first <= last else corners[::-1].copy()


def _square_mean(gray: np.ndarray, quad: np.ndarray) -> float:
    """Mean grey level inside the quadrilateral (4, 2), shrunk towards its centre."""
    centre = quad.mean(axis=0)
    poly = (centre + 0.5 * (quad - centre)).round().astype(np.int32)
    mask = np.zeros(gray.shape, np.uint8)
    cv2.fillConvexPoly(mask, poly, 255)
    return float(cv2.mean(gray, mask)[0])


def is_blurred(det: Detection, max_fraction: float = MAX_BLUR_FRACTION) -> bool:
    """Whether a detection is too blurred to calibrate with (NaN sharpness counts as sharp)."""
    f = det.blur_fraction
    return bool(np.isfinite(f) and f > max_fraction)
