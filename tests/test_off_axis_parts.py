"""A mask's main parts away from the person's vertical axis are dropped (calibrated cameras,
``cleanup.keep_radius_m``): the far end of a long shadow cut off from the feet, someone else in view;
the person's own parts, even split in two, stay."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from gaitcap.camera import Camera
from gaitcap.silhouette.extract import FrameQuality
from gaitcap.silhouette.joint import _without, off_axis_parts, person_region

SIZE = (640, 480)
TOP = np.array([0.1, -0.2, 1.7])  # the person's head top


def _camera(azimuth_deg: float = 20.0) -> Camera:
    a = np.radians(azimuth_deg)
    return Camera.look_at("c", (5 * np.cos(a), 5 * np.sin(a), 1.5), (0.0, 0.0, 0.8), size=SIZE, focal_px=500.0)


def _fill(camera: Camera, points: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """``mask`` (H, W) uint8 with the convex hull of ``points`` (N, 3) drawn as 1."""
    mask = np.zeros((SIZE[1], SIZE[0]), np.uint8) if mask is None else mask
    cv2.fillConvexPoly(mask, cv2.convexHull(camera.project(points).astype(np.float32)).astype(np.int32), 1)
    return mask


def _box(x: float, y: float, z0: float, z1: float) -> np.ndarray:
    return np.array([[x + dx, y + dy, z] for dx in (-0.2, 0.2) for dy in (-0.15, 0.15) for z in (z0, z1)])


def _floor_patch(x: float, y: float, size: float = 0.8) -> np.ndarray:
    """A square of floor (a shadow's far end), more than 15 % of the person's area in the test camera."""
    return np.array([[x, y, 0.0], [x + size, y, 0.0], [x + size, y + size, 0.0], [x, y + size, 0.0]])


def test_the_person_region_holds_the_person_and_not_the_floor_a_metre_aside():
    cam = _camera()
    region = person_region(cam, TOP, 0.6)
    person = _fill(cam, _box(TOP[0], TOP[1], 0.0, TOP[2])).astype(bool)
    aside = _fill(cam, _floor_patch(TOP[0] + 0.3, TOP[1] - 1.8)).astype(bool)
    assert region[person].all()
    assert not region[aside].any()


def test_a_floor_patch_away_from_the_person_is_dropped_and_the_person_kept():
    cam = _camera()
    mask = _fill(cam, _box(TOP[0], TOP[1], 0.0, TOP[2]))
    person = mask.astype(bool).copy()
    patch = _fill(cam, _floor_patch(TOP[0] + 0.3, TOP[1] - 1.8)).astype(bool)
    mask[patch] = 1
    assert (person & patch).sum() == 0  # apart in this view
    drop = off_axis_parts(mask, cam, TOP, 0.6, relative=0.15)
    assert drop is not None
    assert drop[patch].all() and not drop[person].any()


def test_someone_standing_away_from_the_person_is_left_alone():
    """An upright part away from the axis may be someone else whose head was the one triangulated:
    only parts lying on the floor are dropped."""
    cam = _camera()
    mask = _fill(cam, _box(TOP[0], TOP[1], 0.0, TOP[2]))
    other = _fill(cam, _box(TOP[0] + 0.3, TOP[1] - 1.8, 0.0, 1.6)).astype(bool)
    mask[other] = 1
    assert off_axis_parts(mask, cam, TOP, 0.6, relative=0.15) is None


@pytest.mark.parametrize("case", ["alone", "split at the hips", "every part away"])
def test_nothing_is_dropped_unless_some_main_part_is_the_persons(case: str):
    cam = _camera()
    if case == "alone":
        mask = _fill(cam, _box(TOP[0], TOP[1], 0.0, TOP[2]))
    elif case == "split at the hips":  # trousers the colour of the wall behind: two main parts, both the person's
        mask = _fill(cam, _box(TOP[0], TOP[1], 0.0, 0.8))
        _fill(cam, _box(TOP[0], TOP[1], 0.95, TOP[2]), mask)
        assert cv2.connectedComponents(mask)[0] - 1 == 2
    else:  # the person not where the last frame's head top says (lost): nothing to go by, nothing dropped
        mask = _fill(cam, _floor_patch(TOP[0] + 0.3, TOP[1] - 1.8))
        _fill(cam, _floor_patch(TOP[0] - 1.5, TOP[1] + 1.5), mask)
    assert off_axis_parts(mask, cam, TOP, 0.6, relative=0.15) is None


def test_dropped_pixels_update_the_frames_quality():
    mask = np.zeros((40, 60), np.uint8)
    mask[5:15, 5:15] = 1
    mask[20:35, 40:55] = 1
    quality = FrameQuality(index=3, fraction=float(mask.mean()), shadow_fraction=0.01, components=2,
                           bbox=(5, 5, 50, 30), flags=0)  # fmt: skip
    drop = np.zeros(mask.shape, bool)
    drop[5:15, 5:15] = True
    left, q = _without((mask, quality), drop)
    assert not left[5:15, 5:15].any() and left[20:35, 40:55].all()
    assert (q.index, q.components, q.bbox, q.shadow_fraction) == (3, 1, (40, 20, 15, 15), 0.01)
    assert q.fraction == pytest.approx(225 / mask.size)
    assert _without((mask, quality), None) == (mask, quality)
