"""Rendering the body model into camera views of the textured room.

Each frame: empty-room background -> soft cast shadow on the floor -> body capsules, far to near,
shaded -> lens distortion -> slow lighting drift -> sensor noise. The ground-truth silhouette is the
union of the body capsules after the same distortion.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gaitcap.body.model import BodyModel
from gaitcap.body.shape import draw_capsule, project_capsules
from gaitcap.synth.scene import SHADOW_RES_M, CameraView, Room

# BGR colours per clothing preset and body part
SKIN = (120, 150, 200)
HAIR = (35, 45, 60)
CLOTHING: dict[str, dict[str, tuple[int, int, int]]] = {
    "default": {"trousers": (120, 80, 50), "shirt": (60, 60, 175), "shoes": (235, 235, 235)},
    "dark": {"trousers": (38, 36, 35), "shirt": (45, 55, 40), "shoes": (28, 28, 28)},
    "light": {"trousers": (200, 205, 210), "shirt": (220, 225, 225), "shoes": (235, 235, 235)},
}
_PART_OF_SEGMENT = {
    "pelvis": "trousers", "thigh_l": "trousers", "thigh_r": "trousers", "shank_l": "trousers",
    "shank_r": "trousers", "foot_l": "shoes", "foot_r": "shoes", "torso": "shirt",
    "upper_arm_l": "shirt", "upper_arm_r": "shirt", "forearm_l": "shirt", "forearm_r": "shirt",
    "head": "skin",
}  # fmt: skip


@dataclass(frozen=True)
class RenderOptions:
    clothing: str = "default"
    shadow: bool = True
    shadow_strength: float = 0.55
    shadow_blur_m: float = 0.05
    light_direction: tuple[float, float, float] = (0.35, 0.45, -0.82)  # direction light travels
    noise_sigma: float = 2.5  # grey levels
    drift: float = 0.06  # lighting gain goes from 1 - drift to 1 + drift over the session
    seed: int = 0

    def __post_init__(self) -> None:
        if self.clothing not in CLOTHING:
            raise ValueError(f"unknown clothing {self.clothing!r} (choose from {', '.join(CLOTHING)})")
        if self.light_direction[2] >= 0:
            raise ValueError("light_direction must point downwards (negative z)")


def capsule_colors(model: BodyModel, clothing: str) -> list[tuple[float, float, float]]:
    """One BGR colour per capsule of ``model``."""
    palette = {**CLOTHING[clothing], "skin": SKIN}
    colors = []
    seen: dict[int, int] = {}
    for seg_index in model.capsule_segment:
        seg = model.segments[seg_index]
        k = seen.get(seg_index, 0)
        seen[seg_index] = k + 1
        part = _PART_OF_SEGMENT.get(seg.name, "shirt")
        if seg.name.startswith("forearm") and k == 1:
            part = "skin"  # the hand
        if seg.name == "head" and k == 1:
            colors.append(tuple(float(c) for c in HAIR))
            continue
        colors.append(tuple(float(c) for c in palette[part]))
    return colors


def shadow_grid(room: Room, A: np.ndarray, B: np.ndarray, radii: np.ndarray, light: np.ndarray, blur_m: float) -> np.ndarray:
    """Top-down soft shadow of capsules (C, 3) on the floor: (rows, cols) float32 in [0, 1]."""
    L = np.asarray(light, float) / np.linalg.norm(light)
    fa = A - (A[:, 2:3] / L[2]) * L
    fb = B - (B[:, 2:3] / L[2]) * L
    grid = np.zeros(room.shadow_shape, np.float32)
    ga, gb = room.to_shadow_grid(fa[:, :2]), room.to_shadow_grid(fb[:, :2])
    r = radii / SHADOW_RES_M
    for c in range(len(ga)):
        draw_capsule(grid, ga[c], gb[c], float(r[c, 0]), float(r[c, 1]), 1.0)
    sigma = blur_m / SHADOW_RES_M
    return cv2.GaussianBlur(grid, (0, 0), sigma) if sigma > 0 else grid


class Renderer:
    """Renders poses of ``model`` into every camera view."""

    def __init__(self, model: BodyModel, room: Room, views: list[CameraView], options: RenderOptions, n_frames: int) -> None:
        self.model = model
        self.room = room
        self.views = views
        self.options = options
        self.n_frames = max(1, n_frames)
        self.colors = capsule_colors(model, options.clothing)

    def gain(self, frame: int) -> float:
        """Global lighting gain at ``frame``: a slow linear drift."""
        if self.n_frames == 1:
            return 1.0
        return 1.0 + self.options.drift * (2.0 * frame / (self.n_frames - 1) - 1.0)

    def render(self, q: np.ndarray, frame: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """Render pose ``q`` (D,) at ``frame``: per camera (BGR uint8 (h, w, 3), mask uint8 (h, w) 0/1)."""
        A, B, radii = self.model.capsules(q[None])
        A, B = A[0], B[0]
        shadow = None
        if self.options.shadow:
            shadow = shadow_grid(self.room, A, B, radii, np.asarray(self.options.light_direction), self.options.shadow_blur_m)
        out = []
        for ci, view in enumerate(self.views):
            rng = np.random.default_rng((self.options.seed, frame, ci))
            out.append(self._render_view(view, A, B, radii, shadow, frame, rng))
        return out

    def _render_view(self, view: CameraView, A, B, radii, shadow, frame: int, rng: np.random.Generator):
        img = view.background.copy()
        if shadow is not None:
            s = cv2.remap(shadow, view.floor_map[..., 0], view.floor_map[..., 1], cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            img *= (1.0 - self.options.shadow_strength * s)[..., None]
        pc = project_capsules(view.camera, A, B, radii, offset=view.offset)
        mask = np.zeros(img.shape[:2], np.float32)
        for c in np.argsort(-pc.depth):  # far to near
            color = np.asarray(self.colors[c])
            a, b, ra, rb = pc.a[c], pc.b[c], float(pc.ra[c]), float(pc.rb[c])
            draw_capsule(img, a, b, ra, rb, tuple(0.72 * color))  # darker rim
            draw_capsule(img, a, b, 0.6 * ra, 0.6 * rb, tuple(color))  # lit core
            draw_capsule(mask, a, b, ra, rb, 1.0)
        img = view.to_image(img)
        mask = (view.to_image(mask) >= 0.5).astype(np.uint8)
        img = img * self.gain(frame) + rng.normal(0.0, self.options.noise_sigma, size=img.shape).astype(np.float32)
        return np.clip(img + 0.5, 0, 255).astype(np.uint8), mask

    def render_background(self) -> list[np.ndarray]:
        """The empty room per camera (no body, no shadow, no noise, gain 1)."""
        return [np.clip(view.to_image(view.background) + 0.5, 0, 255).astype(np.uint8) for view in self.views]
