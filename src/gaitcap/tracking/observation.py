"""What the tracker observes: per camera, the silhouette as a soft mask on an undistorted,
downscaled pinhole grid.

A full-resolution (distorted) binary mask is remapped to the ideal pinhole image of the same
camera, then area-averaged down by ``scale``: each low-resolution pixel holds the fraction of its
area that is silhouette (0..1). Model capsules are projected with the matching pinhole
intrinsics, so no distortion is evaluated per particle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import cv2
import numpy as np

from gaitcap.camera import Camera, CameraRig, distort_normalized
from gaitcap.tracking.raster import row_prefix


@dataclass(frozen=True)
class TrackingView:
    """One camera at the likelihood's resolution (pinhole, no distortion)."""

    camera: Camera
    scale: float
    K: np.ndarray  # (3, 3) low-resolution pinhole intrinsics
    size: tuple[int, int]  # (w, h) low resolution
    undistort_map: tuple[np.ndarray, np.ndarray] | None  # full-res ideal pixel -> distorted pixel

    @classmethod
    def of(cls, camera: Camera, scale: float) -> TrackingView:
        w, h = camera.size
        lw, lh = max(8, int(round(w * scale))), max(8, int(round(h * scale)))
        sx, sy = lw / w, lh / h
        K = camera.matrix.copy()
        K[0, 0] *= sx
        K[0, 2] = (K[0, 2] + 0.5) * sx - 0.5
        K[1, 1] *= sy
        K[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        umap = None
        if np.any(camera.dist):
            gv, gu = np.mgrid[0:h, 0:w].astype(np.float64)
            Kinv = np.linalg.inv(camera.matrix)
            rays = np.stack([gu, gv, np.ones_like(gu)], -1) @ Kinv.T
            xd, yd = distort_normalized(rays[..., 0], rays[..., 1], camera.dist)
            M = camera.matrix
            umap = ((M[0, 0] * xd + M[0, 2]).astype(np.float32), (M[1, 1] * yd + M[1, 2]).astype(np.float32))
        return cls(camera=camera, scale=scale, K=K, size=(lw, lh), undistort_map=umap)

    def prepare(self, mask: np.ndarray) -> np.ndarray:
        """Full-resolution mask (H, W) -> soft silhouette (h, w) float32 in [0, 1]. An integer mask is
        binary (0/1 or 0/255, any non-zero is silhouette); a float one is a per-pixel confidence in [0, 1]."""
        mask = np.asarray(mask)
        if np.issubdtype(mask.dtype, np.floating):
            m = np.clip(mask, 0.0, 1.0).astype(np.float32, copy=False)
        else:
            m = (mask > 0).astype(np.float32)
        if self.undistort_map is not None:
            m = cv2.remap(m, self.undistort_map[0], self.undistort_map[1], cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return cv2.resize(m, self.size, interpolation=cv2.INTER_AREA)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (..., 3) -> low-resolution pinhole pixels (..., 2) and depth (...)."""
        pc = points @ self.camera.R.T + self.camera.tvec
        z = np.maximum(pc[..., 2], 1e-3)
        u = self.K[0, 0] * pc[..., 0] / z + self.K[0, 2]
        v = self.K[1, 1] * pc[..., 1] / z + self.K[1, 2]
        return np.stack([u, v], -1), z

    @property
    def focal(self) -> float:
        return float(0.5 * (self.K[0, 0] + self.K[1, 1]))


@lru_cache(maxsize=16)
def _ones_prefix(shape: tuple[int, int]) -> np.ndarray:
    """Row prefix sums (h, w + 1) of an (h, w) map of ones, shared by every observation of that size
    (the same every frame; read, never written)."""
    return row_prefix(np.ones(shape, np.float32))


@dataclass
class Observation:
    """One frame: the soft silhouettes (h, w) float32 of every camera, and their areas."""

    silhouettes: list[np.ndarray]
    #: |S_c| per camera when it is not the silhouettes' sum: soft silhouettes with doubtful pixels
    #: outside the mask (silhouette.yaml's ``foreground.doubt_min``) count the mask's area only
    given_areas: np.ndarray | None = None
    _prefix: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, repr=False)

    def arrays(self) -> list[np.ndarray]:
        """What a spool stores of this frame (:meth:`from_arrays` reads it back): the silhouettes, and
        the given areas (float32, so that both passes read the same values) when there are any."""
        if self.given_areas is None:
            return list(self.silhouettes)
        return [*self.silhouettes, np.asarray(self.given_areas, np.float32)]

    @classmethod
    def from_arrays(cls, arrays: list[np.ndarray]) -> Observation:
        """An observation from :meth:`arrays`' output (the areas, if any: the last array, (C,))."""
        if arrays and arrays[-1].ndim == 1:
            return cls(list(arrays[:-1]), given_areas=np.asarray(arrays[-1], np.float64))
        return cls(list(arrays))

    def prefix(self, c: int) -> tuple[np.ndarray, np.ndarray]:
        """Row prefix sums of camera c's silhouette and of ones (cached)."""
        if c not in self._prefix:
            s = self.silhouettes[c]
            self._prefix[c] = (row_prefix(s), _ones_prefix(s.shape))
        return self._prefix[c]

    @cached_property
    def areas(self) -> np.ndarray:
        """|S_c| per camera (C,) (cached: the likelihood reads it at every layer)."""
        if self.given_areas is not None:
            return np.asarray(self.given_areas, float)
        return np.array([float(s.sum()) for s in self.silhouettes])

    def fractions(self) -> np.ndarray:
        """Silhouette area as a fraction of each image."""
        return np.array([float(s.mean()) for s in self.silhouettes])


def tracking_views(rig: CameraRig, scale: float) -> list[TrackingView]:
    return [TrackingView.of(cam, scale) for cam in rig]


def observe(views: list[TrackingView], masks: list[np.ndarray]) -> Observation:
    """Prepare one frame's full-resolution masks (one per camera, rig order)."""
    return Observation([v.prepare(m) for v, m in zip(views, masks)])
