"""``gaitcap synth``: render a synthetic session, with ground truth, from a real walk.

motion file -> joint centres (gaitcap.markers) -> scaled to the subject's height, resampled to
the video rate -> the truth: those joint centres, frame by frame (gaps and the points a marker set
lacks, such as the upper body of a lower-body recording, completed by the body model fitted to
them, gaitcap.synth.fit) -> a look drawn from the seed (gaitcap.synth.variety: build, clothes,
room, light, cameras) -> cameras placed -> textured room (scene) -> the mannequin
(gaitcap.synth.mannequin, not the tracker's capsules) rendered around the truth's joint centres
and streamed to one video per camera and to the truth masks -> the session folder.

The session is assembled in a temporary folder beside the target and renamed into place at the
end, so an interrupted run never leaves a half-written session.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import cv2
import h5py
import numpy as np
import yaml
from tqdm import tqdm

from gaitcap import __version__
from gaitcap.body.model import load_body_spec
from gaitcap.camera import CameraRig
from gaitcap.errors import OutputError
from gaitcap.io.atomic import default_dir_mode, unwritable
from gaitcap.io.calibration_toml import write_calibration
from gaitcap.io.trajectories_h5 import label_units
from gaitcap.io.video_write import CODECS, AtomicVideoWriter
from gaitcap.markers.motion import read_motion
from gaitcap.session import BACKGROUND_DIR, CALIBRATION_FILE, SESSION_FILE, VIDEOS_DIR
from gaitcap.synth.fit import REQUIRED, FitResult, estimate_height, fit_body
from gaitcap.synth.mannequin import Mannequin
from gaitcap.synth.placement import place_cameras_at, walking_direction
from gaitcap.synth.render import Renderer
from gaitcap.synth.scene import Room, Scene
from gaitcap.synth.truth import write_events
from gaitcap.synth.variety import Look, draw_look
from gaitcap.trajectory import POINT_NAMES, GaitEvent, Trajectory

log = logging.getLogger("gaitcap.synth")

TRUTH_FILE = "truth.h5"


@dataclass(frozen=True)
class SynthOptions:
    """Everything ``gaitcap synth`` can be told (defaults: 2 cameras, 640x480, 25 fps).

    The person, clothes, room, light and camera placement are drawn from ``seed``
    (:func:`gaitcap.synth.variety.draw_look`); ``azimuths_deg``, ``shadow`` and ``distortion``
    override the drawn ones.
    """

    cameras: int = 2
    size: tuple[int, int] = (640, 480)
    fps: float = 25.0
    shadow: bool = True
    distortion: bool = True
    azimuths_deg: tuple[float, ...] | None = None
    codec: str = "mp4v"
    seed: int = 0
    height_m: float | None = None  # the recorded subject's height when the file has none
    subject_height_m: float | None = None  # scale the walk uniformly to a subject of this height
    body_config: str | None = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not 1 <= self.cameras <= 8:
            raise ValueError("cameras must be between 1 and 8")
        if self.fps <= 0:
            raise ValueError("fps must be positive")
        if self.codec not in CODECS:
            raise ValueError(f"unknown codec {self.codec!r} (choose from {', '.join(CODECS)})")
        if self.azimuths_deg is not None and len(self.azimuths_deg) != self.cameras:
            raise ValueError(f"{len(self.azimuths_deg)} azimuths for {self.cameras} cameras")
        if self.subject_height_m is not None and not 0.8 <= self.subject_height_m <= 2.2:
            raise ValueError("subject_height_m must be between 0.8 and 2.2 m")


@dataclass(frozen=True)
class SynthResult:
    session: Path
    n_frames: int
    cameras: list[str]
    fit: FitResult
    truth: Trajectory
    look: Look


def _events_on_video_time(events: Sequence[GaitEvent], t0: float, duration: float) -> tuple[GaitEvent, ...]:
    out = []
    for e in events:
        t = e.time_s - t0
        if -1e-9 <= t <= duration + 1e-9:
            out.append(GaitEvent(float(t), e.side, e.event, e.source))
    return tuple(out)


def scale_walk(traj: Trajectory, height_m: float, source_height_m: float) -> Trajectory:
    """The walk of a subject ``height_m`` tall: points scaled about the walk's mean floor position."""
    k = height_m / source_height_m
    pts = traj.points.copy()
    centre = np.nanmean(pts.reshape(-1, 3), axis=0)
    centre[2] = 0.0
    pts = centre + k * (pts - centre)
    return replace(traj, points=pts, meta={**traj.meta, "height_m": height_m})


def truth_points(traj: Trajectory, fit: FitResult) -> np.ndarray:
    """(T, P, 3) under POINT_NAMES: the motion's joint centres, completed by the fitted model's."""
    names = fit.model.point_names
    out = np.array(fit.points, dtype=np.float64)
    for name in POINT_NAMES:
        if traj.has(name):
            obs = traj.point(name)
            ok = np.all(np.isfinite(obs), axis=1)
            out[ok, names.index(name)] = obs[ok]
    return out[:, [names.index(n) for n in POINT_NAMES]]


