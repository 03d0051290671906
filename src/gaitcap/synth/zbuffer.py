"""A z-buffered triangle rasteriser for the synthetic renderer (numba, one thread).

The renderer's person is a triangle mesh (:mod:`gaitcap.synth.mannequin`). Each triangle is
filled over the pixel centres its projection covers (edge functions, top-left fill rule not
needed: a pixel shared by two triangles of one surface gets either); a pixel keeps the nearest
surface (smallest camera depth). The shade is interpolated over the triangle from its vertices
(Gouraud), the colour is the triangle's, so a pixel's value is ``colour * shade``.

The same kernel fills the floor shadow: every triangle of the body projected on the floor along
the light, into a top-down grid, depth ignored.
"""

from __future__ import annotations

import numpy as np
from gaitcap.jit import cached_njit

NEAR_M = 0.05  # triangles with a vertex closer to the camera than this are skipped


@cached_njit()
def _raster(px, z, shade, tris, colors, img, zbuf, cover, use_depth):  # pragma: no cover - compiled
    H, W = zbuf.shape
    for m in range(tris.shape[0]):
        i0, i1, i2 = tris[m, 0], tris[m, 1], tris[m, 2]
        if use_depth and (z[i0] < NEAR_M or z[i1] < NEAR_M or z[i2] < NEAR_M):
            continue
        x0, y0 = px[i0, 0], px[i0, 1]
        x1, y1 = px[i1, 0], px[i1, 1]
        x2, y2 = px[i2, 0], px[i2, 1]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-9:
            continue
        xmin = max(int(np.ceil(min(x0, x1, x2))), 0)
        xmax = min(int(np.floor(max(x0, x1, x2))), W - 1)
        ymin = max(int(np.ceil(min(y0, y1, y2))), 0)
        ymax = min(int(np.floor(max(y0, y1, y2))), H - 1)
        inv = 1.0 / area
        for y in range(ymin, ymax + 1):
            for x in range(xmin, xmax + 1):
                w0 = ((x1 - x) * (y2 - y) - (x2 - x) * (y1 - y)) * inv
                w1 = ((x2 - x) * (y0 - y) - (x0 - x) * (y2 - y)) * inv
                w2 = 1.0 - w0 - w1
                if w0 < -1e-9 or w1 < -1e-9 or w2 < -1e-9:  # edges shared by two triangles: both
                    continue
                cover[y, x] = 1.0
                if not use_depth:
                    continue
                d = w0 * z[i0] + w1 * z[i1] + w2 * z[i2]
                if d >= zbuf[y, x]:
                    continue
                zbuf[y, x] = d
                s = w0 * shade[i0] + w1 * shade[i1] + w2 * shade[i2]
                for c in range(3):
                    img[y, x, c] = colors[m, c] * s


def draw_mesh(
    img: np.ndarray, px: np.ndarray, depth: np.ndarray, shade: np.ndarray, tris: np.ndarray, colors: np.ndarray
) -> np.ndarray:
    """Draw a mesh over ``img`` in place; returns its coverage.

    Args:
        img: (H, W, 3) float32 image, painted where the mesh is the nearest surface.
        px: (V, 2) projected vertices, pixel coordinates (integer = pixel centre).
        depth: (V,) camera depth of the vertices, metres.
        shade: (V,) brightness factor of the vertices.
        tris: (M, 3) vertex indices.
        colors: (M, 3) BGR colour of each triangle.

    Returns:
        (H, W) float32, 1 where the mesh covers a pixel centre, else 0.
    """
    H, W = img.shape[:2]
    zbuf = np.full((H, W), np.inf, np.float32)
    cover = np.zeros((H, W), np.float32)
    _raster(np.ascontiguousarray(px, np.float64), np.ascontiguousarray(depth, np.float64),
            np.ascontiguousarray(shade, np.float64), np.ascontiguousarray(tris, np.int64),
            np.ascontiguousarray(colors, np.float32), img, zbuf, cover, True)  # fmt: skip
    return cover


def fill_triangles(shape: tuple[int, int], px: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Union of the triangles ``tris`` (M, 3) of the 2D vertices ``px`` (V, 2): (rows, cols) float32 0/1."""
    cover = np.zeros(shape, np.float32)
    dummy = np.zeros((1, 1, 3), np.float32)
    zero = np.zeros(len(px))
    _raster(np.ascontiguousarray(px, np.float64), zero, zero, np.ascontiguousarray(tris, np.int64),
            np.zeros((len(tris), 3), np.float32), dummy, np.zeros(shape, np.float32), cover, False)  # fmt: skip
    return cover


def warm_up() -> None:
    """Compile (or load from numba's cache) the kernel with the argument types the renderer passes."""
    img = np.zeros((4, 4, 3), np.float32)
    draw_mesh(img, np.zeros((3, 2)), np.ones(3), np.ones(3), np.zeros((1, 3), np.int64), np.zeros((1, 3), np.float32))
    fill_triangles((4, 4), np.zeros((3, 2)), np.zeros((1, 3), np.int64))
