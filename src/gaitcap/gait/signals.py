"""NaN-aware signal helpers shared by event detection, parameters and angles.

Missing samples (NaN, for example frames the tracker flagged) are never invented over long spans:
short gaps are bridged linearly, long gaps stay NaN and split the signal into segments.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter

from gaitcap.timeseries import filtfilt_runs, finite_runs


def fill_short_gaps(x: np.ndarray, max_gap: int) -> np.ndarray:
    """Linearly bridge interior NaN gaps of at most ``max_gap`` samples, along axis 0.

    Args:
        x: shape (T,) or (T, K). A row is missing if any of its values is NaN.
        max_gap: longest gap (samples) to bridge; gaps at either end are never filled.

    Returns:
        A copy with the short gaps filled, same shape.
    """
    x = np.array(x, dtype=np.float64, copy=True)
    flat = x.reshape(len(x), -1)
    ok = np.all(np.isfinite(flat), axis=1)
    if ok.all() or not ok.any() or max_gap <= 0:
        return x
    idx = np.arange(len(x))
    for start, stop in finite_runs(~ok):
        if start == 0 or stop == len(x) or stop - start > max_gap:
            continue
        for j in range(flat.shape[1]):
            flat[start:stop, j] = np.interp(idx[start:stop], [start - 1, stop], flat[[start - 1, stop], j])
    return flat.reshape(x.shape)


def lowpass(x: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 2) -> np.ndarray:
    """Zero-lag Butterworth low-pass along axis 0, applied to each NaN-free run separately.

    Args:
        x: shape (T,) or (T, K); NaN rows stay NaN.
        rate_hz: sampling rate.
        cutoff_hz: cut-off; clamped to 0.4 x ``rate_hz``; 0 returns a copy.

    Returns:
        Filtered copy, same shape. Runs too short for the filter's padding are left unfiltered.
    """
    if cutoff_hz <= 0:
        return np.array(x, dtype=np.float64, copy=True)
    wn = min(cutoff_hz, 0.4 * rate_hz) / (0.5 * rate_hz)
    return filtfilt_runs(x, butter(order, wn, output="sos"))


def velocity(x: np.ndarray, rate_hz: float) -> np.ndarray:
    """Central-difference time derivative along axis 0 (NaN next to missing samples), same shape."""
    x = np.asarray(x, dtype=np.float64)
    if len(x) < 2:
        return np.full_like(x, np.nan)
    return np.gradient(x, axis=0) * rate_hz


def parabolic_peak(y: np.ndarray, i: int) -> float:
    """Sub-sample position of the extremum at index ``i`` of a (T,) signal (vertex of the parabola
    through samples i-1, i, i+1); ``float(i)`` at the ends or if the neighbours are not finite."""
    if i <= 0 or i >= len(y) - 1:
        return float(i)
    a, b, c = y[i - 1], y[i], y[i + 1]
    den = a - 2 * b + c
    if not np.all(np.isfinite([a, b, c])) or den == 0:
        return float(i)
    return float(i + np.clip(0.5 * (a - c) / den, -0.5, 0.5))
