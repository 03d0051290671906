"""Rendering the mannequin into camera views of the textured room.

Each frame: empty-room background -> soft cast shadows of the body's mesh on the floor (main and
second light) -> the mesh, z-buffered and shaded by both lights -> lens distortion -> lighting
drift -> sensor noise -> optional JPEG re-compression. The ground-truth silhouette is the mesh's
coverage after the same distortion.

The person is :class:`gaitcap.synth.mannequin.Mannequin`, not the tracker's body model.
"""

from __future__ import annotations

import cv2
import numpy as np

from gaitcap.synth.mannequin import Mannequin
from gaitcap.synth.scene import SHADOW_RES_M, CameraView, Room
from gaitcap.synth.variety import Lighting
from gaitcap.synth.zbuffer import draw_mesh, fill_triangles


def shadow_grid(room: Room, vertices: np.ndarray, triangles: np.ndarray, light: np.ndarray, blur_m: float) -> np.ndarray:
    """Top-down shadow of a mesh on the floor along ``light``: (rows, cols) float32 in [0, 1].

    Args:
        vertices: (V, 3) metres; triangles: (M, 3) vertex indices; light: (3,) direction the
        light travels (z < 0); blur_m: penumbra width.
    """
    L = np.asarray(light, float) / np.linalg.norm(light)
    on_floor = vertices - (vertices[:, 2:3] / L[2]) * L
    grid = fill_triangles(room.shadow_shape, room.to_shadow_grid(on_floor[:, :2]), triangles)
    sigma = blur_m / SHADOW_RES_M
    return cv2.GaussianBlur(grid, (0, 0), sigma) if sigma > 0 else grid


class Renderer:
    """Renders frames of joint centres, dressed as ``mannequin``, into every camera view."""

    def __init__(self, mannequin: Mannequin, room: Room, views: list[CameraView], lighting: Lighting,
                 n_frames: int, seed: int = 0) -> None:  # fmt: skip
        self.mannequin = mannequin
        self.room = room
        self.views = views
        self.lighting = lighting
        self.n_frames = max(1, n_frames)
        self.seed = seed

    def gain(self, frame: int) -> float:
        """Global lighting gain at ``frame``: a slow linear drift."""
        if self.n_frames == 1:
            return 1.0
        return 1.0 + self.lighting.drift * (2.0 * frame / (self.n_frames - 1) - 1.0)

    def _shade(self, normals: np.ndarray) -> np.ndarray:
        """(V,) brightness of the vertices: ambient plus Lambert terms of both lights."""
        lt = self.lighting
        main = np.asarray(lt.direction, float)
        shade = lt.ambient + (1.0 - lt.ambient) * 1.15 * np.clip(-normals @ (main / np.linalg.norm(main)), 0, None)
        if lt.second_direction is not None:
            sec = np.asarray(lt.second_direction, float)
            shade += lt.second_strength * np.clip(-normals @ (sec / np.linalg.norm(sec)), 0, None)
        return shade

    def render(self, points: np.ndarray, frame: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """Render the joint centres ``points`` (P, 3) at ``frame``: per camera (BGR uint8 (h, w, 3),
        mask uint8 (h, w) 0/1)."""
        verts, normals = self.mannequin.mesh(points)
        tris = self.mannequin.triangles
        lt = self.lighting
        shadow = None
        if lt.shadow_strength > 0:
            shadow = lt.shadow_strength * shadow_grid(self.room, verts, tris, np.asarray(lt.direction), lt.shadow_blur_m)
            if lt.second_direction is not None:
                shadow += (lt.shadow_strength * lt.second_strength) * shadow_grid(
                    self.room, verts, tris, np.asarray(lt.second_direction), max(lt.shadow_blur_m, 0.05))
            shadow = np.clip(shadow, 0.0, 0.9)
        shade = self._shade(normals)
        out = []
        for ci, view in enumerate(self.views):
            rng = np.random.default_rng((self.seed, frame, ci))
            out.append(self._render_view(view, verts, shade, shadow, frame, rng))
        return out

    def _render_view(self, view: CameraView, verts: np.ndarray, shade: np.ndarray, shadow: np.ndarray | None,
                     frame: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        img = view.background.copy()
        if shadow is not None:
            s = cv2.remap(shadow, view.floor_map[..., 0], view.floor_map[..., 1], cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            img *= (1.0 - s)[..., None]
        cam = view.camera
        px = cam.project(verts, distort=False) + np.asarray(view.offset)
        depth = cam.to_camera(verts)[:, 2]
        cover = draw_mesh(img, px, depth, shade, self.mannequin.triangles, self.mannequin.colors)
        img = view.to_image(img)
        mask = (view.to_image(cover) >= 0.5).astype(np.uint8)
        img = img * self.gain(frame) + rng.normal(0.0, self.lighting.noise_sigma, size=img.shape).astype(np.float32)
        img = np.clip(img + 0.5, 0, 255).astype(np.uint8)
        if self.lighting.jpeg_quality is not None:
            ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, int(self.lighting.jpeg_quality)])
            if ok:
                img = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        return img, mask

    def render_background(self) -> list[np.ndarray]:
        """The empty room per camera (no body, no shadow, no noise, gain 1)."""
        return [np.clip(view.to_image(view.background) + 0.5, 0, 255).astype(np.uint8) for view in self.views]
