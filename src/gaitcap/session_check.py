"""Check a session's videos against each other and against the calibration, before tracking.

First the calibration's geometry (:func:`gaitcap.calibration.quality.check_rig_geometry`: cameras
kilometres away because the translations are in millimetres, cameras under the floor or looking
away from it): a :class:`CalibrationError` naming calibration.toml and the likely cause; so is a
calibration of one camera, or one whose recorded reprojection error is too large to track with
(:func:`gaitcap.calibration.quality.check_recorded_errors`; a poor one is a warning and a note). Once the
first frames' silhouettes are known, :func:`check_silhouettes_meet` checks that they meet in 3D
where the calibration puts them. For each camera: the decoded frame size, the declared frame rate and frame count (the count is
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

import numpy as np

from gaitcap.calibration.formats import fit_to_frame_size
from gaitcap.calibration.quality import check_recorded_errors, check_rig_geometry
from gaitcap.camera import CameraRig
from gaitcap.errors import CalibrationError, InputError
from gaitcap.io.calibration_toml import read_calibration_metadata
from gaitcap.session import CALIBRATION_FILE, SESSION_FILE, VIDEO_EXTENSIONS, VIDEOS_DIR, Session
from gaitcap.tracking.init import height_on_vertical, silhouette_centroid, silhouette_row_centre, triangulate
from gaitcap.tracking.observation import Observation, TrackingView
from gaitcap.video import VideoInfo, VideoReader, differing_rates, probe_video

log = logging.getLogger(__name__)

#: frames whose silhouettes are checked against the calibration (the first ones seen by 2+ cameras)
SILHOUETTE_CHECK_FRAMES = 5
#: the heights (m) between which the centre of a person's silhouettes lies (about 1 m when
#: standing; a child, a crouch or a silhouette cut by the image border move it by tens of cm)
SUBJECT_CENTRE_Z_M = (-0.25, 2.5)
#: the heights (m) between which every silhouette lies on the vertical through the subject's
#: centre: from a little under the floor to above a tall adult's head. A silhouette may miss
#: parts (feet lost on a floor of their colour, a torso of the background's colour), so only how
#: far it reaches is bounded, never how little: its top may be a metre below the others'
SUBJECT_Z_M = (-0.5, 2.6)
#: how far (a fraction of the silhouette's bounding box, each way) the centre found in 3D may
#: reproject outside a camera's silhouette box
BOX_MARGIN = 0.5


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
        notes: what was adjusted or tolerated, one sentence each (also logged; track.json notes them).
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


def _check_camera_count(session: Session) -> None:
    """Refuse a calibration of one camera: tracking needs two or more (naming the session's videos
    that calibration.toml leaves out)."""
    if len(session.rig) >= 2:
        return
    folder = session.root / VIDEOS_DIR
    left_out = sorted(p.name for p in folder.iterdir() if p.suffix.lower() in VIDEO_EXTENSIONS
                      and p.stem not in session.rig.names)  # fmt: skip
    raise CalibrationError(
        f"{session.root / CALIBRATION_FILE}: calibrates one camera ({session.rig.names[0]}); tracking needs two or "
        "more" + (f": {VIDEOS_DIR}/ also holds {', '.join(left_out)}, not in it (calibrate all the cameras together)"
                  if left_out else ""))  # fmt: skip


def _check_fps(videos: dict[str, CameraVideo], allow_mismatch: bool, notes: list[str]) -> float:
    rates = {cam: v.info.fps for cam, v in videos.items()}
    unknown = [cam for cam, fps in rates.items() if not (math.isfinite(fps) and fps > 0)]
    if unknown:
        raise InputError(
            "unknown frame rate (the container does not say) for camera(s) "
            + ", ".join(f"{cam} ({videos[cam].path})" for cam in unknown)
        )
    first = next(iter(rates.values()))
    listing = differing_rates(rates)
    if listing is None:
        return first
    if not allow_mismatch:
        raise InputError(f"the cameras' frame rates differ: {listing}; re-encode the videos at one rate")
    note = f"frame rates differ ({listing}); using {first:g} fps as allowed"
    log.warning("%s", note)
    notes.append(note)
    return first


def _check_counts(videos: dict[str, CameraVideo], notes: list[str], offsets: dict[str, int], info: Path) -> int:
    """The frames common to all cameras, each camera's first ``offsets`` frames skipped (``info``: the
    session.yaml that says so)."""
    too_many = [cam for cam, v in videos.items() if offsets.get(cam, 0) >= v.n_frames]
    if too_many:
        raise InputError(f"{info}: skip_frames leaves no frame of " + ", ".join(
            f"camera {c!r} ({offsets[c]} skipped of the {videos[c].n_frames} of {videos[c].info.path.name})"
            for c in too_many))  # fmt: skip
    counts = {cam: v.n_frames - offsets.get(cam, 0) for cam, v in videos.items()}
    common = min(counts.values())
    skipped = {c: n for c, n in offsets.items() if n}
    if skipped:
        log.info("skip_frames (%s): %s", info.name, ", ".join(f"{c} starts at its frame {n}" for c, n in skipped.items()))
    if len(set(counts.values())) > 1:
        after = " after skip_frames" if skipped else ""
        note = (f"videos of different lengths{after} ({', '.join(f'{c} {n}' for c, n in counts.items())} frames); "
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
        log.info("%s", note)
        notes.append(note)
    return CameraRig(tuple(cams))


def check_session_videos(session: Session, allow_fps_mismatch: bool = False) -> SessionVideos:
    """Check the videos of ``session`` (see the module docstring).

    Raises:
        CalibrationError: a calibration that cannot be right (its cause named, see the module
            docstring).
        InputError: a video that does not open or has no decodable frame (named), frame rates that
            differ (unless allowed) or are unknown, a frame size the calibration cannot be fitted to.
    """
    calibration = session.root / CALIBRATION_FILE
    check_rig_geometry(session.rig, calibration)
    _check_camera_count(session)
    notes: list[str] = check_recorded_errors(session.rig, read_calibration_metadata(calibration), calibration)
    for note in notes:
        log.warning("%s", note)
    videos: dict[str, CameraVideo] = {}
    for cam in session.rig:
        info = probe_video(session.videos[cam.name])
        videos[cam.name] = CameraVideo(cam.name, info, count_frames(info.path, info.frame_count))
    fps = _check_fps(videos, allow_fps_mismatch, notes)
    n_frames = _check_counts(videos, notes, session.offsets, session.root / SESSION_FILE)
    rig = _check_sizes(session.rig, videos, notes)
    log.info("%d cameras, %d common frames at %g fps", len(videos), n_frames, fps)
    return SessionVideos(videos=videos, n_frames=n_frames, fps=fps, rig=rig, notes=tuple(notes))


def _rows(sil: np.ndarray) -> np.ndarray:
    """Rows (ascending) of a soft silhouette (h, w) holding pixels above one half (else any)."""
    rows = np.where(sil.max(axis=1) > 0.5)[0]
    return rows if len(rows) else np.where(sil.max(axis=1) > 0)[0]


def _box(sil: np.ndarray) -> tuple[float, float, float, float]:
    """Bounding box (u0, v0, u1, v1) of a soft silhouette (h, w): its pixels above one half."""
    rows, cols = np.where(sil > 0.5)
    if len(rows) == 0:
        rows, cols = np.where(sil > 0)
    return float(cols.min()), float(rows.min()), float(cols.max() + 1), float(rows.max() + 1)


def _extent(view: TrackingView, sil: np.ndarray, X: np.ndarray) -> tuple[float, float]:
    """Heights (m) of the bottom and top of a silhouette on the vertical through ``X``: where the
    rays through its lowest and highest rows pass; NaN where the silhouette touches that image
    border (the subject cut off)."""
    rows = _rows(sil)
    top, bottom = int(rows[0]), int(rows[-1])
    z_top = height_on_vertical(view, silhouette_row_centre(sil, top), top, X) if top > 0 else None
    z_bottom = (height_on_vertical(view, silhouette_row_centre(sil, bottom), bottom + 1, X)
                if bottom < sil.shape[0] - 1 else None)  # fmt: skip
    return (np.nan if z_bottom is None else z_bottom), (np.nan if z_top is None else z_top)


def _misses(views: list[TrackingView], obs: Observation) -> list[str] | None:
    """The cameras whose silhouette is not where the calibration puts the subject of ``obs`` (see
    :func:`check_silhouettes_meet`); None when fewer than two cameras see a silhouette."""
    centres = [silhouette_centroid(s) for s in obs.silhouettes]
    seen = [c for c, px in enumerate(centres) if px is not None]
    if len(seen) < 2:
        return None
    names = [views[c].camera.name for c in seen]
    X = triangulate(views, centres)
    if X is None or not SUBJECT_CENTRE_Z_M[0] <= X[2] <= SUBJECT_CENTRE_Z_M[1]:
        return names
    out = []
    for c in seen:
        (u, v), _ = views[c].project(X)
        u0, v0, u1, v1 = _box(obs.silhouettes[c])
        mu, mv = BOX_MARGIN * (u1 - u0) + 1.0, BOX_MARGIN * (v1 - v0) + 1.0
        in_front = float(views[c].camera.to_camera(X)[2]) > 0
        if not (in_front and u0 - mu <= u <= u1 + mu and v0 - mv <= v <= v1 + mv):
            out.append(views[c].camera.name)
    if out:
        return out
    ext = np.array([_extent(views[c], obs.silhouettes[c], X) for c in seen])  # (n, 2) bottom, top
    bottom, top = ext[:, 0], ext[:, 1]
    with np.errstate(invalid="ignore"):
        wrong = (bottom > top) | (bottom < SUBJECT_Z_M[0]) | (top > SUBJECT_Z_M[1])
    return [n for n, w in zip(names, wrong, strict=True) if w]


def _judge(views: list[TrackingView], observations: list[Observation]) -> list[tuple[Observation, list[str]]]:
    """The first ``SILHOUETTE_CHECK_FRAMES`` frames seen by two cameras or more, each with the
    cameras it finds wrong (see :func:`_misses`)."""
    judged = []
    for obs in observations:
        missed = _misses(views, obs)
        if missed is not None:
            judged.append((obs, missed))
            if len(judged) >= SILHOUETTE_CHECK_FRAMES:
                break
    return judged


def _n_wrong(judged: list[tuple[Observation, list[str]]]) -> int:
    """Frames judged where the silhouettes do not meet."""
    return sum(bool(m) for _, m in judged)


def _culprit(views: list[TrackingView], observations: list[Observation]) -> str | None:
    """The one camera without which the others' silhouettes meet (three cameras or more), if any."""
    found = []
    for c in range(len(views)):
        without = [Observation(o.silhouettes[:c] + o.silhouettes[c + 1 :]) for o in observations]
        judged = _judge(views[:c] + views[c + 1 :], without)
        if judged and 2 * _n_wrong(judged) <= len(judged):
            found.append(views[c].camera.name)
    return found[0] if len(found) == 1 else None


