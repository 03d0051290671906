"""OpenSim .mot reading and force-threshold crossings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitcap.errors import InputError
from gaitcap.io.mot import read_mot
from gaitcap.markers.events import threshold_crossings

GRF = Path(__file__).resolve().parent / "fixtures" / "walking" / "subject01_walk1_grf.mot"


def test_read_grf_table():
    table = read_mot(GRF)
    assert table.data.shape == (1501, 19)
    assert table.columns[:3] == ("time", "ground_force_vx", "ground_force_vy")
    assert table.header["nRows"] == "1501" and table.in_degrees
    assert table.time[0] == 0.0 and table.time[-1] == pytest.approx(2.5)
    assert table.column("ground_force_vy")[0] == pytest.approx(745.4661142)
    with pytest.raises(InputError, match="ground_force_vw"):
        table.column("ground_force_vw")


def test_not_a_mot_file(tmp_path):
    bad = tmp_path / "x.mot"
    bad.write_text("time\tx\n0\t1\n")
    with pytest.raises(InputError, match="endheader"):
        read_mot(bad)


def test_threshold_crossings_are_interpolated():
    t = np.arange(11) * 0.1
    f = np.array([0, 0, 10, 30, 50, 50, 30, 10, 0, 0, 0], dtype=float)
    up, down = threshold_crossings(t, f, 20.0)
    np.testing.assert_allclose(up, [0.25])
    np.testing.assert_allclose(down, [0.65])
