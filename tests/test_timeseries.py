"""The zero-lag filtering shared by the tracking output's smoothing and the gait analysis, and the
smoothing of the trajectories gaitcap track writes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter

from gaitcap.gait.signals import lowpass as gait_lowpass
from gaitcap.io.track_h5 import QUALITY_OK, QUALITY_POOR_FIT
from gaitcap.pipeline import _finish_points
from gaitcap.timeseries import filtfilt_runs, finite_runs
from gaitcap.tracking.config import load_tracking_config
from gaitcap.tracking.smoothing import lowpass as track_lowpass

RATE = 25.0


def test_finite_runs_are_the_runs_of_true():
    assert finite_runs(np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], bool)) == [(0, 2), (4, 5), (6, 9)]
    assert finite_runs(np.zeros(3, bool)) == []


def test_each_run_is_filtered_on_its_own_and_short_runs_are_kept():
    """A gap splits the signal: each side equals the filter of that side alone (nothing reaches
    across the gap), NaN rows stay NaN, and a run no longer than the padding is left untouched."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((120, 2, 3))
    x[50:53] = np.nan
    x[53:60] = 5.0 + rng.standard_normal((7, 2, 3))  # 7 samples, then another gap: too short
    x[60:62] = np.nan
    sos = butter(4, 0.3, output="sos")  # 2 sections: padding 15
    y = filtfilt_runs(x, sos)
    assert np.all(np.isnan(y[50:53])) and np.all(np.isnan(y[60:62]))
    np.testing.assert_array_equal(y[53:60], x[53:60])
    np.testing.assert_allclose(y[:50], filtfilt_runs(x[:50], sos))
    np.testing.assert_allclose(y[62:], filtfilt_runs(x[62:], sos))
    assert not np.allclose(y[:50], x[:50])  # it did filter
    assert y.shape == x.shape and y.dtype == np.float64


@pytest.mark.parametrize("layout", ["points picked by a list", "transposed", "Fortran order"])
def test_any_memory_layout_is_filtered(layout):
    """The input's memory layout does not matter: a (T, P, 3) array taken with a list of points (numpy
    lays such a result out point-major), a transposed view or a Fortran-ordered array is filtered as its
    C copy is (such inputs once came back unfiltered: the rows were filtered in a copy)."""
    rng = np.random.default_rng(1)
    points = rng.standard_normal((60, 5, 3)).cumsum(axis=0)
    x = {"points picked by a list": points[:, [0, 2, 3]], "transposed": points.transpose(0, 2, 1),
         "Fortran order": np.asfortranarray(points)}[layout]
    assert not x.flags["C_CONTIGUOUS"]
    sos = butter(4, 0.3, output="sos")
    y = filtfilt_runs(x, sos)
    np.testing.assert_array_equal(y, filtfilt_runs(np.ascontiguousarray(x), sos))
    assert not np.allclose(y, x)


@pytest.mark.parametrize("order", [2, 4])
def test_tracking_smoothing_is_minus_3_db_at_its_cut_off(order):
    """Two passes of the Butterworth, each designed at cutoff / C, leave a sine at the cut-off at
    1/sqrt(2) of its amplitude (away from the ends), pass a constant and a slow sine, and stop a
    fast one; the gait analysis's filter (cut-off per pass) attenuates the same sine to 1/2."""
    t = np.arange(1000) / RATE
    cut = 6.0
    mid = slice(200, 800)

    def gain(f, filt):
        y = filt(np.sin(2 * np.pi * f * t), RATE, cut, order)
        return np.sqrt(2 * np.mean(y[mid] ** 2))

    assert gain(cut, track_lowpass) == pytest.approx(2**-0.5, abs=0.01)
    assert gain(1.0, track_lowpass) == pytest.approx(1.0, abs=0.01)
    assert gain(11.0, track_lowpass) < 0.1
    assert gain(cut, gait_lowpass) == pytest.approx(0.5, abs=0.01)
    np.testing.assert_allclose(track_lowpass(np.full((40, 3), 2.5), RATE, cut, order), 2.5)


def test_tracking_smoothing_refuses_a_cut_off_at_or_above_nyquist():
    with pytest.raises(ValueError, match="Nyquist"):
        track_lowpass(np.zeros((40, 3)), RATE, 12.5)


def test_written_points_are_smoothed_at_the_shipped_cut_off_and_not_at_or_above_nyquist(caplog):
    """The trajectories gaitcap track writes: flagged frames NaN, the rest low-passed at the shipped
    cut-off; at a frame rate whose half is not above the cut-off, written unfiltered with a warning
    naming the key."""
    cfg = load_tracking_config()
    raw = np.random.default_rng(2).standard_normal((50, 4, 3)).cumsum(axis=0)
    quality = np.full(50, QUALITY_OK)
    quality[20] = QUALITY_POOR_FIT
    points, note = _finish_points(raw, quality, RATE, cfg)
    assert np.all(np.isnan(points[20])) and f"cut-off {cfg.smoothing.cutoff_hz} Hz" in note
    np.testing.assert_allclose(points[:20], track_lowpass(raw[:20], RATE, cfg.smoothing.cutoff_hz, cfg.smoothing.order))
    slow = 1.9 * cfg.smoothing.cutoff_hz  # frames per second: its half is below the cut-off
    with caplog.at_level("WARNING"):
        points, note = _finish_points(raw, quality, slow, cfg)
    assert note == "none" and "smoothing.cutoff_hz" in caplog.text
    np.testing.assert_array_equal(np.delete(points, 20, axis=0), np.delete(raw, 20, axis=0))
