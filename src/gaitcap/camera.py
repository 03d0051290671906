"""Pinhole cameras with OpenCV's distortion model, and rigs of several cameras.

Conventions (the Pose2Sim / anipose ``calibration.toml`` convention):

* ``rvec`` is the Rodrigues vector and ``tvec`` the translation of the world -> camera transform,
  ``X_cam = R @ X_world + t`` with ``R = Rodrigues(rvec)``; metres.
* The camera looks along its +z axis, x to the right of the image, y down.
* Distortion coefficients follow OpenCV: ``[k1, k2, p1, p2[, k3[, k4, k5, k6]]]``.

The world frame of a gaitcap session: metres, z up, the floor is the plane z = 0.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from gaitcap.errors import CalibrationError

#: the lengths of OpenCV's distortion vector (k1, k2, p1, p2, then k3; k4-k6; s1-s4; tx, ty)
DISTORTION_SIZES = (4, 5, 8, 12, 14)


def _as_points(points: np.ndarray, name: str = "points") -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape[-1:] != (3,):
        raise ValueError(f"{name}: expected shape (..., 3), got {pts.shape}")
    return pts


@dataclass(frozen=True)
class Camera:
    """One calibrated camera.

    Attributes:
        name: camera name; the session's video for it is ``videos/<name>.<ext>``.
        size: image size ``(width, height)`` in pixels.
        matrix: intrinsic matrix K, shape (3, 3).
        dist: distortion coefficients, shape (4,), (5,), (8,), (12,) or (14,) (OpenCV order).
        rvec: Rodrigues rotation world -> camera, shape (3,).
        tvec: translation world -> camera in metres, shape (3,).
    """

    name: str
    size: tuple[int, int]
    matrix: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(4))
    rvec: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tvec: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        K = np.asarray(self.matrix, dtype=np.float64)
        if K.shape != (3, 3) or not np.all(np.isfinite(K)):
            raise CalibrationError(f"camera {self.name!r}: matrix must be a finite 3x3 array")
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise CalibrationError(f"camera {self.name!r}: focal lengths must be positive")
        dist = np.asarray(self.dist, dtype=np.float64).ravel()
        if dist.size not in DISTORTION_SIZES or not np.all(np.isfinite(dist)):
            raise CalibrationError(
                f"camera {self.name!r}: distortions must hold 4, 5, 8, 12 or 14 finite coefficients (OpenCV's "
                f"k1, k2, p1, p2[, k3[, k4, k5, k6[, s1..s4[, tx, ty]]]]), got {dist.size}"
            )
        rvec = np.asarray(self.rvec, dtype=np.float64).ravel()
        tvec = np.asarray(self.tvec, dtype=np.float64).ravel()
        if rvec.size == 9:
            raise CalibrationError(f"camera {self.name!r}: rotation is a 3x3 matrix; calibration.toml takes the "
                                   "Rodrigues vector [rx, ry, rz] (radians, world -> camera): convert it with "
                                   "cv2.Rodrigues")  # fmt: skip
        if rvec.shape != (3,) or tvec.shape != (3,) or not np.all(np.isfinite(np.r_[rvec, tvec])):
            raise CalibrationError(f"camera {self.name!r}: rotation and translation must be 3 finite numbers")
        try:
            w, h = (int(v) for v in self.size)
            whole = all(float(v) == int(v) for v in self.size)
        except (TypeError, ValueError):  # not two numbers ('ab', [640]): a bare unpacking error before
            w = h = 0
            whole = False
        if w <= 0 or h <= 0 or not whole:
            raise CalibrationError(f"camera {self.name!r}: size must be two positive integers [w, h], got {self.size!r}")
        object.__setattr__(self, "matrix", K)
        object.__setattr__(self, "dist", dist)
        object.__setattr__(self, "rvec", rvec)
        object.__setattr__(self, "tvec", tvec)
        object.__setattr__(self, "size", (w, h))

    # ----------------------------------------------------------------- geometry
    @property
    def R(self) -> np.ndarray:
        """Rotation world -> camera, shape (3, 3)."""
        return cv2.Rodrigues(self.rvec)[0]

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates (metres), shape (3,)."""
        return -self.R.T @ self.tvec

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def height(self) -> int:
        return self.size[1]

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """World points (..., 3) -> camera-frame points (..., 3)."""
        pts = _as_points(points)
        return np.einsum("...j,ij->...i", pts, self.R) + self.tvec  # pts @ R.T without a BLAS call

    def project(self, points: np.ndarray, distort: bool = True) -> np.ndarray:
        """Project world points (..., 3) to pixels (..., 2) with OpenCV's model.

        Agrees with ``cv2.projectPoints`` for points in front of the camera. Points behind the
        camera (z <= 0) give NaN. ``distort=False`` gives the ideal pinhole projection.
        """
        pc = self.to_camera(points)
        z = pc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.where(z > 1e-9, pc[..., 0] / z, np.nan)
            y = np.where(z > 1e-9, pc[..., 1] / z, np.nan)
        if distort and np.any(self.dist):
            x, y = distort_normalized(x, y, self.dist)
        K = self.matrix
        u = K[0, 0] * x + K[0, 1] * y + K[0, 2]
        v = K[1, 1] * y + K[1, 2]
        return np.stack([u, v], axis=-1)

    def undistort_pixels(self, pixels: np.ndarray) -> np.ndarray:
        """Distorted pixels (N, 2) -> ideal pinhole pixels (N, 2) with the same K."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        if not np.any(self.dist):
            return px.reshape(-1, 2).copy()
        out = cv2.undistortPoints(px, self.matrix, self.dist, P=self.matrix)
        return out.reshape(-1, 2)

    def pinhole(self) -> Camera:
        """The same camera without distortion."""
        return replace(self, dist=np.zeros(4))

    def projection_matrix(self) -> np.ndarray:
        """P = K [R | t], shape (3, 4) (no distortion)."""
        return self.matrix @ np.hstack([self.R, self.tvec[:, None]])

    def in_image(self, pixels: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask (...,) of pixels (..., 2) inside the image, ``margin`` pixels from the border."""
        px = np.asarray(pixels)
        w, h = self.size
        with np.errstate(invalid="ignore"):
            return (
                (px[..., 0] >= margin)
                & (px[..., 0] <= w - 1 - margin)
                & (px[..., 1] >= margin)
                & (px[..., 1] <= h - 1 - margin)
            )

    # -------------------------------------------------------------- conversion
    def to_dict(self) -> dict:
        """The camera as a ``calibration.toml`` table."""
        return {
            "name": self.name,
            "size": [float(self.size[0]), float(self.size[1])],
            "matrix": self.matrix.tolist(),
            "distortions": self.dist.tolist(),
            "rotation": self.rvec.tolist(),
            "translation": self.tvec.tolist(),
            "fisheye": False,
        }

    @classmethod
    def from_dict(cls, table: dict, source: str = "calibration") -> Camera:
        """Build from a ``calibration.toml`` table; errors name ``source`` and the missing key."""
        where = f"{source}: camera {table.get('name', '?')!r}"
        for key in ("name", "size", "matrix", "distortions", "rotation", "translation"):
            if key not in table:
                raise CalibrationError(f"{where}: missing key '{key}'")
        if table.get("fisheye", False):
            raise CalibrationError(f"{where}: fisheye cameras are not supported")
        try:
            size = tuple(int(round(float(v))) for v in table["size"])
            if len(size) != 2:
                raise ValueError("size must be [w, h]")
            return cls(
                name=str(table["name"]),
                size=size,  # type: ignore[arg-type]
                matrix=np.asarray(table["matrix"], dtype=np.float64),
                dist=np.asarray(table["distortions"], dtype=np.float64),
                rvec=np.asarray(table["rotation"], dtype=np.float64),
                tvec=np.asarray(table["translation"], dtype=np.float64),
            )
        except CalibrationError as e:
            raise CalibrationError(f"{source}: {e}") from e
        except (TypeError, ValueError) as e:
            raise CalibrationError(f"{where}: malformed value ({e})") from e

    @classmethod
    def look_at(
        cls,
        name: str,
        position: Sequence[float],
        target: Sequence[float],
        size: tuple[int, int] = (640, 480),
        focal_px: float = 600.0,
        dist: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
    ) -> Camera:
        """A camera at ``position`` looking at ``target`` with the world z axis up in the image."""
        c = np.asarray(position, dtype=np.float64)
        fwd = np.asarray(target, dtype=np.float64) - c
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        if np.linalg.norm(right) < 1e-6:
            raise ValueError("look_at: the camera cannot look straight up or down")
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        R = np.stack([right, down, fwd])  # rows: camera axes in world coordinates
        rvec = cv2.Rodrigues(R)[0].ravel()
        tvec = -R @ c
        w, h = size
        K = np.array([[focal_px, 0, (w - 1) / 2], [0, focal_px, (h - 1) / 2], [0, 0, 1]])
        return cls(name=name, size=(w, h), matrix=K, dist=np.asarray(dist, float), rvec=rvec, tvec=tvec)


