"""The hot kernel: sums of two per-pixel maps over the union of 2D capsules, for many particles.

A 2D capsule (ends a, b; radii ra, rb in pixels) is the union of the disc (a, ra), the disc
(b, rb) and the quadrilateral a ± n·ra, b ± n·rb (n: the unit normal of b - a), which is what
OpenCV fills when the synth renders it. On each image row the capsule covers an interval of
pixel centres; the union of a particle's capsules on a row is the union of those intervals.

For particle n with capsule set M_n the kernel returns

    s1[n] = sum over the pixels of M_n of g1,     s2[n] = sum over the pixels of M_n of g2

using integral images C[y, x] = sum_{y' < y, x' < x} g[y', x'] (OpenCV's, the fastest to build),
so each merged interval costs four look-ups and a particle costs O(rows x capsules), whatever its
area. Compiled with numba, parallel over particles.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit, prange


def row_prefix(g: np.ndarray) -> np.ndarray:
    """Integral image (H + 1, W + 1) float64 of a map (H, W): C[y, x] = sum of g[:y, :x]."""
    return cv2.integral(np.ascontiguousarray(g, dtype=np.float32), sdepth=cv2.CV_64F)


@njit(cache=True, inline="always")
def _disc_span(y: float, cx: float, cy: float, r: float) -> tuple[float, float]:
    dy = y - cy
    if abs(dy) > r:
        return math.inf, -math.inf
    h = math.sqrt(r * r - dy * dy)
    return cx - h, cx + h


@njit(cache=True, inline="always")
def _edge(y: float, x0: float, y0: float, x1: float, y1: float, lo: float, hi: float) -> tuple[float, float]:
    if (y0 <= y <= y1) or (y1 <= y <= y0):
        if y1 != y0:
            x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            lo, hi = min(lo, x), max(hi, x)
        else:
            lo, hi = min(lo, x0, x1), max(hi, x0, x1)
    return lo, hi


@njit(cache=True)
def _capsule_span(y: float, ax: float, ay: float, bx: float, by: float, ra: float, rb: float) -> tuple[float, float]:
    """Interval [lo, hi] of x covered by one capsule on row y (lo > hi: empty)."""
    lo, hi = _disc_span(y, ax, ay, ra)
    l2, h2 = _disc_span(y, bx, by, rb)
    lo, hi = min(lo, l2), max(hi, h2)
    dx, dy = bx - ax, by - ay
    L = math.sqrt(dx * dx + dy * dy)
    if L > 1e-9:
        nx, ny = -dy / L, dx / L
        p0x, p0y = ax + nx * ra, ay + ny * ra
        p1x, p1y = bx + nx * rb, by + ny * rb
        p2x, p2y = bx - nx * rb, by - ny * rb
        p3x, p3y = ax - nx * ra, ay - ny * ra
        lo, hi = _edge(y, p0x, p0y, p1x, p1y, lo, hi)
        lo, hi = _edge(y, p1x, p1y, p2x, p2y, lo, hi)
        lo, hi = _edge(y, p2x, p2y, p3x, p3y, lo, hi)
        lo, hi = _edge(y, p3x, p3y, p0x, p0y, lo, hi)
    return lo, hi


@njit(parallel=True, cache=True)
def capsule_sums(
    a: np.ndarray, b: np.ndarray, ra: np.ndarray, rb: np.ndarray, c1: np.ndarray, c2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """a, b (N, K, 2); ra, rb (N, K); c1, c2 (H + 1, W + 1) integral images -> s1, s2 (N,)."""
    N, K = a.shape[0], a.shape[1]
    H, W = c1.shape[0] - 1, c1.shape[1] - 1
    s1 = np.zeros(N)
    s2 = np.zeros(N)
    for n in prange(N):
        lo = np.empty(K)
        hi = np.empty(K)
        ylo = np.empty(K, np.int64)  # rows each capsule can touch (empty range: skipped)
        yhi = np.empty(K, np.int64)
        ymin, ymax = H, -1
        for k in range(K):
            ylo[k], yhi[k] = 1, 0
            if not (np.isfinite(a[n, k, 0]) and np.isfinite(a[n, k, 1]) and np.isfinite(b[n, k, 0])
                    and np.isfinite(b[n, k, 1])):
                continue
            r = max(ra[n, k], rb[n, k])
            ylo[k] = max(0, int(math.ceil(min(a[n, k, 1], b[n, k, 1]) - r)))
            yhi[k] = min(H - 1, int(math.floor(max(a[n, k, 1], b[n, k, 1]) + r)))
            if ylo[k] <= yhi[k]:
                ymin = min(ymin, ylo[k])
                ymax = max(ymax, yhi[k])
        acc1 = 0.0
        acc2 = 0.0
        for y in range(ymin, ymax + 1):
            m = 0
            for k in range(K):
                if y < ylo[k] or y > yhi[k]:
                    continue
                l, h = _capsule_span(float(y), a[n, k, 0], a[n, k, 1], b[n, k, 0], b[n, k, 1], ra[n, k], rb[n, k])
                xl, xh = max(0, int(math.ceil(l))), min(W - 1, int(math.floor(h)))
                if xl > xh:
                    continue
                j = m  # insertion sort by left end
                while j > 0 and lo[j - 1] > xl:
                    lo[j] = lo[j - 1]
                    hi[j] = hi[j - 1]
                    j -= 1
                lo[j] = xl
                hi[j] = xh
                m += 1
            if m == 0:
                continue
            cl, ch = int(lo[0]), int(hi[0])
            for i in range(1, m + 1):
                if i < m and int(lo[i]) <= ch + 1:
                    ch = max(ch, int(hi[i]))
                    continue
                acc1 += c1[y + 1, ch + 1] - c1[y + 1, cl] - c1[y, ch + 1] + c1[y, cl]
                acc2 += c2[y + 1, ch + 1] - c2[y + 1, cl] - c2[y, ch + 1] + c2[y, cl]
                if i < m:
                    cl, ch = int(lo[i]), int(hi[i])
        s1[n] = acc1
        s2[n] = acc2
    return s1, s2


def warm_up() -> None:
    """Compile the kernel (cached on disk after the first run)."""
    z = np.zeros((1, 1, 2))
    r = np.ones((1, 1))
    c = row_prefix(np.ones((4, 4), np.float32))
    capsule_sums(z, z + 1, r, r, c, c)
