"""Silhouettes drawn by the tracker's own body model, for unit tests of the filters' mechanics.

``gaitcap synth`` draws its own mannequin, which the tracker's capsules do not fit exactly. Tests of
a mechanism (does the likelihood peak at the true pose, does a swap search put swapped legs back)
need observations the model explains exactly, so that the mechanism, not the model's misfit, is
what they measure. These masks are never used to validate accuracy (that is scripts/bench_suite.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from gaitcap.body.model import BodyModel, load_body_model
from gaitcap.body.shape import project_capsules, rasterize
from gaitcap.camera import Camera, CameraRig
from gaitcap.io.calibration_toml import read_calibration
from gaitcap.synth.truth import Truth, read_truth


def model_mask(model: BodyModel, q: np.ndarray, camera: Camera) -> np.ndarray:
    """(H, W) uint8 0/1: the capsules of pose ``q`` (D,) seen by ``camera``, lens distortion included."""
    A, B, r = model.capsules(q[None])
    W, H = camera.size
    pad = 80
    pc = project_capsules(camera, A[0], B[0], r, offset=(pad, pad))
    canvas = rasterize(pc, (W + 2 * pad, H + 2 * pad)).astype(np.float32)
    gv, gu = np.mgrid[0:H, 0:W].astype(np.float32)
    und = camera.undistort_pixels(np.stack([gu.ravel(), gv.ravel()], -1)).reshape(H, W, 2).astype(np.float32)
    return (cv2.remap(canvas, und[..., 0] + pad, und[..., 1] + pad, cv2.INTER_LINEAR) >= 0.5).astype(np.uint8)


@dataclass
class ModelTruth:
    """A synthetic session's truth, with the masks redrawn by the fitted tracker model."""

    truth: Truth
    rig: CameraRig
    model: BodyModel

    @property
    def poses(self) -> np.ndarray:
        return self.truth.poses

    @property
    def attrs(self) -> dict:
        return self.truth.attrs

    @property
    def trajectory(self):
        return self.truth.trajectory

    def mask(self, camera: str, frame: int) -> np.ndarray:
        return model_mask(self.model, self.truth.poses[frame], self.rig[camera])


def model_truth_setup(session: Path) -> tuple[ModelTruth, CameraRig, BodyModel]:
    """(truth with model-drawn masks, rig, the fitted model) of a ``gaitcap synth`` session."""
    truth = read_truth(session / "truth.h5")
    rig = read_calibration(session / "calibration.toml")
    prop = truth.attrs["proportions"]
    model = load_body_model(height_m=truth.attrs["height_m"], scales=prop["scales"], shifts=prop["shifts"])
    return ModelTruth(truth, rig, model), rig, model
