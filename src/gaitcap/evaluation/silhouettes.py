"""Silhouette IoU of a run's masks (``silhouettes.h5``) against a truth's masks, per camera.

Frames are matched by index (both are the video's frames from frame 0) and read a few at a
time, so memory does not grow with the video. A frame whose true silhouette is empty (the
person out of view) is not scored, only counted.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gaitcap.errors import InputError
from gaitcap.evaluation.metrics import iou_summary, mask_iou
from gaitcap.io.silhouettes_h5 import read_cameras, read_mask_shape, read_masks

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