def _floor_mat(points: np.ndarray, direction: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """A walkway mat under the walk: (centre xy, direction xy, length, width)."""
    xy = points.reshape(-1, 3)[:, :2]
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    centre = 0.5 * (xy.min(axis=0) + xy.max(axis=0))
    along = (xy - centre) @ direction[:2]
    length = float(np.ptp(along)) + 2.0
    return centre, direction[:2] / np.linalg.norm(direction[:2]), length, width


#: a session shorter than this (s) holds no gait cycle: its report finds no parameters
MIN_CYCLE_S = 1.0


def _warn_short(traj: Trajectory, motion: str | Path, fps: float) -> None:
    """Warn when the walk, at the videos' ``fps``, is too short for a gait cycle (a few frames of a
    marker file's start, or a static trial given as the walk)."""
    if traj.n_frames < MIN_CYCLE_S * fps:
        log.warning("%s: the walk lasts %.2f s, %d frame%s at %g fps: too short for a gait cycle (the report "
                    "needs a stride, about %g s), so the session can be tracked but not analysed", Path(motion).name,
                    (traj.n_frames - 1) / fps, traj.n_frames, "" if traj.n_frames == 1 else "s", fps, MIN_CYCLE_S)  # fmt: skip


def synthesize(
    motion: str | Path, out: str | Path, options: SynthOptions = SynthOptions(), force: bool = False, progress: bool = True,
    mapping: str | Path | None = None, subject: str | None = None, static: str | Path | None = None,
) -> SynthResult:
    """Render a synthetic session from ``motion`` into the folder ``out`` (see the module docstring).

    ``mapping``, ``subject`` and ``static`` go to :func:`gaitcap.markers.motion.read_motion` (None: the
    shipped mapping that fits, the subject with the most markers, the static trial the mapping names)."""
    out = Path(out)
    _check_output(out, force)
    traj = read_motion(motion, mapping=mapping, static=static, subject=subject, require=REQUIRED)
    source_t0 = traj.t0_s
    if options.height_m and not traj.meta.get("height_m"):
        traj = replace(traj, meta={**traj.meta, "height_m": options.height_m})
    if options.subject_height_m is not None:
        traj = scale_walk(traj, options.subject_height_m, estimate_height(traj))
    traj = traj.resample(options.fps)
    _warn_short(traj, motion, options.fps)
    spec = load_body_spec(options.body_config)
    log.info("fitting the body model to %d frames of %s (to complete the truth)", traj.n_frames, Path(motion).name)
    fit = fit_body(spec, traj)
    points = truth_points(traj, fit)
    height = float(fit.model.height_m)
    look = draw_look(options.seed, height, options.cameras)
    plan = look.cameras
    k = POINT_NAMES.index
    direction = walking_direction(points[:, k("pelvis")], points[:, k("hip_l")], points[:, k("hip_r")])
    cams = place_cameras_at(
        points, direction, options.azimuths_deg or plan.azimuths_deg, plan.distances_m, plan.heights_m,
        size=options.size, distortion=(plan.k1, 0.2 * abs(plan.k1), 0.0, 0.0) if options.distortion else (0, 0, 0, 0),
    )  # fmt: skip
    rig = CameraRig(tuple(cams))
    room = Room.around(np.vstack([points.reshape(-1, 3), [c.center for c in cams]]))
    scene = Scene(room, look.room, _floor_mat(points, direction, look.room.mat_width_m))
    views = [scene.view(c) for c in cams]
    lighting = look.lighting if options.shadow else replace(look.lighting, shadow_strength=0.0)
    T = traj.n_frames
    renderer = Renderer(Mannequin(look.build, look.outfit), room, views, lighting, T, seed=options.seed)
    truth = Trajectory(
        names=POINT_NAMES, points=points, rate_hz=options.fps, t0_s=0.0,
        events=_events_on_video_time(traj.events, traj.t0_s, (T - 1) / options.fps),
        meta={"source": str(motion), "height_m": height},
    )  # fmt: skip

    tmp = _temporary_folder(out)
    try:
        _write_session(tmp, rig, renderer, fit, traj, truth, options, look, motion, source_t0, progress)
        if out.exists():
            shutil.rmtree(out) if out.is_dir() else out.unlink()
        os.chmod(tmp, default_dir_mode())
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    log.info("wrote %s: %d frames, %d cameras", out, T, len(cams))
    return SynthResult(session=out, n_frames=T, cameras=rig.names, fit=fit, truth=truth, look=look)


#: what a synthetic session folder holds: a folder holding anything else is not replaced (--force)
_SESSION_ENTRIES = {CALIBRATION_FILE, SESSION_FILE, TRUTH_FILE, VIDEOS_DIR, BACKGROUND_DIR}


def _check_output(out: Path, force: bool) -> None:
    """Refuse an output that exists (unless ``force``), that is not a synthetic session's folder (whose
    files ``force`` would delete), or that cannot be written: before any work."""
    if out.is_file():
        raise OutputError(f"{out}: is a file; give a folder for the session")
    entries = sorted(p.name for p in out.iterdir()) if out.is_dir() else []
    if entries and not force:
        raise OutputError(f"{out}: already exists (use --force to replace it)")
    others = [e for e in entries if e not in _SESSION_ENTRIES]
    if others:
        listed = ", ".join(others[:5]) + (", ..." if len(others) > 5 else "")
        raise OutputError(f"{out}: holds files that are not a synthetic session's ({listed}): not replaced, even with "
                          "--force; give a new or empty folder")  # fmt: skip
    os.rmdir(_temporary_folder(out))  # can a session be written beside it?


def _temporary_folder(out: Path) -> Path:
    """A new hidden folder beside ``out`` to write the session into (renamed to ``out`` when complete)."""
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    except OSError as e:
        raise unwritable(out, e) from e


def _write_session(
    root: Path, rig: CameraRig, renderer: Renderer, fit: FitResult, traj: Trajectory, truth: Trajectory,
    options: SynthOptions, look: Look, motion: str | Path, source_t0: float, progress: bool,
) -> None:  # fmt: skip
    (root / VIDEOS_DIR).mkdir()
    (root / BACKGROUND_DIR).mkdir()
    write_calibration(root / CALIBRATION_FILE, rig, {"source": "gaitcap synth (exact)"})
    info = {"subject": {"height_m": round(float(fit.model.height_m), 4)},
            "notes": f"synthetic session rendered by gaitcap {__version__} from {Path(motion).name}"}  # fmt: skip
    (root / SESSION_FILE).write_text(yaml.safe_dump(info, sort_keys=False), encoding="utf-8")
    for cam, plate in zip(rig, renderer.render_background()):
        if not cv2.imwrite(str(root / BACKGROUND_DIR / f"{cam.name}.png"), plate):
            raise OutputError(f"{root / BACKGROUND_DIR / cam.name}.png: cannot write")
    ext = CODECS[options.codec][1]
    T = truth.n_frames
    w, h = options.size
    with h5py.File(root / TRUTH_FILE, "w") as f:
        _write_truth_header(f, fit, traj, truth, options, look, motion, source_t0)
        masks = {c.name: f.create_dataset(f"masks/{c.name}", shape=(T, h, w), dtype=np.uint8,
                                          chunks=(1, h, w), compression="gzip", compression_opts=4)
                 for c in rig}  # fmt: skip
        writers = [AtomicVideoWriter(root / VIDEOS_DIR / f"{c.name}{ext}", options.fps, options.size, options.codec) for c in rig]
        try:
            # disable=None: no bar when stderr is not a terminal (a log file)
            for t in tqdm(range(T), desc="rendering", unit="frame", disable=None if progress else True, leave=False):
                for (img, mask), cam, writer in zip(renderer.render(truth.points[t], t), rig, writers):
                    writer.write(img)
                    masks[cam.name][t] = mask
        except BaseException as e:
            for wr in writers:
                wr.__exit__(type(e), e, e.__traceback__)
            raise
        for wr in writers:
            wr.__exit__(None, None, None)


def _write_truth_header(
    f: h5py.File, fit: FitResult, traj: Trajectory, truth: Trajectory, options: SynthOptions, look: Look,
    motion: str | Path, source_t0: float,
) -> None:  # fmt: skip
    pts = f.create_dataset("points", data=truth.points)
    pts.attrs["names"] = list(truth.names)
    pts.attrs["rate_hz"] = truth.rate_hz
    pts.attrs["t0_s"] = 0.0
    f.create_dataset("times", data=truth.times())
    poses = f.create_dataset("poses", data=fit.poses)
    poses.attrs["dof_names"] = list(fit.model.dof_names)
    poses.attrs["dof_units"] = ["rad" if r else "m" for r in fit.model.is_rotation]
    raw = f.create_dataset("raw_points", data=traj.points)
    raw.attrs["names"] = list(traj.names)
    res = f.create_dataset("fit_residual_m", data=np.array([fit.residual_m[n] for n in traj.names if n in fit.residual_m]))
    res.attrs["names"] = [n for n in traj.names if n in fit.residual_m]
    write_events(f.create_group("events"), truth.events)
    label_units(f)  # points, times, raw points, fit residuals, event times
    scales, shifts = fit.model.proportions()
    f.attrs["gaitcap_version"] = __version__
    f.attrs["source_motion"] = str(motion)
    f.attrs["source_t0_s"] = float(traj.t0_s)
    f.attrs["source_file_t0_s"] = float(source_t0)
    f.attrs["height_m"] = float(fit.model.height_m)
    f.attrs["proportions"] = json.dumps({"scales": scales, "shifts": shifts})
    f.attrs["options"] = json.dumps(asdict(options))
    f.attrs["look"] = json.dumps(asdict(look))
    f.attrs["conditions"] = json.dumps(look.describe())
