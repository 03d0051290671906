from __future__ import annotations

import numpy as np
import pytest

from gaitcap.body.shape import ProjectedCapsules, capsule_polygon, rasterize
from gaitcap.tracking.raster import capsule_sums_views, fill_capsules, row_prefix


def _inside_capsule(x, y, a, b, ra, rb):
    """Pixel centres inside the disc at a, the disc at b or the quadrilateral between them."""
    inside = (x - a[0]) ** 2 + (y - a[1]) ** 2 <= ra * ra
    inside |= (x - b[0]) ** 2 + (y - b[1]) ** 2 <= rb * rb
    poly = capsule_polygon(a, b, ra, rb)
    signs = []
    for i in range(4):
        p, q = poly[i], poly[(i + 1) % 4]
        signs.append((q[0] - p[0]) * (y - p[1]) - (q[1] - p[1]) * (x - p[0]))
    s = np.stack(signs)
    inside |= np.all(s >= -1e-9, axis=0) | np.all(s <= 1e-9, axis=0)
    return inside


def _brute_force(a, b, ra, rb, g1, g2):
    h, w = g1.shape
    y, x = np.mgrid[0:h, 0:w].astype(float)
    union = np.zeros((h, w), bool)
    for k in range(len(a)):
        union |= _inside_capsule(x, y, a[k], b[k], ra[k], rb[k])
    return g1[union].sum(), g2[union].sum(), union


def _sums(a, b, ra, rb, g1, g2):
    """The likelihood's kernel on one view: (N,) sums of g1 and of g2."""
    s1, s2 = capsule_sums_views(a[None], b[None], ra[None], rb[None], (row_prefix(g1),), (row_prefix(g2),))
    return s1[0], s2[0]


def test_single_disc_counts_pixel_centres():
    g = np.ones((50, 50), np.float32)
    a = np.array([[[20.3, 24.6]]])
    r = np.array([[7.2]])
    _, area = _sums(a, a, r, r, g, g)
    y, x = np.mgrid[0:50, 0:50]
    assert area[0] == ((x - 20.3) ** 2 + (y - 24.6) ** 2 <= 7.2**2).sum()


def test_kernel_equals_brute_force_union(rng):
    h, w = 120, 160
    n, k = 30, 3
    a = rng.uniform([10, 10], [150, 110], size=(n, k, 2))
    b = a + rng.uniform(-30, 30, size=(n, k, 2))
    ra = rng.uniform(2, 9, size=(n, k))
    rb = rng.uniform(2, 9, size=(n, k))
    g1 = rng.uniform(size=(h, w)).astype(np.float32)
    g2 = (rng.uniform(size=(h, w)) > 0.3).astype(np.float32)
    s1, s2 = _sums(a, b, ra, rb, g1, g2)
    for i in range(n):
        e1, e2, _ = _brute_force(a[i], b[i], ra[i], rb[i], g1, g2)
        assert s1[i] == pytest.approx(e1, rel=1e-4)
        assert s2[i] == pytest.approx(e2, rel=1e-9)


def test_kernel_agrees_with_the_opencv_fill(rng):
    h, w = 120, 160
    a = rng.uniform([20, 20], [140, 100], size=(10, 2, 2))
    b = a + rng.uniform(-25, 25, size=(10, 2, 2))
    r = rng.uniform(5, 10, size=(10, 2))
    g = np.ones((h, w), np.float32)
    _, s2 = _sums(a, b, r, r, g, g)
    for i in range(10):
        m = rasterize(ProjectedCapsules(a[i], b[i], r[i], r[i], np.ones(2)), (w, h)).astype(bool)
        _, _, exact = _brute_force(a[i], b[i], r[i], r[i], g, g)
        assert s2[i] == exact.sum()
        # OpenCV's fill differs from the exact capsule on a few boundary pixels, without bias
        assert (m ^ exact).sum() <= 0.06 * exact.sum()
        assert abs(int(m.sum()) - int(exact.sum())) <= 0.04 * exact.sum()


