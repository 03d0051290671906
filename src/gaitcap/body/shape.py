"""The body's volume seen by a camera: tapered capsules projected to 2D and rasterised.

A capsule (A, B, r_a, r_b) projects approximately to the convex hull of two discs centred on the
projections a, b of its ends, with radii f·r / z (z: depth of each end). This is exact for a
sphere seen head-on and accurate to a few per cent for limbs at walking distances.

All projection here is ideal pinhole (no lens distortion): callers either undistort the image
(tracking) or distort the rendering afterwards (synth).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gaitcap.camera import Camera


@dataclass(frozen=True)
class ProjectedCapsules:
    """Capsules in one camera. Shapes: a, b (..., C, 2) pixels; ra, rb (..., C) pixels; depth (..., C) metres."""

    a: np.ndarray
    b: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    depth: np.ndarray


def project_capsules(
    camera: Camera, A: np.ndarray, B: np.ndarray, radii: np.ndarray, offset: tuple[float, float] = (0.0, 0.0)
) -> ProjectedCapsules:
    """Project capsule ends A, B (..., C, 3) with radii (C, 2) metres into ``camera`` (pinhole).

    ``offset`` is added to every pixel coordinate (for rendering onto a padded canvas).
    """
    R, t, K = camera.R, camera.tvec, camera.matrix
    ca = A @ R.T + t
    cb = B @ R.T + t
    za = np.maximum(ca[..., 2], 1e-3)
    zb = np.maximum(cb[..., 2], 1e-3)
    f = 0.5 * (K[0, 0] + K[1, 1])
    off = np.asarray(offset)
    a = np.stack([K[0, 0] * ca[..., 0] / za + K[0, 2], K[1, 1] * ca[..., 1] / za + K[1, 2]], axis=-1) + off
    b = np.stack([K[0, 0] * cb[..., 0] / zb + K[0, 2], K[1, 1] * cb[..., 1] / zb + K[1, 2]], axis=-1) + off
    return ProjectedCapsules(a=a, b=b, ra=f * radii[:, 0] / za, rb=f * radii[:, 1] / zb, depth=0.5 * (za + zb))


def capsule_polygon(a: np.ndarray, b: np.ndarray, ra: float, rb: float) -> np.ndarray:
    """The quadrilateral joining the two end discs of one 2D capsule, shape (4, 2)."""
    d = b - a
    n = np.linalg.norm(d)
    if n < 1e-9:
        return np.repeat(a[None], 4, axis=0)
    perp = np.array([-d[1], d[0]]) / n
    return np.array([a + perp * ra, b + perp * rb, b - perp * rb, a - perp * ra])


_SHIFT = 4  # cv2 fixed-point sub-pixel bits
_SCALE = 1 << _SHIFT


def draw_capsule(img: np.ndarray, a: np.ndarray, b: np.ndarray, ra: float, rb: float, color) -> None:
    """Fill one 2D capsule into ``img`` (in place) with sub-pixel accuracy."""
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return
    for c, r in ((a, ra), (b, rb)):
        cv2.circle(img, tuple(int(v) for v in np.round(c * _SCALE)), int(round(r * _SCALE)), color, -1,
                   cv2.LINE_8, _SHIFT)
    poly = np.round(capsule_polygon(a, b, ra, rb) * _SCALE).astype(np.int32)
    cv2.fillConvexPoly(img, poly, color, cv2.LINE_8, _SHIFT)


def rasterize(pc: ProjectedCapsules, size: tuple[int, int], index: int | None = None) -> np.ndarray:
    """Binary mask (h, w) uint8 0/1 of the union of capsules (one pose: a has shape (C, 2)).

    ``index`` selects one pose when ``pc`` holds a batch (..., C, 2).
    """
    w, h = size
    mask = np.zeros((h, w), np.uint8)
    a, b, ra, rb = pc.a, pc.b, pc.ra, pc.rb
    if index is not None:
        a, b, ra, rb = a[index], b[index], ra[index], rb[index]
    for c in range(a.shape[0]):
        draw_capsule(mask, a[c], b[c], float(ra[c]), float(rb[c]), 1)
    return mask
