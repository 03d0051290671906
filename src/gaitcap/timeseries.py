"""Low-level helpers for sampled signals with missing samples (NaN rows), shared by the tracking
output's smoothing and the gait analysis: which rows form NaN-free runs, and zero-lag filtering of
each run on its own (a filter never reaches across a gap)."""

from __future__ import annotations

import numpy as np


def finite_runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """Start (inclusive) and stop (exclusive) indices of the runs of True in a (T,) bool array."""
    v = np.concatenate([[False], np.asarray(valid, dtype=bool), [False]])
    d = np.diff(v.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def filtfilt_runs(x: np.ndarray, sos: np.ndarray) -> np.ndarray:
    """Zero-lag (forward then backward) filtering along axis 0 with the second-order sections
    ``sos`` (n, 6), each NaN-free run of rows on its own.

    Args:
        x: shape (T,) or (T, ...); a row is missing if any of its values is NaN.
        sos: the filter, e.g. ``scipy.signal.butter(..., output="sos")``.

    Returns:
        A float64 copy, same shape: missing rows stay NaN, runs no longer than sosfiltfilt's
        padding (3 (2 n + 1) samples) are left as they are.
    """
    from scipy.signal import sosfiltfilt  # here, not at start-up (gaitcap.pipeline._import_late)

    out = np.array(x, dtype=np.float64, copy=True, order="C")  # C order: ``flat`` is a view of it, not a copy
    flat = out.reshape(len(out), -1)
    pad = 3 * (2 * len(sos) + 1)
    for start, stop in finite_runs(np.all(np.isfinite(flat), axis=1)):
        if stop - start > pad:
            flat[start:stop] = sosfiltfilt(sos, flat[start:stop], axis=0)
    return out