def dlt_point(projections: Sequence[np.ndarray], pixels: Sequence[np.ndarray]) -> np.ndarray | None:
    """Linear (DLT) triangulation of one point from its ideal (undistorted) pixels (2,) in the views
    of projection matrices (3, 4), matched lists: the world point (3,), or None when fewer than two
    views see it or the solution lies at infinity."""
    rows = []
    for P, (u, v) in zip(projections, pixels, strict=True):
        rows.append(u * P[2] - P[0])
        rows.append(v * P[2] - P[1])
    if len(rows) < 4:
        return None
    _, _, vt = np.linalg.svd(np.asarray(rows))
    X = vt[-1]
    return X[:3] / X[3] if abs(X[3]) > 1e-12 else None


def distort_normalized(x: np.ndarray, y: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Apply OpenCV's radial/tangential distortion to normalised coordinates (same shapes)."""
    d = np.zeros(8)
    d[: min(8, dist.size)] = dist[:8]
    k1, k2, p1, p2, k3, k4, k5, k6 = d
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / (1 + k4 * r2 + k5 * r4 + k6 * r6)
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return xd, yd


@dataclass(frozen=True)
class CameraRig:
    """Several calibrated cameras sharing one world frame."""

    cameras: tuple[Camera, ...]

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise CalibrationError("a camera rig needs at least one camera")
        names = [c.name for c in cams]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise CalibrationError(f"duplicate camera names: {', '.join(sorted(dup))}")
        object.__setattr__(self, "cameras", cams)

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self) -> Iterator[Camera]:
        return iter(self.cameras)

    def __getitem__(self, key: int | str) -> Camera:
        if isinstance(key, str):
            for cam in self.cameras:
                if cam.name == key:
                    return cam
            raise KeyError(f"no camera named {key!r} (cameras: {', '.join(self.names)})")
        return self.cameras[key]

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def project(self, points: np.ndarray, distort: bool = True) -> np.ndarray:
        """World points (..., 3) -> pixels (C, ..., 2), one slice per camera."""
        return np.stack([c.project(points, distort=distort) for c in self.cameras])

    def triangulate(self, pixels: np.ndarray) -> np.ndarray:
        """Linear (DLT) triangulation of pixels (C, N, 2) -> world points (N, 3).

        NaN pixels are ignored; a point seen by fewer than two cameras gives NaN. Pixels are
        undistorted first.
        """
        px = np.asarray(pixels, dtype=np.float64)
        if px.ndim != 3 or px.shape[0] != len(self) or px.shape[2] != 2:
            raise ValueError(f"triangulate: expected pixels of shape ({len(self)}, N, 2), got {px.shape}")
        n = px.shape[1]
        und = np.stack([c.undistort_pixels(np.nan_to_num(px[i])) for i, c in enumerate(self.cameras)])
        valid = np.all(np.isfinite(px), axis=2)
        Ps = [c.projection_matrix() for c in self.cameras]
        out = np.full((n, 3), np.nan)
        for j in range(n):
            seen = np.flatnonzero(valid[:, j])
            X = dlt_point([Ps[i] for i in seen], [und[i, j] for i in seen])
            if X is not None:
                out[j] = X
        return out

    def subset(self, names: Iterable[str]) -> CameraRig:
        return CameraRig(tuple(self[n] for n in names))
