"""Marker gaps: a segment's markers fill each other's gaps; a ``first`` rule's later
alternatives fill the frames where the first one has none."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.spatial.transform import Rotation

from gaitcap.markers.jointcentres import apply_mapping, fill_from_donors, fill_segment_gaps
from gaitcap.markers.mapping import Mapping
from gaitcap.trajectory import Trajectory


def _rigid_body(n_frames: int = 60, seed: int = 0) -> np.ndarray:
    """Five markers of one body walking forward and turning (yaw 0-30 deg, some tilt), (T, 5, 3)."""
    rng = np.random.default_rng(seed)
    shape = rng.normal(scale=0.1, size=(5, 3))
    t = np.linspace(0.0, 1.0, n_frames)
    rot = Rotation.from_euler("zx", np.stack([30 * t, 8 * np.sin(6 * t)], axis=1), degrees=True)
    return np.stack([rot[i].apply(shape) for i in range(n_frames)]) + np.stack([1.3 * t, 0 * t, 0.9 + 0 * t], axis=1)[:, None]


def test_three_donors_fill_a_rotating_body_exactly_interior_and_end_gaps():
    body = _rigid_body()
    target = body[:, 0].copy()
    target[10:25] = np.nan  # interior gap
    target[45:] = np.nan  # to the end
    filled = fill_from_donors(target, body[:, 1:])
    np.testing.assert_allclose(filled, body[:, 0], atol=1e-9)


def test_one_donor_carries_the_translation_and_meets_both_edges():
    body = _rigid_body()
    target = body[:, 0].copy()
    target[20:30] = np.nan
    filled = fill_from_donors(target, body[:, [1]])
    np.testing.assert_allclose(filled[[19, 30]], body[[19, 30], 0])  # seen samples untouched
    # the body turns about 5 degrees over the gap: a one-donor fill is close, not exact
    err = np.linalg.norm(filled[20:30] - body[20:30, 0], axis=1)
    assert 0 < err.max() < 0.02
    # without the blend, the fill from the left edge alone would end off by the turn's effect
    jump = np.linalg.norm(filled[29] - filled[30])
    assert jump < 1.5 * np.linalg.norm(body[29, 0] - body[30, 0])


def test_a_gap_without_donors_stays():
    body = _rigid_body()
    target = body[:, 0].copy()
    target[40:] = np.nan
    donors = body[:, 1:].copy()
    donors[50:] = np.nan  # the donors leave before the gap ends: nothing carries it there
    filled = fill_from_donors(target, donors)
    assert np.isnan(filled[40:]).all()


def _markers(names: list[str], points: np.ndarray) -> Trajectory:
    return Trajectory(tuple(names), points, 50.0, 0.0, (), {"source": "test"})


def test_segment_fill_then_first_alternative_per_frame():
    body = _rigid_body()
    lab_hip = body[:, 4] + 0.01  # the lab's own centre, with its own gap
    lab_hip[50:] = np.nan
    points = np.concatenate([body[:, :4], lab_hip[:, None]], axis=1)
    points[35:, 0] = np.nan  # LASI drops out
    markers = _markers(["LASI", "RASI", "SACR", "HEAD", "LHJC"], points)
    mapping = Mapping.model_validate({
        "name": "t",
        "segments": {"pelvis": ["LASI", "RASI", "SACR"]},
        "points": {
            "pelvis": {"mean": ["LASI", "RASI"]},
            "hip_l": {"first": [{"marker": "LHJC"}, {"marker": "SACR"}]},
        },
    })  # fmt: skip
    filled = fill_segment_gaps(markers, mapping.segments)
    assert np.isfinite(filled.point("LASI")).all() and np.isnan(markers.point("LASI")[35:]).all()
    joints = apply_mapping(mapping, markers)
    hip = joints.point("hip_l")
    np.testing.assert_allclose(hip[:50], lab_hip[:50])  # the lab's where it has it
    np.testing.assert_allclose(hip[50:], body[50:, 2])  # the next rule where it has none
    assert np.linalg.norm(joints.point("pelvis")[35:] - 0.5 * (body[35:, 0] + body[35:, 1]), axis=1).max() < 0.01


def test_a_segment_of_one_marker_is_refused():
    with pytest.raises(ValidationError, match="at least two markers"):
        Mapping.model_validate({"name": "t", "segments": {"pelvis": ["SACR"]}, "points": {"pelvis": {"marker": "SACR"}}})
