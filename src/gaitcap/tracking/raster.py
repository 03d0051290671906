"""The hot kernel: sums of two per-pixel maps over the union of 2D capsules, for many particles.

For particle n with capsules k = 1..K (2D ends a, b, radii ra, rb in pixels), let M_n be the set of
pixel centres inside at least one capsule. The kernel returns

    s1[n] = sum over M_n of g1,     s2[n] = sum over M_n of g2.

The silhouette likelihood uses g1 = silhouette x free and g2 = free (free: pixels not yet explained
by segments already placed), which gives the overlap and the model area in one pass. Each pixel
of the union is counted once: a pixel of capsule k counts only if no earlier capsule holds it.
Compiled with numba, parallel over particles.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
def _inside(px: float, py: float, ax: float, ay: float, bx: float, by: float, ra: float, rb: float) -> bool:
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    t = 0.0
    if L2 > 1e-12:
        t = ((px - ax) * dx + (py - ay) * dy) / L2
        t = min(1.0, max(0.0, t))
    cx, cy = ax + t * dx - px, ay + t * dy - py
    r = ra + t * (rb - ra)
    return cx * cx + cy * cy <= r * r


@njit(parallel=True, cache=True)
def capsule_sums(
    a: np.ndarray, b: np.ndarray, ra: np.ndarray, rb: np.ndarray, g1: np.ndarray, g2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """a, b (N, K, 2) float; ra, rb (N, K) float; g1, g2 (H, W) float32 -> s1, s2 (N,) float64."""
    N, K = a.shape[0], a.shape[1]
    H, W = g1.shape
    s1 = np.zeros(N)
    s2 = np.zeros(N)
    for n in prange(N):
        acc1 = 0.0
        acc2 = 0.0
        for k in range(K):
            ax, ay, bx, by = a[n, k, 0], a[n, k, 1], b[n, k, 0], b[n, k, 1]
            r = max(ra[n, k], rb[n, k])
            if not (np.isfinite(ax) and np.isfinite(ay) and np.isfinite(bx) and np.isfinite(by)):
                continue
            x0 = max(0, int(np.floor(min(ax, bx) - r)))
            x1 = min(W - 1, int(np.ceil(max(ax, bx) + r)))
            y0 = max(0, int(np.floor(min(ay, by) - r)))
            y1 = min(H - 1, int(np.ceil(max(ay, by) + r)))
            for y in range(y0, y1 + 1):
                for x in range(x0, x1 + 1):
                    if not _inside(x, y, ax, ay, bx, by, ra[n, k], rb[n, k]):
                        continue
                    earlier = False
                    for j in range(k):
                        if _inside(x, y, a[n, j, 0], a[n, j, 1], b[n, j, 0], b[n, j, 1], ra[n, j], rb[n, j]):
                            earlier = True
                            break
                    if not earlier:
                        acc1 += g1[y, x]
                        acc2 += g2[y, x]
        s1[n] = acc1
        s2[n] = acc2
    return s1, s2


def warm_up() -> None:
    """Compile the kernel (cached on disk after the first run)."""
    z = np.zeros((1, 1, 2))
    r = np.ones((1, 1))
    g = np.ones((4, 4), np.float32)
    capsule_sums(z, z + 1, r, r, g, g)
