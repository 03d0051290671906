"""A textured room seen by calibrated cameras, ray-cast once per camera.

The room is a box: floor z = 0, four walls and a ceiling. Each surface has a procedural texture
(tiles, skirting, posters, fine grain) sampled in metres. For every camera we cast one ray per pixel
of an *ideal pinhole canvas* (the image plus a border, so that lens distortion can be applied
afterwards with a remap) and keep:

- the background colour of the empty room,
- for floor pixels, their (x, y) on the floor as coordinates in the top-down shadow grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gaitcap.camera import Camera
from gaitcap.synth.variety import RoomStyle

TEXTURE_RES_M = 0.005  # metres per texel
SHADOW_RES_M = 0.01  # metres per shadow-grid cell


@dataclass(frozen=True)
class Room:
    """An axis-aligned room (metres)."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float
    height: float = 3.0

    @classmethod
    def around(cls, points: np.ndarray, margin: float = 1.5, height: float = 3.0) -> Room:
        """The smallest room holding ``points`` (N, 3) (cameras, the walk) plus ``margin``."""
        lo = np.nanmin(points[:, :2], axis=0) - margin
        hi = np.nanmax(points[:, :2], axis=0) + margin
        return cls(float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]), height)

    @property
    def shadow_shape(self) -> tuple[int, int]:
        """(rows, cols) of the top-down shadow grid (rows along y, cols along x)."""
        return (int(np.ceil((self.ymax - self.ymin) / SHADOW_RES_M)) + 1,
                int(np.ceil((self.xmax - self.xmin) / SHADOW_RES_M)) + 1)

    def to_shadow_grid(self, xy: np.ndarray) -> np.ndarray:
        """Floor coordinates (..., 2) metres -> shadow-grid pixel coordinates (..., 2) (col, row)."""
        return np.stack([(xy[..., 0] - self.xmin) / SHADOW_RES_M, (xy[..., 1] - self.ymin) / SHADOW_RES_M], -1)


