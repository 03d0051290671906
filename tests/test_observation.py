"""The tracker's observation of a silhouette: binary masks and soft confidences on the tracking grid."""

from __future__ import annotations

import numpy as np

from gaitcap.camera import Camera
from gaitcap.tracking.observation import Observation, TrackingView


def _view(scale: float = 0.5) -> TrackingView:
    cam = Camera("c", (80, 60), np.array([[100.0, 0, 40], [0, 100.0, 30], [0, 0, 1]]))
    return TrackingView.of(cam, scale)


def test_an_integer_mask_is_binary_whatever_its_values():
    mask = np.zeros((60, 80), np.uint8)
    mask[10:30, 20:40] = 255
    s = _view().prepare(mask)
    assert s.shape == (30, 40) and s.dtype == np.float32
    assert s.max() == 1.0 and s[5:15, 10:20].min() == 1.0 and s.sum() == 100.0


def test_a_float_mask_keeps_its_confidence_and_is_clipped_to_0_1():
    soft = np.zeros((60, 80), np.float32)
    soft[10:30, 20:40] = 0.5  # doubtful
    soft[40:50, 20:40] = 1.7  # out of range: clipped to sure
    s = _view().prepare(soft)
    assert np.allclose(s[5:15, 10:20], 0.5) and np.allclose(s[20:25, 10:20], 1.0)
    assert s.min() == 0.0


def test_given_areas_are_the_areas_and_survive_a_spool_round_trip():
    """Soft silhouettes with doubt outside the masks count |S_c| as the masks' areas (``given_areas``):
    what a spool stores (:meth:`Observation.arrays`) reads back to the same silhouettes and areas."""
    a = np.zeros((30, 40), np.float32)
    a[5:15, 10:20] = 1.0
    a[15:20, 10:20] = 0.25  # doubt outside the mask
    b = np.ones((30, 40), np.float32)
    plain = Observation([a, b])
    assert plain.arrays() == [a, b] and np.allclose(plain.areas, [a.sum(), b.sum()])
    again = Observation.from_arrays(plain.arrays())
    assert again.given_areas is None and np.allclose(again.areas, plain.areas)
    given = Observation([a, b], given_areas=np.array([100.0, 1200.0]))
    stored = given.arrays()
    assert len(stored) == 3 and stored[-1].dtype == np.float32
    back = Observation.from_arrays(stored)
    assert len(back.silhouettes) == 2 and np.array_equal(back.silhouettes[0], a)
    assert np.allclose(back.areas, [100.0, 1200.0]) and np.allclose(given.areas, [100.0, 1200.0])
