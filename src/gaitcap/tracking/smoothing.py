"""Zero-lag low-pass filtering of trajectories (Butterworth, forward and backward: scipy filtfilt).

NaN frames split a trajectory into runs; each run long enough for the filter is filtered on its
own, shorter runs are kept as they are.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, filtfilt


def lowpass(points: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Filter points (T, ...) along time; NaN frames stay NaN.

    ``cutoff_hz`` is the -3 dB frequency of the whole zero-lag filter: two passes of an order-n
    Butterworth attenuate more, so each pass is designed at cutoff / C with
    C = (2^(1/2) - 1)^(1/(2n)) (Winter 2009, section 3.4.4.4, generalised to order n).
    """
    if cutoff_hz >= rate_hz / 2:
        raise ValueError(f"cut-off {cutoff_hz} Hz must be below the Nyquist frequency {rate_hz / 2} Hz")
    correction = (2**0.5 - 1) ** (1 / (2 * order))
    b, a = butter(order, (cutoff_hz / correction) / (rate_hz / 2))
    out = np.array(points, dtype=np.float64, copy=True)
    flat = out.reshape(len(out), -1)
    valid = np.all(np.isfinite(flat), axis=1)
    pad = 3 * max(len(a), len(b))
    t = 0
    while t < len(valid):
        if not valid[t]:
            t += 1
            continue
        end = t
        while end < len(valid) and valid[end]:
            end += 1
        if end - t > pad:
            flat[t:end] = filtfilt(b, a, flat[t:end], axis=0)
        t = end
    return out
