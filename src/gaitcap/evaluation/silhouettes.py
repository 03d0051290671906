"""Silhouette IoU of a run's masks (``silhouettes.h5``) against a truth's masks, per camera.

Frames are matched by index (both are the video's frames from frame 0) and read a few at a
time, so memory does not grow with the video. A frame whose true silhouette is empty (the
person out of view) is not scored, only counted.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gaitcap.camera import Camera
from gaitcap.errors import InputError
from gaitcap.evaluation.metrics import iou_summary, mask_iou
from gaitcap.io.silhouettes_h5 import read_cameras, read_mask_shape, read_masks
from gaitcap.trajectory import Trajectory

#: frames read at once per camera
CHUNK_FRAMES = 16


def camera_iou(out_masks: Path, truth_masks: Path, camera: str, n_frames: int, chunk: int = CHUNK_FRAMES) -> np.ndarray:
    """(n_frames,) IoU of ``camera``'s first ``n_frames`` masks; NaN where the true mask is empty."""
    parts = []
    for start in range(0, n_frames, chunk):
        frames = slice(start, min(start + chunk, n_frames))
        est, ref = read_masks(out_masks, camera, frames), read_masks(truth_masks, camera, frames)
        iou = mask_iou(est, ref)
        iou[~ref.any(axis=(1, 2))] = np.nan
        parts.append(iou)
    return np.concatenate(parts) if parts else np.empty(0)


def silhouette_iou(out_masks: str | Path, truth_masks: str | Path) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """IoU per camera of the cameras both files hold: mean, median, 10th percentile over the scored
    frames, and the frame counts.

    Returns:
        (per camera summary, notes about cameras or frames not compared).

    Raises:
        InputError: a camera's masks have different image sizes in the two files.
    """
    out_masks, truth_masks = Path(out_masks), Path(truth_masks)
    out_cams, truth_cams = read_cameras(out_masks), read_cameras(truth_masks)
    notes = [f"silhouettes: camera {c} of the truth is not in {out_masks.name}" for c in truth_cams if c not in out_cams]
    result: dict[str, dict[str, Any]] = {}
    for cam in (c for c in truth_cams if c in out_cams):
        (n_out, *size_out), (n_ref, *size_ref) = read_mask_shape(out_masks, cam), read_mask_shape(truth_masks, cam)
        if size_out != size_ref:
            raise InputError(f"{out_masks}: masks of camera {cam!r} are {size_out[1]}x{size_out[0]}, "
                             f"the truth's ({truth_masks}) {size_ref[1]}x{size_ref[0]}")  # fmt: skip
        n = min(n_out, n_ref)
        if n_out != n_ref:
            notes.append(f"silhouettes: camera {cam}: {n_out} frames in OUT, {n_ref} in the truth; the first {n} compared")
        iou = camera_iou(out_masks, truth_masks, cam, n)
        result[cam] = {**iou_summary(iou), "frames_without_person": int(np.isnan(iou).sum()), "frames": n}
    return result, notes


#: body parts a silhouette must not lose (issue: "no frame in which the head or a foot is missing
#: while in view"): name -> (truth points averaged for its centre, radius around it in metres)
PARTS: dict[str, tuple[tuple[str, ...], float]] = {
    "head": (("head",), 0.10),
    "foot_l": (("heel_l", "toe_l"), 0.08),
    "foot_r": (("heel_r", "toe_r"), 0.08),
}
#: a part is in view when the true mask has at least this many pixels within its radius
MIN_PART_PIXELS = 20


def part_centres(truth: Trajectory) -> dict[str, np.ndarray]:
    """Each part's centre (T, 3) from the truth's points; parts whose points it lacks are left out."""
    out = {}
    for part, (names, _) in PARTS.items():
        if all(truth.has(n) for n in names):
            out[part] = np.mean([truth.point(n) for n in names], axis=0)
    return out


def project_part(camera: Camera, xyz: np.ndarray, part: str) -> tuple[np.ndarray, np.ndarray]:
    """A part's (:data:`PARTS`) centres xyz (T, 3) in the camera: pixels (T, 2) and the disc's radius
    in pixels (T,): focal length x the part's radius / depth (NaN behind the camera)."""
    pix = camera.project(xyz)
    depth = camera.to_camera(xyz)[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        radius = np.where(depth > 0, float(camera.matrix[0, 0]) * PARTS[part][1] / depth, np.nan)
    return pix, radius


def part_pixels(ref: np.ndarray, centre: np.ndarray, radius_px: float) -> tuple[tuple[slice, slice], np.ndarray] | None:
    """The true mask ``ref`` (H, W)'s pixels within ``radius_px`` of ``centre`` (2,) pixels: the disc's
    box in the image and, in it, (h, w) bool; None when fewer than :data:`MIN_PART_PIXELS` true pixels
    are there (the part out of view) or the disc is not finite."""
    h, w = ref.shape
    if not (np.isfinite(centre).all() and np.isfinite(radius_px) and radius_px > 0):
        return None
    x0, x1 = max(int(centre[0] - radius_px), 0), min(int(centre[0] + radius_px) + 1, w)
    y0, y1 = max(int(centre[1] - radius_px), 0), min(int(centre[1] + radius_px) + 1, h)
    if x0 >= x1 or y0 >= y1:
        return None
    yy, xx = np.mgrid[y0:y1, x0:x1]
    disc = (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2 <= radius_px**2
    box = np.s_[y0:y1, x0:x1]
    part = disc & (ref[box] > 0)
    return (box, part) if int(part.sum()) >= MIN_PART_PIXELS else None


def _disc_coverage(est: np.ndarray, ref: np.ndarray, centre: np.ndarray, radius_px: float) -> float:
    """Fraction of :func:`part_pixels` of ``ref`` (H, W) that ``est`` (H, W) also holds; NaN when
    there are none (out of view)."""
    found = part_pixels(ref, centre, radius_px)
    if found is None:
        return float("nan")
    box, part = found
    return float((est[box] > 0)[part].sum() / part.sum())


def part_coverage(
    out_masks: Path, truth_masks: Path, camera: Camera, truth: Trajectory, n_frames: int, chunk: int = CHUNK_FRAMES
) -> dict[str, np.ndarray]:
    """How much of each body part's true silhouette a run's masks hold, frame by frame.

    A part (:data:`PARTS`) is the disc of its radius around its true centre, projected into the
    camera (radius in pixels: focal length x radius / depth); its true silhouette is the true
    mask's pixels in that disc (the part, or whatever stands in front of it: the silhouette is the
    union), and its coverage the fraction of them the run's mask also holds. Frames are matched by
    index with the truth's frames (the truth and the video share their rate).

    Args:
        out_masks, truth_masks: the run's ``silhouettes.h5`` and the truth's masks.
        camera: the camera (its name is the masks' dataset).
        truth: the true points, one frame per video frame.
        n_frames: frames to score.
    Returns:
        part -> (n_frames,) coverage in [0, 1], NaN where the part is out of view (fewer than
        :data:`MIN_PART_PIXELS` true pixels in its disc) or the truth has no frame.
    """
    centres = part_centres(truth)
    out = {part: np.full(n_frames, np.nan) for part in centres}
    m = min(n_frames, truth.n_frames)
    for start in range(0, m, chunk):
        frames = slice(start, min(start + chunk, m))
        est, ref = read_masks(out_masks, camera.name, frames), read_masks(truth_masks, camera.name, frames)
        for part, xyz in centres.items():
            pix, radius = project_part(camera, xyz[frames], part)
            for k in range(len(pix)):
                out[part][start + k] = _disc_coverage(est[k], ref[k], pix[k], radius[k])
    return out
