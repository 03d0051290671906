"""``gaitcap synth``: render a synthetic session, with ground truth, from a real walk.

motion file -> joint centres (gaitcap.markers) -> resampled to the video rate -> body model fitted
(gaitcap.synth.fit) -> cameras placed (placement) -> textured room (scene) -> frames rendered and
streamed to one video per camera and to the truth masks -> the session folder.

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
from dataclasses import asdict, dataclass, field
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
from gaitcap.io.atomic import default_dir_mode
from gaitcap.io.calibration_toml import write_calibration
from gaitcap.io.video_write import CODECS, AtomicVideoWriter
from gaitcap.markers.motion import read_motion
from gaitcap.session import BACKGROUND_DIR, CALIBRATION_FILE, SESSION_FILE, VIDEOS_DIR
from gaitcap.synth.fit import FitResult, fit_body
from gaitcap.synth.placement import DEFAULT_DISTORTION, place_cameras
from gaitcap.synth.render import Renderer, RenderOptions
from gaitcap.synth.scene import Room, Scene
from gaitcap.synth.truth import write_events
from gaitcap.trajectory import GaitEvent, Trajectory

log = logging.getLogger("gaitcap.synth")

TRUTH_FILE = "truth.h5"


@dataclass(frozen=True)
class SynthOptions:
    """Everything ``gaitcap synth`` can be told (defaults: 2 cameras, 640x480, 25 fps)."""

    cameras: int = 2
    size: tuple[int, int] = (640, 480)
    fps: float = 25.0
    clothing: str = "default"
    shadow: bool = True
    noise_sigma: float = 2.5
    drift: float = 0.06
    distortion: bool = True
    camera_height_m: float = 1.1
    azimuths_deg: tuple[float, ...] | None = None
    codec: str = "mp4v"
    seed: int = 0
    height_m: float | None = None
    body_config: str | None = None
    light_direction: tuple[float, float, float] | None = None  # default: from the walk's geometry
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not 1 <= self.cameras <= 8:
            raise ValueError("cameras must be between 1 and 8")
        if self.fps <= 0:
            raise ValueError("fps must be positive")
        if self.codec not in CODECS:
            raise ValueError(f"unknown codec {self.codec!r} (choose from {', '.join(CODECS)})")


@dataclass(frozen=True)
class SynthResult:
    session: Path
    n_frames: int
    cameras: list[str]
    fit: FitResult
    truth: Trajectory


def _light_direction(rig: CameraRig, fit_points: np.ndarray) -> tuple[float, float, float]:
    """Light from the far side, high: the shadow falls towards the first (lateral) camera and ahead."""
    centre = np.nanmean(fit_points.reshape(-1, 3), axis=0)
    towards = rig[0].center - centre
    towards[2] = 0
    towards /= np.linalg.norm(towards)
    d = np.array([towards[1], -towards[0], 0.0])  # along the walk
    L = 0.45 * towards + 0.2 * d + np.array([0.0, 0.0, -0.85])
    return tuple(float(v) for v in L / np.linalg.norm(L))


def _events_on_video_time(events: Sequence[GaitEvent], t0: float, duration: float) -> tuple[GaitEvent, ...]:
    out = []
    for e in events:
        t = e.time_s - t0
        if -1e-9 <= t <= duration + 1e-9:
            out.append(GaitEvent(float(t), e.side, e.event, e.source))
    return tuple(out)


def synthesize(
    motion: str | Path, out: str | Path, options: SynthOptions = SynthOptions(), force: bool = False, progress: bool = True,
    mapping: str | Path | None = None, subject: str | None = None,
) -> SynthResult:
    """Render a synthetic session from ``motion`` into the folder ``out`` (see the module docstring).

    ``mapping`` and ``subject`` go to :func:`gaitcap.markers.motion.read_motion` (None: the
    shipped mapping that fits, the subject with the most markers)."""
    out = Path(out)
    occupied = out.is_file() or (out.is_dir() and any(out.iterdir()))
    if occupied and not force:
        raise OutputError(f"{out}: already exists (use --force to replace it)")
    traj = read_motion(motion, mapping=mapping, subject=subject)
    source_t0 = traj.t0_s
    traj = traj.resample(options.fps)
    spec = load_body_spec(options.body_config)
    log.info("fitting the body model to %d frames of %s", traj.n_frames, Path(motion).name)
    fit = fit_body(spec, traj, height_m=options.height_m)
    points = fit.points
    k = fit.model.point_index
    cams = place_cameras(
        points, points[:, k("pelvis")], points[:, k("hip_l")], points[:, k("hip_r")],
        n_cameras=options.cameras, size=options.size, height_m=options.camera_height_m,
        azimuths_deg=options.azimuths_deg, distortion=DEFAULT_DISTORTION if options.distortion else (0, 0, 0, 0),
    )  # fmt: skip
    rig = CameraRig(tuple(cams))
    room = Room.around(np.vstack([points.reshape(-1, 3), [c.center for c in cams]]))
    scene = Scene(room, seed=options.seed)
    views = [scene.view(c) for c in cams]
    render_opts = RenderOptions(
        clothing=options.clothing, shadow=options.shadow, noise_sigma=options.noise_sigma, drift=options.drift,
        seed=options.seed, light_direction=options.light_direction or _light_direction(rig, points),
    )  # fmt: skip
    T = traj.n_frames
    renderer = Renderer(fit.model, room, views, render_opts, T)
    truth = Trajectory(
        names=fit.model.point_names, points=points, rate_hz=options.fps, t0_s=0.0,
        events=_events_on_video_time(traj.events, traj.t0_s, (T - 1) / options.fps),
        meta={"source": str(motion), "height_m": fit.model.height_m},
    )  # fmt: skip

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        _write_session(tmp, rig, renderer, fit, traj, truth, options, motion, source_t0, progress)
        if out.exists():
            shutil.rmtree(out) if out.is_dir() else out.unlink()
        os.chmod(tmp, default_dir_mode())
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    log.info("wrote %s: %d frames, %d cameras", out, T, len(cams))
    return SynthResult(session=out, n_frames=T, cameras=rig.names, fit=fit, truth=truth)


def _write_session(
    root: Path, rig: CameraRig, renderer: Renderer, fit: FitResult, traj: Trajectory, truth: Trajectory,
    options: SynthOptions, motion: str | Path, source_t0: float, progress: bool,
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
        _write_truth_header(f, fit, traj, truth, options, motion, source_t0)
        masks = {c.name: f.create_dataset(f"masks/{c.name}", shape=(T, h, w), dtype=np.uint8,
                                          chunks=(1, h, w), compression="gzip", compression_opts=4)
                 for c in rig}  # fmt: skip
        writers = [AtomicVideoWriter(root / VIDEOS_DIR / f"{c.name}{ext}", options.fps, options.size, options.codec) for c in rig]
        try:
            for t in tqdm(range(T), desc="rendering", unit="frame", disable=not progress, leave=False):
                for (img, mask), cam, writer in zip(renderer.render(fit.poses[t], t), rig, writers):
                    writer.write(img)
                    masks[cam.name][t] = mask
        except BaseException as e:
            for wr in writers:
                wr.__exit__(type(e), e, e.__traceback__)
            raise
        for wr in writers:
            wr.__exit__(None, None, None)


def _write_truth_header(
    f: h5py.File, fit: FitResult, traj: Trajectory, truth: Trajectory, options: SynthOptions,
    motion: str | Path, source_t0: float,
) -> None:  # fmt: skip
    pts = f.create_dataset("points", data=truth.points)
    pts.attrs["names"] = list(truth.names)
    pts.attrs["rate_hz"] = truth.rate_hz
    pts.attrs["t0_s"] = 0.0
    f.create_dataset("times", data=truth.times())
    poses = f.create_dataset("poses", data=fit.poses)
    poses.attrs["dof_names"] = list(fit.model.dof_names)
    raw = f.create_dataset("raw_points", data=traj.points)
    raw.attrs["names"] = list(traj.names)
    res = f.create_dataset("fit_residual_m", data=np.array([fit.residual_m[n] for n in traj.names if n in fit.residual_m]))
    res.attrs["names"] = [n for n in traj.names if n in fit.residual_m]
    write_events(f.create_group("events"), truth.events)
    scales, shifts = fit.model.proportions()
    f.attrs["gaitcap_version"] = __version__
    f.attrs["source_motion"] = str(motion)
    f.attrs["source_t0_s"] = float(traj.t0_s)
    f.attrs["source_file_t0_s"] = float(source_t0)
    f.attrs["height_m"] = float(fit.model.height_m)
    f.attrs["proportions"] = json.dumps({"scales": scales, "shifts": shifts})
    opts = asdict(options)
    f.attrs["options"] = json.dumps(opts)
