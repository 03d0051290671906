"""Segment lengths measured from joint centres (gaitcap.body.measures)."""

import numpy as np
import pytest

from gaitcap.body.measures import length_errors, model_lengths, outside_ranges, segment_lengths
from gaitcap.body.model import load_body_model


def test_lengths_are_medians_over_frames_and_sides_skipping_gaps():
    names = ["hip_l", "hip_r", "knee_l", "knee_r", "ankle_l", "ankle_r"]
    P = np.zeros((3, 6, 3))
    P[:, 1, 1] = 0.2  # hips 0.2 m apart
    P[:, 2] = [0, 0, -0.40]
    P[:, 3] = [0, 0.2, -0.44]  # right thigh 0.44
    P[:, 4] = [0, 0, -0.80]
    P[:, 5] = [0, 0.2, -0.84]
    P[2, 3] = np.nan  # a gap: that frame's right thigh and shank are skipped
    got = segment_lengths(names, P)
    assert got["pelvis_width"] == pytest.approx(0.2)
    assert got["thigh"] == pytest.approx(np.median([0.4, 0.4, 0.4, 0.44, 0.44]))
    assert got["shank"] == pytest.approx(0.4)
    assert got["leg"] == pytest.approx(got["thigh"] + got["shank"])
    assert "foot" not in got and "upper_arm" not in got  # their points are absent


def test_model_lengths_scale_with_height_and_errors_are_relative():
    a, b = model_lengths(load_body_model(height_m=1.0)), model_lengths(load_body_model(height_m=2.0))
    assert set(a) >= {"thigh", "shank", "leg", "pelvis_width", "foot"}
    for k in a:
        assert b[k] == pytest.approx(2 * a[k])
    assert length_errors(b, a) == pytest.approx({k: 1.0 for k in a})


def test_outside_ranges_names_the_length_and_its_ratio():
    lengths = {"leg": 0.60, "thigh": 0.40}
    problems = outside_ranges(lengths, 2.0, {"leg": (0.40, 0.56), "thigh": (0.19, 0.30), "shank": (0.19, 0.30)})
    assert problems == ["leg 0.600 m is 0.300 of the height, outside 0.40-0.56"]
    assert outside_ranges(lengths, 1.2, {"leg": (0.40, 0.56), "thigh": (0.19, 0.34)}) == []


def test_shipped_body_is_within_the_shipped_ranges_at_every_height():
    from gaitcap.tracking.config import load_tracking_config

    ranges = load_tracking_config().shape.ranges
    assert {"leg", "thigh", "shank", "pelvis_width"} <= set(ranges)
    for h in (1.0, 1.5, 2.0):
        assert outside_ranges(model_lengths(load_body_model(height_m=h)), h, ranges) == []
