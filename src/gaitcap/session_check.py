"""Check a session's videos against each other and against the calibration, before tracking.

For each camera: the decoded frame size, the declared frame rate and frame count (the count is
verified by decoding the last declared frame; when that fails the frames are counted by decoding,
and a warning says the file looks truncated). Then, across cameras:

- frame counts that differ: a warning naming the cameras and counts; tracking uses the common
  range ``[0, min count)``;
- frame rates that differ (by more than 0.1 %): an :class:`InputError` naming every camera and its
  rate, unless ``allow_fps_mismatch`` (then a warning; the first camera's rate is used);
- a frame size that differs from the calibration's: an :class:`InputError` naming the camera and
  both sizes, except for a small centred crop that
  :func:`gaitcap.calibration.formats.fit_to_frame_size` accounts for (the 1080 vs 1088 case of
  some encoders): then the adjusted camera is used and a note says so.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

from gaitcap.calibration.formats import fit_to_frame_size
from gaitcap.camera import CameraRig
from gaitcap.errors import CalibrationError, InputError
from gaitcap.session import Session
from gaitcap.video import VideoInfo, VideoReader, probe_video

log = logging.getLogger(__name__)

#: relative tolerance between two cameras' frame rates
FPS_RTOL = 1e-3


@dataclass(frozen=True)
class CameraVideo:
    """One camera's video as checked.

    Attributes:
        camera: camera name.
        info: what the container declares (size from the first decoded frame).
        n_frames: frames that decode (the declared count, verified at its last frame).
    """

    camera: str
    info: VideoInfo
    n_frames: int

    @property
    def path(self) -> Path:
        return self.info.path


@dataclass(frozen=True)
class SessionVideos:
    """The result of :func:`check_session_videos`.

    Attributes:
        videos: camera name -> :class:`CameraVideo`, in calibration order.
        n_frames: the common frame count (frames ``0 .. n_frames - 1`` exist in every video).
        fps: the common frame rate.
        rig: the calibration, with cameras adjusted to the decoded frame size where a centred crop
            was assumed.
        notes: what was adjusted or tolerated, one sentence each (also logged as warnings).
    """

    videos: dict[str, CameraVideo]
    n_frames: int
    fps: float
    rig: CameraRig
    notes: tuple[str, ...] = field(default=())

    @property
    def frame_range(self) -> tuple[int, int]:
        """``(start, stop)`` of the frames common to all cameras."""
        return (0, self.n_frames)


def count_frames(path: Path, declared: int) -> int:
    """Frames of ``path`` that decode: ``declared`` if its last frame decodes, else counted.

    One seek when the container is honest; a full decode when it is not (truncated file, with a
    warning from :class:`~gaitcap.video.VideoReader`, or a container without a count).
    """
    if declared > 0:
        with VideoReader(path) as video:
            video.seek(declared - 1)
            if video.read() is not None:
                return declared
    with VideoReader(path) as video:  # warns when fewer than the declared frames decode
        return sum(1 for _ in video)


def _check_fps(videos: dict[str, CameraVideo], allow_mismatch: bool, notes: list[str]) -> float:
    rates = {cam: v.info.fps for cam, v in videos.items()}
    unknown = [cam for cam, fps in rates.items() if not (math.isfinite(fps) and fps > 0)]
    if unknown:
        raise InputError(
            "unknown frame rate (the container does not say) for camera(s) "
            + ", ".join(f"{cam} ({videos[cam].path})" for cam in unknown)
        )
    first = next(iter(rates.values()))
    if all(math.isclose(fps, first, rel_tol=FPS_RTOL) for fps in rates.values()):
        return first
    listing = ", ".join(f"{cam} {fps:g} fps" for cam, fps in rates.items())
    if not allow_mismatch:
        raise InputError(f"the cameras' frame rates differ: {listing}; re-encode the videos at one rate (or allow the mismatch)")
    note = f"frame rates differ ({listing}); using {first:g} fps as allowed"
    log.warning("%s", note)
    notes.append(note)
    return first


def _check_counts(videos: dict[str, CameraVideo], notes: list[str]) -> int:
    counts = {cam: v.n_frames for cam, v in videos.items()}
    common = min(counts.values())
    if len(set(counts.values())) > 1:
        note = (f"videos of different lengths ({', '.join(f'{c} {n}' for c, n in counts.items())} frames); "
                f"using the {common} frames common to all cameras")  # fmt: skip
        log.warning("%s", note)
        notes.append(note)
    return common


def _check_sizes(rig: CameraRig, videos: dict[str, CameraVideo], notes: list[str]) -> CameraRig:
    cams = []
    for cam in rig:
        info = videos[cam.name].info
        if info.size == cam.size:
            cams.append(cam)
            continue
        where = f"camera {cam.name!r}: video {info.path.name} is {info.width}x{info.height} but calibration.toml says {cam.width}x{cam.height}"
        try:
            cams.append(fit_to_frame_size(cam, info.size))
        except CalibrationError as e:
            raise InputError(f"{where}; recalibrate at the video size (a resize is not a crop)") from e
        note = f"{where}: assumed a centred crop, principal point moved by half the difference"
        notes.append(note)
    return CameraRig(tuple(cams))


def check_session_videos(session: Session, allow_fps_mismatch: bool = False) -> SessionVideos:
    """Check the videos of ``session`` (see the module docstring).

    Raises:
        InputError: a video that does not open or has no decodable frame (named), frame rates that
            differ (unless allowed) or are unknown, a frame size the calibration cannot be fitted to.
    """
    videos: dict[str, CameraVideo] = {}
    for cam in session.rig:
        info = probe_video(session.videos[cam.name])
        videos[cam.name] = CameraVideo(cam.name, info, count_frames(info.path, info.frame_count))
    notes: list[str] = []
    fps = _check_fps(videos, allow_fps_mismatch, notes)
    n_frames = _check_counts(videos, notes)
    rig = _check_sizes(session.rig, videos, notes)
    log.info("%d cameras, %d common frames at %g fps", len(videos), n_frames, fps)
    return SessionVideos(videos=videos, n_frames=n_frames, fps=fps, rig=rig, notes=tuple(notes))
