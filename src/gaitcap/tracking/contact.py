"""Where two legs would pass through each other: the gap between the left and right legs' axes.

A leg is two segments, hip centre -> knee centre -> ankle centre. The gap of a pose is the smallest
distance between a segment of the left leg and a segment of the right one (thigh-thigh,
shank-shank and each shank against the other thigh). Living legs never come closer than their own
thickness: over the suite's three real walks (Vicon, OpenSim and the C3D.ORG sample, scaled to
1.05-1.95 m) and the shared Vicon walk of the external sessions, the truth's gap stays above 0.05
of the subject's height; a tracked pose with both legs drawn on one silhouette leg comes to 0.

Compiled (numba, cached like the tracking kernels): the tracker asks for the gap of every particle
of every leg node, a few hundred poses at a time, thirty times a frame.
"""

from __future__ import annotations

import math

import numpy as np

from gaitcap.jit import cached_njit

#: the points of the two legs' axes, in the order :func:`leg_gap` reads them
LEG_POINTS = ("hip_l", "knee_l", "ankle_l", "hip_r", "knee_r", "ankle_r")

#: the leg segments :func:`leg_gap` pairs: (left start, left end, right start, right end), rows of LEG_POINTS:
#: thigh-thigh, shank-shank, left shank-right thigh, left thigh-right shank
_PAIRS = np.array([(0, 1, 3, 4), (1, 2, 4, 5), (1, 2, 3, 4), (0, 1, 4, 5)], np.int64)

_TINY = 1e-12


@cached_njit(inline="always")
def _clamp01(x: float) -> float:
    return min(max(x, 0.0), 1.0)


@cached_njit(nogil=True)
def _segment_distance(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> float:
    """Closest distance between the segments p0-p1 and q0-q1 (3,) (see :func:`segment_distances`)."""
    a = e = b = c = f = 0.0
    for i in range(3):
        d1, d2, r = p1[i] - p0[i], q1[i] - q0[i], p0[i] - q0[i]
        a += d1 * d1
        e += d2 * d2
        b += d1 * d2
        c += d1 * r
        f += d2 * r
    s = _clamp01((b * f - c * e) / max(a * e - b * b, _TINY))  # parallel: either end will do
    t = (b * s + f) / max(e, _TINY)
    tc = _clamp01(t)
    if tc != t or e <= _TINY:
        s = _clamp01((b * tc - c) / max(a, _TINY))
    out = 0.0
    for i in range(3):
        g = (p0[i] - q0[i]) + (p1[i] - p0[i]) * s - (q1[i] - q0[i]) * tc
        out += g * g
    return math.sqrt(out)


@cached_njit(nogil=True)
def _leg_gap(legs: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    out = np.empty(legs.shape[0])
    for n in range(legs.shape[0]):
        best = np.inf
        for k in range(pairs.shape[0]):
            i, j, u, v = pairs[k]
            best = min(best, _segment_distance(legs[n, i], legs[n, j], legs[n, u], legs[n, v]))
        out[n] = best
    return out


def segment_distances(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Closest distances between the segments p0-p1 and q0-q1, each (N, 3): (N,).

    The closest points p0 + s (p1 - p0) and q0 + t (q1 - q0), s, t in [0, 1], found as in Ericson's
    Real-Time Collision Detection (5.1.9): s on the lines' common normal, clamped; t the point of
    q0-q1 closest to it; where t had to be clamped (or q0-q1 is a point), s again from t. A
    segment of zero length is its point.
    """
    p0, p1, q0, q1 = (np.ascontiguousarray(x, np.float64) for x in (p0, p1, q0, q1))
    return np.array([_segment_distance(*ends) for ends in zip(p0, p1, q0, q1, strict=True)], np.float64)


def leg_gap(legs: np.ndarray) -> np.ndarray:
    """The smallest distance between the left and right legs' axes (module docstring) of poses whose
    :data:`LEG_POINTS` are ``legs`` (N, 6, 3), metres: (N,)."""
    return _leg_gap(np.ascontiguousarray(legs, np.float64), _PAIRS)


def warm_up() -> None:
    """Compile the kernel with the argument types the tracker passes (a no-op when numba's on-disk
    cache already holds it)."""
    leg_gap(np.zeros((1, 6, 3)))
