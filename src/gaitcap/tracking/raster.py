"""The hot kernel: sums of two per-pixel maps over the union of 2D capsules, for many particles.

A 2D capsule (ends a, b; radii ra, rb in pixels) is the union of the disc (a, ra), the disc
(b, rb) and the quadrilateral a ± n·ra, b ± n·rb (n: the unit normal of b - a), which is what
OpenCV fills when the synth renders it. On each image row the capsule covers an interval of
pixel centres; the union of a particle's capsules on a row is the union of those intervals.

For particle n with capsule set M_n the kernel returns

    s1[n] = sum over the pixels of M_n of g1,     s2[n] = sum over the pixels of M_n of g2

using row prefix sums R[y, x] = sum_{x' < x} g[y, x'], so each merged interval [l, h] of row y
costs two look-ups, R[y, h + 1] - R[y, l], and a particle costs O(rows x capsules), whatever its
area. Row sums (rather than 2D integral images) are half the work to build and let a map that
changes on a few rows be rebuilt on those rows only. Compiled with numba, parallel over particles.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from gaitcap.jit import cached_njit


def row_prefix(g: np.ndarray) -> np.ndarray:
    """Row prefix sums (H, W + 1) float64 of a map (H, W): R[y, x] = sum of g[y, :x], added left
    to right in float64."""
    g = np.asarray(g, dtype=np.float32)
    out = np.zeros((g.shape[0], g.shape[1] + 1))
    np.cumsum(g, axis=1, dtype=np.float64, out=out[:, 1:])
    return out


@cached_njit(inline="always")
def _disc_span(y: float, cx: float, cy: float, r: float, lo: float, hi: float) -> tuple[float, float]:
    dy = y - cy
    if abs(dy) <= r:
        h = math.sqrt(r * r - dy * dy)
        lo, hi = min(lo, cx - h), max(hi, cx + h)
    return lo, hi


@cached_njit(inline="always")
def _edge(y: float, x0: float, y0: float, x1: float, y1: float, lo: float, hi: float) -> tuple[float, float]:
    if (y0 <= y <= y1) or (y1 <= y <= y0):
        if y1 != y0:
            x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            lo, hi = min(lo, x), max(hi, x)
        else:
            lo, hi = min(lo, x0, x1), max(hi, x0, x1)
    return lo, hi


#: per-capsule geometry, computed once per particle: ax, ay, ra, bx, by, rb, then the
#: quadrilateral's corners p0..p3 (x, y) and a flag (1: the quadrilateral exists). The kernels
#: index the table geo (K, _G) by (k, field) and never take a row view of it: a view costs two
#: atomic reference-count updates, which took more time than the geometry itself.
_G = 15


@cached_njit(inline="always")
def _geometry(ax: float, ay: float, bx: float, by: float, ra: float, rb: float, g: np.ndarray, k: int) -> None:
    g[k, 0], g[k, 1], g[k, 2], g[k, 3], g[k, 4], g[k, 5] = ax, ay, ra, bx, by, rb
    dx, dy = bx - ax, by - ay
    L = math.sqrt(dx * dx + dy * dy)
    g[k, 14] = 0.0
    if L > 1e-9:
        nx, ny = -dy / L, dx / L
        g[k, 6], g[k, 7] = ax + nx * ra, ay + ny * ra
        g[k, 8], g[k, 9] = bx + nx * rb, by + ny * rb
        g[k, 10], g[k, 11] = bx - nx * rb, by - ny * rb
        g[k, 12], g[k, 13] = ax - nx * ra, ay - ny * ra
        g[k, 14] = 1.0


@cached_njit(inline="always")
def _span(y: float, g: np.ndarray, k: int) -> tuple[float, float]:
    """Interval [lo, hi] of x covered by capsule k (geometry table ``g``) on row y (lo > hi: empty)."""
    lo, hi = _disc_span(y, g[k, 0], g[k, 1], g[k, 2], math.inf, -math.inf)
    lo, hi = _disc_span(y, g[k, 3], g[k, 4], g[k, 5], lo, hi)
    if g[k, 14] > 0.0:  # the long sides p0-p1 and p2-p3; the short sides p1-p2 and p3-p0 are
        # diameters of the end discs: where a row crosses one it crosses that disc, whose span
        # already holds the crossing, so they can never widen [lo, hi]
        lo, hi = _edge(y, g[k, 6], g[k, 7], g[k, 8], g[k, 9], lo, hi)
        lo, hi = _edge(y, g[k, 10], g[k, 11], g[k, 12], g[k, 13], lo, hi)
    return lo, hi


@cached_njit(inline="always")
def _clamped_int(v: float, lo: int, hi: int) -> int:
    """int(v) clamped to [lo, hi], v integral-valued; casting inf, NaN or |v| >= 2**63 to an int is
    undefined behaviour, so the clamp happens before the cast (NaN: lo)."""
    if not (v > lo):
        return lo
    if v >= hi:
        return hi
    return int(v)


@cached_njit(inline="always")
def _row_range(g: np.ndarray, k: int, H: int) -> tuple[int, int]:
    """Rows capsule k can touch, clipped to the image (empty: lo > hi); NaN or infinite ends or
    radii touch none."""
    r = max(g[k, 2], g[k, 5])
    if not (np.isfinite(g[k, 0]) and np.isfinite(g[k, 1]) and np.isfinite(g[k, 3]) and np.isfinite(g[k, 4])
            and np.isfinite(r)):  # fmt: skip
        return 1, 0
    return (_clamped_int(math.ceil(min(g[k, 1], g[k, 4]) - r), 0, H),
            _clamped_int(math.floor(max(g[k, 1], g[k, 4]) + r), -1, H - 1))  # fmt: skip


@cached_njit(inline="always")
def _prepare(a, b, ra, rb, n: int, H: int, geo: np.ndarray, ylo: np.ndarray, yhi: np.ndarray) -> tuple[int, int]:
    """Geometry and row ranges of particle n's capsules; returns the rows the particle spans."""
    ymin, ymax = H, -1
    for k in range(a.shape[1]):
        _geometry(a[n, k, 0], a[n, k, 1], b[n, k, 0], b[n, k, 1], ra[n, k], rb[n, k], geo, k)
        ylo[k], yhi[k] = _row_range(geo, k, H)
        if ylo[k] <= yhi[k]:
            ymin = min(ymin, ylo[k])
            ymax = max(ymax, yhi[k])
    return ymin, ymax


