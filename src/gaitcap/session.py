"""The session folder: the contract between stages and with users.

```
<session>/calibration.toml                  # see gaitcap.io.calibration_toml
<session>/videos/<camera>.<mp4|avi|mov|mkv> # one video per camera, named after its table
<session>/background/<camera>.<png|jpg>     # optional: the empty scene, per camera
<session>/session.yaml                      # optional: subject: {height_m: 1.72}, skip_frames, notes
```

``skip_frames: {cam1: 2}`` drops a camera's first frames, so that frame k of the session is frame
k + 2 of that camera's video: cameras started by hand, out of step (``gaitcap.sync_check`` finds
them), are brought into step without re-encoding their videos.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

from pydantic import Field

from gaitcap.camera import CameraRig
from gaitcap.config import Strict, load_yaml_model
from gaitcap.errors import InputError
from gaitcap.io.calibration_toml import read_calibration

log = logging.getLogger(__name__)

VIDEO_EXTENSIONS = (".mp4", ".avi", ".mov", ".mkv")
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")
CALIBRATION_FILE = "calibration.toml"
SESSION_FILE = "session.yaml"
VIDEOS_DIR = "videos"
BACKGROUND_DIR = "background"


class SubjectInfo(Strict):
    height_m: float | None = Field(default=None, gt=0.5, lt=2.6, description="standing height, metres")
    mass_kg: float | None = Field(default=None, gt=0, lt=400)


#: the most frames a camera's video may be told to skip (``skip_frames``): 10 s at 25 fps
MAX_SKIP_FRAMES = 250


class SessionInfo(Strict):
    """Schema of ``session.yaml``."""

    subject: SubjectInfo = Field(default_factory=SubjectInfo)
    skip_frames: dict[str, Annotated[int, Field(ge=0, le=MAX_SKIP_FRAMES, strict=True)]] = Field(
        default_factory=dict, description="camera -> frames dropped at the start of its video (cameras out of step)")
    notes: str = ""


@dataclass(frozen=True)
class Session:
    """An opened, validated session folder."""

    root: Path
    rig: CameraRig
    videos: dict[str, Path]
    backgrounds: dict[str, Path] = field(default_factory=dict)
    info: SessionInfo = field(default_factory=SessionInfo)

    @property
    def camera_names(self) -> list[str]:
        return self.rig.names

    @property
    def offsets(self) -> dict[str, int]:
        """Camera -> the frames of its video skipped at the start (``skip_frames``; 0 for most): frame k of
        the session is frame k + offset of that camera's video."""
        return {cam: self.info.skip_frames.get(cam, 0) for cam in self.rig.names}

    @classmethod
    def open(cls, root: str | Path) -> Session:
        """Open ``root``: read the calibration, find one video per camera, read session.yaml."""
        root = Path(root)
        if not root.is_dir():
            raise InputError(f"{root}: session folder not found")
        rig = read_calibration(root / CALIBRATION_FILE)
        videos = find_per_camera(root / VIDEOS_DIR, rig.names, VIDEO_EXTENSIONS, required=True)
        backgrounds = find_per_camera(root / BACKGROUND_DIR, rig.names, IMAGE_EXTENSIONS, required=False)
        info_path = root / SESSION_FILE
        info = load_yaml_model(SessionInfo, info_path) if info_path.exists() else SessionInfo()
        unknown = sorted(set(info.skip_frames) - set(rig.names))
        if unknown:
            raise InputError(f"{info_path}: skip_frames names {', '.join(map(repr, unknown))}, not a camera of "
                             f"calibration.toml (its cameras: {', '.join(rig.names)})")  # fmt: skip
        return cls(root=root, rig=rig, videos=videos, backgrounds=backgrounds, info=info)


def find_per_camera(
    folder: Path, names: list[str], extensions: tuple[str, ...], required: bool
) -> dict[str, Path]:
    """Map each camera name to ``folder/<name>.<ext>``.

    With ``required`` a camera without a file is an :class:`InputError` naming it; files that
    match no camera are reported in the log and ignored.
    """
    found: dict[str, Path] = {}
    if not folder.is_dir():
        if required:
            raise InputError(f"{folder}: folder not found (expected one video per camera: {', '.join(names)})")
        return found
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in extensions)
    for name in names:
        matches = [p for p in files if p.stem == name]
        if len(matches) > 1:
            raise InputError(f"{folder}: several files for camera {name!r}: {', '.join(p.name for p in matches)}")
        if matches:
            found[name] = matches[0]
        elif required:
            have = ", ".join(p.name for p in files) or "none"
            raise InputError(f"{folder}: no video for camera {name!r} from calibration.toml (files: {have})")
    extra = [p.name for p in files if p.stem not in names]
    if extra:
        log.warning("%s: ignoring files that match no calibrated camera: %s", folder, ", ".join(extra))
    return found
