"""Intrinsic calibration of one camera from board views (OpenCV ``calibrateCamera``).

Reprojection error convention (OpenCV's): RMS = sqrt(sum ||x_ij - x̂_ij||² / N) over all N
corners; per view the same over that view's corners.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from gaitcap.calibration.boards import Board, Detection
from gaitcap.camera import Camera
from gaitcap.errors import CalibrationError

log = logging.getLogger(__name__)

MIN_VIEWS = 3
COVERAGE_GRID = (4, 4)


@dataclass
class IntrinsicsResult:
    """Outcome of :func:`calibrate_intrinsics`.

    Attributes:
        camera: the calibrated camera (identity extrinsics).
        rms_px: overall RMS reprojection error, pixels.
        per_view_px: ``source -> RMS`` of each used view, pixels.
        coverage: fraction of the image grid cells (``COVERAGE_GRID``) that hold corners.
        uncovered: names of the uncovered cells, such as ``"top-left"``.
        rvecs, tvecs: board pose in each used view, shapes (V, 3).
    """

    camera: Camera
    rms_px: float
    per_view_px: dict[str, float]
    coverage: float
    uncovered: list[str] = field(default_factory=list)
    rvecs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    tvecs: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def metadata(self) -> dict:
        """The summary stored in ``calibration.toml``'s ``[metadata]`` table."""
        return {
            "error": round(self.rms_px, 4),
            "intrinsics_rms_px": {self.camera.name: round(self.rms_px, 4)},
            "intrinsics_views": {self.camera.name: len(self.per_view_px)},
            "intrinsics_coverage": {self.camera.name: round(self.coverage, 3)},
        }


def select_spread(detections: Sequence[Detection], n: int) -> list[Detection]:
    """Choose ``n`` views that differ most (greedy farthest-point sampling).

    Each view is described by where the board is (centre, normalised by the image size), how
    big it looks and how it is tilted (the aspect of its corner bounding box), so the chosen
    frames of a video cover the image and the range of poses instead of n near-copies.
    """
    if len(detections) <= n:
        return list(detections)
    feats = np.array([_view_descriptor(d) for d in detections])
    feats = (feats - feats.mean(axis=0)) / (feats.std(axis=0) + 1e-9)
    chosen = [int(np.argmax(np.linalg.norm(feats - feats.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(feats - feats[chosen[0]], axis=1)
    while len(chosen) < n:
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(feats - feats[k], axis=1))
    return [detections[k] for k in sorted(chosen)]


def _view_descriptor(det: Detection) -> np.ndarray:
    w, h = det.image_size
    pts = det.corners
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 1.0)
    return np.array([pts[:, 0].mean() / w, pts[:, 1].mean() / h, np.sqrt(span.prod() / (w * h)), np.log(span[0] / span[1])])


def coverage(detections: Sequence[Detection], image_size: tuple[int, int], grid: tuple[int, int] = COVERAGE_GRID) -> tuple[float, list[str]]:
    """Fraction of image cells (``grid`` = columns, rows) holding a corner, and the empty cells."""
    w, h = image_size
    gx, gy = grid
    hit = np.zeros((gy, gx), bool)
    for det in detections:
        ix = np.clip((det.corners[:, 0] / w * gx).astype(int), 0, gx - 1)
        iy = np.clip((det.corners[:, 1] / h * gy).astype(int), 0, gy - 1)
        hit[iy, ix] = True
    names = [f"{_band(iy, gy, ('top', 'middle', 'bottom'))}-{_band(ix, gx, ('left', 'centre', 'right'))}" for iy, ix in zip(*np.nonzero(~hit))]
    return float(hit.mean()), names


def _band(i: int, n: int, words: tuple[str, str, str]) -> str:
    if i == 0:
        return words[0]
    if i == n - 1:
        return words[2]
    return f"{words[1]}{i}"


def calibrate_intrinsics(
    detections: Sequence[Detection],
    board: Board,
    name: str = "cam",
    fix_aspect_ratio: bool = False,
    fix_k3: bool = False,
    zero_tangent: bool = False,
    max_views: int | None = None,
) -> IntrinsicsResult:
    """Calibrate one camera from its board views.

    Args:
        detections: views of one camera (all the same image size), at least ``MIN_VIEWS``.
        board: the board that was detected.
        name: camera name of the result.
        fix_aspect_ratio: fx = fy (OpenCV ``CALIB_FIX_ASPECT_RATIO`` with an initial ratio of 1).
        fix_k3: estimate k1, k2, p1, p2 only (advisable with few views or a small board).
        zero_tangent: p1 = p2 = 0.
        max_views: use at most this many views, chosen by :func:`select_spread`.

    Raises:
        CalibrationError: fewer than ``MIN_VIEWS`` views, or OpenCV fails.
    """
    dets = list(detections)
    if len(dets) < MIN_VIEWS:
        raise CalibrationError(
            f"camera {name!r}: only {len(dets)} usable view(s) of the {board.describe()}; at least {MIN_VIEWS} are needed"
        )
    if max_views:
        dets = select_spread(dets, max_views)
    size = dets[0].image_size
    obj = board.object_points().astype(np.float32)
    objs = [obj[d.ids] for d in dets]
    imgs = [d.corners.astype(np.float32).reshape(-1, 1, 2) for d in dets]
    flags = 0
    K0 = None
    if fix_aspect_ratio:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
        K0 = np.eye(3)
    if fix_k3:
        flags |= cv2.CALIB_FIX_K3
    if zero_tangent:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    try:
        rms, K, dist, rvecs, tvecs, _, _, per_view = cv2.calibrateCameraExtended(objs, imgs, size, K0, None, flags=flags)
    except cv2.error as e:
        raise CalibrationError(f"camera {name!r}: OpenCV calibration failed: {e.err}") from e
    dist = dist.ravel()[:5]
    cam = Camera(name=name, size=size, matrix=K, dist=dist)
    cov, empty = coverage(dets, size)
    result = IntrinsicsResult(
        camera=cam,
        rms_px=float(rms),
        per_view_px={d.source: float(e) for d, e in zip(dets, per_view.ravel())},
        coverage=cov,
        uncovered=empty,
        rvecs=np.array([r.ravel() for r in rvecs]),
        tvecs=np.array([t.ravel() for t in tvecs]),
    )
    if empty:
        log.warning(
            "camera %r: no board corner in %d of %d image regions (%s): distortion there is extrapolated; add views with the board in those parts",
            name, len(empty), COVERAGE_GRID[0] * COVERAGE_GRID[1], ", ".join(empty),
        )
    return result
