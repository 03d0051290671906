"""trajectories.h5 round trip, C3D export read back by ezc3d and by the c3d package."""

from __future__ import annotations

import warnings

import ezc3d
import h5py
import numpy as np
import pytest
from gait_walker import Walker

from gaitcap.errors import InputError
from gaitcap.io.c3d_export import write_c3d
from gaitcap.io.trajectories_h5 import read_trajectory, write_trajectory
from gaitcap.trajectory import GaitEvent, Trajectory


def _traj() -> Trajectory:
    tr = Walker(duration=1.5).trajectory()
    pts = tr.points.copy()
    pts[10] = np.nan  # a flagged frame
    ev = (GaitEvent(0.23, "right", "foot_strike"), GaitEvent(0.912, "right", "foot_off"), GaitEvent(0.78, "left", "foot_strike"))
    return Trajectory(tr.names, pts, tr.rate_hz, t0_s=1.52, events=ev)


def test_trajectories_h5_round_trip(tmp_path, rng) -> None:
    tr = _traj()
    unc = rng.uniform(0, 0.02, (tr.n_frames, len(tr.names)))
    q = np.zeros(tr.n_frames, dtype=np.uint8)
    q[10] = 2
    write_trajectory(tmp_path / "trajectories.h5", tr, uncertainty=unc, quality=q)
    back = read_trajectory(tmp_path / "trajectories.h5")
    assert back.names == tr.names and back.rate_hz == tr.rate_hz and back.t0_s == tr.t0_s
    np.testing.assert_array_equal(back.points, tr.points)  # NaN frames stay NaN
    assert [(e.time_s, e.side, e.event) for e in back.events] == [(e.time_s, e.side, e.event) for e in tr.events]
    np.testing.assert_array_equal(back.meta["uncertainty"], unc)
    np.testing.assert_array_equal(back.meta["quality"], q)
    with h5py.File(tmp_path / "trajectories.h5") as f:
        assert [f[k].attrs["units"] for k in ("points", "uncertainty", "times", "events/time_s")] == ["m", "m", "s", "s"]
        assert "units" not in f["quality"].attrs  # a code, not a quantity


def test_trajectories_h5_errors_name_the_file(tmp_path) -> None:
    with pytest.raises(InputError, match="not found"):
        read_trajectory(tmp_path / "none.h5")
    (tmp_path / "bad.h5").write_text("not hdf5")
    with pytest.raises(InputError, match="bad.h5"):
        read_trajectory(tmp_path / "bad.h5")


def test_trajectories_h5_with_incomplete_events_is_an_input_error(tmp_path) -> None:
    """A hand-made trajectories.h5 whose /events lacks a dataset (or a compound one a field) raised h5py's
    KeyError (or numpy's ValueError) from read_trajectory: an InputError naming the file and what is missing."""
    path = tmp_path / "t.h5"
    with h5py.File(path, "w") as f:
        d = f.create_dataset("points", data=np.zeros((5, 1, 3)))
        d.attrs["names"], d.attrs["rate_hz"] = ["pelvis"], 25.0
        f.create_dataset("events/time_s", data=[0.1])
    with pytest.raises(InputError, match=r"t\.h5: /events has no side, event dataset"):
        read_trajectory(path)
    with h5py.File(path, "a") as f:
        del f["events"]
        f.create_dataset("events", data=np.array([(0.1,)], dtype=[("time_s", "f8")]))
    with pytest.raises(InputError, match=r"t\.h5: /events has no field side, event"):
        read_trajectory(path)