@cached_njit(inline="always")
def _row_intervals(y: int, geo, ylo, yhi, W: int, lo: np.ndarray, hi: np.ndarray) -> int:
    """The pixel intervals covered on row y, sorted by their left end; returns their count."""
    m = 0
    for k in range(geo.shape[0]):
        if y < ylo[k] or y > yhi[k]:
            continue
        l, h = _span(float(y), geo, k)
        if not (l <= h):  # empty (or NaN)
            continue
        xl, xh = _clamped_int(math.ceil(l), 0, W), _clamped_int(math.floor(h), -1, W - 1)
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
    return m


@cached_njit(inline="always")
def _particle_sums(a, b, ra, rb, n: int, c1, c2, geo, ylo, yhi, lo, hi) -> tuple[float, float]:
    """(sum of c1's map, sum of c2's map) over particle n's capsules, scratch arrays given (K,)."""
    H, W = c1.shape[0], c1.shape[1] - 1
    ymin, ymax = _prepare(a, b, ra, rb, n, H, geo, ylo, yhi)
    acc1 = 0.0
    acc2 = 0.0
    for y in range(ymin, ymax + 1):
        m = _row_intervals(y, geo, ylo, yhi, W, lo, hi)
        if m == 0:
            continue
        cl, ch = lo[0], hi[0]
        for i in range(1, m + 1):
            if i < m and lo[i] <= ch + 1:  # merge overlapping or touching intervals
                ch = max(ch, hi[i])
                continue
            acc1 += c1[y, ch + 1] - c1[y, cl]
            acc2 += c2[y, ch + 1] - c2[y, cl]
            if i < m:
                cl, ch = lo[i], hi[i]
    return acc1, acc2


