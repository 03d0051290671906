"""Render views of a checkerboard seen by known cameras (for tests and measurement scripts).

The board texture is warped through the exact camera model, distortion included: for every
output pixel p, the ideal pixel q = undistort(p) is mapped back onto the board plane by the
inverse plane-to-image homography H = K [r1 r2 t] A (A maps texture pixels to board metres).
"""

from __future__ import annotations

import cv2
import numpy as np

from gaitcap.calibration.boards import Board
from gaitcap.camera import Camera


def board_texture(board: Board, px_per_square: int = 40) -> tuple[np.ndarray, float]:
    """Printed checkerboard (uint8, white margin of one square) and the texture pixel of corner 0.

    The square after corner 0 (towards corner ``cols + 1``) is dark, as
    :func:`gaitcap.calibration.boards.canonical_order` expects.
    """
    c, r = board.corner_grid
    nx, ny = c + 1, r + 1
    s = px_per_square
    tex = np.full(((ny + 2) * s, (nx + 2) * s), 255, np.uint8)
    for j in range(ny):
        for i in range(nx):
            if (i + j) % 2 == 0:
                tex[(j + 1) * s:(j + 2) * s, (i + 1) * s:(i + 2) * s] = 0
    return tex, 2.0 * s - 0.5  # pixel centres: corner 0 lies between pixels


def render_board_view(
    camera: Camera,
    board: Board,
    pose: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3)),
    rng: np.random.Generator | None = None,
    noise: float = 2.0,
    background: int = 110,
    px_per_square: int = 40,
) -> np.ndarray:
    """Image (H, W) uint8 of ``board`` placed by ``pose`` (rvec, tvec: board -> world) in ``camera``.

    Adds Gaussian noise of ``noise`` grey levels (with ``rng``) after a slight optical blur.
    """
    tex, o = board_texture(board, px_per_square)
    s = board.square_m / px_per_square
    A = np.array([[s, 0, -o * s], [0, -s, o * s], [0, 0, 1.0]])  # texture px -> board metres (y flipped)
    R = camera.R @ cv2.Rodrigues(np.asarray(pose[0], float))[0]
    t = camera.R @ np.asarray(pose[1], float) + camera.tvec
    H = camera.matrix @ np.column_stack([R[:, 0], R[:, 1], t]) @ A
    w, h = camera.size
    grid = np.stack(np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)), axis=-1).reshape(-1, 2)
    ideal = camera.undistort_pixels(grid)
    q = np.c_[ideal, np.ones(len(ideal))] @ np.linalg.inv(H).T
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = q[:, :2] / q[:, 2:3]
    # points of the plane behind the camera map to no texture
    front = (np.c_[uv, np.ones(len(uv))] @ H.T)[:, 2] * np.sign(q[:, 2]) > 0
    uv[~front | ~np.isfinite(uv).all(axis=1)] = -1e6
    maps = uv.reshape(h, w, 2).astype(np.float32)
    img = cv2.remap(tex, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=background)
    img = cv2.GaussianBlur(img, (0, 0), 0.7).astype(np.float64)
    if noise > 0:
        img += (rng or np.random.default_rng(0)).normal(0.0, noise, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)
