"""A second pass over the clip, backwards in time, and the choice between the two passes.

No dynamic model carries the tracker from frame to frame, so where a forward pass goes wrong (the
legs exchanged at a crossing, a poor start) it stays wrong until the silhouettes pull it back. A
pass that walks the clip from its last frame to its first, started from the forward pass's last
pose, meets each crossing from the other side and goes wrong elsewhere, if at all. The two passes
are merged where they disagree:

    agree_t = mean_k |p_k^F(t) - p_k^B(t)| < agree_m       (p_k: the legs' points, knees to toes)

and every run of frames where they do not agree takes the pass whose fit, summed over the run, is
the higher (a whole leg assignment, never a mixture within the run); a frame where they agree
takes the better fit of the two. This is the choice a clip-level smoother makes between two
hypotheses, with the silhouettes as the only judge.
"""

from __future__ import annotations

import numpy as np

from gaitcap.timeseries import finite_runs

#: the points that decide whether the two passes agree: the legs below the hips
LEG_POINT_PREFIXES = ("knee_", "ankle_", "heel_", "toe_")


def leg_points(names: tuple[str, ...]) -> np.ndarray:
    """Indices of the leg points (:data:`LEG_POINT_PREFIXES`) among ``names``."""
    return np.array([i for i, n in enumerate(names) if n.startswith(LEG_POINT_PREFIXES)], int)


def choose_backward(forward: np.ndarray, backward: np.ndarray, fit_forward: np.ndarray, fit_backward: np.ndarray,
                    agree_m: float) -> np.ndarray:  # fmt: skip
    """(T,) bool: the frames that take the backward pass (module docstring).

    Args:
        forward, backward: (T, K, 3) the two passes' leg points, metres (NaN: not tracked).
        fit_forward, fit_backward: (T,) their fits (NaN: not tracked).
        agree_m: the mean distance (metres, > 0) below which the passes agree.
    """
    forward, backward = np.asarray(forward, float), np.asarray(backward, float)
    if forward.shape != backward.shape or forward.ndim != 3:
        raise ValueError(f"forward and backward must be (T, K, 3) alike, got {forward.shape} and {backward.shape}")
    if agree_m <= 0:
        raise ValueError(f"agree_m must be > 0, got {agree_m}")
    fit_f = np.where(np.isfinite(fit_forward), fit_forward, -np.inf)
    fit_b = np.where(np.isfinite(fit_backward), fit_backward, -np.inf)
    distance = np.linalg.norm(forward - backward, axis=2).mean(axis=1)  # NaN where either is not tracked
    choice = fit_b > fit_f  # where they agree (and where one pass is missing)
    disagree = np.where(np.isfinite(distance), distance >= agree_m, False)
    for s, e in finite_runs(disagree):
        choice[s:e] = np.sum(fit_b[s:e]) > np.sum(fit_f[s:e])
    return choice
