"""The silhouette stage over whole videos: background, masks, quality, outputs.

Outputs under ``OUT``::

    OUT/silhouettes.h5                          masks + quality (gaitcap.io.silhouettes_h5)
    OUT/silhouettes_quality.csv                 camera, frame, time_s, fraction, ..., flags
    OUT/silhouettes/<camera>/<frame:06d>.png    with ``png=True`` (0/255 masks)
    OUT/overlay/<camera>.mp4                    with ``overlay=True``
"""

from __future__ import annotations

import contextlib
import csv
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml

from gaitcap import __version__
from gaitcap.errors import InputError, OutputError
from gaitcap.io.atomic import (atomic_path, check_free_space, check_output_folder, refuse_existing,
                               remove_replaced, remove_stale_parts)  # fmt: skip
from gaitcap.io.silhouettes_h5 import SILHOUETTES_FILE, SilhouetteWriter
from gaitcap.io.video_write import AtomicVideoWriter as VideoWriter
from gaitcap.camera import Camera
from gaitcap.session import IMAGE_EXTENSIONS, VIDEO_EXTENSIONS, Session
from gaitcap.silhouette.background import BackgroundReport
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.extract import FLAG_NAMES, FrameQuality, SilhouetteExtractor, flag_names
from gaitcap.silhouette.joint import JointExtractor
from gaitcap.silhouette.overlay import draw_overlay
from gaitcap.video import VideoReader, differing_rates, iter_synchronised, sample_frames

log = logging.getLogger(__name__)

H5_NAME = SILHOUETTES_FILE
CSV_NAME = "silhouettes_quality.csv"


@dataclass(frozen=True)
class Source:
    """One camera's input: its video, optional empty-scene plate and optional calibration; ``skip``:
    the frames dropped at the start of its video (``session.yaml``'s ``skip_frames``)."""

    camera: str
    video: Path
    plate: Path | None = None
    calibration: Camera | None = None
    skip: int = 0


@dataclass
class CameraSummary:
    """What the stage did for one camera."""

    camera: str
    frames: int
    background: BackgroundReport
    mean_fraction: float
    flag_counts: dict[str, int] = field(default_factory=dict)


def sources_from_session(root: str | Path) -> list[Source]:
    """One :class:`Source` per camera of a session folder (plates from ``background/``, calibrations
    from ``calibration.toml``)."""
    session = Session.open(root)
    return [Source(cam.name, session.videos[cam.name], session.backgrounds.get(cam.name), cam, session.offsets[cam.name])
            for cam in session.rig]  # fmt: skip


def sources_from_videos(paths: Sequence[str | Path]) -> list[Source]:
    """Sources from video files and/or folders of videos; cameras are named after the file stems."""
    sources: list[Source] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.suffix.lower() in VIDEO_EXTENSIONS)
            if not found:
                raise InputError(f"{p}: no video file ({', '.join(VIDEO_EXTENSIONS)}) in this folder")
            sources += [Source(q.stem, q) for q in found]
        elif p.exists():
            sources.append(Source(p.stem, p))
        else:
            raise InputError(f"{p}: video not found")
    names = [s.camera for s in sources]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"several videos would be named {', '.join(dup)}: rename them or pass them separately")
    return sources


def read_plate(path: Path) -> np.ndarray:
    """Read a background plate as (H, W, 3) uint8 BGR."""
    if path.suffix.lower() not in IMAGE_EXTENSIONS:
        raise InputError(f"{path}: background plate must be one of {', '.join(IMAGE_EXTENSIONS)}")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise InputError(f"{path}: cannot read the background plate (missing or corrupt image)")
    return img


def prepare_extractor(source: Source, config: SilhouetteConfig) -> tuple[SilhouetteExtractor, float]:
    """Probe the video, fit the background (plate and/or samples). Returns (extractor, fps)."""
    with VideoReader(source.video) as video:
        info = video.info
    bcfg = config.background
    use_plate = source.plate is not None and bcfg.source in ("auto", "plate")
    if bcfg.source == "plate" and source.plate is None:
        raise InputError(f"{source.camera}: background.source is 'plate' but there is no plate for this camera")
    plate = None
    if use_plate:
        plate = read_plate(source.plate)  # type: ignore[arg-type]
        if plate.shape[:2] != (info.height, info.width):
            raise InputError(
                f"{source.plate}: background plate is {plate.shape[1]}x{plate.shape[0]} but the video "
                f"{source.video.name} is {info.width}x{info.height}"
            )
    samples = sample_frames(source.video, bcfg.samples)
    if plate is not None:  # each measured once
        plate_colour, video_colour = _colour(plate), _colour(samples)
        if (plate_colour == 0 and video_colour >= 2) or (plate_colour >= 2 and video_colour == 0):
            plate_kind, video_kind = ("greyscale", "in colour") if plate_colour == 0 else ("in colour", "greyscale")
            raise InputError(f"{source.plate}: background plate is {plate_kind} but the video {source.video.name} "
                             f"is {video_kind}: save the plate from this camera as the video records it")
    extractor = SilhouetteExtractor(config, name=source.camera)
    extractor.fit_background(plate=plate, samples=samples)
    return extractor, info.fps


