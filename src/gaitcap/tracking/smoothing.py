"""Zero-lag low-pass filtering of trajectories (Butterworth, forward and backward: scipy filtfilt).

NaN frames split a trajectory into runs; each run long enough for the filter is filtered on its
own, shorter runs are kept as they are (:func:`gaitcap.timeseries.filtfilt_runs`).
"""

from __future__ import annotations

import numpy as np

from gaitcap.timeseries import filtfilt_runs


def lowpass(points: np.ndarray, rate_hz: float, cutoff_hz: float, order: int = 4) -> np.ndarray:
    """Filter points (T, ...) along time; NaN frames stay NaN.

    ``cutoff_hz`` is the -3 dB frequency of the whole zero-lag filter. Two passes of an order-n
    Butterworth attenuate more, so each pass is designed with its cut-off moved up by
    1 / C, C = (2^(1/2) - 1)^(1/(2n)) (Winter 2009, section 3.4.4.4, generalised to order n), on
    the digital filter's warped frequency axis, tan(pi f / rate), where a Butterworth's gain is
    exactly 1 / sqrt(1 + (tan(pi f / rate) / tan(pi f_pass / rate))^(2n)):
        f_pass = rate / pi * atan(tan(pi cutoff / rate) / C)
    (scaling the frequency itself, cutoff / C, left the -3 dB point at 6.3 Hz for 6 Hz at 25 Hz).
    """
    if cutoff_hz >= rate_hz / 2:
        raise ValueError(f"cut-off {cutoff_hz} Hz must be below the Nyquist frequency {rate_hz / 2} Hz")
    from scipy.signal import butter  # here, not at start-up (gaitcap.pipeline._import_late)

    correction = (2**0.5 - 1) ** (1 / (2 * order))
    per_pass = rate_hz / np.pi * np.arctan(np.tan(np.pi * cutoff_hz / rate_hz) / correction)
    return filtfilt_runs(points, butter(order, per_pass / (rate_hz / 2), output="sos"))
