"""Tiny session folders for the session and bad-input tests: a calibration.toml, one MJPG video per
camera (frame k has grey level 10 k + 5), optional session.yaml. Everything small and fast."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from silhouette_scene import write_video

from gaitcap.camera import Camera, CameraRig
from gaitcap.io.calibration_toml import write_calibration

SIZE = (96, 64)


def ramp(n_frames: int, size: tuple[int, int] = SIZE) -> np.ndarray:
    w, h = size
    return np.stack([np.full((h, w, 3), (10 * k + 5) % 256, np.uint8) for k in range(n_frames)])


def make_session(
    root: Path,
    frames: dict[str, int] | None = None,
    fps: dict[str, float] | None = None,
    video_size: dict[str, tuple[int, int]] | None = None,
    calib_size: tuple[int, int] = SIZE,
    session_yaml: str | None = None,
) -> Path:
    """Write a session with cameras ``frames.keys()`` (default cam0, cam1 of 20 frames each)."""
    frames = frames or {"cam0": 20, "cam1": 20}
    root.mkdir(parents=True)
    cams = [
        Camera.look_at(name, (3.0 * np.cos(a), 3.0 * np.sin(a), 1.2), (0, 0, 1.0), size=calib_size, focal_px=80.0)
        for name, a in zip(frames, np.linspace(0, np.pi / 2, len(frames)))
    ]
    write_calibration(root / "calibration.toml", CameraRig(tuple(cams)))
    (root / "videos").mkdir()
    for name, n in frames.items():
        size = (video_size or {}).get(name, calib_size)
        write_video(root / "videos" / f"{name}.avi", ramp(n, size), fps=(fps or {}).get(name, 25.0))
    if session_yaml is not None:
        (root / "session.yaml").write_text(session_yaml)
    return root