def _value_noise(rng: np.random.Generator, shape: tuple[int, int], cell: int) -> np.ndarray:
    """Smooth noise in [-1, 1] of ``shape`` with features about ``cell`` texels wide."""
    small = rng.uniform(-1, 1, size=(max(2, shape[0] // cell + 2), max(2, shape[1] // cell + 2))).astype(np.float32)
    return cv2.resize(small, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)


def _tint(color: tuple[float, float, float], value: np.ndarray) -> np.ndarray:
    """(rows, cols, 3) float32: ``value`` (rows, cols), around 1, times the BGR ``color``."""
    return (value[..., None] * np.asarray(color, np.float32)).astype(np.float32)


def floor_texture(rng: np.random.Generator, width_m: float, depth_m: float, style: RoomStyle,
                  mat: tuple[np.ndarray, np.ndarray, float, float] | None = None) -> np.ndarray:
    """The floor seen from above: (rows=y, cols=x, 3) float32 BGR 0-255.

    Tiles with grout, wooden planks, carpet or plain lino in ``style.floor_color``; ``mat`` =
    (centre xy, unit direction xy, length, width) lays a walkway mat of ``style.mat_color``.
    """
    h, w = int(depth_m / TEXTURE_RES_M) + 2, int(width_m / TEXTURE_RES_M) + 2
    y, x = np.mgrid[0:h, 0:w].astype(np.float32) * TEXTURE_RES_M
    grain = 0.03 * rng.standard_normal((h, w)).astype(np.float32)
    if style.floor_kind == "tiles":
        tile = style.tile_m
        ti, tj = np.floor(x / tile).astype(int), np.floor(y / tile).astype(int)
        tile_var = rng.uniform(-0.06, 0.06, size=(ti.max() + 1, tj.max() + 1)).astype(np.float32)[ti, tj]
        grout = ((np.mod(x, tile) < 0.008) | (np.mod(y, tile) < 0.008)).astype(np.float32)
        value = (1 + tile_var + 0.05 * _value_noise(rng, (h, w), 80) + grain) * (1 - 0.35 * grout)
    elif style.floor_kind == "wood":
        plank = 0.18
        pj = np.floor(y / plank).astype(int)
        plank_var = rng.uniform(-0.12, 0.12, size=pj.max() + 1).astype(np.float32)[pj]
        # grain streaks along the planks (x): noise stretched along x
        streaks = 0.08 * cv2.resize(rng.uniform(-1, 1, (h, max(2, w // 60))).astype(np.float32), (w, h),
                                    interpolation=cv2.INTER_LINEAR)
        seams = (np.mod(y, plank) < 0.004).astype(np.float32)
        value = (1 + plank_var + streaks + grain) * (1 - 0.4 * seams)
    elif style.floor_kind == "carpet":
        value = 1 + 0.08 * _value_noise(rng, (h, w), 30) + 3 * grain
    else:
        value = 1 + 0.03 * _value_noise(rng, (h, w), 150) + 0.5 * grain
    tex = _tint(style.floor_color, value)
    if mat is not None and style.mat_color is not None:
        centre, d, length, width = mat
        rel_x, rel_y = x - centre[0], y - centre[1]
        along = rel_x * d[0] + rel_y * d[1]
        across = -rel_x * d[1] + rel_y * d[0]
        on = (np.abs(along) <= length / 2) & (np.abs(across) <= width / 2)
        edge = on & ((np.abs(across) > width / 2 - 0.03) | (np.abs(along) > length / 2 - 0.03))
        mat_tex = _tint(style.mat_color, 1 + 0.05 * _value_noise(rng, (h, w), 20) + grain)
        tex[on] = mat_tex[on]
        tex[edge] *= 0.8
    return tex


def wall_texture(rng: np.random.Generator, length_m: float, height_m: float, style: RoomStyle) -> np.ndarray:
    """A painted wall with a skirting board, maybe a door, and posters: (rows=z from top, cols, 3)."""
    h, w = int(height_m / TEXTURE_RES_M) + 2, int(length_m / TEXTURE_RES_M) + 2
    hue = rng.uniform(0.92, 1.05, size=3).astype(np.float32)
    tex = _tint(tuple(float(c) for c in np.asarray(style.wall_color) * hue), 1 + 0.04 * _value_noise(rng, (h, w), 120))
    skirting = int(0.10 / TEXTURE_RES_M)
    tex[h - skirting :] = rng.uniform(40, 200)
    if style.door_color is not None and length_m > 2.0 and rng.random() < 0.7:
        dw, dh = 0.9, min(2.05, height_m - 0.2)
        c0 = int(rng.uniform(0.2, length_m - dw - 0.2) / TEXTURE_RES_M)
        r0 = int((height_m - dh) / TEXTURE_RES_M)
        frame = int(0.05 / TEXTURE_RES_M)
        tex[r0 - frame : h, c0 - frame : c0 + int(dw / TEXTURE_RES_M) + frame] = 0.8 * np.asarray(style.door_color, np.float32)
        tex[r0:h, c0 : c0 + int(dw / TEXTURE_RES_M)] = np.asarray(style.door_color, np.float32)
    for _ in range(style.n_posters):
        pw, ph = rng.uniform(0.4, 1.2), rng.uniform(0.5, 1.0)
        px, pz = rng.uniform(0, max(0.1, length_m - pw)), rng.uniform(1.0, 2.0)
        c0, r0 = int(px / TEXTURE_RES_M), int((height_m - pz - ph) / TEXTURE_RES_M)
        color = rng.uniform(40, 230, size=3).astype(np.float32)
        tex[max(0, r0) : r0 + int(ph / TEXTURE_RES_M), c0 : c0 + int(pw / TEXTURE_RES_M)] = color
    tex += 2.0 * rng.standard_normal((h, w, 1)).astype(np.float32)
    return tex


@dataclass
class CameraView:
    """What one camera sees of the empty room, on its padded ideal-pinhole canvas."""

    camera: Camera
    pad: int
    background: np.ndarray  # (H + 2 pad, W + 2 pad, 3) float32, canvas
    floor_map: np.ndarray  # (H + 2 pad, W + 2 pad, 2) float32 shadow-grid coords, -1 off the floor
    distort_map: tuple[np.ndarray, np.ndarray] | None  # image pixel -> canvas pixel maps

    @property
    def offset(self) -> tuple[float, float]:
        return (float(self.pad), float(self.pad))

    @property
    def canvas_size(self) -> tuple[int, int]:
        return (self.background.shape[1], self.background.shape[0])

    def to_image(self, canvas: np.ndarray, interpolation: int = cv2.INTER_LINEAR) -> np.ndarray:
        """Crop or distort a canvas-sized array to the camera image."""
        if self.distort_map is None:
            p = self.pad
            return canvas[p : p + self.camera.height, p : p + self.camera.width]
        return cv2.remap(canvas, self.distort_map[0], self.distort_map[1], interpolation,
                         borderMode=cv2.BORDER_REPLICATE)


class Scene:
    """The room, its textures, and what each camera sees of it."""

    def __init__(self, room: Room, style: RoomStyle = RoomStyle(),
                 mat: tuple[np.ndarray, np.ndarray, float, float] | None = None) -> None:
        rng = np.random.default_rng(style.seed)
        self.room = room
        w, d, h = room.xmax - room.xmin, room.ymax - room.ymin, room.height
        if mat is not None:  # floor coordinates of the texture start at (xmin, ymin)
            mat = (np.asarray(mat[0], float) - [room.xmin, room.ymin], mat[1], mat[2], mat[3])
        self.floor = floor_texture(rng, w, d, style, mat)
        self.walls = {
            "ymax": wall_texture(rng, w, h, style), "ymin": wall_texture(rng, w, h, style),
            "xmax": wall_texture(rng, d, h, style), "xmin": wall_texture(rng, d, h, style),
        }  # fmt: skip
        self.ceiling_value = 215.0

    def view(self, camera: Camera, pad_fraction: float = 0.12) -> CameraView:
        """Ray-cast the empty room for ``camera``."""
        W, H = camera.size
        pad = int(round(pad_fraction * max(W, H))) if np.any(camera.dist) else 0
        vv, uu = np.mgrid[0 : H + 2 * pad, 0 : W + 2 * pad].astype(np.float64)
        K = camera.matrix
        x = (uu - pad - K[0, 2]) / K[0, 0]
        y = (vv - pad - K[1, 2]) / K[1, 1]
        dirs = np.stack([x, y, np.ones_like(x)], -1) @ camera.R  # camera -> world (R^T d)
        C = camera.center
        room = self.room
        t_best = np.full(x.shape, np.inf)
        surface = np.full(x.shape, -1, np.int8)
        planes = [(2, 0.0, 0), (2, room.height, 1), (0, room.xmin, 2), (0, room.xmax, 3),
                  (1, room.ymin, 4), (1, room.ymax, 5)]  # (axis, value, id)
        with np.errstate(divide="ignore", invalid="ignore"):
            for axis, value, sid in planes:
                t = (value - C[axis]) / dirs[..., axis]
                better = (t > 1e-6) & (t < t_best)
                t_best = np.where(better, t, t_best)
                surface = np.where(better, sid, surface)
        P = C + dirs * t_best[..., None]
        bg = np.zeros(x.shape + (3,), np.float32)
        floor_map = np.full(x.shape + (2,), -1.0, np.float32)
        res = TEXTURE_RES_M
        on = surface == 0
        fx = ((P[..., 0] - room.xmin) / res).astype(np.float32)
        fy = ((P[..., 1] - room.ymin) / res).astype(np.float32)
        bg[on] = cv2.remap(self.floor, fx, fy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)[on]
        floor_map[on] = room.to_shadow_grid(P[on][:, :2]).astype(np.float32)
        bg[surface == 1] = self.ceiling_value
        zrow = ((room.height - P[..., 2]) / res).astype(np.float32)
        walls = [(2, "xmin", P[..., 1] - room.ymin, 0.82), (3, "xmax", P[..., 1] - room.ymin, 0.82),
                 (4, "ymin", P[..., 0] - room.xmin, 0.9), (5, "ymax", P[..., 0] - room.xmin, 0.9)]
        for sid, key, along, light in walls:
            m = surface == sid
            if m.any():
                col = (along / res).astype(np.float32)
                sample = cv2.remap(self.walls[key], col, zrow, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
                bg[m] = light * sample[m]
        # mild vignetting (cos^4 law, softened)
        r2 = x * x + y * y
        bg *= (0.75 + 0.25 / (1 + r2) ** 2)[..., None].astype(np.float32)
        distort_map = None
        if pad:
            gv, gu = np.mgrid[0:H, 0:W].astype(np.float32)
            und = camera.undistort_pixels(np.stack([gu.ravel(), gv.ravel()], -1)).reshape(H, W, 2)
            distort_map = ((und[..., 0] + pad).astype(np.float32), (und[..., 1] + pad).astype(np.float32))
        return CameraView(camera=camera, pad=pad, background=bg, floor_map=floor_map, distort_map=distort_map)