def test_overlapping_capsules_are_counted_once():
    a = np.array([[[20.0, 20.0], [20.0, 20.0]]])
    b = np.array([[[40.0, 20.0], [40.0, 20.0]]])
    r = np.full((1, 2), 5.0)
    g = np.ones((60, 60), np.float32)
    s1_two, _ = _sums(a, b, r, r, g, g)
    s1_one, _ = _sums(a[:, :1], b[:, :1], r[:, :1], r[:, :1], g, g)
    assert s1_two[0] == s1_one[0] > 0


def test_capsules_outside_the_image_and_nan_count_nothing():
    a = np.array([[[-50.0, -50.0], [np.nan, 3.0]]])
    b = np.array([[[-40.0, -45.0], [4.0, 4.0]]])
    r = np.full((1, 2), 3.0)
    g = np.ones((30, 30), np.float32)
    s1, s2 = _sums(a, b, r, r, g, g)
    assert s1[0] == 0 and s2[0] == 0


def test_fill_marks_exactly_the_pixels_the_kernel_counts(rng):
    h, w = 90, 120
    a = rng.uniform([10, 10], [110, 80], size=(4, 2))
    b = a + rng.uniform(-30, 30, size=(4, 2))
    ra, rb = rng.uniform(2, 9, size=4), rng.uniform(2, 9, size=4)
    mask = np.zeros((h, w), np.float32)
    fill_capsules(mask, a, b, ra, rb, 1.0)
    _, _, exact = _brute_force(a, b, ra, rb, mask, mask)
    assert mask.sum() > 0
    assert np.array_equal(mask > 0, exact)


def test_free_prefixes_are_the_row_sums_of_the_free_silhouette():
    """free_prefixes(_views) equal row_prefix of silhouette x (1 - placed) and of 1 - placed, bit for
    bit, and row_prefix is the sum of each row left of x."""
    from gaitcap.tracking.raster import free_prefixes, free_prefixes_views

    rng = np.random.default_rng(3)
    sil = [rng.uniform(0, 1, (30, 41)).astype(np.float32) for _ in range(2)]
    placed = [(rng.uniform(0, 1, (30, 41)) < 0.3).astype(np.float32) for _ in range(2)]
    R = row_prefix(sil[0])
    assert R.shape == (30, 42) and np.all(R[:, 0] == 0)
    assert np.allclose(R[7, 20], sil[0][7, :20].sum(dtype=np.float64))
    C1, C2 = free_prefixes_views(tuple(sil), tuple(placed))
    for c in range(2):
        one = free_prefixes(sil[c], placed[c])
        want = (row_prefix(sil[c] * (np.float32(1) - placed[c])), row_prefix(np.float32(1) - placed[c]))
        for got_views, got_one, w in zip((C1[c], C2[c]), one, want):
            assert np.array_equal(got_one, w) and np.array_equal(got_views, w)
    into = (np.full_like(C1, np.nan), np.full_like(C2, np.nan))  # reused arrays: every element written
    assert all(r is i for r, i in zip(free_prefixes_views(tuple(sil), tuple(placed), into), into))
    assert np.array_equal(into[0], C1) and np.array_equal(into[1], C2)


def test_free_prefixes_refreshed_on_the_filled_rows_equal_new_ones():
    """After fill_capsules, recomputing only the rows it reports gives the free-pixel sums of the
    new mask bit for bit (the factored filter's Img_n updates)."""
    from gaitcap.tracking.raster import free_prefix_rows, free_prefixes

    rng = np.random.default_rng(5)
    sil = rng.uniform(0, 1, (60, 80)).astype(np.float32)
    placed = np.zeros((60, 80), np.float32)
    C1, C2 = free_prefixes(sil, placed)
    for a, b, r in (([10.0, 12.0], [30.0, 25.0], 4.0), ([70.0, 40.0], [75.0, 58.0], 6.0)):
        before = placed.copy()
        y0, y1 = fill_capsules(placed, np.array([a]), np.array([b]), np.array([r]), np.array([r]), 1.0)
        changed = np.flatnonzero((placed != before).any(axis=1))
        assert y0 <= changed.min() and changed.max() <= y1
        free_prefix_rows(sil, placed, C1, C2, y0, y1)
        want = free_prefixes(sil, placed)
        assert np.array_equal(C1, want[0]) and np.array_equal(C2, want[1])
    assert placed.sum() > 0
