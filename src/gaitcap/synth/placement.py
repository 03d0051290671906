"""Automatic camera placement that keeps the whole walk in view.

The walking direction d is the principal horizontal direction of the pelvis path (or, for a walk
in place, the direction the subject faces). Camera i sits at azimuth theta_i from d (90 degrees:
lateral, on the subject's left; -45 degrees: front-oblique on the right), at a given distance and
height, looking at the middle of the walk, and is zoomed so that every point of the walk, padded
by the body's thickness, lies inside the image with a margin.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitcap.camera import Camera

#: default azimuths (degrees from the walking direction, positive to the subject's left)
DEFAULT_AZIMUTHS = (90.0, -45.0, -135.0, 45.0, 180.0, -90.0, 0.0, 135.0)


def walking_direction(pelvis: np.ndarray, hip_l: np.ndarray, hip_r: np.ndarray) -> np.ndarray:
    """Unit horizontal walking direction (3,), from the pelvis path (T, 3) or the hips' facing."""
    xy = pelvis[np.all(np.isfinite(pelvis), axis=1), :2]
    facing = np.nanmean(np.cross(hip_l - hip_r, [0.0, 0.0, 1.0]), axis=0)[:2]
    facing /= np.linalg.norm(facing)
    if len(xy) >= 2 and np.ptp(xy, axis=0).max() > 0.5:
        _, _, vt = np.linalg.svd(xy - xy.mean(axis=0))
        d = vt[0]
        if np.dot(d, xy[-1] - xy[0]) < 0:
            d = -d
    else:
        d = facing
    return np.array([d[0], d[1], 0.0]) / np.linalg.norm(d)


def padded_walk(points: np.ndarray) -> np.ndarray:
    """The walk's points (T, P, 3), finite ones, padded by the body's thickness: (N, 3)."""
    pts = points.reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    pad = np.array([[dx, dy, dz] for dx in (-0.15, 0.15) for dy in (-0.15, 0.15) for dz in (0.0, 0.12)])
    padded = (pts[:, None, :] + pad[None]).reshape(-1, 3)
    padded[:, 2] = np.maximum(padded[:, 2], 0.0)
    return padded


def place_cameras_at(
    points: np.ndarray,
    direction: np.ndarray,
    azimuths_deg: Sequence[float],
    distances_m: Sequence[float],
    heights_m: Sequence[float],
    size: tuple[int, int] = (640, 480),
    distortion: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
    margin: float = 0.04,
    min_clearance_m: float = 1.5,
) -> list[Camera]:
    """Cameras cam1..camN at given azimuths, distances and heights around the walk, each zoomed
    (focal length) so that the whole padded walk ``points`` (T, P, 3) fits with ``margin``.

    The distance is measured from the middle of the walk and raised where needed so that the
    camera stands at least ``min_clearance_m`` beyond the walk (a frontal camera the subject
    walks towards).
    """
    padded = padded_walk(points)
    lo, hi = padded.min(axis=0), padded.max(axis=0)
    centre = 0.5 * (lo + hi)
    target = np.array([centre[0], centre[1], 0.5 * (hi[2] + lo[2])])
    n = np.cross([0.0, 0.0, 1.0], direction)
    w, h = size
    cams = []
    for i, (az, dist, height) in enumerate(zip(azimuths_deg, distances_m, heights_m)):
        a = np.radians(az)
        way = np.cos(a) * direction + np.sin(a) * n
        reach = float(np.max((padded[:, :2] - target[:2]) @ way[:2]))
        dist = max(float(dist), reach + min_clearance_m)
        pos = target + dist * way
        pos[2] = height
        unit = Camera.look_at(f"cam{i + 1}", pos, target, size=size, focal_px=1.0)
        xy = unit.to_camera(padded)
        xn = np.abs(xy[:, 0] / xy[:, 2]).max()
        yn = np.abs(xy[:, 1] / xy[:, 2]).max()
        focal = min((0.5 - margin) * w / xn, (0.5 - margin) * h / yn)
        # lens distortion pulls the corners in (barrel) or out: leave room for it
        focal *= 0.97 if distortion[0] >= 0 else 1.0
        cams.append(Camera.look_at(f"cam{i + 1}", pos, target, size=size, focal_px=float(focal), dist=distortion))
    return cams