def check_silhouettes_meet(views: list[TrackingView], observations: list[Observation], source: str | Path) -> None:
    """Refuse a calibration under which the first frames' silhouettes cannot be one subject.

    Cheap: in each of the first ``SILHOUETTE_CHECK_FRAMES`` frames where two cameras or more see
    a silhouette, the rays through the silhouettes' centroids are triangulated (DLT): the
    subject's centre. The silhouette cones meet in a plausible volume above the floor when

    - that centre lies at the height of a person's centre (``SUBJECT_CENTRE_Z_M``), in front of
      every camera, and projects into (or near, ``BOX_MARGIN``) every camera's silhouette box;
    - on the vertical through it, the rays through each silhouette's top and bottom rows give a
      top above the bottom, both between a little under the floor and above a tall adult's head
      (``SUBJECT_Z_M``); a silhouette cut by the image border is not measured there. Silhouettes
      miss parts, so a silhouette smaller than the others is no evidence against the calibration.

    With a wrong calibration (a rotation transposed or tilted, an extrinsic of another session)
    the rays cross under the floor, behind a camera, or where one camera sees a floating or
    giant subject. So do they when someone else is in a camera's view (a therapist beside the
    subject, someone by the walkway): that camera's silhouette, and its centroid, hold both; the
    error says so too. A near-symmetric mistake (two cameras' extrinsics swapped in a symmetric
    rig) can pass: this check refuses what cannot be right, it does not prove a calibration.

    Args:
        views: the tracking views (rig order).
        observations: the first frames' observations.
        source: the calibration file, named in the error.

    Raises:
        CalibrationError: one line, when the silhouettes do not meet in more than half of the frames
            checked (with three cameras or more, the one camera without which the others agree is
            named). Frames without two silhouettes are not judged.
    """
    judged = _judge(views, observations)
    n_bad = _n_wrong(judged)
    if 2 * n_bad <= len(judged):
        return
    culprit = _culprit(views, [obs for obs, _ in judged]) if len(views) >= 3 else None
    blame = f"; the others agree without camera {culprit!r}" if culprit else ""
    raise CalibrationError(
        f"{source}: the cameras' silhouettes do not meet in 3D where the calibration puts them ({n_bad} of the "
        f"first {len(judged)} frames seen by two cameras or more{blame}): check the extrinsics "
        "(the cameras' names and order, rotations, a calibration of another session), and that no one but the "
        "subject is in a camera's view (gaitcap tracks one person: someone else's silhouette moves the subject's)"
    )
