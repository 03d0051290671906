"""Coverage of the head and feet by a run's masks (gaitcap.evaluation.silhouettes.part_coverage):
the measure behind "no frame in which the head or a foot is missing while in view"."""

from __future__ import annotations

import cv2
import h5py
import numpy as np

from gaitcap.camera import Camera
from gaitcap.evaluation.silhouettes import PARTS, part_coverage
from gaitcap.trajectory import Trajectory

CAM = Camera.look_at("cam1", position=(0.0, -4.0, 1.0), target=(0.0, 0.0, 0.9))
NAMES = ("head", "heel_l", "toe_l", "heel_r", "toe_r")


def _truth(n: int) -> Trajectory:
    """A still person: head at 1.6 m, feet apart along x on the floor; frame 2 walks the head out
    of the image (2 m above it)."""
    base = np.array([[0.0, 0.0, 1.6], [-0.3, 0.0, 0.0], [-0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.4, 0.0, 0.0]])
    pts = np.repeat(base[None], n, axis=0)
    if n > 2:
        pts[2, 0, 2] = 3.6
    return Trajectory(NAMES, pts, 25.0)


def _discs(truth: Trajectory, k: int, parts: tuple[str, ...]) -> np.ndarray:
    """A (480, 640) 0/1 mask of the named parts' discs (radius as the measure takes it)."""
    mask = np.zeros((480, 640), np.uint8)
    for part in parts:
        names, radius = PARTS[part]
        centre = np.mean([truth.point(n)[k] for n in names], axis=0)
        px = CAM.project(centre[None])[0]
        r = CAM.matrix[0, 0] * radius / CAM.to_camera(centre[None])[0, 2]
        cv2.circle(mask, (int(round(px[0])), int(round(px[1]))), int(r), 1, -1)
    return mask


def _write(path, masks: np.ndarray) -> None:
    with h5py.File(path, "w") as f:
        f.create_dataset("cam1", data=masks)


def test_a_lost_head_has_no_coverage_and_kept_feet_full(tmp_path):
    truth = _truth(3)
    ref = np.stack([_discs(truth, k, tuple(PARTS)) for k in range(3)])
    est = np.stack([_discs(truth, k, ("foot_l", "foot_r")) for k in range(3)])  # the head dropped
    est[1, :, 320:] = 0  # frame 1 also loses the right half of the image: the right foot (x > 0)
    _write(tmp_path / "ref.h5", ref)
    _write(tmp_path / "est.h5", est)
    cov = part_coverage(tmp_path / "est.h5", tmp_path / "ref.h5", CAM, truth, 3)
    assert set(cov) == {"head", "foot_l", "foot_r"}
    assert cov["head"][0] == 0.0 and cov["head"][1] == 0.0
    assert np.isnan(cov["head"][2])  # out of the image: not in view, not missing
    np.testing.assert_allclose(cov["foot_l"], 1.0)
    assert cov["foot_r"][0] == 1.0 and cov["foot_r"][1] < 0.05


def test_half_a_part_is_half_covered_and_a_truth_without_the_part_is_not_scored(tmp_path):
    truth = _truth(1)
    ref = _discs(truth, 0, tuple(PARTS))[None]
    est = ref.copy()
    head = CAM.project(truth.point("head")[:1])[0]
    est[0, : int(round(head[1])), :] = 0  # the upper half of the head's disc gone
    _write(tmp_path / "ref.h5", ref)
    _write(tmp_path / "est.h5", est)
    cov = part_coverage(tmp_path / "est.h5", tmp_path / "ref.h5", CAM, truth, 1)
    assert 0.4 < cov["head"][0] < 0.6
    feet_only = truth.subset(["heel_l", "toe_l", "heel_r", "toe_r"])
    assert set(part_coverage(tmp_path / "est.h5", tmp_path / "ref.h5", CAM, feet_only, 1)) == {"foot_l", "foot_r"}
