"""Small generated scenes for the silhouette and video tests (no dependency on ``gaitcap synth``).

A figure made of ellipses (skin head, coloured shirt, dark trousers) walks across, or sways in
place in front of, a textured wall and a textured grey floor, with a soft cast shadow beside its
feet, sensor noise and a slow brightness drift. Ground-truth masks are the figure without its
shadow. Everything is seeded.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np


@dataclass
class Scene:
    plate: np.ndarray  # (H, W, 3) uint8, the empty scene without noise or drift
    frames: np.ndarray  # (T, H, W, 3) uint8
    masks: np.ndarray  # (T, H, W) uint8 0/1


def _texture(rng: np.random.Generator, h: int, w: int, scale: float, contrast: float) -> np.ndarray:
    noise = rng.normal(0.0, 1.0, (h, w)).astype(np.float32)
    tex = cv2.GaussianBlur(noise, (0, 0), scale) if scale > 0 else noise
    tex /= tex.std() + 1e-6
    return tex * contrast


def make_plate(w: int, h: int, rng: np.random.Generator) -> np.ndarray:
    horizon = int(0.45 * h)
    img = np.zeros((h, w, 3), np.float32)
    img[:horizon] = (175, 185, 195)  # wall, BGR
    img[horizon:] = (128, 128, 128)  # grey floor
    fine = _texture(rng, h, w, 1.0, 10.0)
    coarse = _texture(rng, h, w, 6.0, 8.0)
    img += (fine + coarse)[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def _draw_figure(h: int, w: int, cx: float, phase: float, height: float, feet_y: float) -> tuple[list, np.ndarray]:
    """Ellipses (centre, axes, angle, colour) of the figure and the shadow alpha map."""
    u = height / 10.0  # body unit
    parts = []
    swing = 1.2 * u * np.sin(phase)
    hip_y = feet_y - 5.0 * u
    trousers = (42, 40, 45)
    parts.append(((cx + swing / 2, hip_y + 2.5 * u), (0.8 * u, 2.6 * u), float(np.degrees(-swing / (5 * u))), trousers))
    parts.append(((cx - swing / 2, hip_y + 2.5 * u), (0.8 * u, 2.6 * u), float(np.degrees(swing / (5 * u))), trousers))
    parts.append(((cx, hip_y + 0.3 * u), (1.3 * u, 0.9 * u), 0.0, trousers))  # pelvis
    parts.append(((cx, hip_y - 1.8 * u), (1.2 * u, 2.0 * u), 0.0, (150, 70, 40)))  # shirt (blue)
    parts.append(((cx - swing / 3, hip_y - 1.6 * u), (0.45 * u, 1.8 * u), float(np.degrees(swing / (6 * u))), (150, 70, 40)))
    parts.append(((cx, hip_y - 4.4 * u), (0.65 * u, 0.8 * u), 0.0, (120, 150, 200)))  # head (skin)
    alpha = np.zeros((h, w), np.float32)
    # soft shadow on the floor, cast to the right of the feet
    cv2.ellipse(alpha, (int(cx + 2.2 * u), int(feet_y + 0.2 * u)), (int(3.0 * u), int(0.7 * u)), 0, 0, 360, 1.0, -1)
    alpha = cv2.GaussianBlur(alpha, (0, 0), 0.35 * u)
    return parts, alpha


def render(
    plate: np.ndarray,
    cxs: np.ndarray,
    rng: np.random.Generator,
    noise: float = 3.0,
    drift: float = 0.08,
    shadow_depth: float = 0.45,
) -> Scene:
    h, w = plate.shape[:2]
    t_n = len(cxs)
    frames = np.empty((t_n, h, w, 3), np.uint8)
    masks = np.empty((t_n, h, w), np.uint8)
    height = 0.6 * h
    feet_y = 0.9 * h
    for t, cx in enumerate(cxs):
        parts, alpha = _draw_figure(h, w, float(cx), 2 * np.pi * t / 16.0, height, feet_y)
        img = plate.astype(np.float32) * (1.0 - shadow_depth * alpha)[..., None]
        mask = np.zeros((h, w), np.uint8)
        for centre, axes, angle, colour in parts:
            c = (int(round(centre[0])), int(round(centre[1])))
            a = (max(1, int(round(axes[0]))), max(1, int(round(axes[1]))))
            cv2.ellipse(img, c, a, angle, 0, 360, colour, -1)
            cv2.ellipse(mask, c, a, angle, 0, 360, 1, -1)
        img *= 1.0 + drift * t / max(t_n - 1, 1)
        img += rng.normal(0.0, noise, img.shape).astype(np.float32)
        frames[t] = np.clip(img, 0, 255).astype(np.uint8)
        masks[t] = mask
    return Scene(plate, frames, masks)


def walk_across(w: int = 160, h: int = 120, frames: int = 48, seed: int = 0, **kw) -> Scene:
    """The figure enters on the left and leaves on the right."""
    rng = np.random.default_rng(seed)
    plate = make_plate(w, h, rng)
    cxs = np.linspace(-0.15 * w, 1.15 * w, frames)
    return render(plate, cxs, rng, **kw)


def sway_in_place(w: int = 160, h: int = 120, frames: int = 48, seed: int = 0, **kw) -> Scene:
    """The figure stays near the centre the whole time, swaying (never leaves the view)."""
    rng = np.random.default_rng(seed)
    plate = make_plate(w, h, rng)
    cxs = 0.5 * w + 0.06 * w * np.sin(np.linspace(0, 4 * np.pi, frames))
    return render(plate, cxs, rng, **kw)


def write_video(path: Path, frames: np.ndarray, fps: float = 25.0) -> Path:
    """Write frames with a codec OpenCV always has (MJPG in .avi)."""
    path = Path(path)
    h, w = frames.shape[1:3]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    if not writer.isOpened():
        raise RuntimeError(f"cannot write test video {path}")
    for f in frames:
        writer.write(f)
    writer.release()
    return path


def iou(a: np.ndarray, b: np.ndarray) -> float:
    a = a.astype(bool)
    b = b.astype(bool)
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 1.0


@dataclass
class RigScene:
    """A calibrated scene seen by several cameras (ray-cast, so the views agree geometrically)."""

    cameras: list  # gaitcap.camera.Camera, one per view
    plates: list[np.ndarray]  # (H, W, 3) uint8 per camera
    frames: list[np.ndarray]  # (H, W, 3) uint8 per camera, one instant
    masks: list[np.ndarray]  # (H, W) uint8 0/1 true body per camera
    shadows: list[np.ndarray]  # (H, W) uint8 0/1 visible floor shadow per camera


def grey_body_rig(seed: int = 0, size: tuple[int, int] = (160, 120), noise: float = 2.0,
                  shadow_depth: float = 0.6) -> RigScene:  # fmt: skip
    """A grey upright body (a cylinder 0.4 m wide, 1.7 m tall at the origin) in front of a light grey
    wall (plane y = 1.2 m), on a darker grey floor, with a cast shadow on the floor beside it, seen by
    two cameras 1.5 m high. Over the wall the body is a darker grey of the same chromaticity, as a
    shadow would be; over the floor it is lighter than the floor. ``shadow_depth``: the shadow's
    brightness / the floor's."""
    from gaitcap.camera import Camera

    rng = np.random.default_rng(seed)
    cams = [
        Camera.look_at(name, (x, -3.0, 1.5), (0.0, 0.0, 0.7), size=size, focal_px=150.0)
        for name, x in (("left", -2.0), ("right", 2.0))
    ]
    wall, floor, body, depth = 160.0, 100.0, 125.0, shadow_depth
    out = RigScene(cams, [], [], [], [])
    for cam in cams:
        w, h = cam.size
        u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
        x = (u - cam.matrix[0, 2]) / cam.matrix[0, 0]
        y = (v - cam.matrix[1, 2]) / cam.matrix[1, 1]
        d = np.stack([x, y, np.ones_like(x)], axis=-1) @ cam.R  # world ray directions
        c = cam.center
        with np.errstate(divide="ignore", invalid="ignore"):
            t_floor = np.where(d[..., 2] < 0, -c[2] / d[..., 2], np.inf)
            t_wall = np.where(d[..., 1] > 0, (1.2 - c[1]) / d[..., 1], np.inf)
        # cylinder x^2 + y^2 = r^2, 0 <= z <= 1.7: nearest root of a t^2 + b t + cc = 0
        r = 0.2
        a = d[..., 0] ** 2 + d[..., 1] ** 2
        b = 2 * (c[0] * d[..., 0] + c[1] * d[..., 1])
        cc = c[0] ** 2 + c[1] ** 2 - r * r
        disc = b * b - 4 * a * cc
        t_body = np.where(disc > 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
        z_body = c[2] + t_body * d[..., 2]
        t_body = np.where((z_body >= 0) & (z_body <= 1.7), t_body, np.inf)
        t_scene = np.minimum(t_floor, t_wall)
        p = c + np.where(np.isfinite(t_scene), t_scene, 0)[..., None] * d
        is_floor = t_floor < t_wall
        shadow = is_floor & (((p[..., 0] - 0.8) / 0.5) ** 2 + ((p[..., 1] + 0.5) / 0.4) ** 2 <= 1.0)
        plate = np.where(is_floor, floor, wall)[..., None] * np.array([0.95, 1.0, 1.05])
        frame = plate * np.where(shadow, depth, 1.0)[..., None]
        on_body = t_body < t_scene
        frame[on_body] = body * np.array([0.95, 1.0, 1.05])
        out.plates.append(np.clip(plate + rng.normal(0, noise, plate.shape), 0, 255).astype(np.uint8))
        frame += rng.normal(0, noise, frame.shape)
        out.frames.append(np.clip(frame, 0, 255).astype(np.uint8))
        out.masks.append(on_body.astype(np.uint8))
        out.shadows.append((shadow & ~on_body).astype(np.uint8))
    return out