@cached_njit(parallel=True, nogil=True)
def capsule_sums_views(a: np.ndarray, b: np.ndarray, ra: np.ndarray, rb: np.ndarray, c1s: tuple, c2s: tuple
                       ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Sums of two maps over the union of each particle's capsules, in every view, through the
    maps' row prefix sums (one parallel loop over views x particles): a, b (C, N, K, 2);
    ra, rb (C, N, K); c1s, c2s: C row prefix sums (H, W + 1) each -> s1, s2 (C, N)."""
    C, N, K = a.shape[0], a.shape[1], a.shape[2]
    s1 = np.zeros((C, N))
    s2 = np.zeros((C, N))
    for i in prange(C * N):
        c, n = i // N, i % N
        lo = np.empty(K, np.int64)
        hi = np.empty(K, np.int64)
        ylo = np.empty(K, np.int64)
        yhi = np.empty(K, np.int64)
        geo = np.empty((K, _G))
        s1[c, n], s2[c, n] = _particle_sums(a[c], b[c], ra[c], rb[c], n, c1s[c], c2s[c], geo, ylo, yhi, lo, hi)
    return s1, s2


@cached_njit(nogil=True)
def rows_reached(a: np.ndarray, b: np.ndarray, ra: np.ndarray, rb: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """The first and last rows (C, 2) that :func:`capsule_sums_views` reads in each view for capsules
    a, b (C, N, K, 2), ra, rb (C, N, K) in views of ``heights`` (C,) rows (first > last: none)."""
    C, N, K = ra.shape
    out = np.empty((C, 2), np.int64)
    geo = np.empty((1, _G))
    for c in range(C):
        lo, hi = heights[c], -1
        for n in range(N):
            for k in range(K):
                geo[0, 0], geo[0, 1], geo[0, 2] = a[c, n, k, 0], a[c, n, k, 1], ra[c, n, k]
                geo[0, 3], geo[0, 4], geo[0, 5] = b[c, n, k, 0], b[c, n, k, 1], rb[c, n, k]
                y0, y1 = _row_range(geo, 0, heights[c])
                if y0 <= y1:
                    lo = min(lo, y0)
                    hi = max(hi, y1)
        out[c, 0], out[c, 1] = lo, hi
    return out


@cached_njit(nogil=True, inline="always")
def _free_prefixes_into(silhouette: np.ndarray, placed: np.ndarray, C1: np.ndarray, C2: np.ndarray,
                        y0: int = 0, y1: int = -1) -> None:  # fmt: skip
    """Rows y0..y1 (default: all) of :func:`free_prefixes`, written into C1, C2 (H, W + 1)."""
    H, W = silhouette.shape
    one = np.float32(1.0)
    for y in range(max(y0, 0), (H - 1 if y1 < 0 else min(y1, H - 1)) + 1):
        C1[y, 0] = 0.0
        C2[y, 0] = 0.0
        r1 = 0.0
        r2 = 0.0
        for x in range(W):
            f = one - placed[y, x]
            r1 += silhouette[y, x] * f
            r2 += f
            C1[y, x + 1] = r1
            C2[y, x + 1] = r2


@cached_njit(nogil=True)
def free_prefix_rows(silhouette: np.ndarray, placed: np.ndarray, C1: np.ndarray, C2: np.ndarray, y0: int, y1: int) -> None:
    """Recompute rows y0..y1 of the :func:`free_prefixes` C1, C2 in place, after ``placed``
    changed on those rows only (y0 > y1: nothing)."""
    if y0 <= y1:
        _free_prefixes_into(silhouette, placed, C1, C2, y0, y1)


@cached_njit(nogil=True)
def free_prefixes(silhouette: np.ndarray, placed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row prefix sums (H, W + 1) of silhouette x free and of free, free = 1 - placed, for
    silhouette and placed (H, W) float32, in one pass without temporaries: equal bit for bit to
    :func:`row_prefix` of ``silhouette * (1 - placed)`` and ``1 - placed`` computed by numpy
    (float32 products, added left to right in float64)."""
    H, W = silhouette.shape
    C1 = np.empty((H, W + 1))
    C2 = np.empty((H, W + 1))
    _free_prefixes_into(silhouette, placed, C1, C2)
    return C1, C2


def free_prefixes_views(silhouettes: tuple, placed: tuple, into: tuple[np.ndarray, np.ndarray] | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """:func:`free_prefixes` of every view (C silhouettes and placed masks (H, W) float32, all of
    one size), the views in parallel: C1, C2 (C, H, W + 1), written into ``into`` when given (every
    element: arrays reused from call to call, whose pages are already mapped, cost a fifth of new ones)."""
    C = len(silhouettes)
    H, W = silhouettes[0].shape
    C1, C2 = into if into is not None else (np.empty((C, H, W + 1)), np.empty((C, H, W + 1)))
    _free_prefixes_views_into(silhouettes, placed, C1, C2)
    return C1, C2


@cached_njit(parallel=True, nogil=True)
def _free_prefixes_views_into(silhouettes: tuple, placed: tuple, C1: np.ndarray, C2: np.ndarray) -> None:
    for c in prange(len(silhouettes)):
        _free_prefixes_into(silhouettes[c], placed[c], C1[c], C2[c])


@cached_njit(nogil=True)
def fill_capsules(mask: np.ndarray, a: np.ndarray, b: np.ndarray, ra: np.ndarray, rb: np.ndarray,
                  value: float) -> tuple[int, int]:  # fmt: skip
    """Set the pixels of the union of one pose's capsules a, b (K, 2), ra, rb (K,) to ``value``
    in ``mask`` (H, W), in place: exactly the pixels :func:`capsule_sums_views` counts. Returns
    the first and last rows that may have changed (first > last: none)."""
    H, W = mask.shape
    K = a.shape[0]
    lo = np.empty(K, np.int64)
    hi = np.empty(K, np.int64)
    ylo = np.empty(K, np.int64)
    yhi = np.empty(K, np.int64)
    geo = np.empty((K, _G))
    ymin, ymax = _prepare(a[None], b[None], ra[None], rb[None], 0, H, geo, ylo, yhi)
    for y in range(ymin, ymax + 1):
        m = _row_intervals(y, geo, ylo, yhi, W, lo, hi)
        for i in range(m):
            mask[y, lo[i] : hi[i] + 1] = value
    return ymin, ymax


def warm_up(n_views: int = 2) -> None:
    """Compile the kernels for ``n_views`` views, with the argument types the tracker passes (a
    no-op when numba's on-disk cache already holds them: see :mod:`gaitcap.tracking.precompile`)."""
    z = np.zeros((n_views, 1, 1, 2))
    r = np.ones((n_views, 1, 1))
    c = row_prefix(np.ones((4, 4), np.float32))
    m = np.ones((4, 4), np.float32)
    capsule_sums_views(z, z + 1, r, r, (c,) * n_views, (c,) * n_views)
    free_prefixes(m, m)
    free_prefixes_views((m,) * n_views, (m,) * n_views)
    fill_capsules(np.zeros((4, 4), np.float32), z[0, 0], z[0, 0] + 1, r[0, 0], r[0, 0], 1.0)
    free_prefix_rows(m, m, c, c, 1, 2)
    rows_reached(z, z + 1, r, r, np.full(n_views, 4, np.int64))
