"""The chord function takes the subject's own knee/ankle widths and marker diameter when the C3D
carries them (PROCESSING), the typical widths otherwise."""

from __future__ import annotations

import logging

import ezc3d
import numpy as np

from gaitcap.io.c3d import read_c3d_markers
from gaitcap.markers.jointcentres import apply_mapping
from gaitcap.markers.mapping import Mapping
from gaitcap.trajectory import Trajectory


def _c3d_with_processing(path, values: dict[str, float]) -> None:
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = ("LKNE",)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    data = np.ones((4, 1, 5))
    data[:3] = 100.0
    c["data"]["points"] = data
    for key, value in values.items():
        c.add_parameter("PROCESSING", key, [float(value)])
    c.write(str(path))


def test_reader_keeps_the_plausible_pig_measurements(tmp_path, caplog):
    path = tmp_path / "walk.c3d"
    _c3d_with_processing(path, {"LKneeWidth": 108.0, "RKneeWidth": 0.0, "LAnkleWidth": 66.0,
                                "RAnkleWidth": 6500.0, "MarkerDiameter": 14.0, "Height": 1700.0})  # fmt: skip
    with caplog.at_level(logging.WARNING):
        meta = read_c3d_markers(path).meta
    assert meta["anthropometry_mm"] == {"LKneeWidth": 108.0, "LAnkleWidth": 66.0, "MarkerDiameter": 14.0}
    assert "RAnkleWidth" in caplog.text  # 6.5 m: named and not used


def _knee_frame(meta: dict) -> Trajectory:
    """Hip, thigh wand and knee marker of a straight leg, 3 frames, (3, 3, 3)."""
    hip, wand, kne = [0.0, 0.1, 0.9], [0.06, 0.12, 0.7], [0.0, 0.16, 0.5]
    points = np.repeat(np.array([[hip, wand, kne]]), 3, axis=0)
    return Trajectory(("HIP", "LTHI", "LKNE"), points, 100.0, 0.0, (), {"source": "t", **meta})


MAPPING = Mapping.model_validate({
    "name": "t",
    "points": {"knee_l": {"chord": {"proximal": "HIP", "wand": "LTHI", "marker": "LKNE", "distance_m": 0.057,
                                    "width": "LKneeWidth"}}},
})  # fmt: skip


def test_chord_uses_the_subjects_knee_width_and_marker_diameter(caplog):
    with caplog.at_level(logging.INFO, logger="gaitcap.markers.jointcentres"):
        own = apply_mapping(MAPPING, _knee_frame({"anthropometry_mm": {"LKneeWidth": 120.0, "MarkerDiameter": 10.0}}))
    np.testing.assert_allclose(np.linalg.norm(own.point("knee_l") - [0.0, 0.16, 0.5], axis=1), 0.060 + 0.005)
    assert "LKneeWidth 120 mm" in caplog.text and "MarkerDiameter" in caplog.text


def test_chord_falls_back_to_the_typical_width(caplog):
    width_only = apply_mapping(MAPPING, _knee_frame({"anthropometry_mm": {"LKneeWidth": 120.0}}))
    np.testing.assert_allclose(np.linalg.norm(width_only.point("knee_l") - [0.0, 0.16, 0.5], axis=1), 0.060 + 0.007)
    with caplog.at_level(logging.INFO, logger="gaitcap.markers.jointcentres"):
        typical = apply_mapping(MAPPING, _knee_frame({}))
    np.testing.assert_allclose(np.linalg.norm(typical.point("knee_l") - [0.0, 0.16, 0.5], axis=1), 0.057)
    assert "no LKneeWidth in the file" in caplog.text