def _colour(images: np.ndarray) -> float:
    """How far BGR ``images`` are from grey: the mean difference of neighbouring channels, grey levels
    (0 for a greyscale image read as BGR; 3 to 28 for decoded colour video on the suite's and the
    external sessions' rooms)."""
    x = images.reshape(-1, 3)[:: max(1, images.size // 3 // 200_000)].astype(np.int16)
    return float(np.abs(np.diff(x, axis=1)).mean())


#: the folder of the overlay videos (``--overlay``), in the output folder
OVERLAY_DIR = "overlay"


#: the folder of the PNG masks (``--png``): one folder per camera, one PNG per frame
PNG_DIR = "silhouettes"


def _check_outputs(out: Path, force: bool) -> None:
    """Refuse an earlier run's outputs (unless ``force``); with ``force``, remove its PNG masks and
    overlay videos, which would otherwise be left beside (or mixed into) this run's, whatever it writes."""
    check_output_folder(out)
    check_free_space(out)
    earlier = [*sorted(out.glob(f"{PNG_DIR}/*/[0-9][0-9][0-9][0-9][0-9][0-9].png")),
               *sorted(p for p in out.glob(f"{OVERLAY_DIR}/*.mp4") if not p.name.startswith("."))]  # fmt: skip
    for target in (out / H5_NAME, out / CSV_NAME, *earlier[:1]):
        refuse_existing(target, force)
    remove_replaced(earlier)


def run_silhouettes(
    sources: Sequence[Source],
    out: str | Path,
    config: SilhouetteConfig | None = None,
    png: bool = False,
    overlay: bool = False,
    force: bool = False,
    max_frames: int | None = None,
    progress: Callable[[str, int], None] | None = None,
    on_masks: Callable[[int, list[np.ndarray]], None] | None = None,
) -> list[CameraSummary]:
    """Extract silhouettes of every source, streaming the frames.

    When every source has a calibration, the cameras are read frame by frame together and the
    shadows checked on the floor across them (:class:`JointExtractor`); otherwise one camera
    after the other.

    Args:
        sources: the cameras (see :func:`sources_from_session`, :func:`sources_from_videos`).
        out: output folder.
        config: parameters (None: the shipped defaults).
        png: also write one PNG per mask.
        overlay: also write an overlay video per camera.
        force: overwrite existing outputs.
        max_frames: stop each camera after this many frames (None: whole video).
        progress: called as ``progress(camera, frame_index)`` after each frame.
        on_masks: when every source is calibrated, called as ``on_masks(frame_index, masks)`` after each
            frame with its (H, W) uint8 masks of every camera, in the sources' order (the frame sync's
            check, :class:`gaitcap.sync_check.SyncRecorder`).

    Returns:
        One :class:`CameraSummary` per camera. Unusable backgrounds are logged as warnings and
        every frame of that camera carries the ``no_background`` flag.
    """
    config = config or SilhouetteConfig.load()
    out = Path(out)
    if not sources:
        raise InputError("no video to process")
    _check_outputs(out, force)
    attrs = file_attrs(config)
    # prepare every camera first: bad input fails before anything is written
    prepared = [_Camera(s, *prepare_extractor(s, config)) for s in sources]
    calibrated = all(s.calibration is not None for s in sources)
    if calibrated:  # a session's cameras are read frame by frame together and checked against each other
        _check_rates(prepared)
    for folder in (out, out / OVERLAY_DIR):  # temporary files of a run that was killed
        remove_stale_parts(folder)
    groups = [prepared] if calibrated else [[c] for c in prepared]
    with atomic_path(out / CSV_NAME) as csv_tmp, csv_tmp.open("w", newline="") as fh, SilhouetteWriter(
        out / H5_NAME, attrs
    ) as writer, contextlib.ExitStack() as stack:
        table = csv.writer(fh)
        table.writerow(["camera", "frame", "time_s", "fraction", "shadow_fraction", "components", "flags"])
        for c in prepared:
            c.open_outputs(writer, out, png, overlay, stack)
        for group in groups:
            joint = JointExtractor([c.extractor for c in group],
                                   [c.source.calibration for c in group] if calibrated else None)  # fmt: skip
            videos = {c.source.camera: c.source.video for c in group}
            skips = {c.source.camera: c.source.skip for c in group}
            for index, images in iter_synchronised(videos, 0, max_frames, skips):
                results = joint.process([images[c.source.camera] for c in group])
                for c, frame, (mask, q) in zip(group, (images[c.source.camera] for c in group), results):
                    c.record(index, frame, mask, q, writer, table)
                    if progress is not None:
                        progress(c.source.camera, index)
                if on_masks is not None and calibrated:
                    on_masks(index, [mask for mask, _ in results])
        return [c.summary() for c in prepared]  # raises, writing nothing, when a video had no frame


def _check_rates(prepared: Sequence[_Camera]) -> None:
    """Refuse a session whose videos' frame rates differ (their frames k are not the same instant), as
    ``gaitcap track`` does (:func:`gaitcap.session_check.check_session_videos`)."""
    if listing := differing_rates({c.source.camera: c.fps for c in prepared}):
        raise InputError(f"the cameras' frame rates differ: {listing}; re-encode the videos at one rate")


@dataclass
class _Camera:
    """One camera's state while :func:`run_silhouettes` runs: its outputs and running counts."""

    source: Source
    extractor: SilhouetteExtractor
    fps: float
    png_dir: Path | None = None
    overlay: VideoWriter | None = None
    fractions: list[float] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(FLAG_NAMES.values(), 0))

    def open_outputs(self, writer: SilhouetteWriter, out: Path, png: bool, overlay: bool,
                     stack: contextlib.ExitStack) -> None:  # fmt: skip
        report = self.extractor.report
        if report is None:
            raise InputError(f"{self.source.camera}: the background was not fitted")
        cam = self.source.camera
        w, h = self.extractor.full_size
        writer.add_camera(cam, w, h, self.extractor.background, camera_attrs(self.source, report, self.fps))
        if png:
            self.png_dir = out / PNG_DIR / cam
            self.png_dir.mkdir(parents=True, exist_ok=True)
        if overlay:
            self.overlay = stack.enter_context(VideoWriter(out / OVERLAY_DIR / f"{cam}.mp4", self.fps, (w, h)))

    def record(self, index: int, frame: np.ndarray, mask: np.ndarray, q: FrameQuality, writer: SilhouetteWriter,
               table: csv.writer) -> None:  # type: ignore[valid-type]  # fmt: skip
        cam, fps = self.source.camera, self.fps
        writer.append(cam, mask, quality_row(q))
        table.writerow(
            [cam, index, f"{index / fps:.4f}" if fps else "", f"{q.fraction:.6f}",
             f"{q.shadow_fraction:.6f}", q.components, "|".join(q.flag_names)]
        )  # fmt: skip
        if self.png_dir is not None and not cv2.imwrite(str(self.png_dir / f"{index:06d}.png"), mask * 255):
            raise OutputError(f"{self.png_dir}: cannot write PNG masks")
        if self.overlay is not None:
            self.overlay.write(draw_overlay(frame, mask, q))
        self.fractions.append(q.fraction)
        for name in q.flag_names:
            self.counts[name] += 1

    def summary(self) -> CameraSummary:
        if not self.fractions:
            raise InputError(f"{self.source.video}: no frame decoded")
        return CameraSummary(self.source.camera, len(self.fractions), self.extractor.report,  # type: ignore[arg-type]
                             float(np.mean(self.fractions)), self.counts)  # fmt: skip


def file_attrs(config: SilhouetteConfig) -> dict[str, object]:
    """The root attributes of ``silhouettes.h5``: the configuration (YAML), the version, the flag bits."""
    attrs: dict[str, object] = {"config": yaml.safe_dump(config.model_dump(), sort_keys=False),
                                "gaitcap_version": __version__}  # fmt: skip
    attrs.update({f"flag_{name}": bit for bit, name in FLAG_NAMES.items()})
    return attrs


def camera_attrs(source: Source, report: BackgroundReport, fps: float) -> dict[str, object]:
    """The attributes of one camera's masks in ``silhouettes.h5`` (video, fps, background provenance)."""
    return {
        "fps": fps, "video": str(source.video), "background_source": report.source,
        "background_usable": report.usable, "background_message": report.message,
        "ambiguous_fraction": report.ambiguous_fraction,
    }  # fmt: skip


def quality_row(q: FrameQuality) -> dict[str, object]:
    """One frame's quality values in the layout of :class:`~gaitcap.io.silhouettes_h5.SilhouetteWriter`."""
    return {
        "fraction": q.fraction,
        "shadow_fraction": q.shadow_fraction,
        "components": q.components,
        "flags": q.flags,
        "bbox": q.bbox if q.bbox is not None else (-1, -1, -1, -1),
    }


__all__ = [
    "CameraSummary",
    "Source",
    "camera_attrs",
    "file_attrs",
    "flag_names",
    "prepare_extractor",
    "quality_row",
    "read_plate",
    "run_silhouettes",
    "sources_from_session",
    "sources_from_videos",
]