@pytest.mark.parametrize("rate", [0.0, -5.0, float("nan"), "fast"])
def test_resampling_at_a_rate_that_is_not_positive_is_an_input_error(rate) -> None:
    """Trajectory.resample(-5) raised numpy's "negative dimensions are not allowed", NaN "cannot convert
    float NaN to integer", 0 a RuntimeWarning before the InputError of the new trajectory's rate; a
    trajectory of no frame an IndexError."""
    traj = Trajectory(("pelvis",), np.zeros((4, 1, 3)), 25.0)
    with pytest.raises(InputError, match="cannot resample at .* Hz: the rate must be a positive number"):
        traj.resample(rate)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="cannot resample a trajectory of no frame"):
        Trajectory(("pelvis",), np.zeros((0, 1, 3)), 25.0).resample(50.0)
    assert traj.resample(np.int64(50)).n_frames == 7


def test_c3d_export_is_read_back_by_ezc3d_and_c3d(tmp_path) -> None:
    tr = _traj()
    path = tmp_path / "out.c3d"
    write_c3d(path, tr)
    c = ezc3d.c3d(str(path))
    assert c["header"]["points"]["first_frame"] == 152
    assert tuple(c["parameters"]["POINT"]["LABELS"]["value"]) == tr.names
    assert c["parameters"]["POINT"]["UNITS"]["value"] == ["mm"]
    pts = c["data"]["points"][:3].transpose(2, 1, 0) / 1000.0
    np.testing.assert_allclose(pts[~np.isnan(tr.points)], tr.points[~np.isnan(tr.points)], atol=1e-5)
    assert np.isnan(pts[10]).all()
    ev = c["parameters"]["EVENT"]
    got = sorted(zip(ev["TIMES"]["value"][1], ev["CONTEXTS"]["value"], ev["LABELS"]["value"], strict=True))
    assert [(round(t, 4), ctx, lab) for t, ctx, lab in got] == [
        (0.23, "Right", "Foot Strike"), (0.78, "Left", "Foot Strike"), (0.912, "Right", "Foot Off"),
    ]  # fmt: skip

    import c3d

    with open(path, "rb") as f, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "no analog data"
        r = c3d.Reader(f)
        assert r.first_frame == 153 and r.point_rate == tr.rate_hz
        labels = [s.strip() for s in r.get("EVENT:LABELS").string_array]
        assert r.get_int16("EVENT:USED") == 3  # an integer, as readers take it (it was stored as a float: 0)
        for name, expected in (("ICON_IDS", [1, 1, 2]), ("GENERIC_FLAGS", [0, 0, 0])):
            param = r.get(f"EVENT:{name}")
            assert param.bytes_per_element == 2 and sorted(param.int16_array) == expected  # integers (were floats)
        times = r.get("EVENT:TIMES").float_array[:, 1]
        frames = [p for _, p, _ in r.read_frames()]
    assert sorted(labels) == ["Foot Off", "Foot Strike", "Foot Strike"]
    np.testing.assert_allclose(sorted(times), [0.23, 0.78, 0.912], atol=1e-6)
    assert len(frames) == tr.n_frames
    ok = np.isfinite(tr.points[0]).all(axis=1)
    np.testing.assert_allclose(frames[0][ok, :3] / 1000.0, tr.points[0][ok], atol=1e-5)
    assert (frames[0][~ok, 3] == -1).all() and (frames[10][:, 3] == -1).all()  # missing = invalid points


def test_c3d_export_states_its_up_axis(tmp_path) -> None:
    """The file said nothing of its axes (no POINT:X_SCREEN/Y_SCREEN, which Vicon writes as +X/+Z and viewers and
    readers orient the data from); gaitcap's own reader took z up only by default."""
    from gaitcap.io.c3d import read_c3d_markers

    tr = _traj()
    path = tmp_path / "out.c3d"
    write_c3d(path, tr)
    point = ezc3d.c3d(str(path))["parameters"]["POINT"]
    assert point["X_SCREEN"]["value"] == ["+X"] and point["Y_SCREEN"]["value"] == ["+Z"]
    import c3d

    with open(path, "rb") as f, warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        r = c3d.Reader(f)
        assert r.get("POINT:Y_SCREEN").string_value.strip() == "+Z"
    assert read_c3d_markers(path).meta["up_axis"] == "z"
