"""TRC reading and writing: header, units, axes, gaps, round trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitcap.errors import InputError
from gaitcap.io.trc import read_trc, write_trc
from gaitcap.markers.axes import from_z_up, rotation_to_z_up, to_z_up
from gaitcap.markers.motion import read_markers
from gaitcap.trajectory import Trajectory

WALK = Path(__file__).resolve().parent / "fixtures" / "walking" / "subject01_walk1.trc"


def _random_traj(rng: np.random.Generator, n_frames: int = 7) -> Trajectory:
    pts = rng.uniform(-1.0, 2.0, size=(n_frames, 3, 3))
    pts[2, 1] = np.nan  # a gap
    return Trajectory(("a", "b.mid", "c"), pts, rate_hz=50.0, t0_s=0.2)


def test_fixture_header_and_units():
    traj = read_trc(WALK)
    assert traj.points.shape == (151, 41, 3)
    assert traj.rate_hz == 60.0 and traj.t0_s == 0.0
    assert traj.names[:3] == ("R.ASIS", "L.ASIS", "V.Sacral")
    # first R.ASIS sample of the file is 617.247620 1055.275020 170.781980 mm
    np.testing.assert_allclose(traj.points[0, 0], [0.61724762, 1.05527502, 0.17078198])


@pytest.mark.parametrize("units", ["mm", "m"])
def test_round_trip(tmp_path, rng, units):
    traj = _random_traj(rng)
    path = write_trc(tmp_path / "x.trc", traj, units=units)
    back = read_markers(path, up_axis="y")
    assert back.names == traj.names
    assert back.rate_hz == traj.rate_hz
    assert back.t0_s == pytest.approx(traj.t0_s)
    np.testing.assert_array_equal(np.isnan(back.points), np.isnan(traj.points))
    np.testing.assert_allclose(back.points, traj.points, atol=1e-6, equal_nan=True)


def test_written_layout_follows_opensim(tmp_path, rng):
    traj = _random_traj(rng, n_frames=4)
    lines = write_trc(tmp_path / "x.trc", traj).read_text().split("\n")
    assert lines[0].split("\t")[:3] == ["PathFileType", "4", "(X/Y/Z)"]
    assert lines[1].split("\t") == ["DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units",
                                    "OrigDataRate", "OrigDataStartFrame", "OrigNumFrames"]  # fmt: skip
    assert lines[2].split("\t") == ["50.00", "50.00", "4", "3", "mm", "50.00", "1", "4"]
    assert lines[3].split("\t")[:6] == ["Frame#", "Time", "a", "", "", "b.mid"]
    assert lines[4].split("\t")[2:5] == ["X1", "Y1", "Z1"]
    assert lines[5] == ""
    row3 = lines[8].split("\t")
    assert row3[0] == "3" and row3[5:8] == ["", "", ""]  # the gap of point b in frame 3


def _opensim_cells(line: str) -> list[str]:
    """A data row cut as OpenSim 4.6's TRCFileAdapter cuts it (FileAdapter::tokenize on tabs): every cell a tab
    ends is kept, even empty, but the last cell only when it is not empty."""
    cells = line.split("\t")
    return cells if cells[-1] else cells[:-1]


def test_rows_with_the_last_marker_missing_keep_their_columns_for_opensim(tmp_path, rng):
    """A frame the tracker flagged is NaN for every point; OpenSim refused such a joints.trc ("Unexpected number of
    columns in line 17. Expected = 62. Received = 61"): the row's empty last cell was dropped."""
    traj = _random_traj(rng, n_frames=5)
    pts = traj.points.copy()
    pts[1] = np.nan  # a flagged frame: every point missing
    pts[3, 2] = np.nan  # the last marker alone missing
    traj = Trajectory(traj.names, pts, rate_hz=traj.rate_hz, t0_s=traj.t0_s)
    path = write_trc(tmp_path / "x.trc", traj)
    rows = path.read_text().split("\n")[6:-1]
    assert len(rows) == 5
    for row in rows:
        assert len(_opensim_cells(row)) == 2 + 3 * len(traj.names), row
    back = read_markers(path, up_axis="y")
    np.testing.assert_array_equal(np.isnan(back.points), np.isnan(pts))
    np.testing.assert_allclose(back.points, pts, atol=1e-6, equal_nan=True)
    assert [len(_opensim_cells(r)) for r in WALK.read_text().split("\n")[6:9]] == [2 + 3 * 41] * 3  # OpenSim's own file


def test_metres_and_millimetres_give_the_same_markers(tmp_path, rng):
    traj = _random_traj(rng)
    a = read_markers(write_trc(tmp_path / "m.trc", traj, units="m"))
    b = read_markers(write_trc(tmp_path / "mm.trc", traj, units="mm"))
    np.testing.assert_allclose(a.points, b.points, atol=1e-6)


def test_y_up_file_is_rotated_to_z_up(tmp_path):
    # a marker 1.7 m up and 0.3 m forward in a y-up file
    text = (
        "PathFileType\t4\t(X/Y/Z)\tt.trc\n"
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
        "100\t100\t2\t1\tm\t100\t1\t2\n"
        "Frame#\tTime\tHead\t\t\n\t\tX1\tY1\tZ1\n\n"
        "1\t0.00\t0.3\t1.7\t0.1\n2\t0.01\t\t\t\n"
    )
    path = tmp_path / "t.trc"
    path.write_text(text)
    traj = read_markers(path)  # TRC default: y up
    np.testing.assert_allclose(traj.points[0, 0], [0.3, -0.1, 1.7])
    assert np.isnan(traj.points[1, 0]).all()
    assert traj.meta["file_up_axis"] == "y"
    np.testing.assert_allclose(read_markers(path, up_axis="z").points[0, 0], [0.3, 1.7, 0.1])


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_up_rotations_are_proper_and_invertible(axis, rng):
    r = rotation_to_z_up(axis)
    assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(r @ np.eye(3)["xyz".index(axis)], [0, 0, 1])
    p = rng.normal(size=(5, 3))
    np.testing.assert_allclose(from_z_up(to_z_up(p, axis), axis), p)


def test_opensim_walk_is_z_up():
    traj = read_markers(WALK)
    head = traj.point("Top.Head")
    assert np.nanmedian(head[:, 2]) > 1.5  # standing subject: head well above the floor


def test_malformed_trc_names_the_file(tmp_path):
    bad = tmp_path / "bad.trc"
    bad.write_text("hello\n")
    with pytest.raises(InputError, match="bad.trc"):
        read_trc(bad)
